"""Why the silhouette shadow volume is wrong on the triangle soup (``sv_soup``, issue 37).

Measures ``shadow_volume`` (and its counting modes) against the truth on ``sv_soup`` and sorts
every wrong evaluated pixel into:

- **edge ties**: the truth's shadow ray passes within ``--tie`` pixel widths (the world size of a
  pixel at the point) of a caster triangle's edge
  (:func:`shadowlab.truth.tracing.edge_distances`), where a rasterised volume side and the
  watertight ray test may fall either way; the same fraction is given for random evaluated
  pixels, to show how common such rays are in the scene;
- **the rest**: the object each lies on, the truth's verdict and the distance (in pixel widths)
  from its point to the nearest caster triangles — a point on or against another triangle (a
  crossing, a contact) shows a distance near 0.

Prints the counts and the stencil's peak count (a wrapped 8-bit count would read lit).

    python experiments/soup_error.py [--size 320x240] [--tie 0.05]
"""
from __future__ import annotations

import argparse

import numpy as np
import trimesh

from shadowlab.gpu.frame import Frame
from shadowlab.measurement.pipeline import Evaluator, measure
from shadowlab.scene import load_scene
from shadowlab.techniques import from_spec
from shadowlab.truth.tracing import edge_distances, offset_origins

MODES = ("shadow_volume", "shadow_volume:mode=zpass", "shadow_volume:mode=zfail", "shadow_volume:far=clamp")
#: Random evaluated pixels whose ray-to-edge distance is sampled for comparison.
RANDOM_PIXELS = 300


def parse_size(text: str) -> tuple[int, int]:
    """``"320x240"`` → (320, 240)."""
    w, h = (int(v) for v in text.lower().split("x"))
    return w, h


def pixel_widths(frame, points: np.ndarray) -> np.ndarray:
    """The world size of one pixel at each point (the camera's vertical field over the rows)."""
    dist = np.linalg.norm(points - np.asarray(frame.camera.eye, float), axis=1)
    return dist * 2.0 * np.tan(np.radians(frame.camera.fov_y) / 2.0) / frame.height


def main() -> None:
    """Measure, classify the wrong pixels, print."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--size", type=parse_size, default=(320, 240))
    ap.add_argument("--tie", type=float, default=0.05, help="edge distance (pixel widths) counted as a tie")
    args = ap.parse_args()
    frame = Frame(load_scene("sv_soup"), *args.size)
    truth = Evaluator(frame, truth=from_spec("raytrace")).truth(0).visibility < 0.5
    evaluated = frame.evaluated(0)
    light = frame.scene.lights[0]
    corners = np.concatenate([np.asarray(o.vertices, np.float32)[np.asarray(o.faces)]
                              for o in frame.scene.objects if o.casts])
    compact = {p: i for i, p in enumerate(frame.pixel_index)}
    for spec in MODES:
        m = measure(from_spec(spec), frame, 0, repeat=1, warmup=0, count=False)
        shadow = m.visibility < 0.5
        wrong = (shadow != truth) & evaluated
        print(f"{spec}: {int(wrong.sum())} wrong of {int(evaluated.sum())} evaluated "
              f"(false lit {int((wrong & truth).sum())}, false shadow {int((wrong & ~truth).sum())}), "
              f"stencil peak count {m.stats.get('stencil_peak_count')}")
        if spec != MODES[0]:
            continue
        sel = np.array([compact[p] for p in np.flatnonzero(wrong.ravel())], int)
        origins, points = offset_origins(frame)[sel], frame.compact_position[sel]
        dirs, tfar = light.shadow_rays(origins, points)
        ties = edge_distances(origins, dirs, tfar, corners) / pixel_widths(frame, points) < args.tie
        rng = np.random.default_rng(0)
        sample = rng.choice(len(frame.pixel_index), RANDOM_PIXELS, replace=False)
        o2, p2 = offset_origins(frame)[sample], frame.compact_position[sample]
        d2, t2 = light.shadow_rays(o2, p2)
        random_ties = np.mean(edge_distances(o2, d2, t2, corners) / pixel_widths(frame, p2) < args.tie)
        print(f"  edge ties (ray within {args.tie} pixel widths of an edge): {int(ties.sum())} of {len(sel)}; "
              f"random evaluated pixels that close: {100 * random_ties:.1f} %")
        rest = sel[~ties]
        objects = frame.compact_object[rest]
        rest_truth = truth.ravel()[frame.pixel_index[rest]]
        names = [frame.scene.objects[i].name for i in objects]
        print(f"  the other {len(rest)}: on {dict(zip(*np.unique(names, return_counts=True)))}, "
              f"lit in the truth: {int((~rest_truth).sum())}")
        widths = pixel_widths(frame, frame.compact_position[rest])
        for p, w in zip(frame.compact_position[rest], widths):
            near = trimesh.triangles.closest_point(corners.astype(float), np.repeat(p[None], len(corners), 0))
            d = np.sort(np.linalg.norm(near - p, axis=1))[:3] / w
            print(f"    point {np.round(p, 3)}: nearest caster triangles at {np.round(d, 4)} pixel widths")


if __name__ == "__main__":
    main()
