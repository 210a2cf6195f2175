"""One scene of a study as a run directory (the docs/contracts.md#run-directory contract, exactly as ``shadowlab
compare`` writes it, through the same writer :func:`shadowlab.output.rundir.write_comparison`),
assembled from cached results without GL.

A run directory whose inputs (the cache keys of its results) have not changed is left as it is.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

from ..evaluation import metrics
from ..output.rundir import GROUND_TRUTH_KEY, ConfigImages, RunDirectory, safe_name, write_comparison
from ..measurement.pipeline import pass_order

MANIFEST = ".study-inputs.json"


@dataclass
class SceneRuns:
    """What a study knows of one scene: the truth's cached result, each configuration's, and
    their timings (None where missing or failed). ``rows`` are the finished metrics rows."""

    name: str
    truth: dict | None
    configs: dict[str, dict]              # spec → accuracy result
    rows: list[dict] = field(default_factory=list)
    keys: list[str] = field(default_factory=list)


def image_stem(short_label: str) -> str:
    """File-name stem of a configuration's images (as :class:`ConfigImages` names them)."""
    return safe_name(short_label)


def write_run_dir(folder: Path, scene: SceneRuns, rows: pd.DataFrame, record: dict) -> bool:
    """Write the run directory of one scene into ``folder`` unless it already holds exactly these
    inputs (``scene.keys``); returns whether it was (re)written. ``rows``: the scene's metrics
    rows (truth first), in metrics.csv column order; ``record``: run.json fields of the study
    (renderer, device, revision, timing, ...)."""
    manifest = {"keys": sorted(scene.keys)}
    try:
        if json.loads((folder / MANIFEST).read_text()) == manifest and (folder / "report.html").is_file():
            return False
    except (OSError, json.JSONDecodeError):
        pass
    with RunDirectory(folder) as rd:
        _write(rd, scene, rows, record)
        rd.record(MANIFEST, manifest)
    return True


def _config_images(label: str, result: dict, reference: bool) -> ConfigImages:
    """A cached task result (:mod:`shadowlab.study.tasks`) as the writer's :class:`ConfigImages`."""
    row = result["meta"]["rows"][0]
    params = {k[len("param_"):]: v for k, v in row.items() if k.startswith("param_")}
    pictures = {name[:-len(".png")]: data for name, data in result["files"].items() if name.endswith(".png")}
    return ConfigImages(label, row["short_label"], row["technique"], params, reference, result["arrays"]["mask_0"],
                        pictures)


def _write(rd: RunDirectory, scene: SceneRuns, df: pd.DataFrame, record: dict) -> None:
    from .tasks import STUDY_SIGNED_LIMIT

    truth = scene.truth
    configs = [_config_images(record[GROUND_TRUTH_KEY], truth, True)]
    configs += [_config_images(spec, res, False) for spec, res in scene.configs.items()]
    notes = list(truth["meta"]["notes"])
    judgement = [n for res in scene.configs.values() for n in res["meta"].get("judgement", [])]
    for spec, res in scene.configs.items():
        notes.extend(f"{spec}: {n}" for n in res["meta"]["notes"])
        notes.extend(res["meta"].get("judgement", []))  # they name the configuration themselves
    run = {**record, "scene": truth["meta"]["scene"], "camera": truth["meta"]["camera"],
           "configurations": [{"label": c.label, "technique": c.technique, "params": c.params} for c in configs[1:]],
           "notes": notes, "judgement": judgement}
    write_comparison(rd, df, configs, run, signed_limit=STUDY_SIGNED_LIMIT,
                     pass_timing=bool(record.get("pass_timing")))


def ordered(df: pd.DataFrame) -> pd.DataFrame:
    """Metrics rows in metrics.csv column order (contract columns first, passes in drawing order)."""
    return df[metrics.order_columns(df.columns, pass_order())]
