"""The check behind a scene file's ``metric`` key: it must name a metrics column the lab computes
(a per-pixel metric of :mod:`.metrics` or a texel-footprint column of :mod:`.texel_footprint`),
else the run stops with a one-line error naming the file, the key and the closest column. The
scene reader (the lowest layer) keeps the string; this layer, which owns the columns, judges it."""
from __future__ import annotations

from ..util.validation import SceneError, did_you_mean
from .metrics import COLUMN_BY_NAME, METRIC_COLUMNS
from .texel_footprint import COLUMNS as FOOTPRINT_COLUMNS


def judged_columns() -> list[str]:
    """The metrics columns a scene's ``metric`` key may name, in table order."""
    return [c.name for c in METRIC_COLUMNS] + [c for c in FOOTPRINT_COLUMNS if c in COLUMN_BY_NAME]


def check_scene_metric(scene) -> None:
    """SceneError (file, ``metric``, a suggestion) when ``scene.metric`` is set and names no
    metrics column; nothing otherwise."""
    metric = getattr(scene, "metric", None)
    names = judged_columns()
    if metric is not None and metric not in names:
        hint = did_you_mean(metric, names) or f" (one of {', '.join(names)})"
        where = str(scene.path) if getattr(scene, "path", None) else "<scene>"
        raise SceneError(where, "metric", f"{metric!r} is not a metric column{hint}")
