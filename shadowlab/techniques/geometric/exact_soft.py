"""Exact soft shadows: the visible fraction of a planar area light from every evaluated point, as
the area of a union of projected polygons — no sampling, no noise (issue 28).

The definition (docs/metrics.md) read as geometry, the way Drettakis & Fiume ("A fast shadow
algorithm for area light sources using backprojection", SIGGRAPH 1994) and Laine et al. ("Soft
shadow volumes for ray tracing", SIGGRAPH 2005, §3) read it: from a point P, each occluding
triangle is centrally projected onto the light's plane; the union of the projections, together
with the part of the light below P's tangent plane, intersected with the light's emitting
polygon L, is what P cannot see:

    V(P) = 1 − area((∪ projections ∪ below-horizon) ∩ L) / area(L),   V = 0 behind the light.

This is the shapely oracle of tests/soft_oracle.py computed in compiled code: the geometry —
culling with a bounding-volume hierarchy, clipping, projection, the union's area by Green's
theorem and the exact rules for coincident edges — is :mod:`shadowlab.geometry.soft_visibility`'s
(numba, ``nogil``, no GL); this technique gathers the light's polygon, the casters' triangles
and the evaluated points, and splits the points over the cores like
:mod:`shadowlab.truth.compiled`.

What ``experiments/exact_soft.py`` measures (docs/soft-shadows.md): equal to the exact oracle to
round-off; against the sampled truth within the truth's own per-pixel error bound; faster than
the 1024-sample truth on the shipped soft scenes; time linear in pixels and about linear in a
fine caster's triangles, while the truth's hardly grows with them — so past some triangle count
the truth is the faster one.
"""
from __future__ import annotations

import time

import numpy as np

from ...util.compiled import cores, in_parts
from ...geometry.soft_visibility import build_bvh, cull_polygon, disc_polygon, scratch_buffers, visibility_points
from ...scene.area_lights import AreaLight, DiscLight, RectLight, basis
from ..base import FIRST, SUM, Param, PlotStyle, Technique, TechniqueError

#: Most candidate polygons one point may have (the per-part buffers' size): more is an error.
MAX_POLYGONS = 1 << 17


def light_frame(light) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Centre (3,), unit emitting normal n (3,), in-plane unit axes t, b (3,) with t × b = n
    (the oracle's frame)."""
    n = np.asarray(light.normal, np.float64)
    t, b = basis(n)  # the same completion as the oracle's
    return np.asarray(light.position, np.float64), n, t, b


def light_polygon(light, disc_sides: int) -> np.ndarray:
    """The emitting polygon (k, 2), CCW in the light frame's (t, b) coordinates about its centre:
    a rect's four corners, a disc's equal-area ``disc_sides``-gon; TechniqueError otherwise."""
    if isinstance(light, RectLight):
        c, n, t, b = light_frame(light)
        pts = light.corners() - c
        poly = np.stack([pts @ t, pts @ b], axis=1)
    elif isinstance(light, DiscLight):
        poly = disc_polygon(light.radius, disc_sides)
    else:
        raise TechniqueError(
            f"exact_soft: no exact answer for a {light.shape!r} area light: a sphere light's visibility is a "
            f"fraction of the area of the spherical cap P sees, which no union of flat projections measures "
            f"(rect lights are exact, disc lights a stated polygon); use raytrace:samples=N for it")
    x, y = poly[:, 0], poly[:, 1]
    if np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) < 0:
        poly = poly[::-1].copy()
    return np.ascontiguousarray(poly)


