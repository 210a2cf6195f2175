"""Issue 11, before and after, in one table: each slow path timed the old way and the new way in
the same process, on the same inputs, and the outputs compared.

- ``shadow_polygons``: the preprocessing (bulk culling + clipping + triangulation) with the
  one-pair clipper in a Python loop (``clipper='scalar'``, the code this replaced, run once)
  against the numpy batch clipper and the compiled (numba) kernel, the default (median of
  ``--repeat``, the kernel loaded first); the fragments must be bit-identical.
  The "before" here already uses the new bulk culling (~1 s faster than the old one on these
  scenes), so the speed-up it shows is, if anything, understated.
- ``truth``: the per-frame work of the ray-traced truth — exact float64 hit points and offset
  shadow-ray origins — computed the straightforward way (every pixel's ray from
  ``Camera.pixel_rays``, then ``geometry.rays.ray_plane_hits``; the origins' formula with its
  temporaries) against ``Frame.compute_exact_points`` and ``offset_origins``; must be
  bit-identical. Then end-to-end shadow rays per second (per-frame work + tracing) against raw
  Embree over the same rays, with the scene's own light and with 8 point lights.
- ``shadow_volume``: one torus of ``--torus`` triangles (camera outside every volume), 640x480:
  the whole timed render with ``mode=zpass``, ``zfail`` and ``auto``, interleaved; auto's mask
  must equal z-fail's on every covered pixel.
- ``setup`` and ``memory``: every default technique's ``setup_ms`` beside its frame time (not
  measured before issue 11), and the peak resident memory of the torus scene's measurements.

Timings are wall clock (``ctx.finish()`` around GL work), on whatever runs this; the renderer is
printed and recorded. Writes results/perf_before_after.csv and its provenance (.json).

    python experiments/perf_before_after.py [--torus 1000000] [--repeat 5]
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

from shadowlab.gpu import gl, memory
from shadowlab.output import provenance
from shadowlab.gpu.frame import Frame
from shadowlab.geometry.clipping import compiled as compiled_clipping
from shadowlab.geometry.rays import ray_plane_hits
from shadowlab.scene.lights import PointLight
from shadowlab.measurement.pipeline import measure
from shadowlab.scene import load_scene
from shadowlab.techniques import from_spec
from shadowlab.techniques.rays.raytrace import RayTraced
from shadowlab.truth.tracing import occluded, offset_origins
from shadowlab.geometry.clipping import fragment_triangles
from shadowlab.gpu.timing import time_passes

sys.path.insert(0, str(Path(__file__).parent))
from sv_scaling import torus_scene  # noqa: E402  (the scaling experiment's torus)


def median_ms(fn, repeat, gpu=False):
    """Median wall-clock ms of ``fn`` after one warm-up."""
    return time_passes(fn, repeat=repeat, warmup=1, gpu=gpu).median_ms


def row(part, case, quantity, before, after, identical=None, unit="ms", note=""):
    """One line of the table; ``speedup`` = before / after where both are times."""
    speedup = before / after if unit == "ms" and before and after else float("nan")
    return {"part": part, "case": case, "quantity": quantity, "unit": unit, "before": before, "after": after,
            "speedup": speedup, "identical": identical, "note": note}


# ---------------------------------------------------------------------------------- exact shadow polygons
def shadow_polygons_rows(scenes, repeat):
    rows = []
    for name in scenes:
        frame = Frame(load_scene(name), 400, 300)
        try:
            rec, _, cas = from_spec("shadow_polygons").polygons(frame, 0)
            light_h = frame.scene.lights[0].homogeneous()
            eps = 1e-9 * frame.scene.extent()
            compile_ms = compiled_clipping.warm()  # once per process, outside the timings (compile_ms)
            t0 = time.perf_counter()
            slow = fragment_triangles(rec, cas, light_h, eps, clipper="scalar")
            before = 1e3 * (time.perf_counter() - t0)
            note = f"{len(rec)} receiver x {len(cas)} caster triangles"
            for clipper in ("batch", "compiled"):
                fast = fragment_triangles(rec, cas, light_h, eps, clipper=clipper)
                after = median_ms(lambda: fragment_triangles(rec, cas, light_h, eps, clipper=clipper), repeat)
                same = (fast.triangles.tobytes() == slow.triangles.tobytes()
                        and np.array_equal(fast.receiver, slow.receiver) and fast.pairs == slow.pairs)
                extra = f", kernel load/compile {compile_ms:.0f} ms once per process" if clipper == "compiled" else ""
                rows.append(row("shadow_polygons", name, f"preprocessing ({clipper})", before, after, same,
                                note=f"{note}, {fast.pairs} pairs clipped, {fast.fragments} fragments{extra}"))
                print(f"  shadow_polygons {name} ({clipper}): {before / 1e3:.1f} s -> {after / 1e3:.3f} s, "
                      f"identical {same}", flush=True)
        finally:
            frame.release()
    return rows


# ---------------------------------------------------------------------------------- the truth's per-frame work
def straightforward_exact_points(frame):
    """The per-frame exact points as computed before issue 11: every pixel's ray, picked."""
    idx = np.flatnonzero(frame.covered)
    tri = frame.triangle_id.ravel()[idx]
    rays = frame.camera.pixel_rays(frame.width, frame.height).reshape(-1, 3)[idx]
    return ray_plane_hits(frame.camera.eye, rays, frame.triangles[tri, 0], frame.triangle_normals[tri])


