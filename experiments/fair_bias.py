"""A fair comparison of shadow-map biases: every variant at its exact optimum beside its default,
the per-pixel oracle, one global bias judged on held-out scenes, how the optimum scales, and
what the exact optimisation costs against a brute-force sweep (issue 24; docs/tuning.md).

Everything here comes from the exact bias optimiser (``shadowlab.tuning.exact_bias``): one
render per configuration gives the error of every constant bias at once, so "the optimum" is
exact, not the best of a grid. Parts (each writes ``<out>/<part>.csv``; figures beside):

1. ``regret``: on every shadow-map hard case (the shipped ``sm_*`` scenes) and each variant —
   constant, slope (slope_scale on a grid), normal_offset (on a grid), receiver_plane
   (Isidoro 2006) and adaptive (Dou et al. 2014; adaptive_epsilon on a grid) — the error at the
   variant's defaults, at constant bias 0 (the adaptive schemes' own form), at its optimum, the
   constant-bias optimum and the per-pixel oracle; the regret of each against the oracle.
2. ``global``: one constant bias for every hard case? Leave-one-out: tuned on the others,
   judged on the held-out scene, against its own optimum and the default.
3. ``scaling``: the smallest optimal constant bias against map resolution,
   receiver slope (a floor under a sun at elevations 3°..80°: N·L = sin θ), depth bits and PCF
   radius; log-log fits with 95 % intervals (scipy.stats.linregress).
4. ``cost``: one exact optimisation against a brute-force sweep of 200 renders, and whether the
   two agree.

    python experiments/fair_bias.py [--out results/fair_bias] [--size 320x240] [--parts regret,global,scaling,cost]
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import pandas as pd

from shadowlab.output import provenance
from shadowlab.gpu.frame import Frame
from shadowlab.output.pictures import PLOT_DPI
from shadowlab.measurement.pipeline import Evaluator, measure_configs
from shadowlab.scene import builtin_scenes, load_scene
from shadowlab.scene.reading import parse_scene
from shadowlab.techniques.maps.shadow_map import VARIANTS
from shadowlab.tuning.exact_bias import BiasCurve, exact_bias_tune
from shadowlab.tuning.global_setting import SceneCurve, leave_one_out

#: The grids of the non-constant parts (the constant part is exact on each).
SLOPE_GRID = [0.0, 0.25, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0]
NORMAL_GRID = [0.0, 0.25, 0.5, 1.0, 1.5, 2.0, 3.0, 4.0]
#: adaptive_epsilon (a fraction of the scene's diagonal): 0 (the tangent plane alone) to far too much.
ADAPTIVE_GRID = [0.0, 1e-6, 1e-5, 1e-4, 1e-3, 1e-2]
#: The bias range every optimum is sought in (window depth), the shadow_map parameter's own.
BIAS_RANGE = (0.0, 1.0)
#: The variants of the regret table and the grid parameter each brings.
REGRET_VARIANTS = [("constant", None, None), ("slope", "slope_scale", SLOPE_GRID),
                   ("normal_offset", "normal_offset", NORMAL_GRID),
                   ("receiver_plane", None, None), ("adaptive", "adaptive_epsilon", ADAPTIVE_GRID)]
#: The map fits of the regret table: the lab's default and the classic fit to every receiver.
FITS = ["shadowable", "receivers"]
RESOLUTIONS = [256, 512, 1024, 2048, 4096, 8192]
ELEVATIONS_DEG = [3, 5, 10, 20, 30, 45, 60, 80]
DEPTH_BITS = [16, 24, 32]
FILTERS = ["nearest", "pcf3", "pcf5"]
SWEEP_RENDERS = 200


def hard_cases() -> list[str]:
    """The shipped shadow-map hard cases (scenes named sm_*)."""
    return [n for n in builtin_scenes() if n.startswith("sm_")]


def _tune(ev: Evaluator, spec: str, grid_param=None, grid=None):
    return exact_bias_tune(ev, spec, 0, *BIAS_RANGE, {grid_param: grid} if grid_param else None, repeat=1, warmup=0)


def regret_table(size, scenes) -> tuple[pd.DataFrame, dict]:
    """Part 1 (module docstring) for both fits of the map (the lab's default ``shadowable`` and
    the classic ``receivers``, where the hard cases were designed to show their artefact), and
    each (fit, scene)'s constant-bias curve for part 2."""
    rows, curves = [], {}
    for scene, fit in [(s, f) for s in scenes for f in FITS]:
        ev = Evaluator(Frame(load_scene(scene), *size))
        oracle = None
        for variant, grid_param, grid in REGRET_VARIANTS:
            if variant not in VARIANTS:
                continue
            spec = f"shadow_map:variant={variant},fit={fit}"
            t0 = time.perf_counter()
            tune = _tune(ev, spec, grid_param, grid)
            seconds = time.perf_counter() - t0
            tech_bias = float(tune.base.technique.bias)
            own = next(p for p in tune.points if all(getattr(tune.base.technique, k) == v for k, v in p.params.items())) \
                if grid_param and getattr(tune.base.technique, grid_param) in grid else tune.points[0]
            default = own.curve.at(tech_bias)["error_rate"]
            zero_bias = own.curve.at(0.0)["error_rate"]  # the adaptive schemes' paper form: no constant bias
            point, opt = tune.best("error_rate")
            if variant == "constant":
                oracle = point.curve.oracle["error_rate"]
                curves.setdefault(fit, {})[scene] = SceneCurve.of(scene, point.curve, "error_rate")
            rows.append({"scene": scene, "fit": fit, "variant": variant, "default_error": default,
                         "zero_bias_error": zero_bias, "tuned_error": opt.value,
                         "tuned_bias": opt.bias, "tuned_interval_lo": opt.lo, "tuned_interval_hi": opt.hi,
                         "tuned_grid": ",".join(f"{k}={v:g}" for k, v in point.params.items()),
                         "variant_oracle": point.curve.oracle["error_rate"], "emulation_mismatch": tune.emulation_mismatch,
                         "seconds": seconds, "evaluated_pixels": int(tune.evaluated.sum())})
        for r in rows:
            if r["scene"] == scene and r["fit"] == fit:
                r["constant_oracle"] = oracle
        ev.frame.release()
    df = pd.DataFrame(rows)
    df["default_regret_vs_oracle"] = df["default_error"] - df["constant_oracle"]
    df["tuned_regret_vs_oracle"] = df["tuned_error"] - df["constant_oracle"]
    return df, curves


