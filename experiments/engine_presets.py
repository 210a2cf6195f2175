"""Engine presets (issue 41, part B): each engine's default shadow map on the shadow-map hard cases.

For every preset of :mod:`shadowlab.techniques.maps.presets` (``shadow_map:preset=NAME``) and every
shadow-map hard case of docs/hard-cases.md, ``shadowlab tune SCENE -t shadow_map:preset=NAME
--param bias=LO:HI:log`` is run (the range per the preset's ``bias_space``: :data:`BIAS_RANGES`): the engine's default as given (its error rate, acne =
``false_shadow_rate``, peter-panning = ``false_lit_rate``, ``contact_gap_px``) and the exact
optimum of the same preset with its constant bias free (every other key of the preset held) —
the tuned parameter is ``bias``, in the preset's own ``bias_space``. ``regret`` is the default's
error rate minus the optimum's. A preset whose filter the exact route cannot sweep (none of the
shipped ones) would go by the search route; the ``route`` column says which.

Writes results/presets/presets.csv (one row per preset × scene) and results/presets/presets.json
(the run's record: size, machine, commands). A few minutes at the default 320x240 on a 2-core
machine.

    python experiments/engine_presets.py [--out results/presets] [--size 320x240] [--jobs 2]
        [--scenes SCENE ...] [--presets PRESET ...]   (a partial rerun replaces those rows)
"""
from __future__ import annotations

import argparse
import json
import platform
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pandas as pd

from shadowlab.techniques.maps.presets import KINDS, PRESETS

#: The shadow-map hard cases of docs/hard-cases.md, and the point-light volume case whose lamp is
#: close to its casters.
SCENES = ["sm_contact", "sm_grazing", "sm_thin", "sm_aliasing", "sm_lamp_contact", "sm_point_cube",
          "sm_light_bleeding", "sm_far_origin", "sv_light_close"]
#: The bias range the optimum is searched over, per the preset's ``bias_space``: from far below
#: any preset's value to far above it — window depth: all of it; scene units: 10 (metres in the
#: engines' scenes, several times the hard cases' sizes); texels: 64 map texels.
BIAS_RANGES = {"window": "1e-7:1.0:log", "world": "1e-7:1.0:log", "units": "1e-6:10.0:log",
               "texels": "1e-3:64.0:log"}


def bias_range(preset: str) -> str:
    """The tuned range for ``preset`` (:data:`BIAS_RANGES` of its shadow_map ``bias_space``; the
    presets give every light kind the same space)."""
    spaces = {PRESETS[preset].values("shadow_map", kind).get("bias_space", "world") for kind in KINDS}
    if len(spaces) != 1:
        raise SystemExit(f"preset {preset}: bias_space differs between light kinds ({spaces}); give each its range")
    return BIAS_RANGES[spaces.pop()]
METRICS = ["error_rate", "false_shadow_rate", "false_lit_rate", "contact_gap_px", "visibility_mae"]


def tune_one(preset: str, scene: str, size: str, work: Path) -> dict:
    """One ``shadowlab tune`` run; the default's and the optimum's figures."""
    out = work / f"{preset}_{scene}"
    cmd = [sys.executable, "-m", "shadowlab", "tune", scene, "-t", f"shadow_map:preset={preset}",
           "--param", f"bias={bias_range(preset)}", "--size", size, "--out", str(out)]
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode != 0:
        return {"preset": preset, "scene": scene, "status": "failed",
                "error": (done.stderr.strip().splitlines() or ["?"])[-1]}
    best = json.loads((out / "best.json").read_text())
    rows = pd.read_csv(out / "metrics.csv")
    # light 0 only (the tuned light; a scene with two lights has rows for both)
    rows = rows[(rows["technique"] == "shadow_map") & (rows["light"] == 0)].reset_index(drop=True)
    default, tuned = rows.iloc[0], rows.iloc[len(rows) - 1]
    record = {"preset": preset, "scene": scene, "status": "ok", "route": best.get("route"),
              "light_type": _light_type(out)}
    record.update({f"default_{m}": float(default[m]) for m in METRICS if m in default})
    record.update({f"optimum_{m}": float(tuned[m]) for m in METRICS if m in tuned})
    record["optimum_bias"] = float(best["params"].get("bias", float("nan")))
    record["regret"] = float(best.get("regret_of_default", float("nan")))
    record["bias_range"] = bias_range(preset)
    record["emulation_mismatch"] = best.get("emulation_mismatch")
    record["verified"] = best.get("verified")
    params = default.get("params", "")
    record["params"] = params
    return record


def _light_type(out: Path) -> str:
    """The tuned light's type, from the run's record."""
    try:
        scene = json.loads((out / "tune.json").read_text())["scene"]
        return scene["lights"][0]["type"] if isinstance(scene.get("lights"), list) else ""
    except (OSError, KeyError, TypeError, ValueError, IndexError):
        return ""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default="results/presets")
    ap.add_argument("--size", default="320x240")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--scenes", nargs="*", default=None,
                    help="rerun only these scenes, replacing their rows of an existing presets.csv")
    ap.add_argument("--presets", nargs="*", default=None, choices=list(PRESETS),
                    help="rerun only these presets, replacing their rows of an existing presets.csv")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        jobs = [(p, s) for p in (args.presets or PRESETS) for s in (args.scenes or SCENES)]
        with ThreadPoolExecutor(args.jobs) as pool:
            rows = list(pool.map(lambda job: tune_one(*job, args.size, Path(tmp)), jobs))
    table = pd.DataFrame(rows)
    if (args.scenes or args.presets) and (out / "presets.csv").exists():  # a partial rerun: replace those rows
        old = pd.read_csv(out / "presets.csv")
        rerun = old["scene"].isin(args.scenes or SCENES) & old["preset"].isin(args.presets or list(PRESETS))
        table = pd.concat([old[~rerun], table], ignore_index=True)
        order = {s: i for i, s in enumerate(SCENES)}
        table = table.sort_values(["preset", "scene"], key=lambda c: c.map(order) if c.name == "scene" else
                                  c.map({p: i for i, p in enumerate(PRESETS)})).reset_index(drop=True)
    table.to_csv(out / "presets.csv", index=False)
    record = {"experiment": "engine_presets", "size": args.size, "scenes": SCENES, "presets": list(PRESETS),
              "bias_ranges": {p: bias_range(p) for p in PRESETS}, "tuned_parameter": "bias",
              "command": f"python experiments/engine_presets.py --size {args.size}",
              "machine": platform.platform(), "seconds": round(time.perf_counter() - started, 1)}
    try:
        from shadowlab.gpu import gl

        gl.context()
        record["renderer"] = gl.renderer()
    except Exception as exc:  # the record says why the renderer is unknown
        record["renderer"] = f"unknown ({exc})"
    (out / "presets.json").write_text(json.dumps(record, indent=2))
    print(table.to_string())


if __name__ == "__main__":
    main()