def straightforward_origins(frame, offset_scale):
    """The offset origins as computed before issue 11."""
    p, n = frame.compact_position, frame.compact_normal
    scale = np.maximum(np.abs(p).max(axis=1), frame.scene.extent())
    return (p + (offset_scale * scale)[:, None] * n).astype(np.float32)


def eight_point_lights(scene):
    """8 point lights on a circle above the scene, each seeing it from another side."""
    lo, hi = scene.bounds()
    centre, size = (lo + hi) / 2, float(np.max(hi - lo))
    return [PointLight(position=centre + np.array([0.6 * size * np.cos(a), 0.8 * size, 0.6 * size * np.sin(a)]))
            for a in np.linspace(0.0, 2 * np.pi, 8, endpoint=False)]


def trace_times(frame, light_index, repeat):
    """(rays, truth's per-light ms, raw Embree ms over the same rays) for one light."""
    gt = RayTraced()
    gt.prepare(frame, light_index)
    t_gt = median_ms(gt.render, repeat)
    light = frame.scene.lights[light_index]
    dirs, tfar = light.shadow_rays(gt.eval_origins, gt.eval_points)
    t_raw = median_ms(lambda: occluded(gt.scene, gt.eval_origins, dirs, tfar), repeat)
    return len(gt.eval_origins), t_gt, t_raw


def truth_rows(scenes, size, repeat):
    rows = []
    for name in scenes:
        for lights in ("own", "8 point"):
            scene = load_scene(name)
            if lights != "own":
                scene.lights = eight_point_lights(scene)
            frame = Frame(scene, *size)
            try:
                scale = RayTraced().offset_scale
                pts, normals, valid = straightforward_exact_points(frame)
                same = (pts.tobytes() == frame.compact_position.tobytes()
                        and normals.tobytes() == frame.compact_normal.tobytes()
                        and np.array_equal(valid, frame.compact_valid)
                        and straightforward_origins(frame, scale).tobytes() == offset_origins(frame, scale).tobytes())
                ex_before = median_ms(lambda: straightforward_exact_points(frame), repeat)
                ex_after = median_ms(frame.compute_exact_points, repeat)
                or_before = median_ms(lambda: straightforward_origins(frame, scale), repeat)
                or_after = median_ms(lambda: offset_origins(frame, scale, cached=False), repeat)
                traced = [trace_times(frame, i, repeat) for i in range(len(scene.lights))]
            finally:
                frame.release()
            rays = sum(t[0] for t in traced)
            t_gt = sum(t[1] for t in traced)
            t_raw = sum(t[2] for t in traced)
            case = f"{name} {size[0]}x{size[1]}, {len(scene.lights)} light{'s' if len(scene.lights) > 1 else ''}"
            if lights == "own":
                rows.append(row("truth", case, "exact hit points (per frame)", ex_before, ex_after, same))
                rows.append(row("truth", case, "offset origins (per frame)", or_before, or_after, same))
                rows.append(row("truth", case, "per-frame work / one light's tracing", (ex_before + or_before) / t_gt,
                                (ex_after + or_after) / t_gt, unit="ratio"))
            rows.append(row("truth", case, "end-to-end shadow rays/s", rays / (1e-3 * (ex_before + or_before + t_gt)),
                            rays / (1e-3 * (ex_after + or_after + t_gt)), unit="rays/s",
                            note=f"raw Embree over the same rays: {rays / (1e-3 * t_raw):.3g} rays/s"))
            print(f"  truth {case}: per-frame {ex_before + or_before:.1f} -> {ex_after + or_after:.1f} ms, "
                  f"tracing {t_gt:.1f} ms, identical {same}", flush=True)
    return rows


