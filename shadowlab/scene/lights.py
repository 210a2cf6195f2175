"""Light sources: point, directional, spot and target-direct (docs/contracts.md#scene-files); the area lights
(rect, disc, sphere) are in :mod:`shadowlab.scene.area_lights`; reading them from a scene file
is :func:`shadowlab.scene.reading.parse_light`.

Each light owns its geometry, so techniques never ask which type a light is:

- :meth:`Light.to_light` and :meth:`Light.footprint`: directions, distances and λ at points
  (evaluated-pixel mask, N·L);
- :meth:`Light.shadow_rays`: the ground truth's shadow rays from given points;
- :meth:`Light.shadow_views`: the views a shadow map of this light is rendered through, fitted
  to the points it must cover;
- :meth:`Light.uniforms`: the ``light_*`` uniforms of ``shadowlab/gpu/lights.glsl``;
- :meth:`Light.homogeneous`: the light as a homogeneous point (planar projection, clipping).

Each light has one definition in two languages that must agree: the numpy methods here and
``shadowlab/gpu/lights.glsl``; ``tests/scene/test_lights.py`` checks the two on random points. Adding a
light type is one class here, its entry in :data:`LIGHT_TYPES` and its branch in lights.glsl.

Footprint λ (docs/architecture.md#the-shading-pass-shadowlabgpushadingpy): spot — 1 inside the hotspot half-angle β/2, falling linearly in cos φ
to 0 at the cone half-angle α/2; target-direct (a cylinder of parallel rays of outer radius R,
inner radius r) — 1 within r of the axis, linear to 0 at R, 0 behind the light's plane. A point
or spot light with a ``range`` (> 0) multiplies that by the distance attenuation of
:func:`range_attenuation` (Karis's windowed 1/d², the form KHR_lights_punctual allows), so λ is
then ≥ 0 but no longer bounded by 1 (its ``color`` is its intensity at distance 1); without a
range, λ is the shape factor alone, bit for bit as before ranges existed — unless the light asks for
``inverse_square`` (no range, KHR_lights_punctual's infinite-range light): then the shape factor
times the unwindowed 1/d² of :func:`inverse_square_attenuation`. A spot's shape factor is the
linear ramp in cos φ above, or, with ``cone_falloff = "squared"``, that ramp squared (the
KHR_lights_punctual spot, as glTF files are lit; :mod:`shadowlab.scene.gltf`).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..geometry import frusta
from ..geometry import transforms as tf
from ..util.validation import SceneError, TableReader

#: Where a shadow ray towards a light at a finite position stops, as a fraction of the way: the
#: rays are unnormalised (light − origin), so no normalisation is spent per ray, and they stop
#: just short of the light itself.
T_LIGHT = 1.0 - 2.0 ** -20
#: "Infinity" for rays towards lights at infinity (finite: Embree's tfar is a float32).
T_INFINITE = np.float32(1e30)

#: Values of the ``light_*`` uniforms that a light type does not use (lights.glsl ignores them).
_UNUSED_UNIFORMS = {
    "light_position": (0.0, 0.0, 0.0),
    "light_direction": (0.0, -1.0, 0.0),
    "light_cos_outer": 1.0,
    "light_cos_inner": 1.0,
    "light_radius_outer": 0.0,
    "light_radius_inner": 0.0,
    "light_range": 0.0,
    "light_inverse_square_near": 0.0,
    "light_cone_squared": 0,
}

#: Below this fraction of a light's ``range``, the distance in the 1/d² of
#: :func:`range_attenuation` is held constant: λ stays finite at the light itself, at most
#: 1 / (RANGE_NEAR · range)² (10⁴ / range²).
RANGE_NEAR = 0.01


def range_attenuation(d2: np.ndarray, light_range: float) -> np.ndarray:
    """The distance attenuation of a light with a ``range`` at squared distances ``d2`` (N,)
    float64: ``clamp(1 − (d/range)⁴, 0, 1)² / max(d², (RANGE_NEAR·range)²)``.

    Karis's window ("Real Shading in Unreal Engine 4", SIGGRAPH 2013 course notes; also
    Filament's): physical inverse-square falloff, windowed so that it reaches exactly 0 at
    ``range`` with zero slope there, so a light touches only the
    pixels within ``range`` of it (its evaluated pixels). The light's colour is thus its
    intensity at distance 1. The window is a function of (d/range)² = d²/range², so no square
    root is taken; the lower clamp on d² (:data:`RANGE_NEAR`) keeps a receiver at the light
    finite. glTF 2.0's KHR_lights_punctual allows "some non-quadratic falloff near the edge of the
    range" and recommends the same window unsquared, clamp(1 − (d/range)⁴, 0, 1) / d²: both are 1/d²
    near the light and 0 at the range; between, the squared window is the darker (at d = range/2,
    0.879 against 0.9375 of 1/d²). Must match ``light_attenuation()`` in shadowlab/gpu/lights.glsl
    operation for operation."""
    r2 = light_range * light_range
    x = d2 / r2  # (d / range)²
    window = np.clip(1.0 - x * x, 0.0, 1.0)
    return window * window / np.maximum(d2, (RANGE_NEAR * RANGE_NEAR) * r2)


#: The distance below which :func:`inverse_square_attenuation` holds d² constant (scene units; a
#: millimetre in a glTF file's metres): λ stays finite at the light itself, at most 10⁶.
INVERSE_SQUARE_NEAR = 1e-3


def inverse_square_attenuation(d2: np.ndarray) -> np.ndarray:
    """The distance attenuation of a light without a ``range`` that asks for ``inverse_square``:
    ``1 / max(d², INVERSE_SQUARE_NEAR²)`` at squared distances ``d2`` (N,) float64.

    KHR_lights_punctual's point and spot lights without a range: "the light is assumed to have
    infinite range" with physical inverse-square falloff, so the light's colour is its intensity
    (candela) at distance 1. The lab's plain light without a range has no falloff at all (λ = 1),
    which is why this is a mode of its own rather than a default. The clamp
    (:data:`INVERSE_SQUARE_NEAR`) keeps a receiver at the light finite. Must match
    ``light_inverse_square()`` in shadowlab/gpu/lights.glsl operation for operation."""
    return 1.0 / np.maximum(d2, INVERSE_SQUARE_NEAR * INVERSE_SQUARE_NEAR)


def _vec(v) -> tuple:
    return tuple(map(float, v))


def _plain_f32_rows(a) -> bool:
    """True for a C-contiguous float32 ndarray (K, 3): what the compiled shadow-ray passes take."""
    return isinstance(a, np.ndarray) and a.dtype == np.float32 and a.ndim == 2 and a.shape[1] == 3 \
        and a.flags.c_contiguous


def _constant_rows(vec: np.ndarray, origins) -> np.ndarray:
    """``np.broadcast_to(vec, origins.shape).copy()`` (the same bits), in one compiled pass for
    float32 origins (K, 3)."""
    if not _plain_f32_rows(origins):
        return np.broadcast_to(vec, origins.shape).copy()
    from ..geometry.rows import fill_rows

    out = np.empty((len(origins), 3), vec.dtype)
    fill_rows(vec, out)
    return out


@dataclass
class Light:
    """Base class: colour (diffuse and specular intensity) and ambient intensity."""

    color: np.ndarray = field(default_factory=lambda: np.ones(3))
    ambient: float = 0.15

    type_name = "light"
    #: The integer id of ``LIGHT_*`` in shadowlab/gpu/lights.glsl (a test checks both agree).
    type_id = -1
    #: True when the light is at infinity (rays are parallel): orthographic shadow maps, w = 0.
    at_infinity = False

    def to_light(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """For (N, 3) float64 points: unit directions towards the light (N, 3) and the distance
        to travel along them to reach the light (N,), ``inf`` for lights at infinity."""
        raise NotImplementedError

    def footprint(self, points: np.ndarray) -> np.ndarray:
        """λ ≥ 0 at (N, 3) points: in [0, 1] (1 for point and directional lights), times the
        distance attenuation for a point or spot light with a ``range``."""
        return np.ones(len(points))

    def homogeneous(self) -> np.ndarray:
        """The light as a homogeneous point: (L, 1), or (−direction, 0) for lights at infinity
        (the form planar projection and shadow-frustum construction use)."""
        if self.at_infinity:
            return np.append(-self.direction, 0.0)
        return np.append(self.position, 1.0)

    def shadow_rays(self, origins: np.ndarray, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Shadow rays for Embree from ``origins`` (N, 3) float32 (the offset ray origins of the
        surface ``points`` (N, 3) float64): directions (N, 3) float32 and ``tfar`` (N,) float32,
        the ray parameter at which the light is reached."""
        raise NotImplementedError

    def shadow_views(self, points: np.ndarray, casters: frusta.Casters, resolution: int, *,
                     projection: str = "auto", near: float = 0.0) -> tuple[list[frusta.LightView], list[str]]:
        """The views (1, or 6 for a point light's cube) of a ``resolution``² shadow map that
        covers ``points`` (N, 3) with the scene's ``casters``, and notes for the run.
        ``projection`` (auto | cube | frustum) and ``near`` (force a near plane if > 0) apply to
        the perspective maps of lights at a position, whose near planes are fitted to the caster
        triangles they see (:func:`shadowlab.geometry.frusta.perspective_fit`)."""
        raise NotImplementedError

    def _shape_uniforms(self) -> dict:
        """The type's own ``light_*`` uniforms (position, direction, cone, radii)."""
        return {}

    def uniforms(self) -> dict:
        """Values for the ``light_*`` uniforms of ``shadowlab/gpu/lights.glsl``."""
        return {"light_type": self.type_id, "light_color": _vec(self.color), "light_ambient": float(self.ambient),
                **_UNUSED_UNIFORMS, **self._shape_uniforms()}

    def describe(self) -> dict:
        """The light's parameters as plain JSON-able values (for run.json)."""
        out = {"type": self.type_name}
        for k, v in self.__dict__.items():
            out[k] = v.tolist() if isinstance(v, np.ndarray) else v
        return out


