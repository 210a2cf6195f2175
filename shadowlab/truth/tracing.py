"""Embree ray queries shared by everything on the CPU that traces rays: the ray-traced truth
(:mod:`shadowlab.techniques.rays.raytrace`), blob shadows (:mod:`shadowlab.techniques.geometric.blob`) and the
occluder-layer metric (:mod:`shadowlab.evaluation.occluder_layers`).

One Embree scene of a frame's casters and one set of offset ray origins per frame, built on
first use and kept here, keyed weakly by the frame, so they go with it. Embree runs in robust
(watertight) mode everywhere, so rays through shared edges and vertices do not leak (Woop,
Benthin & Wald 2013).

Ray origins (the truth's rule, docs/architecture.md#evaluation-evaluator-in-shadowlabmeasurementpipelinepy): the exact float64 surface point moved off its own
surface before rounding to float32,

    origin = float32(P + ε · N),   ε = offset_scale · max(‖P‖∞, scene extent),

N the unit geometric normal turned to the camera (Wächter & Binder, "A Fast and Robust Method
for Avoiding Self-Intersection", Ray Tracing Gems ch. 6: an offset that scales with the
coordinates' magnitude). :data:`DEFAULT_OFFSET_SCALE` is the truth's default, which every
metric that follows the truth's rays uses too.
"""
from __future__ import annotations

import weakref

import numpy as np

#: The truth's default ray-origin offset (× max(‖P‖∞, scene extent)): 2^-18, about 32 float32
#: ulps — above the rounding of P and Embree's own error, below 1e-5 of the scene's size.
DEFAULT_OFFSET_SCALE = 2.0 ** -18
#: Two exact float32 ray/triangle tests may disagree on a ray that passes this close to an edge
#: (× max(‖X‖∞, scene extent), X the crossing): about four float32 ulps, a tie either way.
TIE_DISTANCE_SCALE = 2.0 ** -21

#: Per frame: the Embree scene of its casters (and the meshes that must outlive it).
_CASTERS: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()
#: Per frame: the Embree scene of all its objects (camera rays; and the meshes it needs).
_OBJECTS: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()
#: Per frame: {offset_scale: float32 origins (M, 3)}.
_ORIGINS: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def mesh_scene(meshes) -> tuple[object, list]:
    """A robust Embree scene of ``meshes`` (an iterable of (vertices (V, 3), faces (F, 3))), and
    the Embree mesh objects that must stay alive as long as the scene is used. Geometry ids
    follow the order of ``meshes``."""
    from embreex import rtcore_scene as rtcs
    from embreex.mesh_construction import TriangleMesh

    scene = rtcs.EmbreeScene(robust=True)
    keep = [TriangleMesh(scene, np.asarray(v, np.float32), np.asarray(f, np.int32)) for v, f in meshes]
    return scene, keep


def object_scene(frame):
    """Every object of the frame (casters or not, in scene order) as one robust Embree scene,
    built once per frame; geometry id k is object k and primitive id f its face f — the camera
    rays of :mod:`shadowlab.truth.subpixel` find the visible triangle with it."""
    if frame not in _OBJECTS:
        _OBJECTS[frame] = mesh_scene((o.vertices, o.faces) for o in frame.scene.objects)
    return _OBJECTS[frame][0]


def caster_scene(frame):
    """The frame's casters (objects with ``casts``, in scene order) as one robust Embree scene,
    built once per frame; geometry id k is the k-th caster."""
    if frame not in _CASTERS:
        _CASTERS[frame] = mesh_scene((o.vertices, o.faces) for o in frame.scene.objects if o.casts)
    return _CASTERS[frame][0]


def caster_corners(frame) -> np.ndarray:
    """Float32 (3T, 4): the casters' triangle corners as :func:`caster_scene` holds them (each
    object's vertices rounded to float32, in scene order), padded to vec4 for a storage buffer —
    what the GPU techniques that test the truth's own rays exactly (the irregular z-buffer,
    per-triangle and partitioned shadow volumes) test them against. One zero triangle when
    nothing casts, so the buffer is never empty."""
    tris = [np.asarray(o.vertices, np.float32)[np.asarray(o.faces)].reshape(-1, 3)
            for o in frame.scene.objects if o.casts]
    corners = np.concatenate(tris) if tris else np.zeros((3, 3), np.float32)
    out = np.zeros((len(corners), 4), np.float32)
    out[:, :3] = corners
    return out


