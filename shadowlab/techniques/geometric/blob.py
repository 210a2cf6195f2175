"""Blob shadows: a darkened ellipse under each caster on the nearest receiver below it — the
cheapest baseline (the "fake shadows" of games since the 1990s; Akenine-Möller, Haines &
Hoffman, Real-Time Rendering 4th ed., §7.2 "planar shadows", on blob/fake shadows), with its
error measured against the truth.

Per caster object (``casts = true``), computed once per light in :meth:`BlobShadow.setup`:

1. its centre c = the centre of its axis-aligned bounding box; the light's direction there,
   d = −(unit direction from c towards the light) — away from the light along light → c for
   point, spot and area lights (an area light counts as its centre, like every hard technique
   here), the light's own direction for directional and target-direct lights;
2. the nearest receiver below it: the first receiving triangle of *another* object hit by the
   ray c + t·d, t > ``plane_tolerance`` × scene extent (Embree, robust mode, over the receivers
   other than the caster — left out, not stepped over: a caster resting on its receiver is
   coplanar with it there; a surface through the centre itself — a flat caster such as a floor
   and the bottom of a box resting on it — is not "below"; a caster with no receiver below it
   gets no blob, and the run notes say which). One Embree scene per receiving object, built
   once, takes every caster's ray in one batch, and each caster keeps its nearest hit among the
   objects other than itself (:func:`receiver_hits`): O(triangles) build work, not a scene of
   all the other receivers per caster (O(casters × triangles)). An object whose bounding box no
   ray reaches gets no scene at all. On sv_many_casters (12 casters, 245,762 triangles) that took
   the set-up from seconds to milliseconds, the result bit for bit the same
   (tests/techniques/geometric/test_blob.py). The receiver's plane is that triangle's plane (unit normal n turned
   towards the caster), through the hit point h, the blob's centre;
3. the blob's ellipse: the bounding box's three full edge vectors g_i projected along d onto
   the plane, g'_i = g_i − d (n·g_i)/(n·d), in an orthonormal basis (e1, e2) of the plane.
   Approximations: *parallel* projection along the centre's light direction (a near point
   light's true shadow is larger, magnified by distance ratios, and skewed away from the
   centre); the bounding box, not the caster's shape; and the projected box (a zonogon of area
   A = Σ_{i<j} |det(g'_i, g'_j)|) replaced by the ellipse of the same area whose shape is the
   generators' second-moment matrix C = Σ g'_i g'_iᵀ: {x : xᵀ (s C)⁻¹ x ≤ 1} with
   s = A / (π √det C) (for a box seen straight down: the w × l rectangle becomes the ellipse
   with semi-axes w/√π, l/√π).

Per frame (:meth:`BlobShadow.render`, numpy over the frame's exact points of the evaluated
pixels — a CPU technique): every evaluated point P within ``plane_tolerance`` × scene extent of
a blob's plane — and, with ``clip_to_receiver`` (the default), on the blob's receiver object
(the frame's object id of the point) — gets ρ = √(xᵀ (s C)⁻¹ x), x = P − h in plane
coordinates (ρ = 1 on the ellipse), and the darkening opacity · f(ρ) with

    f(ρ) = 1 − smoothstep(1 − softness/2, 1 + softness/2, ρ)

(a smooth falloff band ``softness`` × the radius wide, centred on the ellipse; softness = 0:
a hard edge at ρ = 1). Overlapping blobs do not add up: a point takes its darkest blob,
V = 1 − max_k opacity · f_k(ρ_k). Points that are not evaluated get 1, as in the truth.

What it cannot do, by construction (measured in tests/techniques/geometric/test_blob.py): no self-shadowing, no
shadow on the caster's other receivers or on other casters than the one receiver hit below the
centre (a shadow that spills past the receiver's edge onto a lower surface is missing: on
pp_table_edge, the floor below the table's edge), no shape (a box's blob is an ellipse, and a
caster's bounding box, not the caster, sets its size). With ``clip_to_receiver`` false a blob
falls wherever its plane is — on coplanar surfaces beyond the receiver's edge too.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ...truth.tracing import mesh_scene, nearest_hits
from ..base import FIRST, SUM, Param, PlotStyle, Technique

@dataclass
class Blob:
    """One caster's blob: the caster's object index, the centre h (3,) float64 on the receiver's
    plane, the plane's unit normal n (3,) (towards the caster), the receiver's object index and
    the ellipse as a 3x3 quadratic form Q (ρ² = (P − h)ᵀ Q (P − h), ρ = 1 on the ellipse; Q is
    zero along n)."""

    caster: int
    receiver: int
    centre: np.ndarray
    normal: np.ndarray
    form: np.ndarray


def plane_basis(n: np.ndarray) -> np.ndarray:
    """Two orthonormal vectors spanning the plane with unit normal ``n`` (3,): (2, 3) float64."""
    helper = np.eye(3)[int(np.argmin(np.abs(n)))]
    e1 = np.cross(n, helper)
    e1 /= np.linalg.norm(e1)
    return np.stack([e1, np.cross(n, e1)])


def blob_form(bounds: np.ndarray, d: np.ndarray, n: np.ndarray) -> np.ndarray | None:
    """The ellipse of a bounding box ``bounds`` (2, 3) projected along the unit direction ``d``
    (3,) onto a plane with unit normal ``n`` (3,) (module docstring, step 3): the 3x3 quadratic
    form Q with ρ² = xᵀ Q x for offsets x from the blob's centre (ρ = 1 on the ellipse of the
    projected box's area). None when the projection has no area (a flat box seen edge-on, or d
    parallel to the plane)."""
    dn = float(d @ n)
    if abs(dn) < 1e-12:
        return None
    edges = np.diag(bounds[1] - bounds[0])  # (3, 3): the full edge vectors g_i as rows
    proj = edges - np.outer(edges @ n / dn, d)  # g'_i, along d onto the plane
    basis = plane_basis(n)
    g = proj @ basis.T  # (3, 2) plane coordinates
    area = sum(abs(float(np.linalg.det(g[[i, j]]))) for i, j in ((0, 1), (0, 2), (1, 2)))
    cov = g.T @ g  # Σ g'_i g'_iᵀ
    det = float(np.linalg.det(cov))
    if area <= 0 or det <= 0:
        return None
    scale = area / (np.pi * np.sqrt(det))
    inv = np.linalg.inv(scale * cov)
    return basis.T @ inv @ basis


#: Padding of an object's bounding box in :func:`rays_reach_box`, relative to the box's size plus
#: its largest coordinate: far above float32 rounding (~6e-8 relative) in Embree's hit test, so
#: skipping an object whose padded box a ray misses never changes that ray's nearest hit.
BOX_PAD = 1e-4


def rays_reach_box(origins: np.ndarray, dirs: np.ndarray, bounds: np.ndarray) -> np.ndarray:
    """Bool (K,): whether each ray ``origins`` + t·``dirs`` ((K, 3) float64, t ≥ 0) meets the box
    ``bounds`` (2, 3) padded by :data:`BOX_PAD` (slab test, Kay & Kajiya 1986) — a conservative
    cull: an object whose box no ray reaches needs no Embree scene."""
    pad = BOX_PAD * (np.linalg.norm(bounds[1] - bounds[0]) + np.abs(bounds).max())
    lo, hi = bounds[0] - pad, bounds[1] + pad
    flat = dirs == 0
    safe = np.where(flat, 1.0, dirs)
    t1, t2 = (lo - origins) / safe, (hi - origins) / safe
    inside = (origins >= lo) & (origins <= hi)  # a ray parallel to a slab meets it only from inside
    t_near = np.where(flat, np.where(inside, -np.inf, np.inf), np.minimum(t1, t2))
    t_far = np.where(flat, np.where(inside, np.inf, -np.inf), np.maximum(t1, t2))
    return np.maximum(t_near.max(axis=1), 0.0) <= t_far.min(axis=1)


def receiver_hits(objects, origins: np.ndarray, dirs: np.ndarray,
                  exclude: np.ndarray) -> list[tuple[int, np.ndarray, np.ndarray] | None]:
    """The nearest receiver along each ray ``origins`` + t·``dirs`` ((K, 3) float64 each; t > 0,
    float32 through Embree in robust mode) among the receiving ``objects`` other than object
    ``exclude[k]`` ((K,) int): per ray (object index, hit point (3,) float64, unit geometric normal
    (3,) of the hit triangle), or None when the ray hits nothing (or its nearest hit is on a
    degenerate triangle).

    One Embree scene per receiving object that some ray may reach (:func:`rays_reach_box`),
    each built once and hit by those rays in one batch; per ray the nearest hit over the objects
    it may take (module docstring, step 2): the build is at most O(triangles), where a scene per
    caster of every other receiver was O(casters × triangles). The excluded object is left out,
    not stepped over: a caster resting on its receiver is coplanar with it there."""
    k = len(origins)
    best_t = np.full(k, np.inf)
    best_object = np.full(k, -1)
    best_ng = np.zeros((k, 3))
    for j, obj in enumerate(objects):
        if not obj.receives:
            continue
        rays = np.flatnonzero((exclude != j) & rays_reach_box(origins, dirs, obj.bounds().astype(np.float64)))
        if len(rays) == 0:
            continue
        scene, meshes = mesh_scene([(obj.vertices, obj.faces)])
        hit = nearest_hits(scene, origins[rays], dirs[rays], np.full(len(rays), np.inf))
        del meshes, scene
        tfar = hit["tfar"].astype(np.float64)
        closer = (hit["geomID"] >= 0) & (tfar < best_t[rays])  # ties: the lower object index
        best_t[rays[closer]] = tfar[closer]
        best_object[rays[closer]] = j
        best_ng[rays[closer]] = hit["Ng"][closer].astype(np.float64)
    out: list[tuple[int, np.ndarray, np.ndarray] | None] = []
    for r in range(k):
        norm = np.linalg.norm(best_ng[r])
        if best_object[r] < 0 or norm == 0:
            out.append(None)
            continue
        out.append((int(best_object[r]), origins[r] + best_t[r] * dirs[r], best_ng[r] / norm))
    return out


def blob_falloff(rho: np.ndarray, softness: float) -> np.ndarray:
    """f(ρ) = 1 − smoothstep(1 − softness/2, 1 + softness/2, ρ) (module docstring); a hard edge
    (1 for ρ ≤ 1, else 0) when softness is 0. Float64, the shape of ``rho``."""
    if softness == 0:
        return (rho <= 1.0).astype(np.float64)
    t = np.clip((rho - (1.0 - softness / 2.0)) / softness, 0.0, 1.0)
    return 1.0 - t * t * (3.0 - 2.0 * t)


class BlobShadow(Technique):
    """Blob shadows: per caster a soft darkened ellipse on the nearest receiver below its centre
    along the light's direction (module docstring). CPU (numpy over the exact points)."""

    name = "blob"
    summary = "blob shadows: a darkened ellipse per caster on the nearest receiver below it (cheapest baseline)"
    cpu = True
    PASSES = ("blob",)
    STYLE = PlotStyle("#7f7f7f", "v")
    STATS = {"blobs": FIRST, "passes": SUM, "preprocess_ms": SUM}
    PARAMS = {
        "opacity": Param(0.8, "darkening at the blob's centre (visibility 1 − opacity)", min=0.0, min_open=True,
                         max=1.0),
        "softness": Param(0.25, "width of the falloff band around the ellipse, as a fraction of its radius "
                                "(0: hard edge)", min=0.0, max=2.0),
        "plane_tolerance": Param(1e-3, "a point receives a blob if within this distance (× scene extent) of the "
                                       "blob's receiver plane", min=0.0, max=1.0),
        "clip_to_receiver": Param(True, "a blob darkens only points of its receiver object (false: any surface "
                                        "within plane_tolerance of the receiver's plane, coplanar neighbours too)"),
    }

    def setup(self, frame, slot) -> None:
        """Find each caster's receiver below it and its ellipse (untimed; ``preprocess_ms``)."""
        t0 = time.perf_counter()
        objects = frame.scene.objects
        extent = frame.scene.extent()
        self.tolerance = self.plane_tolerance * extent
        self.blobs: list[Blob] = []
        missing, flat = [], []
        casters, bounds, origins, dirs = [], [], [], []
        for i, obj in enumerate(objects):
            if not obj.casts:
                continue
            box = obj.bounds().astype(np.float64)
            centre = box.mean(axis=0)
            towards, dist = self.light.to_light(centre[None])
            if not dist[0] > 0:  # the light sits at the centre (or behind a target-direct disc)
                missing.append(i)
                continue
            d = -towards[0] / np.linalg.norm(towards[0])
            casters.append(i)
            bounds.append(box)
            # Start plane_tolerance below the centre: a surface through the centre (a flat
            # caster's coplanar neighbour, say the bottom of a box resting on a floor caster) is
            # not below it.
            origins.append(centre + self.tolerance * d)
            dirs.append(d)
        hits = receiver_hits(objects, np.reshape(origins, (-1, 3)), np.reshape(dirs, (-1, 3)),
                             np.asarray(casters, int)) if casters else []
        for i, box, d, hit in zip(casters, bounds, dirs, hits):
            if hit is None:
                missing.append(i)
                continue
            receiver, point, n = hit
            if n @ d > 0:
                n = -n  # towards the caster (against the light's direction)
            form = blob_form(box, d, n)
            if form is None:
                flat.append(objects[i].name)
                continue
            self.blobs.append(Blob(i, receiver, point, n, form))
        if missing:
            names = ", ".join(objects[i].name for i in sorted(missing))
            self.notes.append(f"blob: no receiver below (no blob): {names}")
        if flat:
            self.notes.append(f"blob: bounding box projects to no area (no blob): {', '.join(flat)}")
        self.evaluated = slot.evaluated
        self.points = frame.compact_position[self.evaluated]
        self.objects = frame.compact_object[self.evaluated]  # (N,) object index of each evaluated point
        self.darkening = np.zeros(len(self.points))
        self.preprocess_ms = 1e3 * (time.perf_counter() - t0)

    def render(self) -> None:
        """Darken the evaluated points near each blob's plane (and on its receiver, with
        ``clip_to_receiver``) by its falloff (the darkest blob wins)."""
        with self.timed_pass("blob", cpu=True):
            dark = np.zeros(len(self.points))
            for blob in self.blobs:
                near = np.abs(self.points @ blob.normal - blob.normal @ blob.centre) <= self.tolerance
                if self.clip_to_receiver:
                    near &= self.objects == blob.receiver
                xs = self.points[near] - blob.centre
                rho = np.sqrt(np.maximum(np.sum((xs @ blob.form) * xs, axis=1), 0.0))
                idx = np.flatnonzero(near)
                dark[idx] = np.maximum(dark[idx], self.opacity * blob_falloff(rho, self.softness))
            self.darkening = dark

    def visibility(self) -> np.ndarray:
        """Float32 (H, W), row 0 = top: 1 − darkening on evaluated pixels, 1 elsewhere."""
        vis = np.ones(len(self.evaluated), np.float32)
        vis[self.evaluated] = (1.0 - self.darkening).astype(np.float32)
        return self.frame.to_image(vis, fill=1.0)

    def work(self, counted: dict, stats: dict) -> dict:
        """Points tested against each blob's plane on the CPU (evaluated points × blobs)."""
        return {"blob": {"cpu_points": len(self.points) * len(self.blobs)}}

    def stats(self) -> dict:
        """Blobs drawn (casters with a receiver below), passes per frame, preprocessing time."""
        return {"blobs": len(self.blobs), "passes": 1, "preprocess_ms": self.preprocess_ms}