@dataclass
class PointLight(Light):
    """An omnidirectional light at ``position``; with ``range`` > 0 its λ falls off with distance
    (:func:`range_attenuation`) to 0 at ``range``; 0 (the default) means no falloff, unless
    ``inverse_square`` asks for the unwindowed 1/d² of :func:`inverse_square_attenuation` (glTF's
    light without a range; it may not be combined with a range)."""

    position: np.ndarray = field(default_factory=lambda: np.zeros(3))
    range: float = 0.0
    inverse_square: bool = False
    type_name = "point"
    type_id = 0

    def _shape_footprint(self, points: np.ndarray) -> np.ndarray:
        """λ before the distance attenuation: 1 for a point light (and an area light's centre)."""
        return np.ones(len(points))

    def footprint(self, points):
        """The shape factor (:meth:`_shape_footprint`), times :func:`range_attenuation` when the
        light has a range; without one exactly the shape factor."""
        lam = self._shape_footprint(points)
        if self.range > 0:
            v = np.asarray(points, np.float64) - self.position
            lam = lam * range_attenuation(np.einsum("ij,ij->i", v, v), self.range)
        elif self.inverse_square:
            v = np.asarray(points, np.float64) - self.position
            lam = lam * inverse_square_attenuation(np.einsum("ij,ij->i", v, v))
        return lam

    def describe(self):
        """As :meth:`Light.describe`; ``range``, ``inverse_square`` and a spot's ``cone_falloff``
        only when they are not the defaults (a light without them reads as it did before they
        existed)."""
        out = super().describe()
        if not out.get("range"):
            out.pop("range", None)
        if not out.get("inverse_square"):
            out.pop("inverse_square", None)
        if out.get("cone_falloff", "linear") == "linear":
            out.pop("cone_falloff", None)
        return out

    def to_light(self, points):
        """Unit directions from ``points`` to the light position, and distances."""
        v = self.position - np.asarray(points, np.float64)
        d = np.linalg.norm(v, axis=-1)
        with np.errstate(invalid="ignore", divide="ignore"):
            return v / d[:, None], d

    def shadow_rays(self, origins, points):
        """Unnormalised rays (light − origin), stopping at :data:`T_LIGHT` of the way. Float32
        origins (K, 3) take a compiled pass, bit for bit numpy's broadcast subtraction, which
        loops over three elements per row (issue 27)."""
        pos = self.position.astype(np.float32)
        tfar = np.full(len(origins), T_LIGHT, np.float32)
        if not _plain_f32_rows(origins):
            return pos - origins, tfar
        from ..geometry.rows import vector_minus_rows

        dirs = np.empty((len(origins), 3), np.float32)
        vector_minus_rows(pos, origins, dirs)
        return dirs, tfar

    def shadow_views(self, points, casters, resolution, *, projection="auto", near=0.0):
        """``projection=frustum``: one frustum around the points; ``cube``: six faces; ``auto``:
        the frustum when the points fit in a cone of MAX_POINT_HALF_ANGLE, else the cube."""
        p = self.position
        dirs = (points - p) / np.linalg.norm(points - p, axis=1)[:, None]
        axis = tf.normalize(dirs.mean(axis=0))
        angles = np.degrees(np.arccos(np.clip(dirs @ axis, -1, 1)))
        half = float(angles.max()) * (1 + frusta.PAD)
        limit = frusta.MAX_POINT_HALF_ANGLE
        if projection == "cube" or (projection == "auto" and half > limit):
            near, far, notes = frusta.perspective_fit(p, points, casters, frusta.cube_view_matrices(p), 90.0, near)
            return frusta.cube_views(p, near, far, resolution), notes
        notes = []
        if half > limit:
            outside = int(np.sum(angles > limit))
            notes.append(f"point light: receivers span {half:.1f} degrees around the light, more than one "
                         f"frustum's {limit}; {outside} shadowable pixels lie outside the shadow "
                         f"map and are treated as lit (use projection=cube)")
            half = limit
        near, far, fit_notes = frusta.perspective_fit(p, points, casters, [tf.look_along(p, axis)], 2 * half, near)
        return [frusta.perspective_view(p, axis, 2 * half, near, far, resolution)], notes + fit_notes

    def _falloff_uniforms(self) -> dict:
        """``light_range`` and ``light_inverse_square_near`` (> 0 only for an inverse-square light)."""
        return {"light_range": float(self.range),
                "light_inverse_square_near": INVERSE_SQUARE_NEAR if self.inverse_square and not self.range > 0 else 0.0}

    def _shape_uniforms(self):
        return {"light_position": _vec(self.position), **self._falloff_uniforms()}

    @classmethod
    def parse(cls, rd: TableReader, common: dict) -> "PointLight":
        """From a ``[[lights]]`` table of this type (the common keys already read)."""
        return cls(position=rd.vector("position", 3), **_falloff(rd), **common)


