"""Scaling laws (issue 27): time and error of every technique family against triangles and pixels,
and a fitted cost law t = t0 + a·P^α + b·T^β per family.

The scene is one torus over a floor under a sun, refined from 10k to 4M triangles (the scene
files of the shipped suite ``scaling``, ``shadowlab/suites/scaling/``: only the torus's segment
counts change). Three sweeps, each run as a study (:func:`shadowlab.study.runner.run_study`,
cached, the accuracy phase in parallel and the timing phase alone):

1. **triangles**: the suite ``scaling`` as shipped (every scene at 640x480; what
   ``shadowlab study scaling`` runs);
2. **pixels**: the suite at ``--pixel-scene`` (default the 40k torus) at each ``--pixel-sizes``
   (a suite has one image size, so each size is a study of its own, ``study-scaling-WxH``);
3. **corners** (``--corners``, on by default): the smallest and the largest torus at the
   largest size, where the law fitted on the cross is tested (does fill cost depend on triangles?).

Per family (technique name; the truth ``raytrace`` is a family too) the medians of render time
are fitted jointly over the cross (sweeps 1 and 2; ``--fit-corners``: the corners too) with
:func:`fit_law`: P in Mpx, T in millions of
triangles (the scene's, floor included), non-linear least squares on relative residuals
(scipy ``curve_fit``, sigma = the measured time), 95 % intervals from the covariance (linearised,
Student t with n − 5 degrees of freedom). :func:`crossovers` then finds, from the fitted laws, the
triangle count or pixel count at which one family's cost crosses another's within the range both
were measured on.

Writes under ``--out`` (default ``results/scaling_laws``): ``points.csv`` (one row per family and
measured point: time, its IQR, setup, error rate, boundary error), ``fits.csv`` (with measured /
predicted time at each corner), ``crossovers.csv``, ``fits.md`` (both as markdown tables),
the figures ``scaling_time.png`` and ``scaling_error.png`` (into ``--figures``, default the same
folder) and the provenance record ``scaling_laws.json``.

    python experiments/scaling_laws.py [--out results/scaling_laws] [--figures docs/images]
        [--quick] [--repeat N] [--workers N] [--force] [--no-corners] [--fit-corners]
        [--pixel-sizes 640x480,...] [--pixel-scene scaling_torus_40k]
        [--triangle-study DIR]  (read that study's results.csv instead of running the suite)
        [--points CSV]          (refit and redraw from an earlier points.csv, measuring nothing)

``--quick`` (about 3 minutes): the four smallest tori, 640x480 to 1920x1080, repeat 1, no corners.
"""
from __future__ import annotations

import argparse
import os
import time
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd

from shadowlab.analysis.scaling import LEVEL, PARAMS, LawFit, crossovers, fit_law, scene_triangles

SUITE = "scaling"
#: Image sizes of the pixel sweep, 0.31 to 8.3 Mpx.
PIXEL_SIZES = ((640, 480), (1280, 720), (1920, 1080), (2560, 1440), (3840, 2160))
#: The scene of the pixel sweep: small enough that shadow polygons' setup stays short.
PIXEL_SCENE = "scaling_torus_40k"
#: The corner points: these scenes at the largest pixel size.
CORNER_SCENES = ("scaling_torus_10k", "scaling_torus_4000k")
#: --quick: these scenes of the suite, these sizes, one timed render, no corners.
QUICK_SCENES = ("scaling_torus_10k", "scaling_torus_40k", "scaling_torus_160k", "scaling_torus_640k")
QUICK_SIZES = ((640, 480), (1280, 720), (1920, 1080))
def suite_variant(scenes=None, size=None, repeat=None, name=None):
    """The shipped suite ``scaling`` with only ``scenes`` (names), another image ``size``, another
    ``repeat`` and another ``name`` (the study's): the [[sweeps]] keep only their scenes that stay."""
    from shadowlab.study.suite import parse_suite, resolve_suite_path

    path = resolve_suite_path(SUITE)
    data = tomllib.loads(path.read_text())
    if scenes is not None:
        data["scenes"] = [s for s in data["scenes"] if Path(s).stem in scenes]
        sweeps = []
        for sw in data.get("sweeps", []):
            keep = [s for s in sw.get("scenes", scenes) if s in scenes]
            if keep:
                sweeps.append({**sw, "scenes": keep})
        data["sweeps"] = sweeps
    if size is not None:
        data["size"] = list(size)
    if repeat is not None:
        data["repeat"] = repeat
    if name is not None:
        data["name"] = name
    return parse_suite(data, file=str(path), base=path.parent)