def global_table(curves: dict) -> pd.DataFrame:
    """Part 2: leave-one-out over the hard cases' constant-bias curves, per fit."""
    from shadowlab.techniques.maps.shadow_map import COMPARISON_PARAMS

    default = COMPARISON_PARAMS["bias"].default
    rows = []
    for fit, by_scene in curves.items():
        rows += _held_out_rows(fit, by_scene, default)
    return pd.DataFrame(rows)


def _held_out_rows(fit: str, curves: dict, default: float) -> list[dict]:
    rows = []
    for h in leave_one_out(curves, default):
        s = h.test[0]
        rows.append({"fit": fit, "held_out": s, "global_bias": h.bias, "global_interval_lo": h.interval[0],
                     "global_interval_hi": h.interval[1], "train_mean_error": h.train_mean,
                     "held_out_error": h.test_values[s], "own_optimum_error": h.test_optima[s],
                     "regret": h.regret[s], "default_error": h.default_values[s], "default_regret": h.default_regret[s],
                     "own_interval_lo": curves[s].optimum().lo, "own_interval_hi": curves[s].optimum().hi})
    return rows


def grazing_scene(elevation_deg: float):
    """A 40 m floor with a box and a post under a sun at ``elevation_deg`` (N·L = sin θ), seen as
    sm_grazing sees it; the light's azimuth is sm_grazing's."""
    th = np.radians(elevation_deg)
    az = np.array([-0.9986, -0.05]) / np.hypot(-0.9986, -0.05)
    d = [float(np.cos(th) * az[0]), -float(np.sin(th)), float(np.cos(th) * az[1])]
    data = {"name": f"floor_sun_{elevation_deg:g}deg",
            "camera": {"eye": [0.0, 6.0, 9.0], "target": [0.0, 0.0, 0.0], "fov_y": 50.0},
            "lights": [{"type": "directional", "direction": d}],
            "objects": [{"name": "floor", "mesh": "plane", "size": [40.0, 40.0]},
                        {"name": "box", "mesh": "box", "size": [0.6, 0.8, 0.6], "translate": [3.0, 0.4, -1.0]},
                        {"name": "post", "mesh": "cylinder", "radius": 0.1, "height": 0.6,
                         "translate": [2.0, 0.3, 1.5]}]}
    return parse_scene(data, f"<{data['name']}>")


