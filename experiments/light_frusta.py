"""Light frusta fitted from what casts, and a bias that means the same distance everywhere
(issue 35; docs/tuning.md, "Near planes and the world-distance bias"). Two parts, each a CSV:

1. ``frusta``: for every shipped scene and every light at a position (point, spot: perspective
   maps), the near plane fitted from the caster *bounding boxes* (the fit before issue 35,
   :func:`shadowlab.geometry.frusta.perspective_range`) against the one fitted from the caster
   *triangles* inside each frustum (:func:`shadowlab.geometry.frusta.perspective_fit`, what the
   maps use now), the far plane, and the world size of the default bias at the evaluated
   receivers: before — 0.002 of window depth through the box-fitted projection — and after —
   0.002 × the scene's extent (``bias_space=world``). Points to cover as ``shadow_map``'s
   default fit (``fit=shadowable``).
2. ``defaults``: every depth-map technique at its defaults on every shipped scene and light
   (``--techniques``), error_rate, false_lit_rate and the degenerate flag — the same script run
   on an older revision (``--parts defaults``, a checkout of it on PYTHONPATH) gives the
   "before" column; ``--before CSV`` joins that file into ``defaults_before_after.csv``.
3. ``bias``: the default constant bias re-chosen. On every shipped hard-light scene and light,
   the exact bias optimiser (:mod:`shadowlab.tuning.exact_bias`, one render) gives
   ``shadow_map``'s error at every ``bias`` (``bias_space=world``: × the scene's extent on
   perspective maps, the window-depth bias on orthographic ones); ``bias.csv`` holds each
   scene's optimum and the error at the default, ``bias_candidates.csv`` the mean and largest
   regret (error above the scene's optimum) of each candidate default, and, with ``--before``,
   on how many scene-lights it is worse than the old default.

    python experiments/light_frusta.py [--out results/light_frusta] [--size 320x240]
        [--parts frusta,defaults,bias] [--scenes a,b] [--before OLD_defaults.csv]
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pandas as pd

from shadowlab.output import provenance
from shadowlab.gpu.frame import Frame
from shadowlab.geometry import frusta
from shadowlab.geometry import transforms as tf
from shadowlab.geometry.transforms import BIAS
from shadowlab.scene import builtin_scenes, load_scene

#: Every depth-map technique the defaults part measures (each on the lights it renders for).
TECHNIQUES = ["shadow_map", "filtered_map", "virtual_map", "lispsm", "cascaded_map", "pcss", "moment_soft"]
#: The default constant bias of shadow_map, in both spaces.
DEFAULT_BIAS = 0.002


def frusta_rows(scene_name: str, size: tuple[int, int]) -> list[dict]:
    """Part 1 for one scene: a row per perspective light (point, spot)."""
    from shadowlab.scene.lights import PointLight
    from shadowlab.techniques.maps.toolkit import cube_face_index, shadowable_receivers, window_to_world

    scene = load_scene(scene_name)
    frame = Frame(scene, *size)
    rows = []
    try:
        for li, light in enumerate(scene.lights):
            if not isinstance(light, PointLight):
                continue
            slot = frame.slot(li)
            pts = shadowable_receivers(frame, slot)
            if not len(pts):
                continue
            views, _ = light.shadow_views(pts, frame.casters(), 2048)
            near, far = views[0].near_far()
            axes = np.array([-v.view[2, :3] for v in views])
            fov = 90.0 if len(views) == 6 else 2 * np.degrees(np.arctan(1.0 / views[0].proj[1, 1]))
            box_near, box_far = frusta.perspective_range(light.position, pts, frame.caster_bounds(), axes, fov)
            receivers = frame.compact_position[slot.evaluated]
            to_light, _ = light.to_light(receivers)
            box_proj = tf.perspective(fov, 1.0, box_near, box_far)  # the same views with the box fit's planes
            box_views = [frusta.LightView(v.view, box_proj) for v in views]
            face = cube_face_index(receivers, light.position, len(views))
            mats = np.stack([BIAS @ v.view_proj for v in box_views])[face]
            before = window_to_world(mats, receivers, to_light, np.full(len(receivers), DEFAULT_BIAS))
            finite = before[np.isfinite(before)]
            rows.append({"scene": scene_name, "light": li, "light_type": light.type_name, "faces": len(views),
                         "near_box": box_near, "near_triangles": near, "far": far,
                         "near_gain": near / box_near,
                         "bias_world_before_median": float(np.median(finite)) if len(finite) else np.inf,
                         "bias_world_before_max": float(finite.max()) if len(finite) else np.inf,
                         "bias_world_after": DEFAULT_BIAS * scene.extent()})
    finally:
        frame.release()
    return rows


def default_rows(scene_name: str, size: tuple[int, int], techniques: list[str]) -> list[dict]:
    """Part 2 for one scene: every technique that renders for a light, at its defaults."""
    from shadowlab.measurement.pipeline import check_lights, measure_configs
    from shadowlab.techniques import TechniqueError, from_spec

    scene = load_scene(scene_name)
    frame = Frame(scene, *size)
    rows = []
    try:
        for li, light in enumerate(scene.lights):
            specs = []
            for spec in techniques:
                try:
                    check_lights([from_spec(spec)], scene, [li])
                except TechniqueError:
                    continue  # the technique does not render for this light type
                specs.append(spec)
            for spec in specs:
                try:
                    df = measure_configs(scene, [spec], frame=frame, light_index=li)
                except TechniqueError as exc:
                    rows.append({"scene": scene_name, "light": li, "technique": spec, "skipped": str(exc)[:120]})
                    continue
                r = df[~df["reference"].astype(bool)].iloc[0]
                rows.append({"scene": scene_name, "light": li, "light_type": light.type_name, "technique": spec,
                             "error_rate": r["error_rate"], "false_lit_rate": r["false_lit_rate"],
                             "truth_shadowed_share": r["truth_shadowed_pixels"] / max(r["evaluated_pixels"], 1),
                             "degenerate": bool(r.get("degenerate", False)), "notes": r.get("notes", "")})
    finally:
        frame.release()
    return rows


#: Candidate defaults of ``bias`` (``bias_space=world``) the bias part evaluates.
BIAS_CANDIDATES = np.unique(np.append(np.geomspace(2.5e-4, 0.02, 19), DEFAULT_BIAS))


def bias_rows(scene_name: str, size: tuple[int, int]) -> list[dict]:
    """Part 3 for one scene: per light shadow_map renders for (hard lights only: the exact
    optimiser is not valid for a light-sampled area light), the exact error curve of ``bias``
    at the candidates, the optimum and the default's error."""
    from shadowlab.measurement.pipeline import Evaluator, check_lights
    from shadowlab.techniques import TechniqueError, from_spec
    from shadowlab.tuning.exact_bias import exact_bias_tune

    scene = load_scene(scene_name)
    frame = Frame(scene, *size)
    rows = []
    try:
        ev = Evaluator(frame)
        for li, light in enumerate(scene.lights):
            try:
                check_lights([from_spec("shadow_map")], scene, [li])
            except TechniqueError:
                continue
            if light.type_name == "area":
                continue
            r = exact_bias_tune(ev, "shadow_map", li)
            curve = r.points[0].curve
            opt = curve.optimum("error_rate")
            row = {"scene": scene_name, "light": li, "light_type": light.type_name, "optimum_bias": opt.bias,
                   "optimum_error": opt.value, "default_error": curve.at(DEFAULT_BIAS)["error_rate"],
                   "emulation_mismatch": r.emulation_mismatch}
            row.update({f"error_at_{k:.4g}": curve.at(k)["error_rate"] for k in BIAS_CANDIDATES})
            rows.append(row)
    finally:
        frame.release()
    return rows


