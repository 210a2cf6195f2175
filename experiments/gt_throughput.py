"""Ground-truth throughput against raw Embree occlusion, in the same process.

For each scene and size: the ground truth's per-light work (ray generation from the cached
offset origins + Embree occlusion + bookkeeping) in shadow rays per second, beside a raw
``embreex`` occlusion query over exactly the same rays. The per-frame work the ground truth
shares with evaluation (exact float64 hit points) and its own per-frame work (offset origins)
are reported separately, and amortised over one light in ``gt_end_to_end_rays_per_s``.

    python experiments/gt_throughput.py [--sizes 800x600,1600x1200] [--repeat 9] [--out results/gt_throughput.csv]
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import pandas as pd

from shadowlab import gl
from shadowlab.frame import Frame
from shadowlab.run import parse_size
from shadowlab.scene import load_scene
from shadowlab.techniques.raytrace import RayTraced, occluded


def median_time(fn, repeat):
    fn()  # warm-up
    ts = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t0)
    return float(np.median(ts))


def measure(scene_name, size, repeat):
    scene = load_scene(scene_name)
    frame = Frame(scene, *size)
    t_exact = median_time(frame._exact_points, repeat)
    gt = RayTraced()
    gt.setup(frame, 0)

    def origins():
        frame.__dict__.get("_cache", {}).pop(("raytrace_origins", gt.offset_scale), None)
        gt._origins(frame)
    t_origins = median_time(origins, repeat)
    t_gt = median_time(gt.render, repeat)
    # The identical rays, prepared outside the timed region, through embreex alone.
    org = gt.eval_origins
    light = scene.lights[0]
    if light.type_name in ("point", "spot"):
        dirs = light.position.astype(np.float32) - org
        tfar = np.full(len(org), 1.0 - 2.0 ** -20, np.float32)
    else:
        dirs = np.broadcast_to((-light.direction).astype(np.float32), org.shape).copy()
        tfar = np.full(len(org), 1e30, np.float32) if light.type_name == "directional" else \
            ((gt.eval_points - light.position) @ light.direction).astype(np.float32)
    t_raw = median_time(lambda: occluded(gt.scene, org, dirs, tfar), repeat)
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
    ap.add_argument("--sizes", default="800x600,1600x1200")
    ap.add_argument("--repeat", type=int, default=9)
    ap.add_argument("--out", default="results/gt_throughput.csv")
    args = ap.parse_args()
    rows = [measure(s, parse_size(z), args.repeat) for s in args.scenes.split(",") for z in args.sizes.split(",")]
    df = pd.DataFrame(rows)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    df.to_csv(out, index=False)
    with pd.option_context("display.width", 250):
        print(df.to_string(index=False, float_format=lambda x: f"{x:.4g}"))
    print(f"renderer: {gl.renderer()}  (timings: wall clock, median of {args.repeat})")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
