"""What the irregular z-buffer costs: time and memory beside shadow volumes, a shadow map and the
truth, and how they grow with triangles and pixels (issue 25).

Four techniques at their defaults: ``irregular_zbuffer`` (exact hard shadows in the rasteriser),
``shadow_volume`` (exact too, stencil counting), ``shadow_map`` (2048², constant bias) and the
ground truth ``raytrace`` (Embree). Parts (each writes ``<out>/<part>.csv``):

1. ``suites``: every scene of the ``hard_shadows`` and ``real_meshes`` suites at ``--size``, every
   hard light (area lights are skipped), one row per (scene, light, technique): median render
   ms, setup ms, ``memory_bytes`` (the technique's own figure, NaN where it reports none: the
   truth, shadow volumes), ``gl_bytes`` (the GL buffers, textures and renderbuffers it owns
   after rendering: a figure every technique has), peak RSS, the error rate against the truth
   on the frame's evaluated pixels, and the irregular z-buffer's ``izb_*`` counters. The printed
   per-scene table sums time and setup over the scene's hard lights, and says which of
   irregular_zbuffer / shadow_volume is faster there and by how much.
2. ``triangles``: the torus of ``sv_scaling.py`` (one point light, 640x480) at
   ``--triangle-sizes`` caster triangles: the same four techniques, plus ``izb_pairs`` /
   ``izb_tests``; log-log slopes of time against triangles, fitted on the largest sizes.
3. ``pixels``: ``box_on_plane`` and ``sv_many_casters`` at ``--pixel-sizes``: the same four
   techniques; log-log slopes of time against pixel count, fitted on the largest sizes.

Timings: wall clock around ``ctx.finish()`` (:func:`shadowlab.measurement.pipeline.measure`), median of
``--repeat`` renders after one warm-up. The irregular z-buffer's rays are built on the CPU in its
(untimed) setup, so its setup figure matters as much as its render figure here.

    python experiments/izb_cost.py [--out results/izb_cost] [--parts suites,triangles,pixels]
        [--size 320x240] [--repeat 3] [--triangle-sizes 10000,30000,100000,300000,1000000]
        [--pixel-sizes 160x120,320x240,640x480,1280x960]

Writes ``suites.csv``, ``triangles.csv``, ``pixels.csv``, ``slopes.csv``, the figure
``izb_cost.png`` and the provenance record ``izb_cost.json`` under ``--out``.
"""
from __future__ import annotations

import argparse
import sys
import time
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd

from shadowlab.gpu import gl, memory
from shadowlab.evaluation import metrics
from shadowlab.output import provenance
from shadowlab.gpu.frame import Frame
from shadowlab.output.pictures import PLOT_DPI
from shadowlab.measurement.pipeline import Evaluator, measure
from shadowlab.scene import load_scene
from shadowlab.scene.area_lights import AreaLight
from shadowlab.study.suite import resolve_suite_path
from shadowlab.techniques import TechniqueError, from_spec

sys.path.insert(0, str(Path(__file__).resolve().parent))
from sv_scaling import torus_scene  # noqa: E402  (the torus of the shadow-volume scaling experiment)

#: The techniques compared, at their defaults (shadow_map: 2048², constant bias); the truth last.
IZB, SV, SM, TRUTH = "irregular_zbuffer", "shadow_volume", "shadow_map", "raytrace"
TECHNIQUES = (IZB, SV, SM)
ALL = TECHNIQUES + (TRUTH,)
#: The suites whose scenes part 1 measures.
SUITES = ("hard_shadows", "real_meshes")
#: The scenes of part 3: the smallest scene and the 246k-triangle pillar grid.
PIXEL_SCENES = ("box_on_plane", "sv_many_casters")
#: Image size of part 2 (the size of sv_scaling.py).
TORUS_IMAGE = (640, 480)
#: Warm-up renders before the timed ones.
WARMUP = 1
#: Log-log slopes are fitted on this many of the largest sizes (where fixed costs matter least).
SLOPE_POINTS = 3
#: The irregular z-buffer's counters kept in the tables.
IZB_STATS = ("izb_rays", "izb_pairs", "izb_tests", "izb_hits", "izb_retries", "izb_list_mean", "izb_list_p99",
             "izb_list_max")


