"""The one run-directory writer (docs/contracts.md#run-directory) behind ``compare``, every scene of a ``study``
and ``animate``.

:class:`RunDirectory` writes into a staging folder beside the destination and moves it into
place only when everything is written, so a failed run leaves earlier results intact.
:func:`write_comparison` lays out a comparison run: ``metrics.csv``, ``masks.npz``, the images of
every configuration, the zoom insets (:mod:`shadowlab.output.insets`), the plots, ``run.json``
and ``report.html`` (template ``compare.html``). ``compare`` and a study's scene give it the same
:class:`ConfigImages`, so their run directories are alike, texel-footprint maps included.
"""
from __future__ import annotations

import json
import os
import re
import shutil
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from . import provenance
from ..analysis.aggregate import DEGENERATE_MARK, is_true
from ..util.files import temporary_path
from ..util.validation import RunError
from . import pictures
from .insets import common_insets, wrong_pixels
from ..util.format import fmt_ms, fmt_pct
from .pages import provenance_items, render_page

#: How a run names its ground truth: its key in masks.npz, the stem of its images
#: (``ground_truth_shaded.png``) and the run record's field holding its spec.
GROUND_TRUTH_KEY = "ground_truth"
#: The picture kinds of a configuration, in the order the page offers them.
PICTURE_KINDS = ("shaded", "visibility", "error", "signed", "footprint")


def safe_name(label: str) -> str:
    """A label (technique spec, scene name) as a file-name stem: letters, digits, ``._-``."""
    return re.sub(r"[^A-Za-z0-9._-]+", "_", label).strip("_")