@dataclass
class DirectionalLight(Light):
    """A light at infinity whose rays travel along the unit vector ``direction``."""

    direction: np.ndarray = field(default_factory=lambda: np.array([0.0, -1.0, 0.0]))
    type_name = "directional"
    type_id = 1
    at_infinity = True

    def to_light(self, points):
        """−direction everywhere; distance ∞."""
        n = len(points)
        return np.broadcast_to(-self.direction, (n, 3)).copy(), np.full(n, np.inf)

    def shadow_rays(self, origins, points):
        """Along −direction, to :data:`T_INFINITE`."""
        return _constant_rows((-self.direction).astype(np.float32), origins), np.full(len(origins), T_INFINITE,
                                                                                       np.float32)

    def shadow_views(self, points, casters, resolution, *, projection="auto", near=0.0):
        """Orthographic along the light, sideways fitted to the points, in depth from the
        nearest caster box to the farthest point."""
        view = tf.look_along(points.mean(axis=0), self.direction)
        return [frusta.orthographic_fit(view, points, casters.bounds, resolution)], []

    def _shape_uniforms(self):
        return {"light_direction": _vec(self.direction)}

    @classmethod
    def parse(cls, rd: TableReader, common: dict) -> "DirectionalLight":
        """From a ``[[lights]]`` table of this type (the common keys already read)."""
        return cls(direction=_unit(rd, "direction"), **common)