def parse_size(text: str) -> tuple[int, int]:
    """``"320x240"`` → (320, 240)."""
    w, h = (int(v) for v in text.lower().split("x"))
    return w, h


def measure_light(ev: Evaluator, li: int, repeat: int) -> list[dict]:
    """One row per technique of :data:`ALL` on light ``li`` of the evaluator's frame: timing,
    setup, memory, error rate against the truth, the irregular z-buffer's counters. A technique
    that fails gets a row with its error in ``failure`` (and NaN figures)."""
    frame = ev.frame
    slot = frame.slot(li)
    truth = ev.truth(li)
    evaluated = frame.evaluated_image(slot)
    rows = []
    for name in ALL:
        row = {"technique": name, "failure": ""}
        try:
            if name == TRUTH:
                m, owned = truth, float("nan")
            else:
                tech = from_spec(name)
                m = measure(tech, frame, li, repeat, WARMUP, release=False)
                owned = tech.owned_bytes()
                tech.release()
        except (TechniqueError, RuntimeError) as exc:
            rows.append({**row, "failure": str(exc)})
            continue
        err = metrics.compare(m.visibility, truth.visibility, evaluated)
        row.update({"time_ms": m.timing.median_ms, "setup_ms": m.setup_ms,
                    "memory_bytes": float(m.stats.get("memory_bytes", np.nan)), "gl_bytes": owned,
                    "peak_rss_mib": memory.mib(m.peak_rss_bytes),
                    "evaluated_pixels": err["evaluated_pixels"], "error_rate": err["error_rate"],
                    "false_shadow_pixels": err["false_shadow_pixels"], "false_lit_pixels": err["false_lit_pixels"]})
        row.update({k: m.stats[k] for k in IZB_STATS if k in m.stats})
        rows.append(row)
    return rows


def measure_frame(frame: Frame, repeat: int, **keys) -> list[dict]:
    """:func:`measure_light` on every hard light of ``frame`` (area lights skipped), each row
    prefixed with ``keys``, the light and the frame's size."""
    ev = Evaluator(frame, repeat=repeat, warmup=WARMUP)
    rows = []
    for li, light in enumerate(frame.scene.lights):
        if isinstance(light, AreaLight):
            continue
        prefix = {**keys, "light": li, "light_type": light.type_name, "width": frame.width, "height": frame.height}
        rows += [{**prefix, **r} for r in measure_light(ev, li, repeat)]
    return rows


def suite_scenes(suite: str) -> list[str]:
    """The ``scenes`` list of a shipped suite file (read as it stands: its sweeps and
    techniques are not this experiment's and are not validated)."""
    return tomllib.loads(resolve_suite_path(suite).read_text())["scenes"]


def suites_part(size, repeat) -> pd.DataFrame:
    """Part 1: every scene of :data:`SUITES` (each once), every hard light, every technique."""
    scenes = list(dict.fromkeys(name for s in SUITES for name in suite_scenes(s)))
    rows = []
    for name in scenes:
        t0 = time.perf_counter()
        scene = load_scene(name)
        frame = Frame(scene, *size)
        triangles = sum(len(o.faces) for o in scene.objects if o.casts)
        rows += measure_frame(frame, repeat, scene=name, caster_triangles=triangles)
        frame.release()
        print(f"  {name}: {time.perf_counter() - t0:.1f} s", flush=True)
    return pd.DataFrame(rows)