class ExactSoft(Technique):
    """Exact soft shadows of a rect (or polygonal disc) area light: per evaluated point, the area
    of the light hidden by the union of the occluders' projections (module docstring)."""

    name = "exact_soft"
    summary = ("exact soft shadows: per point, the union of the occluders' projections onto the light, "
               "its area by Green's theorem (compiled, no sampling)")
    cpu = True
    PASSES = ("project",)
    LIGHTS = frozenset({"area"})
    STYLE = PlotStyle("#17becf", "*")
    STATS = {"triangles": FIRST, "candidates_mean": FIRST, "candidates_max": FIRST, "passes": SUM,
             "preprocess_ms": SUM}
    PARAMS = {
        "disc_sides": Param(256, "disc lights: sides of the equal-area polygon standing for the disc "
                                 "(|V error| <= disc_error_bound: 3.9e-5 at 256)", min=8, max=4096),
        "cull_back_faces": Param(True, "skip back faces of closed meshes seen from outside their box (exact; "
                                       "false: project every triangle, as the oracle does)"),
    }

    def setup(self, frame, slot) -> None:
        """Untimed: the light's frame and polygon, the casters' triangles in a BVH, the per-part
        scratch buffers; compiles (or loads) the kernel."""
        t0 = time.perf_counter()
        light = slot.light
        if not isinstance(light, AreaLight):
            raise TechniqueError(f"{self.name}: needs an area light, got {light.type_name}")
        self.poly = light_polygon(light, self.disc_sides)
        self.cull = cull_polygon(self.poly)
        self.centre, self.normal, self.axis_t, self.axis_b = light_frame(light)
        x, y = self.poly[:, 0], self.poly[:, 1]
        self.light_area = 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))
        self.light_size = float(np.sqrt((self.poly ** 2).sum(axis=1)).max())
        tris, tobj, cullable, convex = [], [], [], []
        eye = np.asarray(frame.scene.camera.eye, np.float64)
        for obj in frame.scene.objects:
            if not obj.casts or len(obj.faces) == 0:
                continue
            t = obj.vertices[obj.faces].astype(np.float64)
            k = len(cullable)
            tris.append(t)
            tobj.append(np.full(len(t), k, np.int64))
            # closed and outward: the signed volume Σ v0 · (v1 × v2) / 6 is positive
            closed = bool(self.cull_back_faces and obj.edges.closed
                          and np.einsum("ij,ij->", t[:, 0], np.cross(t[:, 1], t[:, 2])) > 0)
            # the eye outside the mesh's box: every point it sees is outside the solid or on it
            eye_out = bool(np.any(eye < t.reshape(-1, 3).min(axis=0)) or np.any(eye > t.reshape(-1, 3).max(axis=0)))
            cullable.append(closed and eye_out)
            # convex: every vertex on or behind every face's plane (then a point on its surface
            # beyond a face's edge, where the G-buffer's plane hit can put it, is still outside)
            nrm = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
            verts = obj.vertices.astype(np.float64)
            convex.append(bool(closed and len(t) <= 4096 and np.all(
                np.einsum("fk,vk->fv", nrm, verts) - np.einsum("fk,fk->f", nrm, t[:, 0])[:, None]
                <= 1e-9 * np.linalg.norm(nrm, axis=1)[:, None] * max(1.0, np.abs(verts).max()))))
        tris = np.concatenate(tris) if tris else np.zeros((0, 3, 3))
        tobj = np.concatenate(tobj) if tobj else np.zeros(0, np.int64)
        self.triangles = len(tris)
        if len(tris):
            order, self.node_lo, self.node_hi, self.links = build_bvh(tris)
        else:
            order = np.zeros(0, np.int64)
            self.node_lo, self.node_hi = np.zeros((1, 3)), np.zeros((1, 3))
            self.links = np.array([[-1, 0, 0]], np.int64)  # an empty root: nothing to walk
        self.tris = np.ascontiguousarray(tris[order])
        self.tobj = np.ascontiguousarray(tobj[order])
        e1, e2 = self.tris[:, 1] - self.tris[:, 0], self.tris[:, 2] - self.tris[:, 0]
        self.tnorm = np.ascontiguousarray(np.cross(e1, e2))
        self.tlen = np.linalg.norm(self.tnorm, axis=1)
        self.cullable = np.asarray(cullable, np.bool_)
        self.convex = np.asarray(convex, np.bool_)
        self.evaluated = slot.evaluated
        self.points = np.ascontiguousarray(frame.compact_position[self.evaluated], np.float64)
        self.normals = np.ascontiguousarray(frame.compact_normal[self.evaluated], np.float64)
        # each point's caster index, and whether the G-buffer saw its triangle's inner side (a
        # silhouette pixel that rasterised a back face): then that mesh is not culled for it
        caster_of = np.full(len(frame.scene.objects), -1, np.int64)
        caster_of[[i for i, o in enumerate(frame.scene.objects) if o.casts and len(o.faces)]] = \
            np.arange(len(cullable))
        self.pobj = np.ascontiguousarray(caster_of[frame.compact_object[self.evaluated]])
        tri = frame.triangle_id.ravel()[frame.pixel_index][self.evaluated]
        self.pinside = np.ascontiguousarray(np.einsum("ij,ij->i", frame.triangle_normals[tri], self.normals) < 0)
        self.parts = max(1, min(cores(), len(self.points)))
        cap = max(1, min(len(self.tris), MAX_POLYGONS))
        self.scratch = [self._scratch(cap) for _ in range(self.parts)]
        self.vis = np.ones(len(self.points))
        self.cand = np.zeros(len(self.points), np.int64)
        # compile (or load from numba's cache) outside the timed pass
        self._run(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0, np.int64), np.zeros(0, np.bool_), np.zeros(0),
                  np.zeros(0, np.int64), 0, 1, self.scratch[0])
        self.preprocess_ms = 1e3 * (time.perf_counter() - t0)

    def _scratch(self, cap: int) -> tuple:
        """One part's buffers for up to ``cap`` candidate polygons."""
        return scratch_buffers(cap, len(self.links))

    def _run(self, points, normals, pobj, pinside, vout, cand, start, step, scratch) -> None:
        """The kernel over points[start::step]."""
        visibility_points(points, normals, pobj, pinside, start, step, self.tris, self.tnorm, self.tlen, self.tobj, self.cullable,
                          self.convex, self.node_lo, self.node_hi, self.links, self.centre, self.normal,
                          self.axis_t, self.axis_b, np.ascontiguousarray(self.poly[:, 0]),
                          np.ascontiguousarray(self.poly[:, 1]), np.ascontiguousarray(self.cull[:, 0]),
                          np.ascontiguousarray(self.cull[:, 1]), self.light_area, self.light_size, *scratch, vout,
                          cand)

    def render(self) -> None:
        """Timed: V at every evaluated point, the points interleaved over the cores (point i to
        part i mod parts: the penumbra, where the work is, is shared evenly)."""
        with self.timed_pass("project", cpu=True):
            parts = self.parts
            in_parts(lambda a, b: self._run(self.points, self.normals, self.pobj, self.pinside, self.vis, self.cand,
                                            a, parts,
                                            self.scratch[a]),
                     [(k, k + 1) for k in range(parts)])
        if len(self.cand) and self.cand.min() < 0:
            raise TechniqueError(f"{self.name}: {int((self.cand < 0).sum())} points have more than {MAX_POLYGONS} "
                                 f"candidate polygons (the buffers' size, MAX_POLYGONS)")

    def visibility(self) -> np.ndarray:
        """Float32 (H, W), row 0 = top: the exact visible fraction on evaluated pixels, 1 elsewhere."""
        vis = np.ones(len(self.evaluated), np.float32)
        vis[np.flatnonzero(self.evaluated)] = self.vis
        return self.frame.to_image(vis, fill=1.0)

    def work(self, counted: dict, stats: dict) -> dict:
        """Triangles clipped and projected on the CPU (those past the culling), summed over the points."""
        return {"project": {"cpu_triangles": int(self.cand.sum())}}

    def stats(self) -> dict:
        """Caster triangles, triangles clipped per evaluated point (mean, max), passes, setup time."""
        return {"triangles": self.triangles,
                "candidates_mean": float(self.cand.mean()) if len(self.cand) else 0.0,
                "candidates_max": int(self.cand.max()) if len(self.cand) else 0,
                "passes": 1, "preprocess_ms": self.preprocess_ms}
