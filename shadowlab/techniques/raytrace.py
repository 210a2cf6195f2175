"""The ray-traced ground truth (DESIGN §9): one shadow ray per evaluated pixel through Embree.

The ray starts at the exact float64 point where the pixel-centre camera ray meets the triangle
the G-buffer saw (computed once per frame by :class:`shadowlab.frame.Frame`). Embree works in
float32, so the point is moved off its own surface before rounding:

    origin = float32(P + ε · N),   ε = offset_scale · max(‖P‖∞, scene extent)

with N the unit geometric normal turned to the camera (for an evaluated pixel N·L > 0, so
this is also the light's side). The offset scales with the magnitude of the coordinates, as
in Wächter & Binder, "A Fast and Robust Method for Avoiding Self-Intersection" (Ray Tracing
Gems, ch. 6): a fixed offset is too small far from the origin (acne, hard case RT1) and too
large near it (skips thin occluders, RT3). With the default 2^-18 (≈ 32 float32 ulps) the
offset exceeds the float32 rounding of P (½ ulp) and Embree's own error, which is relative to
the scene's extent, by an order of magnitude, yet stays below 1e-5 of the scene's size.
Embree runs in robust (watertight) mode, so shadow rays through shared edges and vertices do
not leak (Woop, Benthin & Wald 2013; hard case RT2). Each light type says which rays reach it
(:meth:`shadowlab.lights.Light.shadow_rays`).

The Embree scene and the offset origins depend only on the frame (and the offset scale): they
are built once per frame and kept here, keyed weakly by the frame, so they go with it.
"""
from __future__ import annotations

import weakref

import numpy as np

from .base import Param, Technique

#: Per frame: the Embree scene of its casters (and the meshes that must outlive it).
_EMBREE: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()
#: Per frame: {offset_scale: float32 origins (M, 3)}.
_ORIGINS: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def embree_scene(frame):
    """The frame's casters as one robust Embree scene (built once per frame)."""
    if frame not in _EMBREE:
        from embreex import rtcore_scene as rtcs
        from embreex.mesh_construction import TriangleMesh

        scene = rtcs.EmbreeScene(robust=True)
        meshes = [TriangleMesh(scene, o.vertices.astype(np.float32), o.faces.astype(np.int32))
                  for o in frame.scene.objects if o.casts]
        _EMBREE[frame] = (scene, meshes)
    return _EMBREE[frame][0]


def offset_origins(frame, offset_scale: float, cached: bool = True) -> np.ndarray:
    """Shadow-ray origins of every covered pixel, float32 (M, 3) in compact order: the exact
    point moved ``offset_scale · max(‖P‖∞, scene extent)`` along the camera-facing normal.
    ``cached=False`` recomputes (for timing) without touching the cache."""
    per_frame = _ORIGINS.setdefault(frame, {})
    if cached and offset_scale in per_frame:
        return per_frame[offset_scale]
    p, n = frame.compact_position, frame.compact_normal
    # float32(p + (offset_scale · max(|p|∞, extent)) · n), bit for bit, with fewer temporaries:
    # the row maximum over the three columns (max is exact, in any order), the product and sum
    # in float64, rounded once to float32 on the way into ``origins``.
    scale = np.abs(p[:, 0])
    np.maximum(scale, np.abs(p[:, 1]), out=scale)
    np.maximum(scale, np.abs(p[:, 2]), out=scale)
    np.maximum(scale, frame.scene.extent(), out=scale)
    scale *= offset_scale
    moved = np.multiply(n, scale[:, None])
    moved += p
    origins = moved.astype(np.float32)
    if cached:
        per_frame[offset_scale] = origins
    return origins


def occluded(scene, origins: np.ndarray, directions: np.ndarray, tfar: np.ndarray) -> np.ndarray:
    """Embree occlusion of float32 rays (N, 3) up to ``tfar`` (N,): bool (N,), True = blocked."""
    if len(origins) == 0:
        return np.zeros(0, bool)
    hit = scene.run(origins, directions, dists=tfar, query="OCCLUDED")
    return hit != -1  # embreex returns -1 for unoccluded rays


class RayTraced(Technique):
    """Exact hard shadows: one shadow ray per evaluated pixel from the float64 hit point."""

    name = "raytrace"
    summary = "ray-traced ground truth (Embree, robust mode, magnitude-scaled offset)"
    cpu = True
    PASSES = ("trace",)
    PARAMS = {
        "offset_scale": Param(2.0 ** -18, "shadow-ray origin offset along the normal, relative to "
                                          "max(|P|inf, scene extent)", min=0.0, max=1e-2),
    }

    def setup(self, frame, light_index: int) -> None:
        """Offset origins (per frame) and the evaluated pixels of this light."""
        self.frame, self.light = frame, frame.scene.lights[light_index]
        self.scene = embree_scene(frame) if frame.has_casters else None
        self.origins = offset_origins(frame, self.offset_scale)
        self.evaluated = frame.compact_evaluated(light_index)
        self.eval_origins = np.ascontiguousarray(self.origins[self.evaluated])
        self.eval_points = frame.compact_position[self.evaluated]
        self.blocked = np.zeros(len(self.eval_origins), bool)

    def render(self) -> None:
        """Trace one shadow ray per evaluated pixel."""
        with self.timed_pass("trace", cpu=True):
            if self.scene is None:  # nothing casts: every ray reaches the light
                return
            dirs, tfar = self.light.shadow_rays(self.eval_origins, self.eval_points)
            self.blocked = occluded(self.scene, self.eval_origins, dirs, tfar)

    def visibility(self) -> np.ndarray:
        """1 where the shadow ray reached the light (and on pixels that are not evaluated)."""
        vis = np.ones(len(self.evaluated), np.float32)
        vis[np.flatnonzero(self.evaluated)[self.blocked]] = 0.0
        return self.frame.to_image(vis, fill=1.0)

    def stats(self) -> dict:
        """Shadow rays traced per render."""
        return {"rays": int(len(self.eval_origins))}
