"""How many distinct casters lie between each evaluated point and a light: the region where
casters overlap in depth, which the light-bleeding metric judges (docs/hard-cases.md, issue 13).

Filtered shadow maps summarise the depths under a filter by a few moments; where two casters at
different depths from the light fall under one filter footprint, the moments describe a
two-depth distribution and the Chebyshev (VSM) or moment (MSM) bound lets light through the
shadow of the lower one (Donnelly & Lauritzen 2006 §5; Lauritzen, GPU Gems 3 ch. 8 "light
bleeding"). The truth knows where that can happen: points whose segment to the light crosses
two or more caster objects.

Counting uses the truth's machinery (:mod:`shadowlab.truth.tracing`): the same Embree scene of the
casters, the same offset ray origins and shadow rays. Each ray is intersected,
then restarted just past its hit (a step of :data:`STEP_SCALE` × the scene's extent along the
ray) until it has met two distinct objects or reaches the light; a closed caster is entered
and left (two hits, one object). An area light counts as its centre, like every hard technique.
The first of those intersections also gives, free, each point's distance to its first caster
(:func:`first_occluder_distance`): the casters' height above their shadows, which the
evaluator compares a shadow map's bias with (issue 35).
"""
from __future__ import annotations

import weakref

import numpy as np

from ..truth.tracing import caster_scene, nearest_hits, offset_origins

#: The restart step past a hit, × the scene's extent: far above float32 rounding of the hit
#: point (2^-24 relative), far below any gap between two casters a scene means.
STEP_SCALE = 2.0 ** -16
#: At most this many intersections per ray (two per closed object crossed, and a few more
#: for coplanar or touching faces); a ray still going after that counts what it has met.
MAX_HITS = 32
#: Per frame: {id(light): (light, the layers image)} (a study judges many configurations on one
#: frame); keyed by the light object, which the entry keeps alive.
_CACHE: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def occluder_layers(frame, slot) -> np.ndarray:
    """Per pixel, how many distinct caster objects lie on the segment from the evaluated point to
    the slot's light (its centre for an area light): 0, 1, or 2 for two or more. Int8 (height,
    width), row 0 = top; 0 on pixels not evaluated. ``slot``: a
    :class:`~shadowlab.gpu.frame.LightSlot` or a scene light's index. Casters are the scene's
    objects with ``casts``."""
    return _layers_and_distances(frame, slot)[0]


def first_occluder_distance(frame, slot) -> np.ndarray:
    """Per pixel, the world distance along the shadow ray from the evaluated point (its offset
    ray origin) to the first caster it meets on the way to the slot's light (its centre for an
    area light): the casters' height above that point, which a shadow map's bias must stay
    below. Float32 (height, width), row 0 = top; NaN where the ray meets no caster or the pixel
    is not evaluated. Free beside :func:`occluder_layers`: the first intersection of its rays
    (computed and cached together)."""
    return _layers_and_distances(frame, slot)[1]


def _layers_and_distances(frame, slot) -> tuple[np.ndarray, np.ndarray]:
    """(:func:`occluder_layers`, :func:`first_occluder_distance`), computed once per frame and light."""
    slot = frame.as_slot(slot)
    per_frame = _CACHE.setdefault(frame, {})
    key = id(slot.light)
    if key not in per_frame:
        per_frame[key] = (slot.light, _count_layers(frame, slot))
    return per_frame[key][1]


def _count_layers(frame, slot) -> tuple[np.ndarray, np.ndarray]:
    """:func:`occluder_layers` and :func:`first_occluder_distance`, computed."""
    cap = 2  # a ray stops at its second distinct object: all the bleeding region needs
    light = slot.light
    evaluated = slot.evaluated
    out = np.zeros(len(evaluated), np.int8)
    distance = np.full(len(evaluated), np.nan, np.float32)
    casters = [i for i, o in enumerate(frame.scene.objects) if o.casts]
    if not casters or not evaluated.any():
        return (frame.to_image(out, fill=0, dtype=np.int8),
                frame.to_image(distance, fill=np.nan, dtype=np.float32))
    scene = caster_scene(frame)
    origins = offset_origins(frame)[evaluated].astype(np.float64)
    dirs, tfar = light.shadow_rays(origins.astype(np.float32), frame.compact_position[evaluated])
    dirs = dirs.astype(np.float64)
    step = STEP_SCALE * frame.scene.extent() / np.maximum(np.linalg.norm(dirs, axis=1), 1e-30)
    t0 = np.zeros(len(origins))  # how far along its ray each restart begins
    first = np.full(len(origins), -1, np.int64)  # the first object met, per ray
    count = np.zeros(len(origins), np.int8)
    live = np.arange(len(origins))
    first_t = np.full(len(origins), np.nan)  # the first hit's ray parameter, per ray
    for _ in range(MAX_HITS):
        if len(live) == 0:
            break
        o = (origins[live] + t0[live, None] * dirs[live]).astype(np.float32)
        remaining = (tfar[live] - t0[live]).astype(np.float32)
        hit = nearest_hits(scene, o, dirs[live], np.maximum(remaining, 0))
        geom = hit["geomID"].astype(np.int64)
        met = geom >= 0
        obj = np.where(met, np.asarray(casters)[np.maximum(geom, 0)], -1)
        new = met & (obj != first[live])
        count[live[new]] += 1
        first[live[new & (first[live] < 0)]] = obj[new & (first[live] < 0)]
        fresh = met & np.isnan(first_t[live])
        first_t[live[fresh]] = t0[live[fresh]] + hit["tfar"][fresh].astype(np.float64)
        t0[live] += np.where(met, hit["tfar"].astype(np.float64) + step[live], 0.0)
        live = live[met & (count[live] < cap)]
    out[evaluated] = np.minimum(count, cap)
    distance[evaluated] = first_t * np.linalg.norm(dirs, axis=1)  # rays are unnormalised
    return (frame.to_image(out, fill=0, dtype=np.int8), frame.to_image(distance, fill=np.nan, dtype=np.float32))