def offset_points(points: np.ndarray, normals: np.ndarray, extent: float,
                  offset_scale: float = DEFAULT_OFFSET_SCALE) -> np.ndarray:
    """The truth's ray-origin rule (module docstring) for float64 ``points`` (K, 3) with unit
    camera-facing ``normals`` (K, 3): float32 (K, 3) ``float32(P + offset_scale · max(‖P‖∞,
    extent) · N)``. The one formula behind :func:`offset_origins` (pixel centres) and
    :class:`shadowlab.truth.subpixel.SubpixelSamples` (sub-pixel samples), so both round alike."""
    # float32(p + (offset_scale · max(|p|∞, extent)) · n), bit for bit, in one compiled pass
    # (issue 27): the row maximum over the three columns (max is exact, in any order), the
    # product and sum in float64, rounded once to float32 (offset_points_reference in numpy).
    from ..util.compiled import in_parts, split
    from .compiled import offset_points as kernel

    points = np.ascontiguousarray(points, np.float64)
    normals = np.ascontiguousarray(normals, np.float64)

    origins = np.empty((len(points), 3), np.float32)
    nan_rows = in_parts(lambda a, b: kernel(points[a:b], normals[a:b], float(extent), float(offset_scale),
                                            origins[a:b]), split(len(points)))
    if sum(nan_rows):
        # Points with no hit (NaN coordinates) give NaN origins, never traced; the numpy formula
        # decides their NaNs' sign bits, and numpy's own choice depends on where in the array a
        # row lies (its SIMD lanes against the scalar tail), so only the whole array recomputed
        # the old way keeps those bits.
        return offset_points_reference(points, normals, extent, offset_scale)
    return origins


def offset_points_reference(points: np.ndarray, normals: np.ndarray, extent: float,
                            offset_scale: float = DEFAULT_OFFSET_SCALE) -> np.ndarray:
    """:func:`offset_points` in numpy (the formula before issue 27), the reference the compiled
    pass is tested against bit for bit."""
    p, n = points, normals
    scale = np.abs(p[:, 0])
    np.maximum(scale, np.abs(p[:, 1]), out=scale)
    np.maximum(scale, np.abs(p[:, 2]), out=scale)
    np.maximum(scale, extent, out=scale)
    scale *= offset_scale
    moved = np.multiply(n, scale[:, None])
    moved += p
    return moved.astype(np.float32)


def set_frame_origins(frame, origins: dict) -> None:
    """Replace the frame's cached origins with ``origins`` ({offset_scale: float32 (M, 3)}):
    :meth:`shadowlab.gpu.frame.Frame.compute_exact_points` forms the default ones in its own pass,
    and a recomputed frame must not keep origins of its earlier points. The arrays are made
    read-only: every ray tracer of the frame shares them."""
    for arr in origins.values():
        arr.flags.writeable = False
    _ORIGINS[frame] = dict(origins)


def offset_origins(frame, offset_scale: float = DEFAULT_OFFSET_SCALE, cached: bool = True) -> np.ndarray:
    """Shadow-ray origins of every covered pixel, float32 (M, 3) in compact order: the exact
    point moved ``offset_scale · max(‖P‖∞, scene extent)`` along the camera-facing normal
    (:func:`offset_points`). ``cached=False`` recomputes (for timing) without touching the cache."""
    per_frame = _ORIGINS.setdefault(frame, {})
    if cached and offset_scale in per_frame:
        return per_frame[offset_scale]
    origins = offset_points(frame.compact_position, frame.compact_normal, frame.scene.extent(), offset_scale)
    if cached:
        origins.flags.writeable = False  # shared by every ray tracer of the frame
        per_frame[offset_scale] = origins
    return origins


