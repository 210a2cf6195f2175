"""Many lights (issue 40): which lights get shadows, at what error in the shaded image, at what cost.

For each many-light scene, every light's visibility is measured once per technique — the exact
shadows (the truth itself: the selection's error alone) and a shadow map (``MAP``), with its time,
faces and texels — and every shadow budget is then the lab's own selection
(:func:`shadowlab.lighting.selection.select`) applied to those images, as
:mod:`shadowlab.measurement.budget` applies it during a measurement (a light kept on no evaluated
pixel is not rendered and costs nothing; a dropped light is lit unshadowed or not drawn). Every
cost counts only the lights that reach a covered pixel — the "every light" rows too: an engine
culls the others, and a budget never renders them. The
shaded image's error is :mod:`shadowlab.evaluation.radiance`'s. One configuration per scene is also
run through the pipeline itself (``compare_frame``) and must give the same radiance error: the
check that this shortcut measures what a study would.

1. Still frames: radiance error against K (1 … all lights) for each selection policy and drop
   policy, the seed's rule's regret against the best policy at each K, and the cost of each
   (maps rendered, faces, texels, milliseconds on this machine): the speed-against-error frontier.
2. Motion (``ml_city_walk``): per frame the same, plus the shaded image's flicker
   (``radiance_flicker``) and how much of the image changes its set of shadowed lights
   (``selection_change_rate``) from frame to frame, for each policy and K.
3. Imperfect shadow maps for the lights outside the budget (``drop=imperfect``) against leaving
   them unshadowed and against full maps for every light, with the ISMs' own per-light error and
   cost beside the full maps' for the same lights.
4. The shadow atlas (``atlas=S`` with the screen policy), through the pipeline: radiance error,
   per-light resolutions and overflow.

Writes results/many_lights/{still,motion,imperfect,atlas,pipeline_check}.csv and the pictures
docs/images/many-lights-*.png. About half an hour at 320x240 on a 2-core machine.

    python experiments/many_lights.py [--out results/many_lights] [--size 320x240] [--only still|motion|imperfect|atlas]
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd
from tqdm import tqdm

from shadowlab.evaluation import radiance, temporal
from shadowlab.gpu.frame import Frame
from shadowlab.lighting import selection
from shadowlab.measurement.pipeline import Evaluator, compare_frame, measure, radiance_terms
from shadowlab.measurement.scenes import load_measured_scene
from shadowlab.scene.animation import frame_times, scene_at
from shadowlab.techniques import from_spec

STILL = ["ml_interior", "ml_city_64", "ml_city_256"]
MOTION = "ml_city_walk"
#: The full-map technique of the budgets (512² per face: what engines give point lights).
MAP = "shadow_map:resolution=512"
ISM = "imperfect_map"
DROPS = ("unshadowed", "unlit")
DOCS_IMAGES = Path(__file__).resolve().parents[1] / "docs" / "images"


def budgets(n: int) -> list[int]:
    """K = 1, 2, 4, … below the light count, then every light."""
    ks, k = [], 1
    while k < n:
        ks.append(k)
        k *= 2
    return ks + [n]


class Lights:
    """One technique's per-light results on a frame: visibility images, time (ms), faces, texels,
    rendered once per light with the pipeline's ``measure``."""

    def __init__(self, frame: Frame, spec: str | None, evaluator: Evaluator, repeat: int, desc: str):
        n = len(frame.scene.lights)
        self.vis, self.ms, self.faces, self.texels = [], np.zeros(n), np.zeros(n), np.zeros(n)
        #: the lights that reach a covered pixel: the only ones any configuration pays for (an
        #: engine culls the others, and a budget never renders them)
        self.reaches = np.array([frame.slot(li).evaluated.any() for li in range(n)])
        for li in tqdm(range(n), desc=desc, leave=False):
            if spec is None:  # the exact shadows: the truth's own images and time
                m = evaluator.truth(li)
            else:
                m = measure(from_spec(spec), frame, li, repeat=repeat, warmup=0 if repeat == 1 else 1)
            self.vis.append(m.visibility)
            self.ms[li] = m.timing.median_ms
            faces = m.stats.get("faces", 0) or 0
            res = m.technique.params().get("resolution", 0) or 0
            self.faces[li], self.texels[li] = faces, faces * res * res


