"""One scene of a study as a run directory (the DESIGN §6 contract, like ``shadowlab compare``
writes), assembled from cached results without GL: ``metrics.csv``, ``masks.npz``,
``run.json``, ``images/``, ``speed_vs_error.png`` and ``pictures.html``.

The directory is written beside its destination and moved into place when complete; a run
directory whose inputs (the cache keys of its results) have not changed is left as it is.
"""
from __future__ import annotations

import json
import shutil
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from ..output import pictures
from .. import metrics, provenance
from ..pipeline import pass_order
from ..commands.compare import GROUND_TRUTH_KEY, peak_mib, move_into_place, safe_name

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
    """File-name stem of a configuration's images."""
    return safe_name(short_label)


def write_run_dir(folder: Path, scene: SceneRuns, rows: pd.DataFrame, record: dict) -> bool:
    """Write the run directory of one scene into ``folder`` unless it already holds exactly these
    inputs (``scene.keys``); returns whether it was (re)written. ``rows``: the scene's metrics
    rows (truth first), in metrics.csv column order; ``record``: run.json fields of the study
    (renderer, device, revision, timing, ...)."""
    manifest = {"keys": sorted(scene.keys)}
    try:
        if json.loads((folder / MANIFEST).read_text()) == manifest and (folder / "pictures.html").is_file():
            return False
    except (OSError, json.JSONDecodeError):
        pass
    tmp = folder.parent / f".{folder.name}.tmp"
    if tmp.exists():
        shutil.rmtree(tmp)
    (tmp / "images").mkdir(parents=True)
    try:
        _write(tmp, scene, rows, record)
        (tmp / MANIFEST).write_text(json.dumps(manifest))
        move_into_place(tmp, folder)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return True


def _write(folder: Path, scene: SceneRuns, df: pd.DataFrame, record: dict) -> None:
    df.to_csv(folder / "metrics.csv", index=False)
    truth = scene.truth
    masks = {GROUND_TRUTH_KEY: truth["arrays"]["mask_0"]}
    images = [_images(folder, "ground_truth", record["ground_truth"], "ground truth", truth["files"])]
    configurations = []
    for spec, res in scene.configs.items():
        short = res["meta"]["rows"][0]["short_label"]
        masks[spec] = res["arrays"]["mask_0"]
        images.append(_images(folder, image_stem(short), spec, short, res["files"]))
        row = res["meta"]["rows"][0]
        configurations.append({"label": spec, "technique": row["technique"],
                               "params": {k[len("param_"):]: v for k, v in row.items() if k.startswith("param_")}})
    np.savez_compressed(folder / "masks.npz", **masks)
    pictures.speed_error_plot(df, folder / "speed_vs_error.png")
    passes_png = pictures.pass_time_plot(df, folder / "pass_times.png") if record.get("pass_timing") else None
    notes = list(truth["meta"]["notes"])
    for spec, res in scene.configs.items():
        notes.extend(f"{spec}: {n}" for n in res["meta"]["notes"])
    signed_map = None
    if any(im.get("signed") for im in images):  # the study draws every signed map on one fixed scale
        from .tasks import STUDY_SIGNED_LIMIT

        signed_map = {"limit": STUDY_SIGNED_LIMIT, "colormap": pictures.SIGNED_COLORMAP,
                      "legend": "images/signed_legend.png", "caption": pictures.SIGNED_CAPTION}
        pictures.signed_legend(folder / signed_map["legend"], STUDY_SIGNED_LIMIT)
    run = {**record, "scene": truth["meta"]["scene"], "camera": truth["meta"]["camera"], "signed_map": signed_map,
           "configurations": configurations, "pass_times_image": passes_png, "masks_light": 0,
           "peak_rss_mib": peak_mib(df), "notes": notes,
           "images": images}
    (folder / "run.json").write_text(json.dumps(run, indent=2, default=provenance.json_default))
    pictures.write_html(folder / "pictures.html", run, df, images)


def _images(folder: Path, stem: str, label: str, title: str, files: dict) -> dict:
    out = {"label": label, "title": title}
    for kind in ("shaded", "visibility", "error", "worst", "signed"):
        data = files.get(f"{kind}.png")
        if data is not None:
            out[kind] = f"images/{stem}_{kind}.png"
            (folder / out[kind]).write_bytes(data)
    return out


def ordered(df: pd.DataFrame) -> pd.DataFrame:
    """Metrics rows in metrics.csv column order (contract columns first, passes in drawing order)."""
    return df[metrics.order_columns(df.columns, pass_order())]

