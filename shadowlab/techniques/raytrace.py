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
not leak (Woop, Benthin & Wald 2013; hard case RT2).

Rays towards point and spot lights are unnormalised (light − origin) and stop at t = 1 − 2^-20,
so no normalisation is spent per light; directional rays travel along −direction to infinity,
target-direct rays to the light's plane.
"""
from __future__ import annotations

import numpy as np

from .base import Param, Technique

#: Where a point-light shadow ray stops, as a fraction of the way to the light.
_T_LIGHT = 1.0 - 2.0 ** -20
#: "Infinity" for rays towards directional lights (finite: Embree's tfar is a float32).
_T_INFINITE = np.float32(1e30)


def embree_scene(frame):
    """The frame's casters as one robust Embree scene (built once per frame, then cached)."""
    cache = frame.__dict__.setdefault("_cache", {})
    if "embree" not in cache:
        from embreex import rtcore_scene as rtcs
        from embreex.mesh_construction import TriangleMesh

        scene = rtcs.EmbreeScene(robust=True)
        meshes = [TriangleMesh(scene, o.vertices.astype(np.float32), o.faces.astype(np.int32))
                  for o in frame.scene.objects if o.casts]
        cache["embree"] = (scene, meshes)
    return cache["embree"][0]


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
    PARAMS = {
        "offset_scale": Param(2.0 ** -18, "shadow-ray origin offset along the normal, relative to "
                                          "max(|P|inf, scene extent)", min=0.0, max=1e-2),
    }

    def setup(self, frame, light_index: int) -> None:
        """Offset origins (per frame) and the evaluated pixels of this light."""
        self.frame, self.light = frame, frame.scene.lights[light_index]
        self.scene = embree_scene(frame) if frame.has_casters else None
        self.origins = self._origins(frame)
        self.evaluated = frame.compact_evaluated(light_index)
        self.eval_origins = np.ascontiguousarray(self.origins[self.evaluated])
        self.eval_points = frame.compact_position[self.evaluated]
        self.blocked = np.zeros(len(self.eval_origins), bool)

    def _origins(self, frame) -> np.ndarray:
        cache = frame.__dict__.setdefault("_cache", {})
        key = ("raytrace_origins", self.offset_scale)
        if key not in cache:
            p, n = frame.compact_position, frame.compact_normal
            scale = np.maximum(np.abs(p).max(axis=1), frame.scene.extent())
            cache[key] = (p + (self.offset_scale * scale)[:, None] * n).astype(np.float32)
        return cache[key]

    def render(self) -> None:
        """Trace one shadow ray per evaluated pixel."""
        if self.scene is None:
            return
        light, org = self.light, self.eval_origins
        if light.type_name in ("point", "spot"):
            dirs = light.position.astype(np.float32) - org
            tfar = np.full(len(org), _T_LIGHT, np.float32)
        elif light.type_name == "directional":
            dirs = np.broadcast_to((-light.direction).astype(np.float32), org.shape).copy()
            tfar = np.full(len(org), _T_INFINITE, np.float32)
        else:  # target_direct: along -direction back to the light's plane
            dirs = np.broadcast_to((-light.direction).astype(np.float32), org.shape).copy()
            tfar = ((self.eval_points - light.position) @ light.direction).astype(np.float32)
        self.blocked = occluded(self.scene, org, dirs, tfar)

    def visibility(self) -> np.ndarray:
        """1 where the shadow ray reached the light (and on pixels that are not evaluated)."""
        vis = np.ones(len(self.evaluated), np.float32)
        vis[np.flatnonzero(self.evaluated)[self.blocked]] = 0.0
        return self.frame.to_image(vis, fill=1.0)

    def stats(self) -> dict:
        """Shadow rays traced per render."""
        return {"rays": int(len(self.eval_origins))}