def apply_budget(frame: Frame, sel: selection.Selection, lights: Lights, drop: str, rest: Lights | None = None):
    """The images of a budget: per light the technique's visibility where kept, the drop policy
    elsewhere (as shadowlab.measurement.budget does), the weights, and which lights are rendered
    (kept on an evaluated pixel) and which need the rest's map (dropped on one)."""
    vis, weights = [], []
    n = len(frame.scene.lights)
    rendered, needs_rest = np.zeros(n, bool), np.zeros(n, bool)
    for li in range(n):
        kept_c = sel.compact_mask(frame, li)
        ev = frame.slot(li).evaluated
        rendered[li] = (kept_c & ev).any()
        needs_rest[li] = (~kept_c & ev).any()
        kept = frame.to_image(kept_c, fill=False, dtype=bool) | ~frame.covered
        if drop == "unshadowed":
            vis.append(np.where(kept, lights.vis[li], 1.0).astype(np.float32))
            weights.append(None)
        elif drop == "unlit":
            vis.append(np.where(kept, lights.vis[li], 0.0).astype(np.float32))
            weights.append(kept.astype(np.float32))
        else:
            vis.append(np.where(kept, lights.vis[li], rest.vis[li]).astype(np.float32))
            weights.append(None)
    return vis, weights, rendered, needs_rest


def cost(lights: Lights, rendered: np.ndarray, rest: Lights | None = None, needs_rest=None) -> dict:
    """The cost columns of a budget: maps, faces, texels and milliseconds of the rendered lights
    (plus the rest's for the lights that need it)."""
    out = {"maps": int(rendered.sum()), "faces": float(lights.faces[rendered].sum()),
           "texels": float(lights.texels[rendered].sum()), "time_ms": float(lights.ms[rendered].sum())}
    if rest is not None:
        out.update(rest_maps=int(needs_rest.sum()), rest_texels=float(rest.texels[needs_rest].sum()),
                   rest_ms=float(rest.ms[needs_rest].sum()))
        out["time_ms"] += out["rest_ms"]
    return out


def still_rows(scene_name: str, size, repeat: int) -> tuple[pd.DataFrame, dict]:
    """Radiance error and cost of every (technique, policy, K, drop) on one still frame."""
    scene = load_measured_scene(scene_name)
    frame = Frame(scene, *size)
    try:
        ev = Evaluator(frame, repeat=repeat, warmup=0)
        exact = Lights(frame, None, ev, repeat, f"{scene_name}: truth")
        truth = exact.vis
        techs = {"exact": exact, "shadow_map": Lights(frame, MAP, ev, repeat, f"{scene_name}: {MAP}")}
        terms = radiance_terms(frame)
        n = len(scene.lights)
        rows = []
        for tname, lights in techs.items():
            full, _ = radiance.radiance_columns(frame, lights.vis, truth, None, terms)
            rows.append({"scene": scene_name, "technique": tname, "policy": "all", "k": n, "drop": "none",
                         **full, **cost(lights, lights.reaches)})
            for policy in selection.POLICIES:
                for k in budgets(n):
                    sel = selection.select(policy, k, scene.lights, scene.objects, frame)
                    for drop in DROPS:
                        vis, weights, rendered, _ = apply_budget(frame, sel, lights, drop)
                        image, _ = radiance.radiance_columns(frame, vis, truth, weights, terms)
                        rows.append({"scene": scene_name, "technique": tname, "policy": policy, "k": k,
                                     "drop": drop, **image, **cost(lights, rendered)})
        check = pipeline_check(frame, scene_name, rows)
        return pd.DataFrame(rows), check
    finally:
        frame.release()


def pipeline_check(frame: Frame, scene_name: str, rows: list[dict]) -> dict:
    """One configuration through compare_frame: its radiance error must equal this script's."""
    ks = budgets(len(frame.scene.lights))
    k = ks[min(3, len(ks) - 2)]  # 8 lights of many, fewer of a few
    spec = f"raytrace:budget={k},select=screen,seed=1"
    result = compare_frame(frame, [from_spec(spec)], repeat=1, warmup=0)
    df = result.rows
    got = float(df[~df["reference"].astype(bool)]["radiance_error"].iloc[0])
    mine = next(r["radiance_error"] for r in rows if r["technique"] == "exact" and r["policy"] == "screen"
                and r["k"] == k and r["drop"] == "unshadowed")
    equal = bool(np.isclose(got, mine, rtol=1e-9, atol=1e-12))
    if not equal:
        raise AssertionError(f"{scene_name}: {spec} through the pipeline gives radiance_error {got}, this script {mine}")
    return {"scene": scene_name, "spec": spec, "pipeline_radiance_error": got, "script_radiance_error": mine,
            "equal": equal}


