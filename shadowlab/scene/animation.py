"""Animated scenes: keyframed camera, light and object paths (the ``[animation]`` table of a scene file).

A scene may declare how its camera and lights move over a normalised time t in [0, 1]::

    [animation]
    frames = 24                      # default frame count (``shadowlab animate --frames`` overrides)
    [[animation.camera]]             # camera keyframes: t, eye, target (fov_y optional)
    t = 0.0
    eye = [0.0, 2.0, 8.0]
    target = [0.0, 0.0, 0.0]
    [[animation.lights]]             # light keyframes: light (index), t, direction and/or position
    light = 0
    t = 0.0
    direction = [-0.4, -1.0, -0.3]
    [[animation.objects]]            # object keyframes: object (name), t, translate
    object = "box"
    t = 0.0
    translate = [0.0, 0.0, 0.0]      # an offset from where the file puts the object

Keyframes of one path have strictly increasing t, the first at 0 and the last at 1. Positions,
eyes, targets and fields of view are interpolated linearly; directions by spherical linear
interpolation (slerp, Shoemake 1985, "Animating rotation with quaternion curves", §3, here on
unit vectors), so a rotating sun turns at a constant angular speed and stays unit length.
An object path moves the object rigidly by a linearly interpolated offset (translation only);
a frame's scene shares every object that does not move with the still scene.

Parsing is as strict as the rest of the scene format (:mod:`shadowlab.util.validation`): unknown
keys, missing keys, bad t sequences, light indices out of range, a key the light type does not
have (``direction`` on a point light, ``position`` on a directional one) and opposite
consecutive directions (slerp is undefined there) are errors naming the file and the key.
"""
from __future__ import annotations

import copy
import dataclasses
from dataclasses import dataclass, field

import numpy as np

from ..util.validation import SceneError, TableReader

#: Two consecutive direction keyframes whose unit vectors' dot product is below this are
#: (nearly) opposite: the great circle between them is undefined, so slerp is refused.
OPPOSITE_DOT = -1.0 + 1e-9
#: Below this angle between two unit directions (radians), slerp is replaced by a normalised
#: lerp: sin(ω) → 0 makes the slerp weights ill-conditioned, and the two agree to ~ω³.
SLERP_MIN_ANGLE = 1e-6


@dataclass
class CameraKey:
    """One camera keyframe at time ``t``: ``eye``, ``target`` (float64 (3,)) and optionally ``fov_y``
    (degrees; None: the scene camera's)."""

    t: float
    eye: np.ndarray
    target: np.ndarray
    fov_y: float | None = None


@dataclass
class LightKey:
    """One keyframe of light ``light`` at time ``t``: a unit ``direction`` and/or a ``position``
    (float64 (3,); None where the path does not move that quantity)."""

    light: int
    t: float
    direction: np.ndarray | None = None
    position: np.ndarray | None = None


@dataclass
class ObjectKey:
    """One keyframe of object ``obj`` (its index in the scene) at time ``t``: ``translate``
    (float64 (3,)), its offset from where the scene file puts it."""

    obj: int
    t: float
    translate: np.ndarray


@dataclass
class Animation:
    """A scene's animation: the default frame count, the camera keyframes (empty: the camera
    stands still), per animated light index its keyframes and per moving object index its
    keyframes, each list sorted by t."""

    frames: int
    camera: list[CameraKey] = field(default_factory=list)
    lights: dict[int, list[LightKey]] = field(default_factory=dict)
    objects: dict[int, list[ObjectKey]] = field(default_factory=dict)

    @property
    def camera_moves(self) -> bool:
        """True when the animation has a camera path."""
        return bool(self.camera)

    def describe(self) -> dict:
        """The keyframes as plain JSON-able values (for animation.json)."""
        def vec(v):
            return None if v is None else [float(x) for x in v]

        return {"frames": self.frames,
                "camera": [{"t": k.t, "eye": vec(k.eye), "target": vec(k.target), "fov_y": k.fov_y}
                           for k in self.camera],
                "lights": {str(i): [{"t": k.t, "direction": vec(k.direction), "position": vec(k.position)}
                                    for k in keys] for i, keys in self.lights.items()},
                "objects": {str(i): [{"t": k.t, "translate": vec(k.translate)} for k in keys]
                            for i, keys in self.objects.items()}}


# --------------------------------------------------------------------------- parsing

def _check_times(keys, where: str, file: str) -> None:
    """Keyframe times of one path: at least two, strictly increasing, first 0 and last 1."""
    ts = [k.t for k in keys]
    if len(ts) < 2:
        raise SceneError(file, where, f"needs at least 2 keyframes (t = 0 and t = 1), got {len(ts)}")
    for a, b in zip(ts, ts[1:]):
        if not b > a:
            raise SceneError(file, f"{where}.t", f"keyframe times must increase strictly, got {a} then {b}")
    if ts[0] != 0.0:
        raise SceneError(file, f"{where}.t", f"the first keyframe must be at t = 0, got {ts[0]}")
    if ts[-1] != 1.0:
        raise SceneError(file, f"{where}.t", f"the last keyframe must be at t = 1, got {ts[-1]}")


