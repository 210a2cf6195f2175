"""Ground-truth throughput against raw Embree occlusion, in the same process.

For each scene and size: the ground truth's per-light work (ray generation from the cached
offset origins + Embree occlusion + bookkeeping) in shadow rays per second, beside a raw
``embreex`` occlusion query over exactly the same rays. The per-frame work the ground truth
shares with evaluation (exact float64 hit points) and its own per-frame work (offset origins)
are reported separately, and amortised over one light in ``gt_end_to_end_rays_per_s``.
Area lights (``--area-scenes``): the scene's first light is replaced by a rect area light at its
position (``--area-edge`` square, emitting down) and the sampled truth (``--area-samples`` rays
per pixel, its worker threads) is timed end to end per light (sample generation, horizon test,
ray set-up, Embree, counting), beside raw Embree occlusion of exactly the same rays (generated
chunk by chunk outside the timed region, with the same chunks and seeds), run on the same
number of threads (``raw_embree_rays_per_s``) and on one (``raw_embree_1thread_rays_per_s``).
Writes results/gt_throughput.csv and its provenance (.json).

    python experiments/gt_throughput.py [--sizes 320x240] [--repeat 5]
    (the figures in the notes: --sizes 800x600,1600x1200 --repeat 9)
    python experiments/gt_throughput.py --scenes "" --area-scenes spot_scene --area-sizes 640x480
"""
from __future__ import annotations

import argparse
import time
import tomllib
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pandas as pd

from shadowlab import gl, provenance
from shadowlab.cli import parse_size
from shadowlab.frame import Frame
from shadowlab.scene.lights import T_LIGHT
from shadowlab.scene import load_scene, parse_scene, resolve_scene_path
from shadowlab.tracing import occluded, offset_origins
from shadowlab.techniques.raytrace import RayTraced, area_chunk_rays, area_chunks, area_workers
from shadowlab.timing import time_passes


def median_s(fn, repeat):
    """Median wall-clock seconds of ``fn`` (CPU work: no GL finish), after one warm-up."""
    return time_passes(fn, repeat=repeat, warmup=1, gpu=False).median_ms / 1e3


def measure(scene_name, size, repeat):
    scene = load_scene(scene_name)
    frame = Frame(scene, *size)
    t_exact = median_s(frame.compute_exact_points, repeat)
    gt = RayTraced()
    gt.prepare(frame, 0)
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


def area_scene(scene_name, edge):
    """The shipped scene with its lights replaced by one square rect light of side ``edge`` at
    the first light's position, emitting straight down (−y)."""
    path = resolve_scene_path(scene_name)
    data = tomllib.loads(path.read_text())
    pos = data["lights"][0]["position"]
    data["lights"] = [{"type": "area", "shape": "rect", "position": pos, "u": [edge, 0.0, 0.0], "v": [0.0, 0.0, edge]}]
    data["name"] = f"{data.get('name', scene_name)}_rect"
    return parse_scene(data, str(path), path.parent)


def raw_area_seconds(gt, threads):
    """Seconds of Embree occlusion alone over the sampled truth's rays (same chunks and seeds),
    ``threads`` chunks at a time; the rays of each group are generated outside the timed region."""
    chunks = area_chunks(len(gt.eval_points), gt.samples, gt.seed, gt.decorrelate)
    total, rays = 0.0, 0
    with ThreadPoolExecutor(threads) as pool:
        for g in range(0, len(chunks), threads):
            group = []
            for a, b, rng in chunks[g:g + threads]:
                _, _, org, dirs = area_chunk_rays(gt.light, gt.eval_points[a:b], gt.eval_normals[a:b],
                                                  gt.eval_origins[a:b], gt.samples, rng)
                group.append((org, dirs, np.full(len(org), T_LIGHT, np.float32)))
                rays += len(org)
            t0 = time.perf_counter()
            list(pool.map(lambda r: occluded(gt.scene, *r), group))
            total += time.perf_counter() - t0
    return total, rays


def measure_area(scene_name, size, repeat, samples, edge):
    """The sampled truth of a rect area light against raw Embree on the same rays."""
    scene = area_scene(scene_name, edge)
    frame = Frame(scene, *size)
    t_exact = median_s(frame.compute_exact_points, repeat)
    gt = RayTraced(samples=samples)
    gt.prepare(frame, 0)
    t_origins = median_s(lambda: offset_origins(frame, gt.offset_scale, cached=False), repeat)
    t_gt = median_s(gt.render, repeat)
    n = gt.stats()["rays"]
    threads = area_workers(samples, len(area_chunks(len(gt.eval_points), samples, gt.seed, gt.decorrelate)))
    t_raw, raw_rays = raw_area_seconds(gt, threads)
    t_raw1, _ = raw_area_seconds(gt, 1)
    assert raw_rays == n, (raw_rays, n)
    tris = sum(len(o.faces) for o in scene.objects)
    frame.release()
    return {
        "scene": scene.name, "width": size[0], "height": size[1], "light": "area/rect", "samples": samples,
        "triangles": tris, "pixels": int(len(gt.eval_points)), "threads": threads, "rays": n,
        "raw_embree_rays_per_s": n / t_raw, "raw_embree_1thread_rays_per_s": n / t_raw1,
        "gt_rays_per_s": n / t_gt, "gt_over_raw": t_raw / t_gt,
        "gt_per_light_ms": 1e3 * t_gt, "raw_embree_ms": 1e3 * t_raw,
        "exact_points_ms_per_frame": 1e3 * t_exact, "offset_origins_ms_per_frame": 1e3 * t_origins,
        "gt_end_to_end_rays_per_s": n / (t_gt + t_exact + t_origins),
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", default="box_on_plane,spot_scene,sun_scene,target_direct_scene")
    ap.add_argument("--sizes", default="320x240")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--area-scenes", default="spot_scene", help="scenes re-lit by a rect area light ('' for none)")
    ap.add_argument("--area-sizes", default="320x240")
    ap.add_argument("--area-samples", type=int, default=1024)
    ap.add_argument("--area-edge", type=float, default=1.0, help="side of the square area light")
    ap.add_argument("--area-repeat", type=int, default=1)
    ap.add_argument("--out", default="results/gt_throughput.csv")
    args = ap.parse_args()
    names = [s for s in args.scenes.split(",") if s]
    rows = [measure(s, parse_size(z), args.repeat) for s in names for z in args.sizes.split(",")]
    rows += [measure_area(s, parse_size(z), args.area_repeat, args.area_samples, args.area_edge)
             for s in args.area_scenes.split(",") if s for z in args.area_sizes.split(",")]
    df = pd.DataFrame(rows)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    df.to_csv(out, index=False)
    provenance.write_record(out, {"timing": f"wall clock, median of {args.repeat} (area lights: "
                                            f"{args.area_repeat}) after 1 warm-up"})
    with pd.option_context("display.width", 250):
        print(df.to_string(index=False, float_format=lambda x: f"{x:.4g}"))
    print(f"renderer: {gl.renderer()}  (timings: wall clock, median of {args.repeat})")
    print(f"wrote {out} and {out.with_suffix('.json')}")


if __name__ == "__main__":
    main()
