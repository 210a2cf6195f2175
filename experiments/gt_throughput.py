"""Ground-truth throughput against raw Embree occlusion, in the same process.

For each scene and size: the ground truth's per-light work (ray generation from the cached
offset origins + Embree occlusion + bookkeeping) in shadow rays per second, beside a raw
``embreex`` occlusion query over exactly the same rays. The per-frame work the ground truth
shares with evaluation (exact float64 hit points) and its own per-frame work (offset origins)
are reported separately, and amortised over one light in ``gt_end_to_end_rays_per_s``;
``gt_end_to_end_over_raw`` is that against raw Embree — the hard truth's "fraction of raw
Embree at one light" of issue 27. The frame's pass forms the default-offset origins beside the
exact points (:meth:`shadowlab.gpu.frame.Frame.compute_exact_points`), so ``exact_points_ms_per_frame``
holds both and ``offset_origins_ms_per_frame`` is 0 unless the truth's ``offset_scale`` is not
the default (then its origins are a pass of their own, timed there).
Area lights (``--area-scenes``): the scene's first light is replaced by a rect area light at its
position (``--area-edge`` square, emitting down) and the sampled truth (``--area-samples`` rays
per pixel, its worker threads) is timed end to end per light (sample generation, horizon test,
ray set-up, Embree, counting), beside raw Embree occlusion of exactly the same rays (generated
chunk by chunk outside the timed region, with the same chunks and seeds), run on the same
number of threads (``raw_embree_rays_per_s``) and on one (``raw_embree_1thread_rays_per_s``);
``gt_over_raw`` is the soft truth's fraction of raw Embree.

Timing (issue 27): the truth, raw Embree and the per-frame steps are timed in turn, round after
round (``--repeat`` rounds; area lights ``--area-repeat``), and each figure is the median of its
rounds, so that load from other processes on a shared machine falls on all of them alike.
Besides wall-clock seconds, ``cpu_gt_over_raw`` and ``cpu_gt_end_to_end_over_raw`` give the same
fractions in CPU seconds of this process (all threads), which other processes' load disturbs
far less.

Before and after issue 27 (compiled per-ray passes, :mod:`shadowlab.truth.compiled`; same bits),
measured with this script's protocol on the same 2-core machine (Intel Xeon, llvmpipe — Embree
runs on the CPU either way), the old and new code run alternately under the same load:
see docs/guide.md (the ``raytrace`` row and the gt_throughput entry) for the figures.

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

from shadowlab.gpu import gl
from shadowlab.output import provenance
from shadowlab.cli import parse_size
from shadowlab.gpu.frame import Frame
from shadowlab.scene.lights import T_LIGHT
from shadowlab.scene import load_scene, parse_scene, resolve_scene_path
from shadowlab.truth.tracing import DEFAULT_OFFSET_SCALE, occluded, offset_origins
from shadowlab.techniques.rays.raytrace import RayTraced, area_chunk_rays, area_chunks, area_workers


def void(_result) -> None:
    """Drop a timed call's result (:func:`interleaved` reads a returned value as its own timing)."""
    return None


def interleaved(fns: dict, repeat: int) -> tuple[dict, dict]:
    """Median wall-clock and CPU seconds (this process, all threads) of each function in ``fns``
    (name → callable returning None, or (wall, cpu) seconds of its own timed part), called in turn,
    round after round (``repeat`` rounds, after one warm-up round): load from elsewhere falls on
    every function alike. CPU work only (no GL finish)."""
    wall = {k: [] for k in fns}
    cpu = {k: [] for k in fns}
    for rnd in range(repeat + 1):
        for k, fn in fns.items():
            w0, c0 = time.perf_counter(), time.process_time()
            own = fn()
            w, c = time.perf_counter() - w0, time.process_time() - c0
            if own is not None:  # the function timed its own part: (wall, cpu)
                w, c = own
            if rnd:
                wall[k].append(w)
                cpu[k].append(c)
    return ({k: float(np.median(v)) for k, v in wall.items()}, {k: float(np.median(v)) for k, v in cpu.items()})


def per_frame_passes(frame, gt) -> dict:
    """The truth's per-frame work to time: the frame's exact points (with the default-offset
    origins, one pass) and, for a truth at another offset, its own origins pass; a function
    returning (0, 0) seconds stands for a pass the frame's already did."""
    if gt.offset_scale == DEFAULT_OFFSET_SCALE:
        origins = lambda: (0.0, 0.0)  # noqa: E731  formed in the exact points' pass
    else:
        origins = lambda: void(offset_origins(frame, gt.offset_scale, cached=False))  # noqa: E731
    return {"exact": frame.compute_exact_points, "origins": origins}