def _optimum_row(ev, spec, receiver: str | None = None, **facts) -> dict:
    """The optimum of ``spec`` on the evaluator's frame; with ``receiver`` (an object's name) the
    optimum over that object's pixels only (the curve of those pixels, from the same render)."""
    tune = _tune(ev, spec)
    point, opt = tune.best("error_rate")
    curve = point.curve
    if receiver is not None:
        frame = ev.frame
        index = [o.name for o in frame.scene.objects].index(receiver)
        mask = tune.evaluated & (frame.object_id == index)
        curve = BiasCurve.build(point.thresholds[:, mask.ravel()], ev.truth(0).visibility[mask], *BIAS_RANGE)
        opt = curve.optimum("error_rate")
    return {**facts, "spec": spec, "receiver": receiver or "all", "optimum_bias": opt.bias, "optimum_lo": opt.lo,
            "optimum_hi": opt.hi, "error_at_optimum": opt.value,
            "error_at_default": curve.at(float(tune.base.technique.bias))["error_rate"],
            "depth_range": tune.base.stats.get("depth_range"), "texel_world": tune.base.stats.get("texel_world")}


def scaling_table(size) -> pd.DataFrame:
    """Part 3 (module docstring)."""
    rows = []
    for scene in ["sm_grazing", "sm_contact"]:
        ev = Evaluator(Frame(load_scene(scene), *size))
        for r in RESOLUTIONS:
            rows.append(_optimum_row(ev, f"shadow_map:resolution={r}", scene=scene, axis="resolution", x=r))
        for bits in DEPTH_BITS:
            rows.append(_optimum_row(ev, f"shadow_map:depth_bits={bits}", scene=scene, axis="depth_bits", x=bits))
        for f in FILTERS:
            rows.append(_optimum_row(ev, f"shadow_map:filter={f}", scene=scene, axis="pcf_radius",
                                     x={"nearest": 0, "pcf3": 1, "pcf5": 2}[f]))
        ev.frame.release()
    for deg in ELEVATIONS_DEG:
        scene = grazing_scene(deg)
        ev = Evaluator(Frame(scene, *size))
        for receiver in (None, "floor"):
            rows.append(_optimum_row(ev, "shadow_map", receiver, scene=scene.name, axis="n_dot_l",
                                     x=float(np.sin(np.radians(deg)))))
        ev.frame.release()
    return pd.DataFrame(rows)


