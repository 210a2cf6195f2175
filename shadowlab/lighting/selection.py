"""Which lights get shadows where: the selection policies of a shadow budget.

A shadow budget (``budget=K``, ``select=POLICY`` on any technique's spec) gives at most K lights
their shadows at each surface; the other lights are either drawn without a shadow or not drawn at
all there (``drop``, applied by :mod:`shadowlab.measurement.budget`). Engines live by such budgets:
OpenGL's fixed pipeline enables at least eight lights, and the seed's renderer draws each face
with the eight most significant lights of its list, chosen once when its map is prepared; Godot
draws at most 8 omni and 8 spot lights per mesh, Unity URP 8 additional lights per object. A
policy decides, per (light, face) of the frame, whether the light's shadow is computed on that
face (:class:`Selection`):

- ``face`` — the seed's rule: per receiver face, the K lights of largest unshadowed contribution
  at its centroid (:func:`face_contributions`: λ · |N·L| · luminance of the light's colour) —
  lights that contribute nothing there are not among them; chosen once from the scene, whatever
  the camera sees. Ties are kept (a face may keep more than K lights when contributions are
  equal); ``shadow_polygons:max_lights`` uses this same rule.
- ``closest`` — the K lights closest to the camera (one set for the frame; a light at infinity
  counts as the closest): the baseline of ReSTIR-sampled shadow maps (Zhang, Lin, Wyman &
  Yuksel, EG 2025: "maps only for the closest lights").
- ``object`` — per object, the first K lights in order of the light's unshadowed intensity at the
  object's bounds (:func:`object_importance`: luminance × distance falloff at the point of the
  object's bounding box nearest the light, × the spot cone there): Godot's and Unity URP's per-object light
  lists. A large object (a floor) gets only K lights over its whole surface.
- ``screen`` — the K lights of largest screen-space importance (:func:`screen_importance`: each
  light's unshadowed diffuse radiance summed over the frame's covered pixels); one set per frame.
- ``restir`` — K lights drawn per frame without replacement with probability weighted by screen
  importance (weighted reservoir sampling, Efraimidis & Spirakis 2006: the K largest keys
  u^(1/w)), with temporal reuse as in ReSTIR (Bitterli et al. 2020): the weight is an exponential
  average of the importance over frames (history ``RESERVOIR_HISTORY`` frames), and a light
  selected in the previous frame keeps its random number with its weight counted as often as
  it has been selected in a row (up to ``RESERVOIR_HISTORY``, ReSTIR's confidence cap M), so a
  selection changes rarely unless the weights change. Deterministic: the random numbers come from a fixed seed and the frame
  index (:class:`ReservoirState`).

Per-face policies follow what a frame shows at face granularity: a face is a triangle of the
frame's scene (its index in the frame's triangle order, as the G-buffer's triangle ids).
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np

from ..geometry.triangles import triangle_normals

#: Rec. 709 luminance weights of linear RGB: a light's colour as one intensity.
LUMA = np.array([0.2126, 0.7152, 0.0722])
#: The selection policies, in the order pages list them.
POLICIES = ("face", "closest", "object", "screen", "restir")
#: Which policies decide per face (the others decide per object or per frame).
PER_FACE = frozenset({"face"})
#: Which policies depend on the camera (and so may change as it moves: the flicker metrics).
VIEW_DEPENDENT = frozenset({"closest", "screen", "restir"})
#: The reservoirs' history length (frames) — ReSTIR's M cap: the exponential average's weight of
#: the newest frame is 1/RESERVOIR_HISTORY.
RESERVOIR_HISTORY = 8
#: The fixed seed of the reservoirs' random numbers (a run is reproducible).
RESERVOIR_SEED = 20_251_127
_SERIALS = itertools.count()


def light_luminance(light) -> float:
    """The luminance of a light's colour (its diffuse and specular intensity)."""
    return float(np.asarray(light.color, np.float64) @ LUMA)