# ---------------------------------------------------------------------------------- shadow volumes, setup, memory
def torus_rows(triangles, repeat):
    rows = []
    scene = torus_scene(triangles)
    frame = Frame(scene, 640, 480)
    try:
        samples = {m: [] for m in ("zpass", "zfail", "auto")}
        masks, stats = {}, {}
        for _ in range(repeat):  # interleaved, so a busy spell falls on every mode alike
            for mode in samples:
                m = measure(from_spec(f"shadow_volume:mode={mode}"), frame, 0, repeat=3, warmup=1)
                samples[mode] += m.timing.samples_ms
                masks[mode], stats[mode] = m.visibility, m.stats
        ms = {mode: float(np.median(v)) for mode, v in samples.items()}
        cov = frame.covered
        same = bool(np.array_equal(masks["auto"][cov], masks["zfail"][cov]))
        case = f"torus {len(scene.objects[1].faces)} triangles, 640x480"
        rows.append(row("shadow_volume", case, "frame time, default mode (zfail -> auto)", ms["zfail"], ms["auto"], same,
                        note=f"zpass {ms['zpass']:.1f} ms; auto / zpass = {ms['auto'] / ms['zpass']:.2f}; auto's z-fail "
                             f"casters: {stats['auto']['zfail_casters']}; fill per pixel zfail "
                             f"{stats['zfail']['fill_per_pixel']:.2f}, auto {stats['auto']['fill_per_pixel']:.2f}"))
        print(f"  shadow_volume {case}: zpass {ms['zpass']:.1f}, zfail {ms['zfail']:.1f}, auto {ms['auto']:.1f} ms, "
              f"auto mask == zfail {same}", flush=True)
        memory.reset_peak()
        peak = 0
        for spec in ("raytrace", "shadow_volume", "shadow_map", "planar"):
            m = measure(from_spec(spec), frame, 0, repeat=1, warmup=0)
            peak = max(peak, m.peak_rss_bytes)
            rows.append(row("setup", case, f"{spec}: setup / frame", float("nan"), m.setup_ms, unit="ms",
                            note=f"frame {m.timing.median_ms:.1f} ms; setup was not measured before issue 11"))
        rows.append(row("memory", case, "peak resident memory (truth, shadow_volume, shadow_map, planar)",
                        float("nan"), memory.mib(peak), unit="MiB", note="limit asked for: 4096 MiB"))
    finally:
        frame.release()
    return rows


def setup_rows(name, repeat):
    rows = []
    frame = Frame(load_scene(name), 400, 300)
    try:
        for spec in ("raytrace", "shadow_volume", "shadow_map", "planar", "shadow_polygons"):
            m = measure(from_spec(spec), frame, 0, repeat=repeat, warmup=1)
            rows.append(row("setup", f"{name} 400x300", f"{spec}: setup / frame", float("nan"), m.setup_ms,
                            note=f"frame {m.timing.median_ms:.2f} ms; setup was not measured before issue 11"))
    finally:
        frame.release()
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sp-scenes", default="sv_directional,spot_scene", help="shadow-polygon scenes")
    ap.add_argument("--gt-scenes", default="box_on_plane,spot_scene,rm_bunny", help="truth scenes")
    ap.add_argument("--gt-size", default="800x600")
    ap.add_argument("--torus", type=int, default=1_000_000, help="torus triangles for shadow volumes and memory")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--out", default="results/perf_before_after.csv")
    args = ap.parse_args()
    size = tuple(int(v) for v in args.gt_size.lower().split("x"))
    print("shadow polygons (the scalar runs take about a minute per scene) ...", flush=True)
    rows = shadow_polygons_rows(args.sp_scenes.split(","), args.repeat)
    print("ground truth ...", flush=True)
    rows += truth_rows(args.gt_scenes.split(","), size, args.repeat)
    print("shadow volumes, set-up and memory ...", flush=True)
    rows += torus_rows(args.torus, args.repeat)
    rows += setup_rows("spot_scene", args.repeat)
    df = pd.DataFrame(rows)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    df.to_csv(out, index=False)
    provenance.write_record(out, {"timing": f"wall clock, median of {args.repeat} after 1 warm-up (scalar clipper: one run)"})
    with pd.option_context("display.width", 250, "display.max_colwidth", 120):
        print(df.to_string(index=False, float_format=lambda x: f"{x:.4g}"))
    print(f"renderer: {gl.renderer()}")
    print(f"wrote {out} and {out.with_suffix('.json')}")


if __name__ == "__main__":
    main()