def regret(still: pd.DataFrame) -> pd.DataFrame:
    """Per scene, technique, drop and K: the seed's rule's radiance error minus the best policy's."""
    df = still[still["policy"] != "all"]
    rows = []
    for (scene, tech, drop, k), g in df.groupby(["scene", "technique", "drop", "k"]):
        best = g.loc[g["radiance_error"].idxmin()]
        seed = g[g["policy"] == "face"]["radiance_error"].iloc[0]
        rows.append({"scene": scene, "technique": tech, "drop": drop, "k": k, "face_error": seed,
                     "best_policy": best["policy"], "best_error": best["radiance_error"],
                     "face_regret": seed - best["radiance_error"]})
    return pd.DataFrame(rows)


def motion_rows(size, repeat: int, ks=(1, 4, 8, 16, 32)) -> pd.DataFrame:
    """Per frame of the animated scene, per technique, policy and K: radiance error, radiance
    flicker and selection change against the previous frame."""
    scene = load_measured_scene(MOTION)
    n_frames = scene.animation.frames
    states = {(p, k): selection.ReservoirState() for p in selection.POLICIES for k in ks}
    prev = {}
    prev_geom = prev_cov = None
    rows = []
    for fi, t in enumerate(tqdm(frame_times(n_frames), desc=f"{MOTION}: frames")):
        frame = Frame(scene_at(scene, t), *size)
        try:
            ev = Evaluator(frame, repeat=repeat, warmup=0)
            exact = Lights(frame, None, ev, repeat, "truth")
            techs = {"exact": exact, "shadow_map": Lights(frame, MAP, ev, repeat, MAP)}
            terms = radiance_terms(frame)
            truth_lum = radiance.luminance_image(frame, exact.vis, None, terms)
            floor = radiance.DARK_FLOOR * max(float(np.nanmean(truth_lum)), 1e-12)
            geom = temporal.FrameGeometry.of(frame)
            reproj = None if prev_geom is None else temporal.reproject(geom, prev_geom, frame.covered, prev_cov)
            evals = [frame.evaluated(li) for li in range(len(scene.lights))]
            sels = {(p, k): selection.select(p, k, frame.scene.lights, frame.scene.objects, frame, states[(p, k)])
                    for p in selection.POLICIES for k in ks}
            for tname, lights in techs.items():
                for (policy, k), sel in sels.items():
                    vis, weights, rendered, _ = apply_budget(frame, sel, lights, "unshadowed")
                    image, _ = radiance.radiance_columns(frame, vis, exact.vis, weights, terms)
                    lum = radiance.luminance_image(frame, vis, weights, terms)
                    kept = [frame.to_image(sel.compact_mask(frame, li), fill=False, dtype=bool) & evals[li]
                            for li in range(len(scene.lights))]
                    key = (tname, policy, k)
                    row = {"frame": fi, "technique": tname, "policy": policy, "k": k, **image,
                           **cost(lights, rendered)}
                    if reproj is not None and key in prev:
                        row["radiance_flicker"] = temporal.radiance_pair(prev[key][0], lum, prev["truth"], truth_lum,
                                                                         reproj, floor)
                        row["selection_change_rate"] = temporal.selection_change(prev[key][1], kept, prev["evals"],
                                                                                 evals, reproj)
                    rows.append(row)
                    prev[key] = (lum, kept)
            prev["truth"], prev["evals"] = truth_lum, evals
            prev_geom, prev_cov = geom, frame.covered.copy()
        finally:
            frame.release()
    return pd.DataFrame(rows)


def imperfect_rows(scene_name: str, size, repeat: int) -> pd.DataFrame:
    """Budgets with the rest unshadowed, with imperfect shadow maps, and full maps for all; and
    per light, the ISM's error and cost against the full map's."""
    from shadowlab.evaluation import metrics

    scene = load_measured_scene(scene_name)
    frame = Frame(scene, *size)
    try:
        ev = Evaluator(frame, repeat=repeat, warmup=0)
        exact = Lights(frame, None, ev, repeat, "truth")
        maps = Lights(frame, MAP, ev, repeat, MAP)
        isms = Lights(frame, ISM, ev, repeat, ISM)
        terms = radiance_terms(frame)
        n = len(scene.lights)
        rows = []
        for name, lights in (("all full maps", maps), ("all imperfect maps", isms)):
            image, _ = radiance.radiance_columns(frame, lights.vis, exact.vis, None, terms)
            rows.append({"scene": scene_name, "kind": "budget", "config": name, "k": n, **image,
                         **cost(lights, lights.reaches)})
        for k in budgets(n)[:-1]:
            sel = selection.select("screen", k, scene.lights, scene.objects, frame)
            for drop, rest in (("unshadowed", None), ("imperfect", isms)):
                vis, weights, rendered, needs = apply_budget(frame, sel, maps, drop, rest)
                image, _ = radiance.radiance_columns(frame, vis, exact.vis, weights, terms)
                rows.append({"scene": scene_name, "kind": "budget", "config": f"screen, rest {drop}", "k": k,
                             **image, **cost(maps, rendered, rest, needs)})
        for li in range(n):
            evi = frame.evaluated(li)
            for name, lights in (("full map", maps), ("imperfect map", isms)):
                m = metrics.compare(lights.vis[li], exact.vis[li], evi)
                rows.append({"scene": scene_name, "kind": "light", "config": name, "light": li,
                             "error_rate": m["error_rate"], "false_lit_rate": m["false_lit_rate"],
                             "evaluated_pixels": m["evaluated_pixels"], "time_ms": lights.ms[li],
                             "texels": lights.texels[li]})
        return pd.DataFrame(rows)
    finally:
        frame.release()