def scaling_fits(df: pd.DataFrame) -> pd.DataFrame:
    """Log-log fits of the smallest optimal bias, in world units (``optimum_lo`` × the map's depth
    range), against what the rule of thumb says it should follow: the depth change across one
    texel on the receiver, texel_world × tan(angle between N and L) — over the resolution series
    (tan fixed: the exponent against the texel size) and the sun-elevation series (texel_world ×
    cot(elevation)) — with 95 % intervals of the exponent; the rule says exponent 1."""
    from scipy import stats

    out = []
    series = [(f"resolution: {sc}", g, g["texel_world"]) for sc, g in
              df[df["axis"] == "resolution"].groupby("scene")]
    for receiver, el in df[df["axis"] == "n_dot_l"].groupby("receiver"):
        series.append((f"sun elevation: floor_sun_*, {receiver} receivers", el,
                       el["texel_world"] * np.sqrt(1 - el["x"] ** 2) / el["x"]))
    for name, g, x in series:
        y = g["optimum_lo"] * g["depth_range"]
        keep = (y > 0) & (x > 0)
        if keep.sum() < 3:
            continue
        fit = stats.linregress(np.log(x[keep]), np.log(y[keep]))
        half = stats.t.ppf(0.975, int(keep.sum()) - 2) * fit.stderr
        out.append({"series": name, "x": "texel_world" if name.startswith("resolution") else "texel_world*cot(elev)",
                    "y": "optimum_lo * depth_range (world)", "exponent": fit.slope, "exponent_lo": fit.slope - half,
                    "exponent_hi": fit.slope + half, "r2": fit.rvalue ** 2, "points": int(keep.sum())})
    return pd.DataFrame(out)


def cost_table(size) -> pd.DataFrame:
    """Part 4: one exact optimisation against a brute-force sweep of 200 renders."""
    rows = []
    for scene in ["sm_grazing", "sm_contact"]:
        ev = Evaluator(Frame(load_scene(scene), *size))
        ev.truth(0)
        t0 = time.perf_counter()
        tune = _tune(ev, "shadow_map")
        exact_s = time.perf_counter() - t0
        point, opt = tune.best("error_rate")
        biases = sorted({float(np.float32(b)) for b in np.geomspace(1e-6, 0.05, SWEEP_RENDERS)})
        t0 = time.perf_counter()
        df = measure_configs(None, [f"shadow_map:bias={b!r}" for b in biases], evaluator=ev)
        sweep_s = time.perf_counter() - t0
        rendered = df[~df["reference"]]["error_rate"].to_numpy()
        predicted = np.array([point.curve.at(b)["error_rate"] for b in biases])
        rows.append({"scene": scene, "width": size[0], "height": size[1], "exact_seconds": exact_s,
                     "sweep_renders": len(biases), "sweep_seconds": sweep_s, "speedup": sweep_s / exact_s,
                     "exact_optimum": opt.value, "exact_bias": opt.bias, "sweep_best": rendered.min(),
                     "sweep_best_bias": biases[int(np.argmin(rendered))],
                     "renders_equal_to_curve": int((rendered == predicted).sum()), "steps": len(point.curve.breaks)})
        ev.frame.release()
    return pd.DataFrame(rows)