@dataclass
class SpotLight(PointLight):
    """A point light restricted to a cone around ``direction``: full cone angle ``alpha``,
    full hotspot angle ``beta`` (degrees, 0 <= beta <= alpha < 180)."""

    direction: np.ndarray = field(default_factory=lambda: np.array([0.0, -1.0, 0.0]))
    alpha: float = 60.0
    beta: float = 40.0
    #: ``linear`` (the lab's ramp in cos φ) or ``squared`` (that ramp squared: KHR_lights_punctual).
    cone_falloff: str = "linear"
    type_name = "spot"
    type_id = 2

    def _shape_footprint(self, points):
        """1 inside the hotspot, linear in cos φ to 0 at the cone edge (``cone_falloff =
        "squared"``: that ramp squared, as KHR_lights_punctual's spot)."""
        v = np.asarray(points, np.float64) - self.position
        with np.errstate(invalid="ignore", divide="ignore"):
            cos_phi = (v @ self.direction) / np.linalg.norm(v, axis=-1)
        cos_phi = np.nan_to_num(cos_phi, nan=-1.0)
        cos_o, cos_i = np.cos(np.radians(self.alpha / 2)), np.cos(np.radians(self.beta / 2))
        # Must match light_footprint() in shadowlab/gpu/lights.glsl operation for operation.
        width = cos_i - cos_o
        if width > 0:
            ramp = np.clip((cos_phi - cos_o) / width, 0.0, 1.0)
            return ramp * ramp if self.cone_falloff == "squared" else ramp
        return (cos_phi >= cos_o).astype(np.float64)

    def shadow_views(self, points, casters, resolution, *, projection="auto", near=0.0):
        """One perspective view along the cone's axis with the cone's full angle α."""
        fov = min(self.alpha * (1 + frusta.PAD), frusta.MAX_FOV)
        view = tf.look_along(self.position, self.direction)
        near, far, notes = frusta.perspective_fit(self.position, points, casters, [view], fov, near)
        return [frusta.perspective_view(self.position, self.direction, fov, near, far, resolution)], notes

    def _shape_uniforms(self):
        return {"light_position": _vec(self.position), "light_direction": _vec(self.direction),
                "light_cos_outer": float(np.cos(np.radians(self.alpha / 2))),
                "light_cos_inner": float(np.cos(np.radians(self.beta / 2))),
                "light_cone_squared": int(self.cone_falloff == "squared"), **self._falloff_uniforms()}

    @classmethod
    def parse(cls, rd: TableReader, common: dict) -> "SpotLight":
        """From a ``[[lights]]`` table of this type; rejects beta > alpha and alpha ≥ 180."""
        alpha = rd.number("alpha", min=0.0, min_open=True)
        beta = rd.number("beta", min=0.0)  # 0: no hotspot (glTF's default innerConeAngle)
        if alpha >= 180.0:
            raise rd.error("alpha", f"full cone angle must be < 180 degrees, got {alpha}")
        if beta > alpha:
            raise rd.error("beta", f"hotspot angle must be <= alpha ({alpha}), got {beta}")
        return cls(position=rd.vector("position", 3), direction=_unit(rd, "direction"),
                   alpha=alpha, beta=beta, cone_falloff=rd.string("cone_falloff", "linear", choices=CONE_FALLOFFS),
                   **_falloff(rd), **common)


