"""Resolution where the view needs it, at equal memory (issue 26): one map, focused cascades, SDSM,
LiSPSM and a virtual shadow map at 16 MiB each, on every sun-lit scene and the long views, then
the same techniques in motion, with and without the virtual map's page caching.

1. Still frames: the shipped suite ``equal_memory`` (640x480; ``shadowlab study equal_memory``
   gives its full page), summarised per technique and scene: boundary error (px), error rate,
   texel footprint p50 / p95 / max (Lloyd et al.'s m: texel size over pixel size; ≤ 1 means no
   perspective aliasing), time, memory (``memory_bytes``; the virtual map's pool is 256 pages of
   128² texels, 16 MiB, its resident pages ``resident_memory_bytes``).
2. Motion: ``shadowlab animate`` on ``tm_rotating_sun`` (the light moves: every page is
   invalid every frame), ``tm_camera_dolly`` (the camera moves: pages fixed in light space stay
   valid) and ``tm_moving_caster`` (a crate slides: only its pages change), with the virtual map
   fixed in light space (``fit=scene``) and in clipmaps around the camera (``fit=clipmap``),
   each cached and not cached: the flip rate (flicker) and the pages rendered per frame.

Writes ``<out>.csv`` (still frames), ``<out>_motion.csv``, ``<out>.png`` and ``<out>.json``
(provenance); the study goes beside it (``study-equal_memory``), the animations under
``<out>_motion/``.

    python experiments/equal_memory.py [--out results/equal_memory] [--workers N] [--force]
        [--frames N] [--motion-size 320x240]
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd

from shadowlab.output import provenance
from shadowlab.commands.animate import animate
from shadowlab.output.pictures import PLOT_DPI
from shadowlab.analysis.aggregate import per_configuration
from shadowlab.study.experiment import run_experiment_suite

SUITE = "equal_memory"
#: The still-frame columns kept per (scene, configuration).
STILL_COLUMNS = ["boundary_error_px", "error_rate", "texel_footprint_p50", "texel_footprint_p95",
                 "texel_footprint_max", "time_ms_median", "memory_bytes", "resident_memory_bytes",
                 "pages_requested", "pages_dropped"]
#: The animated scenes and what moves in each.
MOTION_SCENES = {"tm_rotating_sun": "the light", "tm_camera_dolly": "the camera", "tm_moving_caster": "a caster"}
#: The configurations animated: the equal-memory set, the virtual map fixed in light space cached and not.
MOTION_SPECS = ["shadow_map", "cascaded_map", "cascaded_map:fit=sdsm", "lispsm", "virtual_map:pool_pages=256",
                "virtual_map:pool_pages=256,fit=scene", "virtual_map:pool_pages=256,fit=scene,cache=false",
                "virtual_map:pool_pages=256,fit=clipmap", "virtual_map:pool_pages=256,fit=clipmap,cache=false"]
#: The animations' default size (flicker is a per-pixel rate; a smaller image keeps this quick).
MOTION_SIZE = (320, 240)
MIB = 2 ** 20


def still_table(results: pd.DataFrame) -> pd.DataFrame:
    """Light 0's row per (scene, configuration) with :data:`STILL_COLUMNS` (memory in MiB)."""
    rows = results[(results["light"] == 0) & (~results["reference"].astype(bool))]
    keep = ["scene", "config"] + [c for c in STILL_COLUMNS if c in rows.columns]
    out = rows[keep].copy()
    for col in ("memory_bytes", "resident_memory_bytes"):
        if col in out:
            out[col.replace("_bytes", "_mib")] = out.pop(col) / MIB
    return out.reset_index(drop=True)


def motion_table(out_dir: Path, frames: int | None, size) -> pd.DataFrame:
    """Per animated scene and configuration: mean and max flip rate, mean temporal error, pages
    rendered and cached per frame (the virtual maps), time per frame."""
    rows = []
    for scene, what in MOTION_SCENES.items():
        run = animate(scene, MOTION_SPECS, frames=frames, size=size, out=out_dir / scene)
        df = pd.read_csv(run / "frames.csv")
        for label, g in df[~df["reference"].astype(bool)].groupby("short_label", sort=False):
            later = g[g["frame"] > 0]
            row = {"scene": scene, "moves": what, "config": label, "frames": int(g["frame"].nunique()),
                   "flip_rate_mean": float(later["flip_rate"].mean()),
                   "flip_rate_max": float(later["flip_rate"].max()),
                   "temporal_error_mean": float(later["temporal_error"].mean()),
                   "time_ms_median": float(g["time_ms_median"].median())}
            if "pages_rendered" in g and g["pages_rendered"].notna().any():
                row.update(pages_requested_per_frame=float(later["pages_requested"].mean()),
                           pages_rendered_per_frame=float(later["pages_rendered"].mean()),
                           pages_cached_per_frame=float(later["pages_cached"].mean()))
            rows.append(row)
    return pd.DataFrame(rows)