def per_scene(df: pd.DataFrame) -> pd.DataFrame:
    """Part 1 per scene: time and setup summed over the scene's hard lights, per technique
    (columns ``<technique>_ms``, ``<technique>_setup_ms``), error rates (largest over its lights),
    the faster of irregular_zbuffer / shadow_volume and the speed-up (shadow_volume / izb ms)."""
    g = df.groupby(["scene", "technique"], sort=False)
    t = g["time_ms"].sum(min_count=1).unstack()[list(ALL)]
    s = g["setup_ms"].sum(min_count=1).unstack()[list(ALL)]
    e = g["error_rate"].max().unstack()[list(TECHNIQUES)]
    out = pd.concat([t.add_suffix("_ms"), s.add_suffix("_setup_ms"), e.add_suffix("_err")], axis=1)
    out.insert(0, "triangles", df.groupby("scene", sort=False)["caster_triangles"].first())
    out.insert(1, "lights", df.groupby("scene", sort=False)["light"].nunique())
    out["sv_over_izb"] = out[f"{SV}_ms"] / out[f"{IZB}_ms"]
    out["faster"] = np.where(out["sv_over_izb"] > 1, IZB, SV)
    return out.reset_index()


def wide(df: pd.DataFrame, index: list[str], izb_columns=()) -> pd.DataFrame:
    """One row per ``index``: median ms per technique (``<technique>_ms``), setup ms of the
    irregular z-buffer and the truth, the largest error rate of the three techniques, and the
    irregular z-buffer's ``izb_columns``."""
    t = df.pivot_table(index=index, columns="technique", values="time_ms")[list(ALL)].add_suffix("_ms")
    s = df.pivot_table(index=index, columns="technique", values="setup_ms")[[IZB, TRUTH]].add_suffix("_setup_ms")
    e = df.pivot_table(index=index, columns="technique", values="error_rate")[list(TECHNIQUES)].add_suffix("_err")
    izb = df[df["technique"] == IZB].groupby(index)[list(izb_columns)].sum()
    return pd.concat([t, s, e, izb], axis=1).reset_index()


def triangles_part(sizes, repeat) -> pd.DataFrame:
    """Part 2: the torus at each caster-triangle count, 640x480, one point light."""
    rows = []
    for n in sizes:
        t0 = time.perf_counter()
        scene = torus_scene(n)
        frame = Frame(scene, *TORUS_IMAGE)
        rows += measure_frame(frame, repeat, scene=scene.name, triangles=len(scene.objects[1].faces))
        frame.release()
        print(f"  torus {n}: {time.perf_counter() - t0:.1f} s", flush=True)
    return pd.DataFrame(rows)


def pixels_part(sizes, repeat) -> pd.DataFrame:
    """Part 3: :data:`PIXEL_SCENES` at each image size."""
    rows = []
    for name in PIXEL_SCENES:
        scene = load_scene(name)
        for size in sizes:
            t0 = time.perf_counter()
            frame = Frame(scene, *size)
            rows += measure_frame(frame, repeat, scene=name, pixels=size[0] * size[1])
            frame.release()
            print(f"  {name} {size[0]}x{size[1]}: {time.perf_counter() - t0:.1f} s", flush=True)
    return pd.DataFrame(rows)


def slope(x, y, points: int = SLOPE_POINTS) -> float:
    """Log-log slope of ``y`` against ``x`` (numpy polyfit) over the ``points`` largest x."""
    order = np.argsort(np.asarray(x, float))[-points:]
    x, y = np.asarray(x, float)[order], np.asarray(y, float)[order]
    ok = np.isfinite(y) & (y > 0)
    return float(np.polyfit(np.log(x[ok]), np.log(y[ok]), 1)[0]) if ok.sum() >= 2 else float("nan")


def slopes(df: pd.DataFrame, axis: str, group: str | None = None) -> list[dict]:
    """Log-log slopes against ``axis`` of each technique's time, and of the irregular z-buffer's
    pairs and tests, per ``group`` (e.g. scene; None: one group)."""
    out = []
    groups = df.groupby(group, sort=False) if group else [("torus", df)]
    for key, g in groups:
        for tech, h in g.groupby("technique", sort=False):
            base = {"axis": axis, "scene": key, "fitted_on": ",".join(str(v) for v in sorted(h[axis])[-SLOPE_POINTS:])}
            out.append({**base, "quantity": f"{tech} ms", "slope": slope(h[axis], h["time_ms"])})
            if tech == IZB:
                out += [{**base, "quantity": k, "slope": slope(h[axis], h[k])} for k in ("izb_pairs", "izb_tests")]
    return out