@dataclass
class TargetDirectLight(Light):
    """A cylinder of parallel rays leaving a disc at ``position`` along ``direction``:
    full intensity within radius ``r`` of the axis, linear falloff to 0 at ``R`` (0 < r <= R)."""

    position: np.ndarray = field(default_factory=lambda: np.zeros(3))
    direction: np.ndarray = field(default_factory=lambda: np.array([0.0, -1.0, 0.0]))
    R: float = 1.0
    r: float = 0.5
    type_name = "target_direct"
    type_id = 3
    at_infinity = True

    def axial(self, points) -> tuple[np.ndarray, np.ndarray]:
        """Signed distance along the axis in front of the light's plane, and distance from the axis."""
        v = np.asarray(points, np.float64) - self.position
        t = v @ self.direction
        rho = np.linalg.norm(v - t[:, None] * self.direction, axis=-1)
        return t, rho

    def to_light(self, points):
        """−direction, travelled up to the light's plane (distance ≤ 0 behind the light)."""
        t, _ = self.axial(points)
        return np.broadcast_to(-self.direction, (len(points), 3)).copy(), t

    def footprint(self, points):
        """1 within r of the axis, linear to 0 at R, 0 behind the light's plane."""
        t, rho = self.axial(points)
        width = self.R - self.r
        lam = np.clip((self.R - rho) / width, 0.0, 1.0) if width > 0 else (rho <= self.R).astype(np.float64)
        return np.where(t > 0, lam, 0.0)

    def shadow_rays(self, origins, points):
        """Along −direction, back to the light's plane (nothing behind the disc casts)."""
        dirs = _constant_rows((-self.direction).astype(np.float32), origins)
        return dirs, ((points - self.position) @ self.direction).astype(np.float32)

    def shadow_views(self, points, casters, resolution, *, projection="auto", near=0.0):
        """Orthographic from the light's disc along its axis, sideways within radius R of the
        axis, near plane not behind the disc."""
        view = tf.look_along(self.position, self.direction)
        return [frusta.orthographic_fit(view, points, casters.bounds, resolution, radius=self.R, near_min=0.0)], []

    def _shape_uniforms(self):
        return {"light_position": _vec(self.position), "light_direction": _vec(self.direction),
                "light_radius_outer": float(self.R), "light_radius_inner": float(self.r)}

    @classmethod
    def parse(cls, rd: TableReader, common: dict) -> "TargetDirectLight":
        """From a ``[[lights]]`` table of this type; rejects r > R."""
        R = rd.number("R", min=0.0, min_open=True)
        r = rd.number("r", min=0.0, min_open=True)
        if r > R:
            raise rd.error("r", f"inner radius must be <= R ({R}), got {r}")
        return cls(position=rd.vector("position", 3), direction=_unit(rd, "direction"), R=R, r=r, **common)