def bias_candidates(rows: pd.DataFrame, before: pd.DataFrame | None) -> pd.DataFrame:
    """Per candidate default: mean and largest regret over the scene-lights (percentage points)
    and, given the old revision's defaults, how many are worse than its shadow_map (by > 0.01 pp)."""
    if before is not None:
        old = before[before["technique"] == "shadow_map"][["scene", "light", "error_rate"]]
        rows = rows.merge(old.rename(columns={"error_rate": "before"}), on=["scene", "light"], how="left")
    out = []
    for k in BIAS_CANDIDATES:
        err = rows[f"error_at_{k:.4g}"]
        regret = err - rows["optimum_error"]
        out.append({"bias": k, "mean_error_pct": 100 * err.mean(), "mean_regret_pp": 100 * regret.mean(),
                    "max_regret_pp": 100 * regret.max(),
                    "worse_than_before": int(((err - rows["before"]) > 1e-4).sum()) if before is not None else None})
    return pd.DataFrame(out)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="results/light_frusta")
    ap.add_argument("--size", default="320x240")
    ap.add_argument("--parts", default="frusta,defaults,bias")
    ap.add_argument("--scenes", default=None, help="comma-separated (default: every shipped scene)")
    ap.add_argument("--techniques", default=",".join(TECHNIQUES))
    ap.add_argument("--before", default=None, help="a defaults.csv from an older revision to join")
    args = ap.parse_args(argv)
    size = tuple(int(v) for v in args.size.lower().split("x"))
    scenes = args.scenes.split(",") if args.scenes else sorted(builtin_scenes())
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    parts = args.parts.split(",")
    from tqdm import tqdm

    if "frusta" in parts:
        rows = [r for s in tqdm(scenes, desc="frusta") for r in frusta_rows(s, size)]
        pd.DataFrame(rows).to_csv(out / "frusta.csv", index=False)
    if "defaults" in parts:
        rows = [r for s in tqdm(scenes, desc="defaults") for r in default_rows(s, size, args.techniques.split(","))]
        pd.DataFrame(rows).to_csv(out / "defaults.csv", index=False)
    before = None
    if args.before:
        before = pd.read_csv(args.before)
        # an older revision names the scenes it did not ship by their file's path
        before["scene"] = [Path(s).stem if str(s).endswith(".toml") else s for s in before["scene"]]
    if "bias" in parts:
        rows = pd.DataFrame([r for s in tqdm(scenes, desc="bias") for r in bias_rows(s, size)])
        rows.to_csv(out / "bias.csv", index=False)
        bias_candidates(rows, before).to_csv(out / "bias_candidates.csv", index=False)
    if before is not None:
        old, new = before, pd.read_csv(out / "defaults.csv")
        key = ["scene", "light", "technique"]
        both = old[key + ["error_rate", "false_lit_rate"]].merge(
            new[key + ["error_rate", "false_lit_rate", "degenerate"]], on=key, suffixes=("_before", "_after"))
        both.to_csv(out / "defaults_before_after.csv", index=False)
    (out / "provenance.json").write_text(json.dumps(provenance.record(), indent=2))
    print(f"wrote {out}/")


if __name__ == "__main__":
    main()
