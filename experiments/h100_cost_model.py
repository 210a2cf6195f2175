"""A cost model of the H100 from the shared GPU evidence (issue 27).

``results/gpu/h100/h100_matrix_1280x720.csv`` (a copy of the GPU run the project was given) holds GL_TIME_ELAPSED times of 11 shipped scenes × 10
configurations at 1280x720 on an NVIDIA H100 (commit d63d2dd, 2026-11-22), but no work
counters: that commit had none. This experiment recomputes the counters *here*, for the same
scenes, size, lights and specifications (one counting render each, :mod:`shadowlab.gpu.work`: the
counters are the same on every driver, which the exact figures below check), then fits the H100's
cost model (:func:`shadowlab.analysis.cost.fit`, target ``gpu_time_ms_median``) with its leave-one-scene-
out error, and writes it where ``shadowlab cost predict`` can use it.

What may no longer match, and how it is checked: the scenes and techniques have changed since
d63d2dd. Per row it records ``evaluated_pixels`` (H100 run) against the same figure here, and the
exact counts the H100 run also reported — shadow volumes' ``volume_fragments`` and
``stencil_updates``, ``volume_triangles`` — against the same counts on this machine's driver; a
spec that no longer parses, or a scene that no longer loads, is listed and left out.

    python experiments/h100_cost_model.py [--evidence results/gpu/h100/h100_matrix_1280x720.csv]
        [--out results/cost/h100]

Writes ``<out>/results.csv`` (the H100 rows with the counters recomputed here; a study-like
table, so ``shadowlab cost fit <out> --target gpu_time_ms_median`` refits it), ``study.json``
(the device), ``mismatches.csv``, ``cost_model.json`` and ``cost_fit.png``.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from shadowlab.analysis import cost
from shadowlab.gpu import work
from shadowlab.commands import cost as cost_cmd  # noqa: E402
from shadowlab.gpu.frame import Frame  # noqa: E402
from shadowlab.measurement.pipeline import measure  # noqa: E402
from shadowlab.scene import load_scene  # noqa: E402
from shadowlab.techniques import TechniqueError, from_spec  # noqa: E402

DEVICE = "NVIDIA H100 (driver 580.159.04, GL through EGL; shared/gpu evidence of commit d63d2dd)"
#: Exact counts the H100 run reported that this machine recomputes (same scene, same spec).
EXACT_STATS = ("volume_fragments", "stencil_updates", "volume_triangles")


def main(argv=None) -> int:
    """Recompute the counters for every evidence row, write the table and fit the model."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--evidence", default=str(ROOT / "results" / "gpu" / "h100" / "h100_matrix_1280x720.csv"))
    ap.add_argument("--out", default=str(ROOT / "results" / "cost" / "h100"))
    args = ap.parse_args(argv)
    evidence = pd.read_csv(args.evidence)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows, mismatches, frames = [], [], {}
    t0 = time.perf_counter()
    timed = evidence[evidence["gpu_time_ms_median"].notna()]
    for i, (_, r) in enumerate(timed.iterrows()):
        spec = f"{r['technique']}:{r['params']}" if isinstance(r["params"], str) and r["params"] else r["technique"]
        where = f"{r['scene']} light {int(r['light'])} {spec}"
        try:
            tech = from_spec(spec)
        except TechniqueError as exc:
            mismatches.append({"scene": r["scene"], "light": r["light"], "label": spec, "what": "spec",
                               "h100": "", "here": str(exc)})
            continue
        key = (r["scene"], int(r["width"]), int(r["height"]))
        if key not in frames:
            frames[key] = Frame(load_scene(r["scene"]), int(r["width"]), int(r["height"]))
        frame = frames[key]
        m = measure(tech, frame, int(r["light"]), repeat=1, warmup=0)
        here_pixels = int(frame.evaluated_image(frame.slot(int(r["light"]))).sum())
        row = {"scene": r["scene"], "light": int(r["light"]), "technique": r["technique"], "label": tech.spec(),
               "h100_label": spec, "status": "ok", "gpu_time_ms_median": float(r["gpu_time_ms_median"]),
               "time_ms_median": float(r["time_ms_median"]), "evaluated_pixels": here_pixels,
               "h100_evaluated_pixels": int(r["evaluated_pixels"]), **work.columns(m.work)}
        for stat in EXACT_STATS:
            if stat in m.stats and stat in r and pd.notna(r[stat]):
                row[stat], row[f"h100_{stat}"] = m.stats[stat], r[stat]
                if float(m.stats[stat]) != float(r[stat]):
                    mismatches.append({"scene": r["scene"], "light": r["light"], "label": spec, "what": stat,
                                       "h100": r[stat], "here": m.stats[stat]})
        if here_pixels != int(r["evaluated_pixels"]):
            mismatches.append({"scene": r["scene"], "light": r["light"], "label": spec, "what": "evaluated_pixels",
                               "h100": int(r["evaluated_pixels"]), "here": here_pixels})
        rows.append(row)
        print(f"[{i + 1}/{len(timed)}] {where}: {r['gpu_time_ms_median']:.3f} ms on the H100", flush=True)
    table = pd.DataFrame(rows)
    table.to_csv(out / "results.csv", index=False)
    (out / "study.json").write_text(json.dumps({"name": "h100_evidence", "device": DEVICE,
                                                "source": str(Path(args.evidence).name)}, indent=2) + "\n")
    pd.DataFrame(mismatches, columns=["scene", "light", "label", "what", "h100", "here"]).to_csv(
        out / "mismatches.csv", index=False)
    model, path = cost_cmd.fit_command(out, out / "cost_model.json", target="gpu_time_ms_median", device=DEVICE)
    print(f"{len(table)} rows counted in {time.perf_counter() - t0:.0f} s; {len(mismatches)} mismatches "
          f"(see {out / 'mismatches.csv'})")
    print(cost.summary_line(model))
    print(model.table().to_string(index=False))
    print(f"per scene (left out): {json.dumps({k: round(v, 3) for k, v in model.cv_per_scene.items()})}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