def plot_regret(df: pd.DataFrame, path: Path) -> None:
    """Bars per hard case, one panel per fit: each variant's error at its defaults (pale) and at
    its optimum (solid); the per-pixel oracle as a black dash."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fits = list(dict.fromkeys(df["fit"]))
    fig = Figure(figsize=(11, 3.6 * len(fits)), dpi=PLOT_DPI)
    FigureCanvasAgg(fig)
    colors = {"constant": "#1f77b4", "slope": "#ff7f0e", "normal_offset": "#2ca02c", "receiver_plane": "#9467bd",
              "adaptive": "#8c564b"}
    for ax, fit in zip(fig.subplots(len(fits), 1, squeeze=False)[:, 0], fits):
        d = df[df["fit"] == fit]
        scenes = list(dict.fromkeys(d["scene"]))
        variants = list(dict.fromkeys(d["variant"]))
        width = 0.8 / len(variants)
        for i, v in enumerate(variants):
            g = d[d["variant"] == v].set_index("scene").reindex(scenes)
            x = np.arange(len(scenes)) + (i - (len(variants) - 1) / 2) * width
            ax.bar(x, 100 * g["default_error"], width, color=colors.get(v, "#777777"), alpha=0.35)
            ax.bar(x, 100 * g["tuned_error"], width * 0.6, color=colors.get(v, "#777777"), label=v)
        oracle = d.groupby("scene", sort=False)["constant_oracle"].first().reindex(scenes)
        ax.plot(np.arange(len(scenes)), 100 * oracle, "k_", ms=28, mew=2, ls="none", label="per-pixel oracle")
        ax.set_xticks(np.arange(len(scenes)), scenes, fontsize=8)
        ax.set_yscale("symlog", linthresh=0.01)
        ax.set_ylabel("error rate, %")
        ax.set_title(f"fit={fit}: each bias variant at its defaults (pale) and at its exact optimum (solid)",
                     fontsize=10)
        ax.legend(fontsize=7.5, ncol=3)
        ax.grid(alpha=0.3, axis="y")
    fig.tight_layout()
    fig.savefig(path)


def plot_scaling(df: pd.DataFrame, path: Path) -> None:
    """The smallest optimal bias (window depth) against each axis."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(12, 3.4), dpi=PLOT_DPI)
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, 4)
    for ax, (axis, label) in zip(axes, [("resolution", "map resolution, texels"), ("n_dot_l", "N·L (sun elevation)"),
                                        ("depth_bits", "depth bits"), ("pcf_radius", "PCF radius, texels")]):
        for key, g in df[df["axis"] == axis].groupby("scene" if axis != "n_dot_l" else "receiver"):
            ax.plot(g["x"], g["optimum_lo"].clip(lower=1e-9), "o-",
                    label=key if axis != "n_dot_l" else f"{key} receivers")
        ax.set_xlabel(label)
        ax.set_yscale("log")
        if axis in ("resolution", "n_dot_l"):
            ax.set_xscale("log")
        if axis == "resolution":
            ax.set_xticks(RESOLUTIONS, [str(r) for r in RESOLUTIONS], fontsize=7)
            ax.minorticks_off()
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    axes[0].set_ylabel("smallest optimal bias (window depth)")
    fig.tight_layout()
    fig.savefig(path)


def show(table: pd.DataFrame) -> None:
    """Print a result table whole (wide, every column) on the terminal."""
    with pd.option_context("display.width", 220, "display.max_columns", 20):
        print(table.to_string(index=False))


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="results/fair_bias", help="output folder")
    ap.add_argument("--size", default="320x240", help="image size WIDTHxHEIGHT (default 320x240)")
    ap.add_argument("--parts", default="regret,global,scaling,cost", help="comma-separated parts to run")
    args = ap.parse_args(argv)
    size = tuple(int(v) for v in args.size.lower().split("x"))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    parts = set(args.parts.split(","))
    written = []
    t_start = time.perf_counter()
    if parts & {"regret", "global"}:
        regret, curves = regret_table(size, hard_cases())
        if "regret" in parts:
            regret.to_csv(out / "regret.csv", index=False)
            plot_regret(regret, out / "regret.png")
            written += ["regret.csv", "regret.png"]
            show(regret[["scene", "fit", "variant", "default_error", "tuned_error", "tuned_bias", "tuned_grid",
                          "constant_oracle", "emulation_mismatch"]])
        if "global" in parts:
            g = global_table(curves)
            g.to_csv(out / "global.csv", index=False)
            written.append("global.csv")
            show(g)
    if "scaling" in parts:
        s = scaling_table(size)
        s.to_csv(out / "scaling.csv", index=False)
        fits = scaling_fits(s)
        fits.to_csv(out / "scaling_fits.csv", index=False)
        plot_scaling(s, out / "scaling.png")
        written += ["scaling.csv", "scaling_fits.csv", "scaling.png"]
        show(s[["scene", "axis", "x", "optimum_lo", "optimum_hi", "error_at_optimum", "error_at_default",
                 "depth_range"]])
        show(fits)
    if "cost" in parts:
        c = cost_table(size)
        c.to_csv(out / "cost.csv", index=False)
        written.append("cost.csv")
        show(c)
    provenance.write_record(out / "fair_bias", {"size": list(size), "parts": sorted(parts),
                                                "seconds": time.perf_counter() - t_start})
    print(f"wrote {', '.join(str(out / w) for w in written)} and {out / 'fair_bias.json'}")


if __name__ == "__main__":
    main()