def occluded(scene, origins: np.ndarray, directions: np.ndarray, tfar: np.ndarray) -> np.ndarray:
    """Embree occlusion of float32 rays (N, 3) up to ``tfar`` (N,): bool (N,), True = blocked."""
    if len(origins) == 0:
        return np.zeros(0, bool)
    hit = scene.run(origins, directions, dists=tfar, query="OCCLUDED")
    return hit != -1  # embreex returns -1 for unoccluded rays


def occlusion_ids(scene, origins: np.ndarray, directions: np.ndarray, tfar: np.ndarray) -> np.ndarray:
    """Embree occlusion of float32 rays (N, 3) up to ``tfar`` (N,) as embreex answers it: int32
    (N,), −1 where the ray is unoccluded (what :func:`occluded` compares against), for callers
    that count the answers in compiled code without a bool copy."""
    if len(origins) == 0:
        return np.zeros(0, np.int32)
    return scene.run(origins, directions, dists=tfar, query="OCCLUDED")


def nearest_hits(scene, origins: np.ndarray, directions: np.ndarray, tfar: np.ndarray) -> dict:
    """Embree's nearest intersection of float32 rays (N, 3) up to ``tfar`` (N,): a dict of
    arrays (N,) ``geomID`` (−1: no hit), ``primID``, ``tfar`` (the hit's ray parameter) and
    ``Ng`` (N, 3) (the hit triangle's unnormalised geometric normal)."""
    return scene.run(np.asarray(origins, np.float32), np.asarray(directions, np.float32),
                     dists=np.asarray(tfar, np.float32), query="INTERSECT", output=1)


def edge_distances(origins: np.ndarray, directions: np.ndarray, tfar: np.ndarray, corners: np.ndarray,
                   chunk: int = 4096) -> np.ndarray:
    """Per ray (K,), the world distance from where it crosses a triangle's plane to the nearest
    point of that triangle's edges (the segments, not their lines), minimised over the
    triangles whose planes it crosses within (0, ``tfar``]: float64 arithmetic on the float32
    rays and the triangles' float32 corners (T, 3, 3), as the tracers see them. Where two
    exact-in-float32 tests disagree about a ray (Embree's and the irregular z-buffer's), this
    says whether it was a tie: a ray that passes within float32 resolution of an edge can fall
    either way. Inf where a ray crosses no triangle's plane in range. Brute force over every
    triangle: for the few rays two tracers disagree on."""
    corners = np.asarray(corners, np.float64)
    a, e1, e2 = corners[:, 0], corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]
    ends = np.roll(corners, -1, axis=1)                # edge k runs from corner k to corner k + 1
    out = np.full(len(origins), np.inf)
    for k, (o, d, tf) in enumerate(zip(np.asarray(origins, np.float64), np.asarray(directions, np.float64),
                                       np.asarray(tfar, np.float64))):
        for s in range(0, len(corners), chunk):
            sl = slice(s, s + chunk)
            normal = np.cross(e1[sl], e2[sl])
            with np.errstate(divide="ignore", invalid="ignore"):
                t = np.einsum("ij,ij->i", a[sl] - o, normal) / (normal @ d)
            crossing = (t > 0) & (t <= tf) & np.isfinite(t)
            if not crossing.any():
                continue
            x = o + t[crossing, None] * d                  # the crossing points, in the triangles' planes
            p0, edge = corners[sl][crossing], ends[sl][crossing] - corners[sl][crossing]  # (C, 3 edges, 3)
            with np.errstate(divide="ignore", invalid="ignore"):
                u = np.einsum("cij,cij->ci", x[:, None, :] - p0, edge) / np.einsum("cij,cij->ci", edge, edge)
            u = np.clip(np.nan_to_num(u), 0.0, 1.0)        # the nearest point of each segment
            dist = np.linalg.norm(x[:, None, :] - (p0 + u[..., None] * edge), axis=2).min(axis=1)
            out[k] = min(out[k], float(dist.min()))
    return out