def points_from(results: pd.DataFrame, triangles: dict[str, int], sweep: str) -> pd.DataFrame:
    """One row per (family, scene, size) of a study's ``results`` (light 0, finished runs only):
    family (the technique's name; the truth is ``raytrace``), config, pixels, triangles (from
    ``triangles``: scene name → count), render time median and IQR, setup, repeats, error rate
    and boundary error against the truth, and which ``sweep`` measured it."""
    df = results[(results["light"] == 0) & (results["status"].fillna("ok") == "ok")]
    out = pd.DataFrame({
        "sweep": sweep, "family": df["technique"], "config": df["config"], "scene": df["scene"],
        "width": df["width"].astype(int), "height": df["height"].astype(int),
        "pixels": df["width"].astype(int) * df["height"].astype(int),
        "triangles": df["scene"].map(triangles),
        "time_ms": df["time_ms_median"], "time_ms_iqr": df["time_ms_iqr"], "setup_ms": df.get("setup_ms"),
        "repeats": df.get("time_repeats"), "error_rate": df["error_rate"],
        "boundary_error_px": df.get("boundary_error_px"), "renderer": df.get("renderer")})
    return out.reset_index(drop=True)


def run_sweeps(args) -> tuple[pd.DataFrame, dict]:
    """Run (or read) the three sweeps' studies and return their points and a record of what ran
    (study directories, tasks run and cached, seconds)."""
    from shadowlab.cli import StudyProgress
    from shadowlab.study.runner import run_study

    base = suite_variant()
    triangles = {s.name: scene_triangles(s.path) for s in base.scenes}
    out = Path(args.out)
    tri_scenes = list(QUICK_SCENES) if args.quick else [s.name for s in base.scenes]
    sizes = list(QUICK_SIZES if args.quick else [parse_size(s) for s in args.pixel_sizes.split(",")])
    plan = [("triangles", suite_variant(scenes=tri_scenes, repeat=args.repeat,
                                        name=SUITE if not args.quick else f"{SUITE}-quick"))]
    plan += [("pixels", suite_variant(scenes=[args.pixel_scene], size=s, repeat=args.repeat,
                                      name=f"{SUITE}-{s[0]}x{s[1]}"))
             for s in sizes if tuple(s) != tuple(base.size)]
    if args.corners and not args.quick:
        big = max(sizes, key=lambda s: s[0] * s[1])
        plan.append(("corners", suite_variant(scenes=list(CORNER_SCENES), size=big, repeat=args.repeat,
                                              name=f"{SUITE}-corners-{big[0]}x{big[1]}")))
    frames, record = [], {"studies": []}
    for k, (sweep, suite) in enumerate(plan, 1):
        t0 = time.perf_counter()
        load_before = os.getloadavg()[0]  # others' work on a shared host shows here, not in the study
        if sweep == "triangles" and args.triangle_study:
            study_dir = Path(args.triangle_study)
            results = pd.read_csv(study_dir / "results.csv")
            results = results[results["scene"].isin(tri_scenes)]
            ran = cached = 0
            print(f"[{k}/{len(plan)}] {sweep}: read {study_dir / 'results.csv'}", flush=True)
        else:
            study_dir = out / f"study-{suite.name}"
            print(f"[{k}/{len(plan)}] {sweep}: study {suite.name}, {len(suite.scenes)} scene(s) at "
                  f"{suite.size[0]}x{suite.size[1]}, repeat {suite.repeat} -> {study_dir}", flush=True)
            outcome = run_study(suite, out=study_dir, workers=args.workers, force=args.force,
                                progress=StudyProgress(enabled=False if args.no_progress else None))
            if outcome.failed:
                print(f"  failed runs (left out of the fit): {outcome.failed}", flush=True)
            results, ran, cached = outcome.results, outcome.ran, outcome.cached
        frames.append(points_from(results, triangles, sweep))
        seconds = time.perf_counter() - t0
        record["studies"].append({"sweep": sweep, "study": str(study_dir), "size": list(suite.size),
                                  "scenes": [s.name for s in suite.scenes], "repeat": suite.repeat,
                                  "ran": ran, "cached": cached, "seconds": round(seconds, 1),
                                  "loadavg_1min_before": load_before, "loadavg_1min_after": os.getloadavg()[0]})
        print(f"  {seconds:.0f} s", flush=True)
    return pd.concat(frames, ignore_index=True), record