def contributions(lights, points: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """(lights, N) float64: each light's unshadowed diffuse intensity at ``points`` (N, 3) with
    unit ``normals`` (N, 3): λ (the light's footprint: cone, range falloff) · |N·L| (two-sided
    surfaces) · luminance of its colour — the "significance" the seed ranks a face's lights by."""
    out = np.zeros((len(lights), len(points)))
    for i, light in enumerate(lights):
        dirs, _ = light.to_light(points)
        facing = np.abs(np.einsum("ij,ij->i", dirs, normals))
        out[i] = light.footprint(points) * facing * light_luminance(light)
    return out


def face_contributions(lights, triangles: np.ndarray) -> np.ndarray:
    """(lights, F): :func:`contributions` at the centroids of ``triangles`` (F, 3, 3)."""
    normal, _ = triangle_normals(triangles)
    return contributions(lights, triangles.mean(axis=1), normal)


def top_k_with_ties(scores: np.ndarray, k: int) -> np.ndarray:
    """Bool like ``scores`` (lights, F): per column, the K largest entries, ties at the K-th kept
    (so exactly K when there are no ties) — among the entries > 0 only: a light that contributes
    nothing at a face's centroid is not one of its K most significant, even when fewer than K
    lights contribute there (with ranged lights, most faces are reached by a few)."""
    if scores.shape[0] <= k:
        return np.ones(scores.shape, bool)
    kth = -np.partition(-scores, k - 1, axis=0)[k - 1]  # the K-th largest per column
    return (scores >= kth) & (scores > 0)


def top_k(scores: np.ndarray, k: int) -> np.ndarray:
    """Bool (lights,): exactly ``min(k, lights)`` entries, the largest ``scores`` (ties: the lower
    index first, a stable order)."""
    keep = np.zeros(len(scores), bool)
    keep[np.argsort(-scores, kind="stable")[:k]] = True
    return keep


def object_importance(lights, objects) -> np.ndarray:
    """(lights, objects): each light's unshadowed intensity at each object — luminance × λ at the
    point of the object's axis-aligned bounding box nearest the light (a light at infinity: at
    the box's centre). How engines rank an object's lights for its per-object list (by the
    light's attenuated intensity at the object's bounds)."""
    out = np.zeros((len(lights), len(objects)))
    for j, obj in enumerate(objects):
        tris = obj.triangles.reshape(-1, 3)
        lo, hi = tris.min(axis=0), tris.max(axis=0)
        for i, light in enumerate(lights):
            if light.at_infinity or not hasattr(light, "position"):
                p = (lo + hi) / 2
            else:
                p = np.clip(np.asarray(light.position, np.float64), lo, hi)
            out[i, j] = float(light.footprint(p[None])[0]) * light_luminance(light)
    return out


def screen_importance(lights, frame) -> np.ndarray:
    """(lights,): each light's unshadowed diffuse intensity (:func:`contributions`) summed over the
    frame's covered pixels, facing the light only (N·L > 0 with the normal turned to the camera).
    Kept on the frame for the same lights (every budget of a frame asks for it)."""
    key = tuple(id(light) for light in lights)
    cached = getattr(frame, "_screen_importance", None)
    if cached is not None and cached[0] == key:
        return cached[1].copy()
    out = _screen_importance(lights, frame)
    frame._screen_importance = (key, out)
    return out.copy()


def _screen_importance(lights, frame) -> np.ndarray:
    """:func:`screen_importance`, computed."""
    points, normals = frame.compact_position, frame.compact_normal
    out = np.zeros(len(lights))
    for i, light in enumerate(lights):
        dirs, _ = light.to_light(points)
        ndl = np.einsum("ij,ij->i", dirs, normals)
        lam = light.footprint(points)
        ok = np.isfinite(ndl)
        out[i] = float(np.sum(np.where(ok & (ndl > 0), lam * np.maximum(ndl, 0.0), 0.0))) * light_luminance(light)
    return out


def camera_distance(lights, eye) -> np.ndarray:
    """(lights,): distance from the camera's eye to each light (0 for a light at infinity)."""
    eye = np.asarray(eye, np.float64)
    return np.array([0.0 if (light.at_infinity or not hasattr(light, "position"))
                     else float(np.linalg.norm(np.asarray(light.position, np.float64) - eye)) for light in lights])


@dataclass
class ReservoirState:
    """What the ``restir`` policy carries from one frame to the next: per light the averaged
    weight, the random number it drew, how many frames in a row it has been selected (its
    reservoir's confidence M, capped at :data:`RESERVOIR_HISTORY`), and the frame counter."""

    weights: np.ndarray | None = None
    numbers: np.ndarray | None = None
    ages: np.ndarray | None = None
    frame: int = 0
    #: A number no other state of the process has (what a cache of plans may key on: an id() can
    #: be reused once a state is gone).
    serial: int = field(default_factory=lambda: next(_SERIALS))

    def select(self, importance: np.ndarray, k: int) -> np.ndarray:
        """Bool (lights,): this frame's K lights, updating the state.

        Weighted sampling without replacement takes the K largest keys u^(1/w) (Efraimidis &
        Spirakis 2006; compared as log(u)/w). Temporal reuse as in ReSTIR's temporal pass: a
        light selected in the previous frame keeps its random number and its weight counts
        min(age + 1, M) times — the previous reservoir's confidence — so a fresh candidate
        replaces it about as often as one new sample replaces a reservoir of M; the weights
        themselves are an exponential average of the importance over about M frames."""
        n = len(importance)
        rng = np.random.default_rng([RESERVOIR_SEED, self.frame])
        fresh = rng.random(n)
        importance = np.asarray(importance, np.float64)
        if self.weights is None or len(self.weights) != n:
            self.weights, numbers, ages = importance.copy(), fresh, np.zeros(n, np.int64)
        else:
            a = 1.0 / RESERVOIR_HISTORY
            self.weights = (1.0 - a) * self.weights + a * importance
            kept = self.ages > 0
            numbers = np.where(kept, self.numbers, fresh)  # temporal reuse: the kept keep their draw
            ages = self.ages
        w = self.weights * np.minimum(ages + 1, RESERVOIR_HISTORY)
        with np.errstate(divide="ignore"):
            keys = np.where(w > 0, np.log(np.maximum(numbers, 1e-300)) / np.where(w > 0, w, 1.0), -np.inf)
        chosen = top_k(keys, k)  # lights of weight 0 (key −∞) only when fewer than K have weight
        self.numbers = numbers
        self.ages = np.where(chosen, ages + 1, 0)
        self.frame += 1
        return chosen


@dataclass
class Selection:
    """Which lights get shadows on which face of a frame: ``kept`` bool (lights, faces) over the
    frame's triangles (G-buffer triangle ids), and the scores the policy ranked by."""

    policy: str
    k: int
    kept: np.ndarray
    scores: np.ndarray = field(repr=False, default=None)

    def compact_mask(self, frame, light_index: int) -> np.ndarray:
        """Bool (M,) over the frame's covered pixels: the light's shadow is computed there."""
        tri = frame.triangle_id.ravel()[frame.pixel_index]
        return self.kept[light_index][tri]

    def pixel_mask(self, frame, light_index: int) -> np.ndarray:
        """Bool (height, width): :meth:`compact_mask` as an image (False where nothing is seen)."""
        return frame.to_image(self.compact_mask(frame, light_index), fill=False, dtype=bool)

    def lights(self) -> np.ndarray:
        """Bool (lights,): the lights kept on at least one face."""
        return self.kept.any(axis=1)


def face_ranges(objects) -> list[tuple[int, int]]:
    """Each object's (first, end) triangle indices in the frame's triangle order."""
    starts = np.cumsum([0] + [len(o.faces) for o in objects])
    return [(int(starts[i]), int(starts[i + 1])) for i in range(len(objects))]


def select(policy: str, k: int, lights, objects, frame, state: ReservoirState | None = None) -> Selection:
    """The :class:`Selection` of ``policy`` with budget ``k`` for the scene ``lights`` and
    ``objects`` seen by ``frame`` (its camera and G-buffer; the per-face ``face`` and per-object
    ``object`` policies read only the scene). ``state``: the ``restir`` policy's reservoirs (a
    fresh state when None: a still frame)."""
    if policy not in POLICIES:
        raise ValueError(f"unknown selection policy {policy!r} (known: {', '.join(POLICIES)})")
    n_faces = sum(len(o.faces) for o in objects)
    n = len(lights)
    ranges = face_ranges(objects)
    if policy == "face":
        triangles = np.concatenate([o.triangles for o in objects]) if objects else np.zeros((0, 3, 3))
        scores = face_contributions(lights, triangles)
        return Selection(policy, k, top_k_with_ties(scores, k), scores)
    if policy == "object":
        scores = object_importance(lights, objects)
        per_object = np.stack([top_k(scores[:, j], k) for j in range(len(objects))], axis=1) if objects \
            else np.zeros((n, 0), bool)
        kept = np.zeros((n, n_faces), bool)
        for j, (a, b) in enumerate(ranges):
            kept[:, a:b] = per_object[:, j:j + 1]
        return Selection(policy, k, kept, scores)
    if policy == "closest":
        scores = -camera_distance(lights, frame.camera.eye)
        chosen = top_k(scores, k)
    elif policy == "screen":
        scores = screen_importance(lights, frame)
        chosen = top_k(scores, k)
    else:  # restir
        scores = screen_importance(lights, frame)
        chosen = (state or ReservoirState()).select(scores, k)
    return Selection(policy, k, np.repeat(chosen[:, None], n_faces, axis=1), scores)