def plot(scenes: pd.DataFrame | None, tri: pd.DataFrame | None, pix: pd.DataFrame | None, path: Path) -> None:
    """Per-scene time (log) of the four techniques on top; time against triangles and against
    pixels below."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(13, 8.5), dpi=PLOT_DPI)
    FigureCanvasAgg(fig)
    grid = fig.add_gridspec(2, 2, height_ratios=[1.15, 1])
    style = {t: from_spec(t).STYLE for t in ALL}
    if scenes is not None:
        ax = fig.add_subplot(grid[0, :])
        x = np.arange(len(scenes))
        for t in ALL:
            ax.scatter(x, scenes[f"{t}_ms"], color=style[t].color, marker=style[t].marker, label=t, s=28)
        ax.set_xticks(x, scenes["scene"], rotation=60, ha="right", fontsize=7.5)
        ax.set_yscale("log")
        ax.set_ylabel("render ms (median, summed over hard lights)")
        ax.set_title("hard_shadows + real_meshes scenes", fontsize=10)
        ax.grid(alpha=0.3, which="both", axis="y")
        ax.legend(fontsize=8, ncol=4)
    for col, (df, axis, label) in enumerate(((tri, "triangles", "torus caster triangles (640x480)"),
                                             (pix, "pixels", "pixels"))):
        if df is None:
            continue
        ax = fig.add_subplot(grid[1, col])
        for (scene, t), g in df.groupby(["scene" if axis == "pixels" else "technique", "technique"], sort=False):
            g = g.sort_values(axis)
            dashed = axis == "pixels" and scene != PIXEL_SCENES[0]
            ax.loglog(g[axis], g["time_ms"], marker=style[t].marker, color=style[t].color, ls="--" if dashed else "-",
                      label=None if dashed else t)
        ax.set_xlabel(label)
        ax.set_ylabel("render ms (median)")
        ax.set_title("time vs triangles (torus, one point light)" if axis == "triangles" else
                     f"time vs pixels (solid: {PIXEL_SCENES[0]}, dashed: {PIXEL_SCENES[1]})", fontsize=10)
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=8)
    fig.suptitle(f"Irregular z-buffer cost beside shadow volumes, a 2048² shadow map and the ray-traced truth\n"
                 f"{gl.renderer()}", fontsize=11)
    fig.tight_layout()
    fig.savefig(path)


def show(table: pd.DataFrame, title: str) -> None:
    """Print a table whole, numbers to 4 significant digits."""
    print(f"\n== {title}")
    with pd.option_context("display.width", 250, "display.max_columns", 40, "display.max_rows", 500):
        print(table.to_string(index=False, float_format=lambda v: f"{v:.4g}"))


def failures(df: pd.DataFrame) -> pd.DataFrame:
    """Rows where the irregular z-buffer failed or disagrees with the truth on some pixel."""
    bad = (df["technique"] == IZB) & ((df["failure"] != "") | (df["error_rate"].fillna(1) > 0))
    return df[bad]


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="results/izb_cost", help="output folder")
    ap.add_argument("--parts", default="suites,triangles,pixels", help="comma-separated parts to run")
    ap.add_argument("--size", default="320x240", help="image size of the suites part, WIDTHxHEIGHT")
    ap.add_argument("--repeat", type=int, default=3, help="timed renders per measurement (median)")
    ap.add_argument("--triangle-sizes", default="10000,30000,100000,300000,1000000", help="torus triangle counts")
    ap.add_argument("--pixel-sizes", default="160x120,320x240,640x480,1280x960", help="image sizes of part 3")
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    parts = set(args.parts.split(","))
    t_start = time.perf_counter()
    seconds, fits, written = {}, [], []
    suite_rows = scenes = tri = pix = None
    if "suites" in parts:
        t0 = time.perf_counter()
        df = suite_rows = suites_part(parse_size(args.size), args.repeat)
        df.to_csv(out / "suites.csv", index=False)
        scenes = per_scene(df)
        show(scenes.drop(columns=[f"{t}_setup_ms" for t in (SV, SM)]), f"suites at {args.size}, per scene "
             f"(ms summed over hard lights; *_err: largest error rate over lights)")
        memory_table = df.groupby("technique", sort=False)[["memory_bytes", "gl_bytes", "peak_rss_mib"]].agg(
            ["median", "max"])
        memory_table.columns = [f"{a}_{b}" for a, b in memory_table.columns]
        show(memory_table.reset_index(), "memory over the suite rows (scene, light)")
        show(df[df["technique"] == IZB][["scene", "light", "izb_rays", "izb_pairs", "izb_tests", "izb_hits",
                                          "izb_list_mean", "izb_list_p99", "izb_list_max", "memory_bytes"]],
             "irregular_zbuffer counters")
        wins = scenes[scenes["faster"] == IZB]["scene"].tolist()
        print(f"\nirregular_zbuffer faster than shadow_volume on {len(wins)}/{len(scenes)} scenes: {', '.join(wins)}")
        written.append("suites.csv")
        seconds["suites"] = time.perf_counter() - t0
    if "triangles" in parts:
        t0 = time.perf_counter()
        tri = triangles_part([int(v) for v in args.triangle_sizes.split(",")], args.repeat)
        tri.to_csv(out / "triangles.csv", index=False)
        show(wide(tri, ["triangles"], ("izb_pairs", "izb_tests", "memory_bytes")), "torus, 640x480")
        fits += slopes(tri, "triangles")
        written.append("triangles.csv")
        seconds["triangles"] = time.perf_counter() - t0
    if "pixels" in parts:
        t0 = time.perf_counter()
        pix = pixels_part([parse_size(v) for v in args.pixel_sizes.split(",")], args.repeat)
        pix.to_csv(out / "pixels.csv", index=False)
        show(wide(pix, ["scene", "pixels"], ("izb_rays", "izb_pairs", "izb_tests", "memory_bytes")), "pixels")
        fits += slopes(pix, "pixels", "scene")
        written.append("pixels.csv")
        seconds["pixels"] = time.perf_counter() - t0
    if fits:
        fit_df = pd.DataFrame(fits)
        fit_df.to_csv(out / "slopes.csv", index=False)
        show(fit_df, f"log-log slopes (fitted on the {SLOPE_POINTS} largest sizes)")
        written.append("slopes.csv")
    bad = pd.concat([failures(d) for d in (suite_rows, tri, pix) if d is not None])
    if len(bad):
        show(bad[["scene", "light", "width", "height", "technique", "error_rate", "false_shadow_pixels",
                  "false_lit_pixels", "failure"]], "irregular_zbuffer: failures or pixels unlike the truth")
    else:
        print("\nirregular_zbuffer matches the truth on every evaluated pixel of every measurement")
    plot(scenes, tri, pix, out / "izb_cost.png")
    seconds["total"] = time.perf_counter() - t_start
    provenance.write_record(out / "izb_cost", {
        "parts": sorted(parts), "size": args.size, "repeat": args.repeat, "warmup": WARMUP,
        "triangle_sizes": args.triangle_sizes, "pixel_sizes": args.pixel_sizes, "torus_image": list(TORUS_IMAGE),
        "techniques": list(ALL), "suites": list(SUITES), "pixel_scenes": list(PIXEL_SCENES),
        "lights": "every hard light, one row per light (area lights skipped); per-scene figures summed over lights",
        "timing": f"wall clock around ctx.finish(), median of {args.repeat} after {WARMUP} warm-up",
        "slopes": fits, "seconds": seconds})
    print(f"\n{seconds}\nrenderer: {gl.renderer()}; wrote {', '.join(str(out / w) for w in written)}, "
          f"{out / 'izb_cost.png'} and {out / 'izb_cost.json'}")


if __name__ == "__main__":
    main()
