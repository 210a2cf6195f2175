"""Light sources: point, directional, spot and target-direct (DESIGN §4, §8).

Each light has one definition in two languages that must agree: the numpy methods here (used by
the ground truth and the evaluated-pixel mask) and ``shaders/lights.glsl`` (used by the GL
passes), fed by :meth:`Light.uniforms`. ``tests/test_lights.py`` checks the two on random points.

Footprint λ (DESIGN §8): spot — 1 inside the hotspot half-angle β/2, falling linearly in cos φ
to 0 at the cone half-angle α/2; target-direct (a cylinder of parallel rays of outer radius R,
inner radius r) — 1 within r of the axis, linear to 0 at R, 0 behind the light's plane.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .validation import SceneError, TableReader

#: Integer ids shared with ``shaders/lights.glsl`` (``LIGHT_POINT`` ...); a test checks both agree.
LIGHT_TYPE_IDS = {"point": 0, "directional": 1, "spot": 2, "target_direct": 3}


@dataclass
class Light:
    """Base class: colour (diffuse and specular intensity) and ambient intensity."""

    color: np.ndarray = field(default_factory=lambda: np.ones(3))
    ambient: float = 0.15

    type_name = "light"
    #: True when the light is at infinity (rays are parallel): orthographic shadow maps, w = 0.
    at_infinity = False

    def to_light(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """For (N, 3) float64 points: unit directions towards the light (N, 3) and the distance
        to travel along them to reach the light (N,), ``inf`` for lights at infinity."""
        raise NotImplementedError

    def footprint(self, points: np.ndarray) -> np.ndarray:
        """λ in [0, 1] at (N, 3) points (1 for point and directional lights)."""
        return np.ones(len(points))

    def homogeneous(self) -> np.ndarray:
        """The light as a homogeneous point: (L, 1), or (−direction, 0) for lights at infinity
        (the form planar projection and shadow-frustum construction use)."""
        if self.at_infinity:
            return np.append(-self.direction, 0.0)
        return np.append(self.position, 1.0)

    def uniforms(self) -> dict:
        """Values for the ``light_*`` uniforms of ``shaders/lights.glsl``."""
        return {
            "light_type": LIGHT_TYPE_IDS[self.type_name],
            "light_color": tuple(map(float, self.color)),
            "light_ambient": float(self.ambient),
            "light_position": tuple(map(float, getattr(self, "position", np.zeros(3)))),
            "light_direction": tuple(map(float, getattr(self, "direction", np.array([0.0, -1.0, 0.0])))),
            "light_cos_outer": float(np.cos(np.radians(getattr(self, "alpha", 0.0) / 2))),
            "light_cos_inner": float(np.cos(np.radians(getattr(self, "beta", 0.0) / 2))),
            "light_radius_outer": float(getattr(self, "R", 0.0)),
            "light_radius_inner": float(getattr(self, "r", 0.0)),
        }

    def describe(self) -> dict:
        """The light's parameters as plain JSON-able values (for run.json)."""
        out = {"type": self.type_name}
        for k, v in self.__dict__.items():
            out[k] = v.tolist() if isinstance(v, np.ndarray) else v
        return out


@dataclass
class PointLight(Light):
    """An omnidirectional light at ``position``."""

    position: np.ndarray = field(default_factory=lambda: np.zeros(3))
    type_name = "point"

    def to_light(self, points):
        """Unit directions from ``points`` to the light position, and distances."""
        v = self.position - np.asarray(points, np.float64)
        d = np.linalg.norm(v, axis=-1)
        with np.errstate(invalid="ignore", divide="ignore"):
            return v / d[:, None], d


@dataclass
class DirectionalLight(Light):
    """A light at infinity whose rays travel along the unit vector ``direction``."""

    direction: np.ndarray = field(default_factory=lambda: np.array([0.0, -1.0, 0.0]))
    type_name = "directional"
    at_infinity = True

    def to_light(self, points):
        """−direction everywhere; distance ∞."""
        n = len(points)
        return np.broadcast_to(-self.direction, (n, 3)).copy(), np.full(n, np.inf)