def plot(still: pd.DataFrame, motion: pd.DataFrame, path: Path, renderer: str) -> None:
    """Three panels: boundary error and footprint p95 per scene and configuration (log), and
    pages rendered per frame in motion, cached against not."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    configs = list(dict.fromkeys(still["config"]))
    scenes = list(dict.fromkeys(still["scene"]))
    fig, axes = plt.subplots(1, 3, figsize=(18, 5.5), dpi=PLOT_DPI, gridspec_kw={"width_ratios": [2, 2, 1.2]})
    width = 0.8 / len(configs)
    for ax, col, title in ((axes[0], "boundary_error_px", "boundary error, px (log)"),
                           (axes[1], "texel_footprint_p95", "texel footprint p95 (m: texel / pixel; log)")):
        for k, cfg in enumerate(configs):
            d = still[still["config"] == cfg].set_index("scene").reindex(scenes)
            ax.bar(np.arange(len(scenes)) + k * width, d[col].to_numpy(dtype=float), width, label=cfg)
        ax.set_yscale("log")
        ax.set_xticks(np.arange(len(scenes)) + 0.4, scenes, rotation=60, ha="right", fontsize=8)
        ax.set_title(title, fontsize=10)
        ax.grid(axis="y", alpha=0.3)
    axes[1].axhline(1.0, color="k", lw=0.8, ls="--")
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=len(configs) // 2 + len(configs) % 2, fontsize=8)
    vm = motion[motion["config"].str.startswith("virtual_map") & motion["config"].str.contains("fit=")]
    bar = 0.8 / max(1, vm["config"].nunique())
    for k, (cfg, g) in enumerate(vm.groupby("config", sort=False)):
        ax = axes[2]
        ax.bar(np.arange(len(g)) + k * bar, g["pages_rendered_per_frame"], bar,
               label=cfg.replace("virtual_map:pool_pages=256,", ""))
        ax.set_xticks(np.arange(len(g)) + 0.4, [f"{s}\n({m} moves)" for s, m in zip(g["scene"], g["moves"])],
                      fontsize=8)
    axes[2].set_title("virtual map: pages rendered per frame", fontsize=10)
    axes[2].legend(fontsize=8)
    fig.suptitle(f"Equal memory (16 MiB): one map, cascades, SDSM, LiSPSM, virtual map — {renderer}", fontsize=11)
    fig.tight_layout(rect=(0.0, 0.1, 1.0, 1.0))  # the legend below the panels
    fig.savefig(path)
    plt.close(fig)


def main(argv=None) -> None:
    """Run the suite and the animations, write the tables, the figure and the provenance."""
    argv = list(sys.argv[1:] if argv is None else argv)
    frames, size = None, MOTION_SIZE
    for flag in ("--frames", "--motion-size"):
        if flag in argv:
            i = argv.index(flag)
            value = argv[i + 1]
            del argv[i:i + 2]
            if flag == "--frames":
                frames = int(value)
            else:
                size = tuple(int(v) for v in value.lower().split("x"))
    run = run_experiment_suite(SUITE, __doc__.splitlines()[0], "results/equal_memory", argv)
    still = still_table(run.outcome.results)
    run.out.parent.mkdir(parents=True, exist_ok=True)
    still.to_csv(run.out.with_suffix(".csv"), index=False)
    motion = motion_table(run.out.parent / f"{run.out.name}_motion", frames, size)
    motion.to_csv(run.out.parent / f"{run.out.name}_motion.csv", index=False)
    plot(still, motion, run.out.with_suffix(".png"), run.record["renderer"])
    provenance.write_record(run.out, {"suite": SUITE, "motion_size": list(size), "frames": frames})
    with pd.option_context("display.width", 250, "display.max_columns", 30):
        print(still.to_string(index=False))
        print(motion.to_string(index=False))
        print(per_configuration(run.outcome.results).groupby("short_label")[["boundary_error_px", "time_ms"]]
              .median().to_string())
    print(f"wrote {run.out.with_suffix('.csv')}, {run.out.parent / (run.out.name + '_motion.csv')}, "
          f"{run.out.with_suffix('.png')}")


if __name__ == "__main__":
    main()