def measure(scene_name, size, repeat):
    scene = load_scene(scene_name)
    frame = Frame(scene, *size)
    gt = RayTraced()
    gt.prepare(frame, 0)
    # The identical rays, prepared outside the timed region, through embreex alone.
    light = scene.lights[0]
    org = gt.eval_origins
    dirs, tfar = light.shadow_rays(org, gt.eval_points)
    wall, cpu = interleaved({"raw": lambda: void(occluded(gt.scene, org, dirs, tfar)), "gt": gt.render,
                             **per_frame_passes(frame, gt)}, repeat)
    frame.release()
    n = len(org)
    t_raw, t_gt, t_exact, t_origins = wall["raw"], wall["gt"], wall["exact"], wall["origins"]
    return {
        "scene": scene_name, "width": size[0], "height": size[1], "light": light.type_name, "rays": n,
        "raw_embree_rays_per_s": n / t_raw, "gt_rays_per_s": n / t_gt, "gt_over_raw": t_raw / t_gt,
        "gt_per_light_ms": 1e3 * t_gt, "raw_embree_ms": 1e3 * t_raw,
        "exact_points_ms_per_frame": 1e3 * t_exact, "offset_origins_ms_per_frame": 1e3 * t_origins,
        "gt_end_to_end_rays_per_s": n / (t_gt + t_exact + t_origins),
        "gt_end_to_end_over_raw": t_raw / (t_gt + t_exact + t_origins),
        "cpu_gt_over_raw": cpu["raw"] / cpu["gt"],
        "cpu_gt_end_to_end_over_raw": cpu["raw"] / (cpu["gt"] + cpu["exact"] + cpu["origins"]),
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
    """Wall-clock and CPU seconds (this process) of Embree occlusion alone over the sampled
    truth's rays (same chunks and seeds), ``threads`` chunks at a time as the truth's workers
    run them, and the number of rays; the rays of each group are generated outside the timed
    region (all of them at once would not fit in memory at 640x480 × 1024 samples)."""
    chunks = area_chunks(len(gt.eval_points), gt.samples, gt.seed, gt.decorrelate)
    wall, cpu, rays = 0.0, 0.0, 0
    with ThreadPoolExecutor(threads) as pool:
        for g in range(0, len(chunks), threads):
            group = []
            for a, b, rng in chunks[g:g + threads]:
                _, _, org, dirs = area_chunk_rays(gt.light, gt.eval_points[a:b], gt.eval_normals[a:b],
                                                  gt.eval_origins[a:b], gt.samples, rng)
                group.append((org, dirs, np.full(len(org), T_LIGHT, np.float32)))
                rays += len(org)
            w0, c0 = time.perf_counter(), time.process_time()
            list(pool.map(lambda r: occluded(gt.scene, *r), group))
            wall += time.perf_counter() - w0
            cpu += time.process_time() - c0
    return wall, cpu, rays


def measure_area(scene_name, size, repeat, samples, edge):
    """The sampled truth of a rect area light against raw Embree on the same rays."""
    scene = area_scene(scene_name, edge)
    frame = Frame(scene, *size)
    gt = RayTraced(samples=samples)
    gt.prepare(frame, 0)
    gt.render()
    n = gt.stats()["rays"]
    threads = area_workers(samples, len(area_chunks(len(gt.eval_points), samples, gt.seed, gt.decorrelate)))
    *_, raw_rays = raw_area_seconds(gt, 1)
    assert raw_rays == n, (raw_rays, n)
    wall, cpu = interleaved({"raw": lambda: raw_area_seconds(gt, threads)[:2], "gt": gt.render,
                             "raw1": lambda: raw_area_seconds(gt, 1)[:2], **per_frame_passes(frame, gt)}, repeat)
    tris = sum(len(o.faces) for o in scene.objects)
    frame.release()
    t_raw, t_gt, t_exact, t_origins = wall["raw"], wall["gt"], wall["exact"], wall["origins"]
    return {
        "scene": scene.name, "width": size[0], "height": size[1], "light": "area/rect", "samples": samples,
        "triangles": tris, "pixels": int(len(gt.eval_points)), "threads": threads, "rays": n,
        "raw_embree_rays_per_s": n / t_raw, "raw_embree_1thread_rays_per_s": n / wall["raw1"],
        "gt_rays_per_s": n / t_gt, "gt_over_raw": t_raw / t_gt,
        "gt_per_light_ms": 1e3 * t_gt, "raw_embree_ms": 1e3 * t_raw,
        "exact_points_ms_per_frame": 1e3 * t_exact, "offset_origins_ms_per_frame": 1e3 * t_origins,
        "gt_end_to_end_rays_per_s": n / (t_gt + t_exact + t_origins),
        "gt_end_to_end_over_raw": t_raw / (t_gt + t_exact + t_origins),
        "cpu_gt_over_raw": cpu["raw"] / cpu["gt"],
        "cpu_gt_end_to_end_over_raw": cpu["raw"] / (cpu["gt"] + cpu["exact"] + cpu["origins"]),
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
    ap.add_argument("--area-repeat", type=int, default=3)
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
    provenance.write_record(out, {"timing": f"wall clock and process CPU time, median of {args.repeat} interleaved "
                                            f"rounds (area lights: {args.area_repeat}) after 1 warm-up round"})
    with pd.option_context("display.width", 250):
        print(df.to_string(index=False, float_format=lambda x: f"{x:.4g}"))
    print(f"renderer: {gl.renderer()}  (timings: wall clock, median of {args.repeat} interleaved rounds)")
    print(f"wrote {out} and {out.with_suffix('.json')}")


if __name__ == "__main__":
    main()
