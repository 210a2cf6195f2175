"""Scenes loaded for measuring: :func:`shadowlab.scene.load_scene` (strict reading) plus the checks
only the measuring layers can make — that the scene's ``metric`` key names a metrics column
(:func:`shadowlab.evaluation.scene_metric.check_scene_metric`). Every command and study task
loads its scenes here."""
from __future__ import annotations

from ..evaluation.scene_metric import check_scene_metric
from ..scene import Scene, load_scene


def load_measured_scene(ref) -> Scene:
    """The scene ``ref`` (a shipped name or a path), read and checked; SceneError on any problem."""
    scene = load_scene(ref)
    check_scene_metric(scene)
    return scene
