"""Area lights (docs/contracts.md#scene-files, docs/soft-shadows.md): a rectangle, a disc and a sphere, each a light you can sample.

An area light is, for everything that needs one position (the Blinn terms of the shading, the
evaluated-pixel mask, a hard technique run on it without light sampling), a point light at its
centre: the classes derive from :class:`shadowlab.scene.lights.PointLight`. What makes it an area
light is its surface, sampled two ways:

- :meth:`AreaLight.pattern`: N fixed points (and their emitting normals) shared by every pixel —
  the light-sampling average of the hard techniques renders once from each
  (:mod:`shadowlab.measurement.light_sampling`). The points are the centres of N equal-area strata of the
  unit square (:func:`strata`), mapped onto the surface by area-preserving maps, so one sample
  is the centre (a sphere: the point of it nearest the receivers) and a regular pattern shows
  its banding on purpose.
- :meth:`AreaLight.sample_for`: per shaded point, N stratified points jittered independently
  for every point (decorrelated between pixels), for the sampled ground truth.

Visibility of an area light from a point P (docs/metrics.md): the fraction, by area, of the emitting
surface facing P that P sees unoccluded. A one-sided ``rect`` or ``disc`` emits towards its
normal only (u × v, or ``direction``): a point behind its plane sees none of it. A ``sphere``
emits all around; from P it shows the cap bounded by its silhouette, and visibility is the
unoccluded fraction of that cap. Samples below P's own tangent plane are hidden by P's surface
(:func:`above_horizon`), so a light partly below a receiver's plane is partly hidden from it.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..geometry import transforms as tf
from .lights import PointLight
from ..util.validation import TableReader


def strata(n: int) -> tuple[np.ndarray, np.ndarray]:
    """N equal-area cells tiling the unit square: lower corners (n, 2) and sizes (n, 2).

    round(√n) rows, the n cells dealt out among them as evenly as possible; a row of k cells
    is k/n high and its cells 1/k wide, so every cell has area 1/n for any n (a perfect square
    gives the usual √n × √n grid). One jittered sample per cell is stratified sampling, whose
    variance never exceeds independent sampling's."""
    if n < 1:
        raise ValueError(f"need at least one sample, got {n}")
    rows = max(1, int(round(np.sqrt(n))))
    per_row = np.full(rows, n // rows)
    per_row[: n % rows] += 1
    lo, size = [], []
    y = 0.0
    for k in per_row:
        h = k / n
        x = np.arange(k) / k
        lo.append(np.stack([x, np.full(k, y)], axis=1))
        size.append(np.tile([1.0 / k, h], (k, 1)))
        y += h
    return np.concatenate(lo), np.concatenate(size)


def concentric_disc(uv: np.ndarray) -> np.ndarray:
    """Shirley & Chiu's concentric map (1997), unit square (..., 2) → unit disc (..., 2):
    area-preserving and continuous, so strata of the square stay strata of the disc; (½, ½) →
    the centre."""
    a = 2.0 * uv[..., 0] - 1.0
    b = 2.0 * uv[..., 1] - 1.0
    first = np.abs(a) > np.abs(b)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(first, a, b)
        phi = np.where(first, (np.pi / 4) * (b / a), np.pi / 2 - (np.pi / 4) * (a / b))
    phi = np.where((a == 0) & (b == 0), 0.0, phi)
    return np.stack([r * np.cos(phi), r * np.sin(phi)], axis=-1)


def basis(normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors (3,) that complete the unit ``normal`` to a right-handed frame."""
    helper = np.array([1.0, 0.0, 0.0]) if abs(normal[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    t = tf.normalize(np.cross(helper, normal))
    return t, np.cross(normal, t)


def above_horizon(samples: np.ndarray, points: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """Bool (M, N): sample (M, N, 3) strictly above the tangent plane of its point (M, 3) with
    the camera-facing normal (M, 3) — below it, the point's own surface hides the light."""
    return np.einsum("mnk,mk->mn", samples - points[:, None, :], normals) > 0


def _unit_direction(vec: np.ndarray) -> np.ndarray:
    """``vec`` (3,) scaled to unit length without overflow or underflow: divided by its largest
    |entry| first, so entries of any finite magnitude (1e±300) give the true direction."""
    scaled = vec / np.abs(vec).max()
    return scaled / np.linalg.norm(scaled)


def _checked_area(rd: TableReader, key: str, light: "AreaLight", what: str) -> "AreaLight":
    """``light`` if its :attr:`~AreaLight.area` is finite and > 0, else a SceneError on ``key``:
    parameters of extreme (finite) magnitude can overflow the area to ∞ (r = 1e300 → π r²) or
    underflow it to 0, and every sampler, weight and report divides by or prints the area."""
    try:
        with np.errstate(over="ignore", under="ignore"):  # an overflow is the error reported below
            area = light.area
    except OverflowError:  # a Python float's ** raises where numpy would give inf
        area = float("inf")
    if not (np.isfinite(area) and area > 0):
        raise rd.error(key, f"{what} gives the light an area of {area!r}: it must be finite and > 0")
    return light


@dataclass
class AreaLight(PointLight):
    """Base of the area lights: ``position`` is the centre (docs/contracts.md#scene-files)."""

    type_name = "area"
    type_id = 4  # LIGHT_AREA in shadowlab/gpu/lights.glsl: lit as a point light at the centre
    shape = "area"
    #: True for a light that emits towards its normal only (rect, disc).
    one_sided = True

    @property
    def area(self) -> float:
        """Emitting area (world units²)."""
        raise NotImplementedError

    def _surface(self, uv: np.ndarray) -> np.ndarray:
        """Points (..., 3) of the surface at unit-square coordinates ``uv`` (..., 2), by an
        area-preserving map."""
        raise NotImplementedError

    def emits_towards(self, points: np.ndarray) -> np.ndarray:
        """Bool (M,): points on the emitting side (always true for a sphere)."""
        return (np.asarray(points, np.float64) - self.position) @ self.normal > 0

    def pattern(self, n: int, towards: np.ndarray | None = None) -> np.ndarray:
        """N fixed sample points (n, 3) on the surface, the centres of :func:`strata` (n = 1:
        the centre); what the light-sampling average renders from. ``towards`` is used by the
        sphere only."""
        lo, size = strata(n)
        return self._surface(lo + 0.5 * size)

    def sample_for(self, points: np.ndarray, n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """Per point (M, 3): n stratified samples (M, n, 3) jittered independently per point,
        uniform by area over the surface facing the point, and which of them emit towards it
        (M, n) bool (a one-sided light's points behind its plane get none)."""
        lo, size = strata(n)
        uv = lo + rng.random((len(points), n, 2)) * size
        samples = self._surface(uv)
        facing = np.broadcast_to(self.emits_towards(points)[:, None], (len(points), n))
        return samples, facing

    def describe(self) -> dict:
        """Parameters for run.json, the shape included."""
        return {**super().describe(), "shape": self.shape, "area": self.area}


@dataclass
class RectLight(AreaLight):
    """A rectangle centred at ``position`` with full edge vectors ``u`` and ``v``, emitting
    towards u × v."""

    u: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0]))
    v: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, -1.0]))
    shape = "rect"

    @property
    def normal(self) -> np.ndarray:
        """Unit emitting normal u × v / |u × v|."""
        return tf.normalize(np.cross(self.u, self.v))

    @property
    def area(self) -> float:
        """|u × v| (the edges need not be perpendicular: a parallelogram)."""
        return float(np.linalg.norm(np.cross(self.u, self.v)))

    def _surface(self, uv):
        return self.position + (uv[..., :1] - 0.5) * self.u + (uv[..., 1:] - 0.5) * self.v

    def sample_for(self, points, n, rng):
        """:meth:`AreaLight.sample_for` (the same jitter from ``rng``, the same bits), with the
        strata's jitter mapped onto the rectangle in one compiled pass
        (:func:`shadowlab.geometry.rows.rect_samples`) instead of numpy's (M, n, 3) temporaries:
        the sampled truth's largest cost besides Embree (issue 27)."""
        from ..geometry.rows import rect_samples

        lo, size = strata(n)
        jitter = np.ascontiguousarray(rng.random((len(points), n, 2)), np.float64)
        samples = np.empty((len(points), n, 3))
        rect_samples(jitter, np.ascontiguousarray(lo, np.float64), np.ascontiguousarray(size, np.float64),
                     *(np.ascontiguousarray(a, np.float64) for a in (self.position, self.u, self.v)), samples)
        facing = np.broadcast_to(self.emits_towards(points)[:, None], (len(points), n))
        return samples, facing

    def corners(self) -> np.ndarray:
        """The four corners (4, 3), counter-clockwise seen from the emitting side."""
        return self._surface(np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]))

    @classmethod
    def parse(cls, rd: TableReader, common: dict) -> "RectLight":
        """position, u, v; rejects parallel edges (sin of their angle ≤ 1e-12, tested on unit
        vectors so that huge or tiny edges neither overflow nor underflow the test) and an area
        |u × v| that is not finite and > 0."""
        u, v = rd.vector("u", 3, nonzero=True), rd.vector("v", 3, nonzero=True)
        if not np.linalg.norm(np.cross(_unit_direction(u), _unit_direction(v))) > 1e-12:
            raise rd.error("v", "u and v are parallel: the rectangle has zero area")
        light = cls(position=rd.vector("position", 3), u=u, v=v, **common)
        return _checked_area(rd, "u", light, "|u × v|")