def _light_fields(light) -> set[str]:
    return {f.name for f in dataclasses.fields(light)}


def _parse_camera_key(table, i: int, file: str) -> CameraKey:
    rd = TableReader(table, f"animation.camera[{i}]", file)
    key = CameraKey(t=rd.number("t", min=0.0, max=1.0), eye=rd.vector("eye", 3), target=rd.vector("target", 3),
                    fov_y=rd.number("fov_y", None, min=0.0, min_open=True, max=179.0))
    rd.finish()
    if not np.abs(key.target - key.eye).max() > 0:
        raise rd.error("target", "must differ from eye")
    return key


def _parse_light_key(table, i: int, file: str, lights) -> LightKey:
    rd = TableReader(table, f"animation.lights[{i}]", file)
    index = rd.number("light", min=0, integer=True)
    if lights is not None and index >= len(lights):
        raise rd.error("light", f"no light {index}: the scene has {len(lights)} light(s), indices from 0")
    t = rd.number("t", min=0.0, max=1.0)
    direction = rd.vector("direction", 3, default=None, nonzero=True)
    position = rd.vector("position", 3, default=None)
    rd.finish()
    if direction is None and position is None:
        raise rd.error("direction", "a light keyframe needs a direction and/or a position")
    if lights is not None:
        have = _light_fields(lights[index])
        for name, val in (("direction", direction), ("position", position)):
            if val is not None and name not in have:
                raise rd.error(name, f"light {index} ({lights[index].type_name}) has no {name} to animate")
    if direction is not None:
        # scale by the largest entry first: entries of any finite magnitude give the true direction
        direction = direction / np.abs(direction).max()
        direction = direction / np.linalg.norm(direction)
    return LightKey(index, t, direction, position)


def _parse_object_key(table, i: int, file: str, names) -> ObjectKey:
    rd = TableReader(table, f"animation.objects[{i}]", file)
    name = rd.string("object")
    t = rd.number("t", min=0.0, max=1.0)
    translate = rd.vector("translate", 3)
    rd.finish()
    if names is None:
        raise rd.error("object", "object keyframes need the scene's objects to resolve names (parse_animation's "
                                 "object_names)")
    if name not in names:
        from ..util.validation import did_you_mean

        raise rd.error("object", f"no object named {name!r}{did_you_mean(name, names)}")
    if names.count(name) > 1:
        raise rd.error("object", f"{names.count(name)} objects are named {name!r}: give the one that moves a name "
                                 f"of its own")
    return ObjectKey(names.index(name), t, translate)


def parse_animation(table, file: str = "<scene>", lights=None, object_names=None) -> Animation:
    """Build an :class:`Animation` from the ``[animation]`` table of a scene file; ``lights``
    (the scene's parsed lights), when given, checks light indices and that each animated
    quantity exists on its light; ``object_names`` (the scene's objects' names, in order)
    resolves the objects that move. Raises :class:`SceneError` naming the file and the key."""
    rd = TableReader(table, "animation", file)
    frames = rd.number("frames", min=2, integer=True)
    cam_tables = rd.table_list("camera", [])
    light_tables = rd.table_list("lights", [])
    object_tables = rd.table_list("objects", [])
    rd.finish()
    if not cam_tables and not light_tables and not object_tables:
        raise rd.error("camera", "an animation needs camera keyframes ([[animation.camera]]), light "
                                 "keyframes ([[animation.lights]]) and/or object keyframes ([[animation.objects]])")
    camera = [_parse_camera_key(t, i, file) for i, t in enumerate(cam_tables)]
    if camera:
        _check_times(camera, "animation.camera", file)
        with_fov = {k.fov_y is not None for k in camera}
        if len(with_fov) > 1:
            raise SceneError(file, "animation.camera.fov_y", "give fov_y in every camera keyframe or in none")
    keys = [_parse_light_key(t, i, file, lights) for i, t in enumerate(light_tables)]
    by_light: dict[int, list[LightKey]] = {}
    for k in keys:
        by_light.setdefault(k.light, []).append(k)
    for index, path in by_light.items():
        where = f"animation.lights (light {index})"
        _check_times(path, where, file)
        for name in ("direction", "position"):
            given = {getattr(k, name) is not None for k in path}
            if len(given) > 1:
                raise SceneError(file, f"{where}.{name}", f"give {name} in every keyframe of the light or in none")
        if path[0].direction is not None:
            for a, b in zip(path, path[1:]):
                if float(a.direction @ b.direction) < OPPOSITE_DOT:
                    raise SceneError(file, f"{where}.direction", f"directions at t = {a.t} and t = {b.t} are "
                                     f"opposite: the rotation between them is undefined (add a keyframe between)")
    by_object: dict[int, list[ObjectKey]] = {}
    for k in (_parse_object_key(t, i, file, object_names) for i, t in enumerate(object_tables)):
        by_object.setdefault(k.obj, []).append(k)
    for index, path in by_object.items():
        name = object_names[index] if object_names is not None else str(index)
        _check_times(path, f"animation.objects ({name})", file)
    return Animation(frames, camera, by_light, by_object)