def atlas_rows(scene_name: str, size, sizes=(1024, 2048, 4096), k: int = 64) -> pd.DataFrame:
    """shadow_map with a budget and a shared atlas, through the pipeline: radiance error, per-light
    resolutions and overflow per atlas size."""
    scene = load_measured_scene(scene_name)
    frame = Frame(scene, *size)
    try:
        specs = [f"{MAP},budget={k},select=screen"] + [f"{MAP},budget={k},select=screen,atlas={s}" for s in sizes]
        result = compare_frame(frame, [from_spec(s) for s in specs], repeat=1, warmup=0)
        df = result.rows[~result.rows["reference"].astype(bool)]
        rows = []
        for label, g in df.groupby("label", sort=False):
            kept = g[g["budget_rendered"] == 1]
            res = kept["atlas_resolution"] if "atlas_resolution" in g else pd.Series(dtype=float)
            rows.append({"scene": scene_name, "config": g["short_label"].iloc[0], "k": k,
                         "radiance_error": g["radiance_error"].iloc[0], "radiance_bias": g["radiance_bias"].iloc[0],
                         "lights_rendered": int(len(kept)), "time_ms": float(g["time_ms_median"].sum()),
                         "overflow": int(g["atlas_overflow"].fillna(0).sum()) if "atlas_overflow" in g else 0,
                         "res_min": float(res.min()) if len(res.dropna()) else np.nan,
                         "res_median": float(res.median()) if len(res.dropna()) else np.nan,
                         "res_max": float(res.max()) if len(res.dropna()) else np.nan,
                         "texels_used": float(g["atlas_texels_used"].iloc[0]) if "atlas_texels_used" in g else np.nan})
        return pd.DataFrame(rows)
    finally:
        frame.release()


# --------------------------------------------------------------------------- pictures

COLORS = {"face": "#d62728", "closest": "#7f7f7f", "object": "#ff7f0e", "screen": "#1f77b4", "restir": "#2ca02c"}


