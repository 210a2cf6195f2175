"""Ground-truth throughput against raw Embree occlusion, in the same process.

For each scene and size: the ground truth's per-light work (ray generation from the cached
offset origins + Embree occlusion + bookkeeping) in shadow rays per second, beside a raw
``embreex`` occlusion query over exactly the same rays. The per-frame work the ground truth
shares with evaluation (exact float64 hit points) and its own per-frame work (offset origins)
are reported separately, and amortised over one light in ``gt_end_to_end_rays_per_s``.
Writes results/gt_throughput.csv and its provenance (.json).

    python experiments/gt_throughput.py [--sizes 320x240] [--repeat 5]
    (the figures in the notes: --sizes 800x600,1600x1200 --repeat 9)
"""
from __future__ import annotations

import argparse
from pathlib import Path

import pandas as pd

from shadowlab import gl, provenance
from shadowlab.cli import parse_size
from shadowlab.frame import Frame
from shadowlab.scene import load_scene
from shadowlab.techniques.raytrace import RayTraced, occluded, offset_origins
from shadowlab.timing import time_passes


def median_s(fn, repeat):
    """Median wall-clock seconds of ``fn`` (CPU work: no GL finish), after one warm-up."""
    return time_passes(fn, repeat=repeat, warmup=1, gpu=False).median_ms / 1e3


def measure(scene_name, size, repeat):
    scene = load_scene(scene_name)
    frame = Frame(scene, *size)
    t_exact = median_s(frame.compute_exact_points, repeat)
    gt = RayTraced()
    gt.setup(frame, 0)
    t_origins = median_s(lambda: offset_origins(frame, gt.offset_scale, cached=False), repeat)
    t_gt = median_s(gt.render, repeat)
    # The identical rays, prepared outside the timed region, through embreex alone.
    light = scene.lights[0]
    org = gt.eval_origins
    dirs, tfar = light.shadow_rays(org, gt.eval_points)
    t_raw = median_s(lambda: occluded(gt.scene, org, dirs, tfar), repeat)
    frame.release()
    n = len(org)
    return {
        "scene": scene_name, "width": size[0], "height": size[1], "light": light.type_name, "rays": n,
        "raw_embree_rays_per_s": n / t_raw, "gt_rays_per_s": n / t_gt, "gt_over_raw": t_raw / t_gt,
        "gt_per_light_ms": 1e3 * t_gt, "raw_embree_ms": 1e3 * t_raw,
        "exact_points_ms_per_frame": 1e3 * t_exact, "offset_origins_ms_per_frame": 1e3 * t_origins,
        "gt_end_to_end_rays_per_s": n / (t_gt + t_exact + t_origins),
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", default="box_on_plane,spot_scene,sun_scene,target_direct_scene")
    ap.add_argument("--sizes", default="320x240")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--out", default="results/gt_throughput.csv")
    args = ap.parse_args()
    rows = [measure(s, parse_size(z), args.repeat) for s in args.scenes.split(",") for z in args.sizes.split(",")]
    df = pd.DataFrame(rows)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    df.to_csv(out, index=False)
    provenance.write_record(out, {"timing": f"wall clock, median of {args.repeat} after 1 warm-up"})
    with pd.option_context("display.width", 250):
        print(df.to_string(index=False, float_format=lambda x: f"{x:.4g}"))
    print(f"renderer: {gl.renderer()}  (timings: wall clock, median of {args.repeat})")
    print(f"wrote {out} and {out.with_suffix('.json')}")


if __name__ == "__main__":
    main()