@dataclass
class SpotLight(PointLight):
    """A point light restricted to a cone around ``direction``: full cone angle ``alpha``,
    full hotspot angle ``beta`` (degrees, 0 < beta <= alpha < 180)."""

    direction: np.ndarray = field(default_factory=lambda: np.array([0.0, -1.0, 0.0]))
    alpha: float = 60.0
    beta: float = 40.0
    type_name = "spot"

    def footprint(self, points):
        """1 inside the hotspot, linear in cos φ to 0 at the cone edge."""
        v = np.asarray(points, np.float64) - self.position
        with np.errstate(invalid="ignore", divide="ignore"):
            cos_phi = (v @ self.direction) / np.linalg.norm(v, axis=-1)
        cos_phi = np.nan_to_num(cos_phi, nan=-1.0)
        cos_o, cos_i = np.cos(np.radians(self.alpha / 2)), np.cos(np.radians(self.beta / 2))
        # Must match light_footprint() in shaders/lights.glsl operation for operation.
        width = cos_i - cos_o
        if width > 0:
            return np.clip((cos_phi - cos_o) / width, 0.0, 1.0)
        return (cos_phi >= cos_o).astype(np.float64)


@dataclass
class TargetDirectLight(Light):
    """A cylinder of parallel rays leaving a disc at ``position`` along ``direction``:
    full intensity within radius ``r`` of the axis, linear falloff to 0 at ``R`` (0 < r <= R)."""

    position: np.ndarray = field(default_factory=lambda: np.zeros(3))
    direction: np.ndarray = field(default_factory=lambda: np.array([0.0, -1.0, 0.0]))
    R: float = 1.0
    r: float = 0.5
    type_name = "target_direct"
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


def parse_light(table, where: str, file: str) -> Light:
    """Build a Light from one ``[[lights]]`` table, rejecting impossible values."""
    rd = TableReader(table, where, file)
    kind = rd.string("type", choices=list(LIGHT_TYPE_IDS) + ["area"])
    if kind == "area":
        raise rd.error("type", "area lights are not implemented yet (they come with the soft-shadow work); "
                               "use point, directional, spot or target_direct")
    color = rd.vector("color", 3, default=[1.0, 1.0, 1.0])
    if np.any(color < 0):
        raise rd.error("color", "entries must be >= 0")
    common = dict(color=color, ambient=rd.number("ambient", 0.15, min=0.0))
    if kind == "point":
        light = PointLight(position=rd.vector("position", 3), **common)
    elif kind == "directional":
        light = DirectionalLight(direction=_unit(rd, "direction"), **common)
    elif kind == "spot":
        alpha = rd.number("alpha", min=0.0, min_open=True)
        beta = rd.number("beta", min=0.0, min_open=True)
        if alpha >= 180.0:
            raise rd.error("alpha", f"full cone angle must be < 180 degrees, got {alpha}")
        if beta > alpha:
            raise rd.error("beta", f"hotspot angle must be <= alpha ({alpha}), got {beta}")
        light = SpotLight(position=rd.vector("position", 3), direction=_unit(rd, "direction"),
                          alpha=alpha, beta=beta, **common)
    else:
        R = rd.number("R", min=0.0, min_open=True)
        r = rd.number("r", min=0.0, min_open=True)
        if r > R:
            raise rd.error("r", f"inner radius must be <= R ({R}), got {r}")
        light = TargetDirectLight(position=rd.vector("position", 3), direction=_unit(rd, "direction"),
                                  R=R, r=r, **common)
    rd.finish()
    return light


def _unit(rd: TableReader, name: str) -> np.ndarray:
    vec = rd.vector(name, 3, nonzero=True)
    return vec / np.linalg.norm(vec)


__all__ = ["Light", "PointLight", "DirectionalLight", "SpotLight", "TargetDirectLight",
           "parse_light", "LIGHT_TYPE_IDS", "SceneError"]