def parse_size(text: str) -> tuple[int, int]:
    """``"640x480"`` → (640, 480)."""
    w, h = (int(v) for v in text.lower().split("x"))
    return w, h


def fit_all(points: pd.DataFrame, with_corners: bool = False) -> tuple[dict[str, LawFit], pd.DataFrame]:
    """:func:`fit_law` per family over its points of the cross (the triangle and pixel sweeps;
    the corners too when ``with_corners``); the fits and their table (one row per family: the
    parameters with their intervals, R², rms relative residual, points, the measured ranges,
    parameters on a bound, or the reason a family could not be fitted). Fitted on the cross, the
    law is then tested at the corners, which it never saw: ``corner_<T>k`` is measured / predicted
    time there (1 where pixel cost and triangle cost add, as the law assumes)."""
    from shadowlab.analysis.aggregate import family_order

    fits, rows = {}, []
    for fam in family_order(points["family"].unique()):
        every = points[points["family"] == fam]
        g = every if with_corners else every[every["sweep"] != "corners"]
        row = {"family": fam, "config": g["config"].iloc[0], "points": len(g),
               "pixels_min": g["pixels"].min(), "pixels_max": g["pixels"].max(),
               "triangles_min": g["triangles"].min(), "triangles_max": g["triangles"].max()}
        try:
            f = fit_law(g["pixels"], g["triangles"], g["time_ms"])
        except (ValueError, RuntimeError) as exc:
            rows.append({**row, "note": str(exc)})
            continue
        fits[fam] = f
        for name in PARAMS:
            lo, hi = f.interval(name)
            row.update({name: f.value(name), f"{name}_lo": lo, f"{name}_hi": hi})
        row.update({"r2": f.r2, "rel_rms": f.rel_rms, "at_bound": ",".join(f.at_bound), "note": ""})
        for _, c in every[every["sweep"] == "corners"].iterrows():
            row[f"corner_{c['triangles'] / 1e3:.0f}k"] = c["time_ms"] / float(f.predict(c["pixels"], c["triangles"]))
        rows.append(row)
    return fits, pd.DataFrame(rows)


def all_crossovers(fits: dict[str, LawFit], points: pd.DataFrame) -> pd.DataFrame:
    """:func:`crossovers` along the two measured lines of the cross: the triangles at the triangle
    sweep's pixel count and the pixels at the pixel sweep's triangle count, each family over the
    range it was measured on there (nothing is extrapolated off the cross)."""
    rows = []
    for axis, sweep, held in (("triangles", "triangles", "pixels"), ("pixels", "pixels", "triangles")):
        line = points[points["sweep"] == sweep]
        if not len(line):
            continue
        at = int(line[held].iloc[0])
        line = points[(points[held] == at) & (points["sweep"] != "corners")]
        rng = {f: (g[axis].min(), g[axis].max()) for f, g in line.groupby("family")}
        rows += crossovers({f: v for f, v in fits.items() if f in rng}, rng, axis, at)
    return pd.DataFrame(rows, columns=["axis", "held", "held_at", "family_a", "family_b", "crosses_at", "time_ms",
                                       "cheaper_above"])


def _style(family: str):
    from shadowlab.techniques import from_spec

    return from_spec(family).STYLE