def plot_still(still: pd.DataFrame, out: Path) -> None:
    """Radiance error against K per policy (exact shadows: the selection's own error), one panel
    per scene; solid drop=unshadowed, dashed drop=unlit."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scenes = list(dict.fromkeys(still["scene"]))
    fig, axes = plt.subplots(1, len(scenes), figsize=(4.6 * len(scenes), 3.8), squeeze=False)
    for ax, scene in zip(axes[0], scenes):
        d = still[(still["scene"] == scene) & (still["technique"] == "exact") & (still["policy"] != "all")]
        for policy in selection.POLICIES:
            for drop, style in (("unshadowed", "-"), ("unlit", "--")):
                g = d[(d["policy"] == policy) & (d["drop"] == drop)].sort_values("k")
                ax.plot(g["k"], 100 * g["radiance_error"], style, color=COLORS[policy], marker="o", ms=3,
                        label=policy if drop == "unshadowed" else None)
        ax.set_xscale("log", base=2)
        ax.set_yscale("symlog", linthresh=0.1)
        ax.set_ylim(bottom=0)
        ax.set_xlabel("budget K (lights with shadows per face)")
        ax.set_ylabel("radiance error, %")
        ax.set_title(f"{scene} ({int(d['k'].max())} lights)")
        ax.grid(alpha=0.3)
    axes[0][0].legend(title="select (dashed: drop=unlit)", fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def plot_frontier(still: pd.DataFrame, out: Path) -> None:
    """Time against radiance error of every shadow-map budget (drop=unshadowed), per scene, the
    Pareto front drawn."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scenes = list(dict.fromkeys(still["scene"]))
    fig, axes = plt.subplots(1, len(scenes), figsize=(4.6 * len(scenes), 3.8), squeeze=False)
    for ax, scene in zip(axes[0], scenes):
        d = still[(still["scene"] == scene) & (still["technique"] == "shadow_map")
                  & (still["drop"].isin(["unshadowed", "none"]))]
        for policy in list(selection.POLICIES) + ["all"]:
            g = d[d["policy"] == policy]
            ax.scatter(g["time_ms"], 100 * g["radiance_error"], s=14, color=COLORS.get(policy, "black"),
                       label=policy if policy != "all" else "every light")
        pts = d.sort_values(["time_ms", "radiance_error"])
        front, best = [], np.inf
        for _, r in pts.iterrows():
            if r["radiance_error"] < best:
                front.append((r["time_ms"], 100 * r["radiance_error"]))
                best = r["radiance_error"]
        if front:
            ax.step(*zip(*front), where="post", color="black", lw=0.8, alpha=0.6)
        ax.set_xscale("symlog", linthresh=10)
        ax.set_yscale("symlog", linthresh=0.1)
        ax.set_ylim(bottom=0)
        ax.set_xlabel(f"{MAP}: summed ms per frame (llvmpipe)")
        ax.set_ylabel("radiance error, %")
        ax.set_title(scene)
        ax.grid(alpha=0.3)
    axes[0][0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def plot_motion(motion: pd.DataFrame, out: Path) -> None:
    """Mean radiance flicker and selection change against K per policy (exact shadows)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    d = motion[motion["technique"] == "exact"].groupby(["policy", "k"], as_index=False)[
        ["radiance_error", "radiance_flicker", "selection_change_rate"]].mean()
    fig, axes = plt.subplots(1, 3, figsize=(13.5, 3.6))
    for ax, col, label in zip(axes, ["radiance_error", "radiance_flicker", "selection_change_rate"],
                              ["radiance error, %", "radiance flicker, %", "pixels whose shadowed lights change, %"]):
        for policy in selection.POLICIES:
            g = d[d["policy"] == policy].sort_values("k")
            ax.plot(g["k"], 100 * g[col], marker="o", ms=3, color=COLORS[policy], label=policy)
        ax.set_xscale("log", base=2)
        ax.set_xlabel("budget K")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle(f"{MOTION}: mean over frames (exact shadows for the kept lights, the rest unshadowed)", fontsize=10)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", type=Path, default=Path("results/many_lights"))
    ap.add_argument("--size", default="320x240")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--only", choices=["still", "motion", "imperfect", "atlas", "plots"],
                    help="one part; 'plots' redraws the pictures from the CSVs in --out")
    ap.add_argument("--scenes", nargs="*", default=STILL)
    args = ap.parse_args()
    size = tuple(int(v) for v in args.size.split("x"))
    args.out.mkdir(parents=True, exist_ok=True)
    DOCS_IMAGES.mkdir(parents=True, exist_ok=True)
    if args.only == "plots":
        plot_still(pd.read_csv(args.out / "still.csv"), DOCS_IMAGES / "many-lights-error-vs-k.png")
        plot_frontier(pd.read_csv(args.out / "still.csv"), DOCS_IMAGES / "many-lights-frontier.png")
        if (args.out / "motion.csv").exists():
            plot_motion(pd.read_csv(args.out / "motion.csv"), DOCS_IMAGES / "many-lights-motion.png")
        return
    if args.only in (None, "still"):
        parts = [still_rows(s, size, args.repeat) for s in args.scenes]
        still = pd.concat([p[0] for p in parts], ignore_index=True)
        still.to_csv(args.out / "still.csv", index=False)
        regret(still).to_csv(args.out / "regret.csv", index=False)
        pd.DataFrame([p[1] for p in parts]).to_csv(args.out / "pipeline_check.csv", index=False)
        plot_still(still, DOCS_IMAGES / "many-lights-error-vs-k.png")
        plot_frontier(still, DOCS_IMAGES / "many-lights-frontier.png")
    if args.only in (None, "motion"):
        motion = motion_rows(size, 1)
        motion.to_csv(args.out / "motion.csv", index=False)
        plot_motion(motion, DOCS_IMAGES / "many-lights-motion.png")
    if args.only in (None, "imperfect"):
        pd.concat([imperfect_rows(s, size, args.repeat) for s in args.scenes],
                  ignore_index=True).to_csv(args.out / "imperfect.csv", index=False)
    if args.only in (None, "atlas"):
        pd.concat([atlas_rows(s, size) for s in args.scenes if s != "ml_interior"],
                  ignore_index=True).to_csv(args.out / "atlas.csv", index=False)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