def staging_dir(out: Path) -> Path:
    """A fresh, empty folder beside ``out`` to write a run into before :func:`move_into_place`
    puts it there (RunError when ``out`` exists and is not a folder)."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise RunError(f"--out {out} exists and is not a directory")
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = temporary_path(out)
    if tmp.exists():
        shutil.rmtree(tmp)
    tmp.mkdir(parents=True)
    return tmp


def move_into_place(tmp: Path, out: Path) -> None:
    """Replace ``out`` (if any) by the finished directory ``tmp``, removing the old one last."""
    old = None
    if out.exists():
        old = out.parent / f".{out.name}.old-{os.getpid()}"
        out.rename(old)
    tmp.rename(out)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


class RunDirectory:
    """A run directory being written: use as a context manager; inside, ``path`` is the staging
    folder and the methods write into it; on a clean exit it replaces ``out``, on an exception it
    is removed and ``out`` is left as it was."""

    def __init__(self, out: Path):
        self.out = Path(out)
        self.path = staging_dir(self.out)

    def __enter__(self) -> "RunDirectory":
        return self

    def __exit__(self, exc_type, exc, tb) -> bool:
        if exc_type is None:
            move_into_place(self.path, self.out)
        else:
            shutil.rmtree(self.path, ignore_errors=True)
        return False

    def table(self, name: str, df: pd.DataFrame) -> Path:
        """Write ``df`` as the CSV ``name``."""
        df.to_csv(self.path / name, index=False)
        return self.path / name

    def record(self, name: str, data: dict) -> Path:
        """Write ``data`` as the JSON ``name`` (numpy values and paths converted)."""
        (self.path / name).write_text(json.dumps(data, indent=2, default=provenance.json_default))
        return self.path / name

    def masks(self, masks: dict[str, np.ndarray]) -> Path:
        """Write ``masks.npz`` (float32 (H, W) per key, NaN off the evaluated pixels)."""
        np.savez_compressed(self.path / "masks.npz", **masks)
        return self.path / "masks.npz"

    def image(self, rel: str, picture) -> str:
        """Write an image at ``rel`` (relative path): PNG bytes as they are, an RGB float array in
        [0, 1] (H, W, 3) encoded as PNG. Returns ``rel``."""
        path = self.path / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(picture if isinstance(picture, (bytes, bytearray)) else pictures.encode_png(picture))
        return rel

    def page(self, template: str, name: str = "report.html", **context) -> Path:
        """Render a page template (:func:`shadowlab.output.pages.render_page`) as ``name``."""
        return render_page(template, self.path / name, **context)


@dataclass
class ConfigImages:
    """What a run directory shows of one configuration: ``label`` (the full spec, the key of
    masks.npz), ``title`` (short label), ``technique``, ``params``, ``reference`` (the ground
    truth), ``mask`` (first light's visibility, float32 (H, W), NaN off the evaluated pixels)
    and ``pictures`` ({kind: PNG bytes} for the kinds of :data:`PICTURE_KINDS` it has)."""

    label: str
    title: str
    technique: str
    params: dict
    reference: bool
    mask: np.ndarray
    pictures: dict = field(default_factory=dict)

    @property
    def stem(self) -> str:
        """File-name stem of its images."""
        return GROUND_TRUTH_KEY if self.reference else safe_name(self.title)


def write_comparison(rd: RunDirectory, rows: pd.DataFrame, configs: list[ConfigImages], record: dict,
                     signed_limit: float | None = None, pass_timing: bool = False) -> dict:
    """Lay out a comparison run in ``rd``: ``metrics.csv`` (``rows``), ``masks.npz``, each
    configuration's images (``images/<stem>_<kind>.png``), the zoom insets common to all
    configurations, ``speed_vs_error.png`` (and ``pass_times.png`` with ``pass_timing``), the
    signed and footprint colour bars where a configuration has such a map, ``run.json``
    (``record`` plus images, insets and legends) and ``report.html``. ``configs`` starts with the
    truth. Returns the run.json record."""
    rd.table("metrics.csv", rows)
    truth = configs[0]
    rd.masks({GROUND_TRUTH_KEY: truth.mask, **{c.label: c.mask for c in configs[1:]}})
    images = []
    for c in configs:
        files = {kind: rd.image(f"images/{c.stem}_{kind}.png", c.pictures[kind])
                 for kind in PICTURE_KINDS if kind in c.pictures}
        images.append({"label": c.label, "title": "ground truth" if c.reference else c.title,
                       "reference": c.reference, **files})
    h, w = truth.mask.shape
    insets = common_insets(truth.mask, [c.mask for c in configs[1:]])
    wrong = {c.label: _wrong_in(c.mask, truth.mask, insets) for c in configs[1:]}
    for im in images:
        im["inset_wrong"] = wrong.get(im["label"], [])
    legends = {}
    if any("signed" in im for im in images) and signed_limit is not None:
        pictures.signed_legend(rd.path / "images/signed_legend.png", signed_limit)
        legends["signed"] = {"file": "images/signed_legend.png", "limit": signed_limit,
                             "colormap": pictures.SIGNED_COLORMAP, "caption": pictures.SIGNED_CAPTION}
    if any("footprint" in im for im in images):
        pictures.footprint_legend(rd.path / "images/footprint_legend.png")
        legends["footprint"] = {"file": "images/footprint_legend.png", "colormap": pictures.FOOTPRINT_COLORMAP,
                                "caption": pictures.FOOTPRINT_CAPTION}
    pictures.speed_error_plot(rows, rd.path / "speed_vs_error.png")
    passes_png = pictures.pass_time_plot(rows, rd.path / "pass_times.png") if pass_timing else None
    run = {**record, "size": [w, h], "masks_light": 0, "pass_times_image": passes_png,
           "images": images, "insets": [{"box": list(i.box), "wrong": i.wrong} for i in insets],
           "legends": legends, "peak_rss_mib": peak_mib(rows),
           # the keys earlier run.json files had for the two colour bars (scripts read them)
           "signed_map": ({"limit": signed_limit, "colormap": pictures.SIGNED_COLORMAP,
                           "legend": legends["signed"]["file"], "caption": pictures.SIGNED_CAPTION}
                          if "signed" in legends else None),
           "footprint_legend": legends["footprint"]["file"] if "footprint" in legends else None}
    rd.record("run.json", run)
    rd.page("compare.html", title=f"shadowlab: {run['scene']['name']}", renderer=run.get("renderer"),
            provenance=provenance_items(run), run=run, table=compare_table(rows), insets=insets,
            images=images, error_colors=error_legend(), captions=captions_of(rows), degenerate_mark=DEGENERATE_MARK)
    return run


def captions_of(rows: pd.DataFrame) -> dict[str, list[str]]:
    """Caption lines per configuration label from its first light's metrics row: error rate and
    the false shadow / false lit split, a degenerate configuration's mark (it draws almost no
    shadow where the truth has one: its small error rate must not read as "nearly right"), time
    per frame and set-up time."""
    out = {}
    first = rows[rows["light"] == rows["light"].min()] if "light" in rows.columns else rows
    for _, r in first.iterrows():
        lines = []
        if not is_true(r.get("reference")):
            lines.append(f"error {fmt_pct(r.get('error_rate'))} (false shadow {fmt_pct(r.get('false_shadow_rate'))},"
                         f" false lit {fmt_pct(r.get('false_lit_rate'))})")
            if is_true(r.get("degenerate")):
                lines.append(f"{DEGENERATE_MARK}: almost no shadow drawn (see the notes)")
        timing = f"{fmt_ms(r.get('time_ms_median'))} ms per frame" if fmt_ms(r.get("time_ms_median")) else "no time"
        if fmt_ms(r.get("setup_ms")):
            timing += f" · set-up {fmt_ms(r.get('setup_ms'))} ms"
        lines.append(timing)
        out[str(r["label"])] = lines
    return out


def _wrong_in(mask: np.ndarray, truth: np.ndarray, insets) -> list[int]:
    """Wrong pixels of one configuration inside each inset."""
    wrong = wrong_pixels(mask, truth)
    return [int(wrong[y0:y1, x0:x1].sum()) for (x0, y0, x1, y1) in (i.box for i in insets)]


def error_legend() -> list[tuple[str, str]]:
    """The error map's colours as (label, CSS rgb()) pairs."""
    return [(label, "rgb({})".format(",".join(str(int(255 * v)) for v in color)))
            for label, color in pictures.ERROR_COLORS.values()]


def compare_table(rows: pd.DataFrame) -> dict:
    """The run page's metrics table as {"columns": [...], "rows": [[...]]} of display strings
    (:func:`shadowlab.evaluation.metrics.format_table` in its "report" form), a degenerate row's
    configuration marked :data:`~shadowlab.analysis.aggregate.DEGENERATE_MARK`."""
    from ..evaluation.metrics import format_table

    if "degenerate" in rows.columns and "short_label" in rows.columns:
        rows = rows.copy()
        marked = rows["degenerate"].map(is_true)
        rows.loc[marked, "short_label"] = rows.loc[marked, "short_label"].astype(str) + f" {DEGENERATE_MARK}"
    t = format_table(rows, "report")
    return {"columns": list(t.columns), "rows": t.astype(str).values.tolist()}


def peak_mib(df: pd.DataFrame) -> float | None:
    """The largest ``peak_rss_mib`` of a run's rows (None when not measured)."""
    if "peak_rss_mib" not in df.columns or df["peak_rss_mib"].isna().all():
        return None
    return float(df["peak_rss_mib"].max())
