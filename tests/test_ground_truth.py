"""The ray-traced ground truth against closed-form shadows (DESIGN §9, issue: spine).

A convex box's shadow on the plane y = 0 is the convex hull of its vertices projected from the
light (central projection for a point light, parallel for a directional light). Every floor
pixel whose centre lies farther than 0.01 px from the projected hull boundary must agree.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import ConvexHull

from shadowlab.frame import Frame
from shadowlab.lights import PointLight
from shadowlab.techniques.raytrace import RayTraced, occluded
from shadowlab import transforms as tf

from conftest import make_scene

BOXES = [
    {"name": "box_a", "mesh": "box", "size": [1.0, 0.6, 0.8], "translate": [0.3, 1.3, -0.2], "rotate": [20.0, 35.0, 10.0]},
    {"name": "box_b", "mesh": "box", "size": [0.7, 0.7, 0.7], "translate": [-1.6, 0.35, 1.0], "rotate": [0.0, 15.0, 0.0]},
    {"name": "box_c", "mesh": "box", "size": [0.3, 1.2, 0.3], "translate": [1.8, 2.0, 1.4], "rotate": [0.0, 0.0, 25.0]},
]
FLOOR = {"name": "floor", "mesh": "plane", "size": [14.0, 14.0]}
LIGHTS = {
    "point": {"type": "point", "position": [1.0, 5.0, 0.5]},
    "directional": {"type": "directional", "direction": [-0.35, -1.0, -0.25]},
}


def project_to_floor(light, verts):
    """Project (N, 3) vertices onto y = 0 along the light's rays; returns (N, 2) xz."""
    if isinstance(light, PointLight):
        L = light.position
        s = L[1] / (L[1] - verts[:, 1])
        return (L + (verts - L) * s[:, None])[:, [0, 2]]
    d = light.direction
    return (verts - d * (verts[:, 1] / d[1])[:, None])[:, [0, 2]]


def hull_polygon(pts2):
    """Counter-clockwise convex hull vertices (K, 2)."""
    return pts2[ConvexHull(pts2).vertices]


def inside(poly, q):
    """Strictly-inside test of (M, 2) points in a CCW convex polygon."""
    a, b = poly, np.roll(poly, -1, axis=0)
    cross = (b[:, 0] - a[:, 0])[None] * (q[:, 1:2] - a[:, 1][None]) - (b[:, 1] - a[:, 1])[None] * (q[:, 0:1] - a[:, 0][None])
    return np.all(cross > 0, axis=1)


def screen_distance(frame, segments_world, pix):
    """Distance in pixels from pixel centres (M, 2) to world segments (E, 2, 3) projected to the screen."""
    ends = tf.transform_points(frame.view_projection, segments_world.reshape(-1, 3)).reshape(-1, 2, 3)
    sx = (ends[..., 0] + 1) / 2 * frame.width
    sy = (1 - ends[..., 1]) / 2 * frame.height
    a = np.stack([sx[:, 0], sy[:, 0]], 1)
    b = np.stack([sx[:, 1], sy[:, 1]], 1)
    ab = b - a
    t = np.clip(((pix[:, None, :] - a[None]) * ab[None]).sum(-1) / (ab * ab).sum(-1)[None], 0, 1)
    closest = a[None] + t[..., None] * ab[None]
    return np.linalg.norm(pix[:, None, :] - closest, axis=-1).min(axis=1)