#: The light types a scene file may name (``type = "..."``).
LIGHT_TYPES: dict[str, type[Light]] = {cls.type_name: cls for cls in
                                       (PointLight, DirectionalLight, SpotLight, TargetDirectLight)}
#: Integer ids shared with ``shadowlab/gpu/lights.glsl`` (``LIGHT_POINT`` ...); a test checks both agree.
LIGHT_TYPE_IDS = {**{name: cls.type_id for name, cls in LIGHT_TYPES.items()}, "area": 4}


#: The ``range`` values a scene file may give: range² and (RANGE_NEAR·range)² must stay normal
#: float32 numbers in lights.glsl.
RANGE_LIMITS = (1e-15, 1e15)


def _range(rd: TableReader) -> float:
    """The optional ``range`` key of a point or spot light: > 0 (within :data:`RANGE_LIMITS`),
    or 0 (no falloff) when absent."""
    value = rd.number("range", 0.0, min=0.0, min_open=True)
    lo, hi = RANGE_LIMITS
    if value and not lo <= value <= hi:
        raise rd.error("range", f"must be between {lo:g} and {hi:g} (its square is taken in float32 on the GPU), "
                                f"got {value!r}")
    return value


#: The spot's ``cone_falloff`` values: the lab's linear ramp in cos φ, or KHR_lights_punctual's square of it.
CONE_FALLOFFS = ("linear", "squared")


def _falloff(rd: TableReader) -> dict:
    """The optional ``range`` and ``inverse_square`` keys of a point or spot light (at most one of them)."""
    out = {"range": _range(rd), "inverse_square": rd.boolean("inverse_square", False)}
    if out["range"] and out["inverse_square"]:
        raise rd.error("inverse_square", "a light with a range already falls off as 1/d² (windowed); "
                                         "give range or inverse_square, not both")
    return out


def _unit(rd: TableReader, name: str) -> np.ndarray:
    vec = rd.vector(name, 3, nonzero=True)
    return vec / np.linalg.norm(vec)


__all__ = ["Light", "PointLight", "DirectionalLight", "SpotLight", "TargetDirectLight", "LIGHT_TYPES",
           "LIGHT_TYPE_IDS", "SceneError", "T_LIGHT", "T_INFINITE", "RANGE_NEAR", "range_attenuation",
           "INVERSE_SQUARE_NEAR", "inverse_square_attenuation", "CONE_FALLOFFS"]