def plot(points: pd.DataFrame, fits: dict[str, LawFit], column: str, path: Path, renderer: str) -> None:
    """Two panels, ``column`` (time_ms or error_rate) against triangles (at the triangle sweep's
    image size) and against pixels (at the pixel sweep's scene), one line per family; for time
    the fitted law as a dashed line over the family's measured range. The corner points (the
    largest image) join the triangles panel as hollow markers, with the law there dotted."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.ticker import NullFormatter

    from shadowlab.output.pictures import PLOT_DPI
    from shadowlab.analysis.aggregate import family_order

    fig = Figure(figsize=(13, 5.4), dpi=PLOT_DPI)
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, 2)
    tri = points[points["sweep"] == "triangles"]
    p_tri = int(tri["pixels"].iloc[0]) if len(tri) else 0
    t_pix = points[points["sweep"] == "pixels"]["triangles"]
    t_pix = int(t_pix.iloc[0]) if len(t_pix) else int(points["triangles"].min())
    for ax, axis in zip(axes, ("triangles", "pixels")):
        held = points[(points["pixels"] == p_tri)] if axis == "triangles" else points[points["triangles"] == t_pix]
        for fam in family_order(held["family"].unique()):
            if column == "error_rate" and fam == "raytrace":
                continue  # the truth against itself
            g = held[held["family"] == fam].sort_values(axis)
            st = _style(fam)
            y = g[column].to_numpy(float)
            ax.plot(g[axis], y, marker=st.marker, color=st.color, ls="-" if column == "error_rate" else "none",
                    label=fam)
            if column == "time_ms" and fam in fits:
                xs = np.geomspace(g[axis].min(), g[axis].max(), 100)
                args = (xs, np.full_like(xs, t_pix)) if axis == "pixels" else (np.full_like(xs, p_tri), xs)
                ax.plot(xs, fits[fam].predict(*args), color=st.color, ls="--", lw=1)
            corner = points[(points["sweep"] == "corners") & (points["family"] == fam)].sort_values("triangles")
            if axis == "triangles" and len(corner):
                ax.plot(corner["triangles"], corner[column], marker=st.marker, color=st.color, ls="none", mfc="none")
                if column == "time_ms" and fam in fits:
                    xs = np.geomspace(corner["triangles"].min(), corner["triangles"].max(), 100)
                    p_big = float(corner["pixels"].iloc[0])
                    ax.plot(xs, fits[fam].predict(np.full_like(xs, p_big), xs), color=st.color, ls=":", lw=0.8,
                            alpha=0.6)
        ax.set_xscale("log")
        if column == "time_ms":
            ax.set_yscale("log")
            ax.set_ylabel("render ms (median; dashed: fitted law)")
        else:
            ax.set_yscale("symlog", linthresh=1e-6)
            ax.set_ylim(bottom=0)
            ax.set_ylabel("error rate against the truth (symlog below 1e-6)")
        if axis == "triangles":
            ax.set_xlabel("scene triangles (torus refined)")
            big = points[points["sweep"] == "corners"]["pixels"]
            extra = f" (hollow: {big.iloc[0] / 1e6:.1f} Mpx)" if len(big) else ""
            ax.set_title(f"against triangles, {p_tri / 1e6:.2f} Mpx{extra}", fontsize=10)
        else:
            ax.set_xlabel("pixels")
            ax.set_xticks(sorted(held["pixels"].unique()), [f"{v / 1e6:.2f}M" for v in sorted(held["pixels"].unique())])
            ax.xaxis.set_minor_formatter(NullFormatter())
            ax.set_title(f"against pixels, {t_pix / 1e3:.0f}k triangles", fontsize=10)
        ax.grid(alpha=0.3, which="both")
    axes[0].legend(fontsize=8, ncol=2)
    what = "Render time" if column == "time_ms" else "Error rate"
    fig.suptitle(f"{what} against scale, one spec per family — {renderer}", fontsize=11)
    fig.tight_layout()
    fig.savefig(path)


def _num(v: float) -> str:
    """A number to 3 significant digits for the markdown tables."""
    return "–" if not np.isfinite(v) else f"{v:.3g}"


def markdown(table: pd.DataFrame, cross: pd.DataFrame) -> str:
    """The fits and the crossovers as markdown tables (``fits.md``, what docs/scaling.md quotes):
    each parameter with its interval, R², the rms relative residual, points and measured ranges."""
    corners = [c for c in table.columns if c.startswith("corner_")]
    lines = ["| family | points | t0 ms | a ms (at 1 Mpx) | α | b ms (at 1M tris) | β | R² | rms rel. resid. | on a bound |"
             + "".join(f" {c.replace('corner_', 'corner ')} |" for c in corners),
             "|---|---|---|---|---|---|---|---|---|---|" + "---|" * len(corners)]
    for _, r in table.iterrows():
        if r.get("note"):
            lines.append(f"| {r['family']} | {r['points']} | {r['note']} |" + " |" * 7)
            continue
        cells = [f"{_num(r[n])} [{_num(r[n + '_lo'])}, {_num(r[n + '_hi'])}]" for n in PARAMS]
        lines.append(f"| {r['family']} | {r['points']} | " + " | ".join(cells)
                     + f" | {r['r2']:.3f} | {r['rel_rms']:.2f} | {r['at_bound'] or ''} |"
                     + "".join(f" {_num(r[c])} |" for c in corners))
    lines += ["", "| along | held at | families | cross at | time there, ms | cheaper above |", "|---|---|---|---|---|---|"]
    for _, c in cross.iterrows():
        held = f"{c['held_at'] / 1e6:.2f} Mpx" if c["held"] == "pixels" else f"{c['held_at'] / 1e3:.0f}k triangles"
        at = f"{c['crosses_at'] / 1e3:.0f}k triangles" if c["axis"] == "triangles" else f"{c['crosses_at'] / 1e6:.2f} Mpx"
        lines.append(f"| {c['axis']} | {held} | {c['family_a']} / {c['family_b']} | {at} | {c['time_ms']:.3g} | "
                     f"{c['cheaper_above']} |")
    return "\n".join(lines) + "\n"


def show(table: pd.DataFrame, title: str) -> None:
    """Print a table whole, numbers to 4 significant digits."""
    print(f"\n== {title}")
    with pd.option_context("display.width", 250, "display.max_columns", 40, "display.max_rows", 500):
        print(table.to_string(index=False, float_format=lambda v: f"{v:.4g}"))


def main(argv=None) -> None:
    """Run or read the sweeps, fit the laws, find the crossovers, write tables, figures, record."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="results/scaling_laws", help="output folder (studies go inside)")
    ap.add_argument("--figures", default=None, help="folder of the figures (default: --out)")
    ap.add_argument("--quick", action="store_true", help="four smallest tori, 640x480-1920x1080, repeat 1")
    ap.add_argument("--repeat", type=int, default=None, help="timed renders per point (default: the suite's)")
    ap.add_argument("--workers", type=int, default=None, help="accuracy-phase worker processes")
    ap.add_argument("--force", action="store_true", help="ignore the studies' caches")
    ap.add_argument("--no-corners", dest="corners", action="store_false", help="skip the corner points")
    ap.add_argument("--fit-corners", action="store_true",
                    help="fit the corners too (default: fit the cross, test the law at the corners)")
    ap.add_argument("--pixel-sizes", default=",".join(f"{w}x{h}" for w, h in PIXEL_SIZES))
    ap.add_argument("--pixel-scene", default=PIXEL_SCENE, help="the scene of the pixel sweep")
    ap.add_argument("--triangle-study", default=None, help="a study directory of the suite to read, not run")
    ap.add_argument("--points", default=None, help="an earlier points.csv: refit and redraw only")
    ap.add_argument("--no-progress", action="store_true", help="no progress bar (it shows only on a terminal)")
    args = ap.parse_args(argv)
    if args.quick and args.repeat is None:
        args.repeat = 1
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    figures = Path(args.figures) if args.figures else out
    figures.mkdir(parents=True, exist_ok=True)
    t_start = time.perf_counter()
    if args.points:
        points = pd.read_csv(args.points)
        record = {"points_from": args.points}
    else:
        points, record = run_sweeps(args)
        points.to_csv(out / "points.csv", index=False)
    fits, table = fit_all(points, args.fit_corners)
    table.to_csv(out / "fits.csv", index=False)
    cross = all_crossovers(fits, points)
    cross.to_csv(out / "crossovers.csv", index=False)
    (out / "fits.md").write_text(markdown(table, cross))
    renderer = str(points["renderer"].dropna().iloc[0]) if points["renderer"].notna().any() else "unknown renderer"
    plot(points, fits, "time_ms", figures / "scaling_time.png", renderer)
    plot(points, fits, "error_rate", figures / "scaling_error.png", renderer)
    show(points.drop(columns=["config", "renderer"]), "measured points (render ms: median)")
    show(table.drop(columns=["config"]), f"fits t = t0 + a·P^α + b·T^β (P in Mpx, T in M triangles, ms; "
                                         f"{LEVEL:.0%} intervals from the covariance)")
    show(cross, "crossovers of the fitted laws (on the cross, within the ranges both families were measured on)")
    from shadowlab.output import provenance

    record.update({"renderer": renderer, "law": "t = t0 + a*(P/1e6)^alpha + b*(T/1e6)^beta, ms",
                   "fit": "scipy curve_fit, sigma = time (relative residuals), bounds >= 0, exponents <= 3",
                   "fitted_on": "cross and corners" if args.fit_corners else "cross (triangle and pixel sweeps)",
                   "intervals": f"{LEVEL:.0%}, covariance at the optimum, Student t with n-5 dof",
                   "seconds": round(time.perf_counter() - t_start, 1)})
    provenance.write_record(out / "scaling_laws", record, gl_info=False)
    wrote = f"{out / 'points.csv'}, fits.csv" if not args.points else f"{out / 'fits.csv'}"
    print(f"\nrenderer: {renderer}; wrote {wrote}, fits.md, crossovers.csv, scaling_laws.json, "
          f"{figures / 'scaling_time.png'} and {figures / 'scaling_error.png'} ({record['seconds']:.0f} s)")


if __name__ == "__main__":
    main()