@pytest.mark.parametrize("light_kind", ["point", "directional"])
def test_ground_truth_equals_projected_hull(light_kind):
    scene = make_scene([FLOOR] + BOXES, [LIGHTS[light_kind]])
    frame = Frame(scene, 640, 480)
    gt = RayTraced()
    gt.setup(frame, 0)
    gt.render()
    vis = gt.visibility()
    light = scene.lights[0]
    polys, segments = [], []
    for obj in scene.objects[1:]:
        poly = hull_polygon(project_to_floor(light, obj.vertices))
        polys.append(poly)
        p3 = np.stack([poly[:, 0], np.zeros(len(poly)), poly[:, 1]], 1)
        segments.append(np.stack([p3, np.roll(p3, -1, axis=0)], 1))
    segments = np.concatenate(segments)
    ev = frame.evaluated(0) & (frame.object_id == 0)  # floor pixels
    rows, cols = np.nonzero(ev)
    pts = frame.position[rows, cols]
    expected_shadow = np.zeros(len(pts), bool)
    for poly in polys:
        expected_shadow |= inside(poly, pts[:, [0, 2]])
    pix = np.stack([cols + 0.5, rows + 0.5], 1)
    far_from_edge = screen_distance(frame, segments, pix) > 0.01
    got_shadow = vis[rows, cols] < 0.5
    assert far_from_edge.sum() > 0.9 * len(pts)
    assert expected_shadow[far_from_edge].sum() > 2000, "the test scene must have sizeable shadows"
    mismatches = np.sum(got_shadow[far_from_edge] != expected_shadow[far_from_edge])
    assert mismatches == 0, f"{mismatches} floor pixels disagree with the closed-form shadow"


def test_ground_truth_no_self_shadowing_far_from_origin():
    """RT1: the scene translated by 16384 units — a magnitude-scaled offset shows no acne."""
    off = [16384.0, 0.0, 16384.0]
    objs = [dict(FLOOR, translate=off), dict(BOXES[0], translate=list(np.add(BOXES[0]["translate"], off)))]
    light = {"type": "directional", "direction": [-0.3, -1.0, -0.2]}
    scene = make_scene(objs, [light], eye=tuple(np.add([4.0, 6.0, 7.0], off)), target=tuple(off))
    frame = Frame(scene, 320, 240)
    gt = RayTraced()
    gt.setup(frame, 0)
    gt.render()
    vis = gt.visibility()
    ev = frame.evaluated(0)
    box_faces_lit = ev & (frame.object_id == 1)
    # Faces of the box that face the light are lit; the shadow on the floor stays a few % of it.
    assert (vis[box_faces_lit] > 0.5).all()
    floor = ev & (frame.object_id == 0)
    assert 0.005 < (vis[floor] < 0.5).mean() < 0.2


def test_ground_truth_sees_thin_sheet_on_floor():
    """RT3: a 0.1 mm sheet lying 0.1 mm above the floor: the shadow-ray offset is smaller than
    the gap, so rays from floor points under the sheet are blocked, and the sheet's own top
    does not shadow itself."""
    sheet = {"name": "sheet", "mesh": "box", "size": [2.0, 1e-4, 2.0], "translate": [0.0, 1.5e-4, 0.0]}
    light = {"type": "point", "position": [0.5, 5.0, 0.3]}
    scene = make_scene([FLOOR, sheet], [light], eye=(0.0, 6.0, 4.0), target=(0.0, 0.0, 0.0), fov_y=60.0)
    frame = Frame(scene, 200, 200)
    gt = RayTraced()
    gt.setup(frame, 0)
    floor = frame.compact_object == 0
    origins = gt.origins[floor]
    lift = origins[:, 1].astype(np.float64)
    assert (lift > 0).all() and lift.max() < 1e-4, "offset must stay below the 0.1 mm gap"
    # Move the floor's actual ray origins under the sheet (same height above the floor).
    rng = np.random.default_rng(0)
    under = origins[:2000].copy()
    under[:, [0, 2]] = rng.uniform(-0.5, 0.5, size=(len(under), 2)).astype(np.float32)
    dirs = (scene.lights[0].position.astype(np.float32) - under)
    blocked = occluded(gt.scene, under, dirs, np.full(len(under), 0.999, np.float32))
    assert blocked.all()
    gt.render()
    vis = gt.visibility()
    sheet_px = frame.evaluated(0) & (frame.object_id == 1)
    assert sheet_px.sum() > 100 and (vis[sheet_px] > 0.5).all(), "the sheet's top must not shadow itself"