@dataclass
class DiscLight(AreaLight):
    """A disc centred at ``position`` of ``radius``, emitting towards the unit ``direction``."""

    direction: np.ndarray = field(default_factory=lambda: np.array([0.0, -1.0, 0.0]))
    radius: float = 0.5
    shape = "disc"

    @property
    def normal(self) -> np.ndarray:
        """Unit emitting normal (``direction``)."""
        return self.direction

    @property
    def area(self) -> float:
        """π r²."""
        return float(np.pi * self.radius ** 2)

    def _surface(self, uv):
        t, b = basis(self.direction)
        d = concentric_disc(uv) * self.radius
        return self.position + d[..., :1] * t + d[..., 1:] * b

    @classmethod
    def parse(cls, rd: TableReader, common: dict) -> "DiscLight":
        """position, direction (non-zero), radius > 0 with a finite, non-zero area π r²."""
        direction = rd.vector("direction", 3, nonzero=True)
        light = cls(position=rd.vector("position", 3), direction=_unit_direction(direction),
                    radius=rd.number("radius", min=0.0, min_open=True), **common)
        return _checked_area(rd, "radius", light, "the radius")


@dataclass
class SphereLight(AreaLight):
    """A sphere centred at ``position`` of ``radius``, emitting all around."""

    radius: float = 0.5
    shape = "sphere"
    one_sided = False

    @property
    def area(self) -> float:
        """4 π r²."""
        return float(4.0 * np.pi * self.radius ** 2)

    def emits_towards(self, points):
        """Every point outside the sphere sees part of it."""
        return np.linalg.norm(np.asarray(points, np.float64) - self.position, axis=-1) > self.radius

    def pattern(self, n, towards=None):
        """N fixed points on the cap of the sphere seen from ``towards`` (the receivers' centre;
        default: from straight below), uniform by area over it as the truth samples each point's
        own cap: the strata centres go through the concentric map to the unit disc (radius ρ,
        angle φ), then to the cap point at cos θ = 1 − ρ² (1 − r/D) about the axis towards the
        receivers (ρ² is uniform, so cos θ is uniform on [r/D, 1]: Archimedes, equal areas).
        n = 1 gives the cap's apex, the point nearest the receivers. Points far off that
        direction see another cap — the approximation a shared pattern makes."""
        target = self.position + [0.0, -2.0 * self.radius, 0.0] if towards is None else np.asarray(towards, float)
        offset = target - self.position
        dist = float(np.linalg.norm(offset))
        axis = offset / dist if dist > 0 else np.array([0.0, -1.0, 0.0])
        cos_max = min(1.0, self.radius / dist) if dist > self.radius else 0.0  # inside: a hemisphere
        t, b = basis(axis)
        lo, size = strata(n)
        d = concentric_disc(lo + 0.5 * size)
        rho2 = np.sum(d * d, axis=1)
        z = 1.0 - rho2 * (1.0 - cos_max)
        phi = np.arctan2(d[:, 1], d[:, 0])
        s = np.sqrt(np.maximum(0.0, 1.0 - z * z))
        direction = z[:, None] * axis + (s * np.cos(phi))[:, None] * t + (s * np.sin(phi))[:, None] * b
        return self.position + self.radius * direction

    def sample_for(self, points, n, rng):
        """Uniform by area over the cap each point sees (bounded by the silhouette): about the
        axis from the centre to the point, cos θ uniform in [r/d, 1] (Archimedes: equal heights,
        equal areas), stratified in (cos θ, φ)."""
        points = np.asarray(points, np.float64)
        lo, size = strata(n)
        uv = lo + rng.random((len(points), n, 2)) * size
        offset = points - self.position
        dist = np.linalg.norm(offset, axis=1)
        inside = dist <= self.radius
        axis = offset / np.where(inside, 1.0, dist)[:, None]
        axis[inside] = [0.0, 1.0, 0.0]
        helper = np.where(np.abs(axis[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
        t = np.cross(helper, axis)
        t /= np.linalg.norm(t, axis=1, keepdims=True)
        b = np.cross(axis, t)
        cos_max = np.where(inside, 1.0, self.radius / np.where(inside, 1.0, dist))
        z = 1.0 - uv[..., 0] * (1.0 - cos_max[:, None])
        s = np.sqrt(np.maximum(0.0, 1.0 - z * z))
        phi = 2.0 * np.pi * uv[..., 1]
        direction = (z[..., None] * axis[:, None] + (s * np.cos(phi))[..., None] * t[:, None]
                     + (s * np.sin(phi))[..., None] * b[:, None])
        return self.position + self.radius * direction, np.broadcast_to(~inside[:, None], (len(points), n))

    @classmethod
    def parse(cls, rd: TableReader, common: dict) -> "SphereLight":
        """position, radius > 0 with a finite, non-zero area 4 π r²."""
        light = cls(position=rd.vector("position", 3), radius=rd.number("radius", min=0.0, min_open=True), **common)
        return _checked_area(rd, "radius", light, "the radius")


#: Area light shapes a scene file may name (``type = "area"``, ``shape = "..."``).
AREA_SHAPES: dict[str, type[AreaLight]] = {cls.shape: cls for cls in (RectLight, DiscLight, SphereLight)}