# --------------------------------------------------------------------------- interpolation

def frame_times(n: int) -> np.ndarray:
    """The times of ``n`` >= 2 frames, t_k = k / (n − 1): float64 (n,), 0 first and 1 last exactly."""
    if int(n) != n or n < 2:
        raise ValueError(f"an animation needs at least 2 frames, got {n}")
    return np.arange(int(n), dtype=np.float64) / (int(n) - 1)


def lerp(a: np.ndarray, b: np.ndarray, s: float) -> np.ndarray:
    """(1 − s)·a + s·b: exactly a at s = 0 and b at s = 1."""
    return (1.0 - s) * np.asarray(a, np.float64) + s * np.asarray(b, np.float64)


def slerp(a: np.ndarray, b: np.ndarray, s: float) -> np.ndarray:
    """Spherical linear interpolation of unit vectors a, b (float64 (3,)) at s in [0, 1]
    (Shoemake 1985 §3): the point at fraction s of the great-circle arc from a to b, unit length
    (renormalised against rounding); exactly a at s = 0 and b at s = 1."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    if s == 0.0:
        return a.copy()
    if s == 1.0:
        return b.copy()
    omega = float(np.arccos(np.clip(a @ b, -1.0, 1.0)))
    if omega < SLERP_MIN_ANGLE:
        v = lerp(a, b, s)
    else:
        v = (np.sin((1.0 - s) * omega) * a + np.sin(s * omega) * b) / np.sin(omega)
    return v / np.linalg.norm(v)


def _segment(keys, t: float) -> tuple[int, float]:
    """The keyframe segment holding ``t`` and the fraction s of the way through it."""
    ts = np.array([k.t for k in keys])
    i = int(np.clip(np.searchsorted(ts, t, side="right") - 1, 0, len(ts) - 2))
    s = (t - ts[i]) / (ts[i + 1] - ts[i])
    return i, float(min(max(s, 0.0), 1.0))


def scene_at(scene, t: float):
    """A copy of ``scene`` at time ``t`` in [0, 1] of its animation: camera, animated lights and
    moving objects at their interpolated keyframe values (near/far as in the file: refitted per
    frame where the file leaves them out); still objects, shading and the animation itself
    shared. A scene without animation gives a plain copy (still frames)."""
    t = float(t)
    if not 0.0 <= t <= 1.0:
        raise ValueError(f"animation time must lie in [0, 1], got {t}")
    out = copy.copy(scene)
    out.lights = list(scene.lights)
    out.objects = list(scene.objects)
    anim = scene.animation
    if anim is None:
        return out
    file = str(scene.path) if scene.path else "<scene>"
    if anim.camera:
        i, s = _segment(anim.camera, t)
        a, b = anim.camera[i], anim.camera[i + 1]
        cam = dataclasses.replace(scene.camera, eye=lerp(a.eye, b.eye, s), target=lerp(a.target, b.target, s))
        if a.fov_y is not None:
            cam.fov_y = float(lerp(a.fov_y, b.fov_y, s))
        forward = cam.target - cam.eye
        if not np.linalg.norm(forward) > 0 or np.linalg.norm(
                np.cross(forward / np.linalg.norm(forward), cam.up / np.linalg.norm(cam.up))) < 1e-6:
            raise SceneError(file, "animation.camera", f"at t = {t} the camera looks along its up vector or "
                                                       f"its target meets its eye")
        out.camera = cam
    for index, keys in anim.lights.items():
        i, s = _segment(keys, t)
        a, b = keys[i], keys[i + 1]
        changes = {}
        if a.direction is not None:
            changes["direction"] = slerp(a.direction, b.direction, s)
        if a.position is not None:
            changes["position"] = lerp(a.position, b.position, s)
        out.lights[index] = dataclasses.replace(scene.lights[index], **changes)
    for index, keys in anim.objects.items():
        i, s = _segment(keys, t)
        offset = lerp(keys[i].translate, keys[i + 1].translate, s)
        obj = scene.objects[index]
        out.objects[index] = dataclasses.replace(obj, vertices=obj.vertices + offset)
    return out
