"""The ray-traced ground truth against closed-form shadows (docs/architecture.md#evaluation-evaluator-in-shadowlabmeasurementpipelinepy), with every expected value
computed here, independently of the code under test.

A convex box's shadow on the plane y = 0 is the convex hull of its vertices projected from the
light (central projection for point and spot lights, parallel for directional and target-direct
lights). The floor points are this file's own pixel-centre rays (docs/architecture.md#conventions) met with y = 0;
they must equal the frame's exact points. Every evaluated floor pixel whose centre lies farther
than 0.01 px from a projected hull edge must agree with the closed form, and the evaluated
region must be the light's footprint (spot cone, target-direct cylinder) computed here.

The truth's rays start ε = offset_scale · max(‖P‖∞, extent) above the surface (docs/architecture.md#evaluation-evaluator-in-shadowlabmeasurementpipelinepy): a
ray from there passes the blocker ε · tan θ to the side of the one from P itself (θ: the
light's angle from the receiver's normal), so it may legitimately move a shadow edge by that
much, plus a few float32 ulps of the coordinates (Embree's vertices and the ray origins are
float32). Pixels within that band of an edge are not judged either: negligible at the origin,
it is 0.027 units (14 ulps) at 16384 — seen, and the reason the band is derived, not guessed.
"""
from __future__ import annotations

import matplotlib.image as mpimg
import numpy as np
import pytest
from scipy.spatial import ConvexHull

from shadowlab.gpu.frame import Frame
from shadowlab.commands.compare import compare
from shadowlab.scene import load_scene
from shadowlab.techniques.rays.raytrace import RayTraced
from shadowlab.truth.tracing import DEFAULT_OFFSET_SCALE, occluded, offset_origins

from helpers import floor_points, make_scene

BOXES = [
    {"name": "box_a", "mesh": "box", "size": [1.0, 0.6, 0.8], "translate": [0.3, 1.3, -0.2], "rotate": [20.0, 35.0, 10.0]},
    {"name": "box_b", "mesh": "box", "size": [0.7, 0.7, 0.7], "translate": [-1.6, 0.35, 1.0], "rotate": [0.0, 15.0, 0.0]},
    {"name": "box_c", "mesh": "box", "size": [0.3, 1.2, 0.3], "translate": [1.8, 2.0, 1.4], "rotate": [0.0, 0.0, 25.0]},
]
FLOOR = {"name": "floor", "mesh": "plane", "size": [14.0, 14.0]}
TD_DIRECTION = np.array([-0.15, -1.0, -0.1]) / np.linalg.norm([-0.15, -1.0, -0.1])
LIGHTS = {
    "point": {"type": "point", "position": [1.0, 5.0, 0.5]},
    "directional": {"type": "directional", "direction": [-0.35, -1.0, -0.25]},
    "spot": {"type": "spot", "position": [1.0, 5.0, 0.5], "direction": [-0.1, -1.0, 0.05], "alpha": 80.0, "beta": 50.0},
    "target_direct": {"type": "target_direct", "position": [0.8, 6.0, 0.6], "direction": TD_DIRECTION.tolist(),
                      "R": 3.2, "r": 2.0},
}
SIZE = (640, 480)


def unit(v):
    v = np.asarray(v, np.float64)
    return v / np.linalg.norm(v)


def project_to_floor(spec, verts):
    """Project (N, 3) vertices onto y = 0 along the light's rays, from the light's scene-file
    values; returns (N, 2) xz."""
    if "position" in spec and spec["type"] in ("point", "spot"):
        L = np.array(spec["position"])
        s = L[1] / (L[1] - verts[:, 1])
        return (L + (verts - L) * s[:, None])[:, [0, 2]]
    d = unit(spec["direction"])
    return (verts - d * (verts[:, 1] / d[1])[:, None])[:, [0, 2]]


def footprint_margin(spec, pts):
    """Signed distance-like value > 0 inside the light's footprint on the floor, < 0 outside
    (+inf for lights without one), from the scene-file values."""
    if spec["type"] == "spot":
        cos_phi = ((pts - spec["position"]) @ unit(spec["direction"])) / np.linalg.norm(pts - spec["position"], axis=1)
        return cos_phi - np.cos(np.radians(spec["alpha"] / 2))
    if spec["type"] == "target_direct":
        v = pts - spec["position"]
        t = v @ TD_DIRECTION
        rho = np.linalg.norm(v - t[:, None] * TD_DIRECTION, axis=1)
        return np.where(t > 0, spec["R"] - rho, -1.0)
    return np.full(len(pts), np.inf)


def hull_polygon(pts2):
    """Counter-clockwise convex hull vertices (K, 2)."""
    return pts2[ConvexHull(pts2).vertices]


def inside(poly, q):
    """Strictly-inside test of (M, 2) points in a CCW convex polygon."""
    a, b = poly, np.roll(poly, -1, axis=0)
    cross = (b[:, 0] - a[:, 0])[None] * (q[:, 1:2] - a[:, 1][None]) - (b[:, 1] - a[:, 1])[None] * (q[:, 0:1] - a[:, 0][None])
    return np.all(cross > 0, axis=1)


def to_pixels(camera, size, pts):
    """World points (N, 3) → pixel coordinates (N, 2) (x right, y down; pixel centres at +0.5),
    by the pinhole model of docs/architecture.md#conventions written here."""
    w, h = size
    forward = unit(camera.target - camera.eye)
    right = unit(np.cross(forward, camera.up))
    up = np.cross(right, forward)
    d = pts - camera.eye
    z = d @ forward
    half_h = np.tan(np.radians(camera.fov_y) / 2)
    x = (d @ right) / (z * half_h * w / h)
    y = (d @ up) / (z * half_h)
    return np.stack([(x + 1) / 2 * w, (1 - y) / 2 * h], 1)


def screen_distance(camera, size, segments_world, pix):
    """Distance in pixels from pixel centres (M, 2) to world segments (E, 2, 3) projected to the screen."""
    ends = to_pixels(camera, size, segments_world.reshape(-1, 3)).reshape(-1, 2, 2)
    a, b = ends[:, 0], ends[:, 1]
    ab = b - a
    t = np.clip(((pix[:, None, :] - a[None]) * ab[None]).sum(-1) / (ab * ab).sum(-1)[None], 0, 1)
    closest = a[None] + t[..., None] * ab[None]
    return np.linalg.norm(pix[:, None, :] - closest, axis=-1).min(axis=1)


def floor_distance(segments, pts):
    """World distance on the floor (xz) from points (M, 3) to segments (E, 2, 3)."""
    a, b, q = segments[:, 0, [0, 2]], segments[:, 1, [0, 2]], pts[:, [0, 2]]
    ab = b - a
    t = np.clip(((q[:, None, :] - a[None]) * ab[None]).sum(-1) / (ab * ab).sum(-1)[None], 0, 1)
    return np.linalg.norm(q[:, None, :] - (a[None] + t[..., None] * ab[None]), axis=-1).min(axis=1)


def check_closed_form(scene, light_spec, size, offset=np.zeros(3)):
    """Run the truth on ``scene`` (a floor at y = offset_y, then convex boxes) and compare it with
    the closed form; returns the number of floor pixels checked and shadowed."""
    frame = Frame(scene, *size)
    gt = RayTraced()
    gt.prepare(frame, 0)
    gt.render()
    vis = gt.visibility()
    local_spec = dict(light_spec)
    if "position" in light_spec:
        local_spec["position"] = np.array(light_spec["position"]) - offset
    polys, segments = [], []
    for obj in scene.objects[1:]:
        poly = hull_polygon(project_to_floor(local_spec, obj.vertices - offset))
        polys.append(poly)
        p3 = np.stack([poly[:, 0], np.zeros(len(poly)), poly[:, 1]], 1) + offset
        segments.append(np.stack([p3, np.roll(p3, -1, axis=0)], 1))
    segments = np.concatenate(segments)
    cam = scene.camera
    local_cam = type(cam)(cam.eye - offset, cam.target - offset, cam.up, cam.fov_y)
    expected_pts = floor_points(local_cam, *size)          # this file's own pixel-centre rays
    floor = frame.covered & (frame.object_id == 0)
    rows, cols = np.nonzero(floor)
    pts = expected_pts[rows, cols]
    # The frame's exact points are the pixel-centre rays met with the floor (docs/architecture.md#conventions).
    assert np.allclose(frame.position[rows, cols] - offset, pts, rtol=0, atol=1e-9 * (1 + np.abs(offset).max()))
    # The evaluated floor pixels are the light's footprint (the floor faces every light here).
    margin = footprint_margin(local_spec, pts)
    clear = np.abs(margin) > 1e-9
    assert np.array_equal(frame.evaluated(0)[rows, cols][clear], (margin > 0)[clear])
    ev = (margin > 0) & clear
    expected_shadow = np.zeros(len(pts), bool)
    for poly in polys:
        expected_shadow |= inside(poly, pts[:, [0, 2]])
    pix = np.stack([cols + 0.5, rows + 0.5], 1)
    if light_spec["type"] in ("point", "spot"):
        to_light = local_spec["position"] - pts
    else:
        to_light = np.broadcast_to(-unit(light_spec["direction"]), pts.shape)
    tan_theta = np.linalg.norm(to_light[:, [0, 2]], axis=1) / to_light[:, 1]  # light's angle from the floor normal
    coords = max(np.abs(offset).max(), np.abs(pts).max())
    eps = RayTraced().offset_scale * max(coords, scene.extent())
    band = eps * tan_theta + 4 * float(np.spacing(np.float32(coords)))
    far_from_edge = (screen_distance(cam, size, segments, pix) > 0.01) & (floor_distance(segments - offset, pts) > band)
    check = ev & far_from_edge
    got_shadow = vis[rows, cols] < 0.5
    mismatches = int(np.sum(got_shadow[check] != expected_shadow[check]))
    assert mismatches == 0, f"{mismatches} floor pixels disagree with the closed-form shadow"
    if light_spec["type"] in ("spot", "target_direct"):  # the footprint's edge crosses the view
        assert (margin < 0).sum() > 1000 and (margin > 0).sum() > 1000
    frame.release()
    return int(check.sum()), int(expected_shadow[check].sum()), float(far_from_edge.mean())


#: The inner loop keeps spot (central projection, a cone's footprint) and target_direct (parallel
#: projection, a cylinder's footprint); point and directional, the same projections without a
#: footprint, run with the slow tests (each case: a 640x480 frame and truth, ~1 s).
@pytest.mark.parametrize("light_kind", [k if k in ("spot", "target_direct") else pytest.param(k, marks=pytest.mark.slow)
                                        for k in LIGHTS])
def test_ground_truth_equals_projected_hull(light_kind):
    scene = make_scene([FLOOR] + BOXES, [LIGHTS[light_kind]])
    checked, shadowed, clear_of_edges = check_closed_form(scene, LIGHTS[light_kind], SIZE)
    assert clear_of_edges > 0.9
    assert checked > 30_000 and shadowed > 2000, "the test scene must have sizeable shadows and footprints"


def test_ground_truth_no_self_shadowing_far_from_origin():
    """RT1: the whole scene translated by 16384 units — a magnitude-scaled offset shows no acne:
    the truth still equals the closed form on every floor pixel away from the shadow's edges."""
    off = np.array([16384.0, 0.0, 16384.0])
    objs = [dict(FLOOR, translate=off.tolist())] + [dict(b, translate=list(np.add(b["translate"], off))) for b in BOXES]
    light = LIGHTS["directional"]
    scene = make_scene(objs, [light], eye=tuple(np.add([4.0, 6.0, 7.0], off)), target=tuple(off))
    checked, shadowed, _ = check_closed_form(scene, light, (320, 240), offset=off)
    assert checked > 20_000 and shadowed > 300


def test_ground_truth_sees_thin_sheet_on_floor():
    """RT3: a 0.1 mm sheet lying 0.1 mm above the floor: the shadow-ray offset is smaller than
    the gap, so rays from floor points under the sheet are blocked, and the sheet's own top
    does not shadow itself."""
    sheet = {"name": "sheet", "mesh": "box", "size": [2.0, 1e-4, 2.0], "translate": [0.0, 1.5e-4, 0.0]}
    light = {"type": "point", "position": [0.5, 5.0, 0.3]}
    scene = make_scene([FLOOR, sheet], [light], eye=(0.0, 6.0, 4.0), target=(0.0, 0.0, 0.0), fov_y=60.0)
    frame = Frame(scene, 200, 200)
    gt = RayTraced()
    gt.prepare(frame, 0)
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
    frame.release()
    assert sheet_px.sum() > 100 and (vis[sheet_px] > 0.5).all(), "the sheet's top must not shadow itself"


def test_image_convention_row_zero_is_the_top(tmp_path):
    """docs/architecture.md#conventions on an asymmetric scene, through to the saved files: a red box seen in the
    upper-left quadrant and its shadow are where this file's own pinhole model puts them, in
    the frame's arrays, in masks.npz and in the shaded PNG (row 0 = top)."""
    size = (160, 120)
    box = {"name": "red_box", "mesh": "box", "size": [0.6, 0.6, 0.6], "translate": [-2.5, 0.3, -2.0],
           "material": {"diffuse": [0.9, 0.05, 0.05], "specular": [0.0, 0.0, 0.0]}}
    light = {"type": "directional", "direction": [1.0, -1.0, 0.3]}
    floor = dict(FLOOR, material={"diffuse": [0.3, 0.3, 0.3], "specular": [0.0, 0.0, 0.0]})
    camera = {"eye": [0.0, 6.0, 6.0], "target": [0.0, 0.0, 0.0], "fov_y": 60.0}
    scene = make_scene([floor, box], [light], **camera)
    cam = scene.camera
    top = np.array([-2.5, 0.6, -2.0])                       # centre of the box's top face
    shadow = top + np.array([1.0, -1.0, 0.3]) * 0.6          # its shadow on the floor: 0.3 inside the hull
    (bx, by), (sx, sy) = to_pixels(cam, size, np.stack([top, shadow]))
    assert bx < size[0] / 2 and by < size[1] / 2, "the scene must put the box in the upper-left quadrant"
    frame = Frame(scene, *size)
    assert frame.object_id[int(by), int(bx)] == 1
    frame.release()
    out = compare(scene_file(tmp_path, [floor, box], [light], camera), ["shadow_volume"], size=size, out=tmp_path / "run", repeat=1, warmup=0)
    masks = np.load(out / "masks.npz")
    assert masks["ground_truth"][int(sy), int(sx)] == 0.0           # the box's shadow
    assert masks["ground_truth"][size[1] - 1 - int(sy), size[0] - 1 - int(sx)] == 1.0  # mirrored: lit floor
    png = mpimg.imread(out / "images" / "ground_truth_shaded.png")[..., :3]
    r, g, b = png[int(by), int(bx)]
    assert r > 3 * g and r > 3 * b, "the red box must be at the top-left of the saved image"


def scene_file(folder, objects, lights, camera):
    """Write a scene file from the plain dicts ``make_scene`` takes (docs/contracts.md#scene-files keys)."""
    import json

    def table(d):
        lines, sub = [], []
        for k, v in d.items():
            if isinstance(v, dict):
                sub.append((k, v))
            else:
                lines.append(f"{k} = {json.dumps(v)}")
        return lines, sub

    lines = ['name = "convention"', "[camera]"] + table(camera)[0]
    for light in lights:
        lines += ["[[lights]]"] + table(light)[0]
    for obj in objects:
        flat, sub = table(obj)
        lines += ["[[objects]]"] + flat
        for k, v in sub:
            lines += [f"[objects.{k}]"] + table(v)[0]
    path = folder / "scene.toml"
    path.write_text("\n".join(lines) + "\n")
    return path


# --------------------------------------------------------------------- exact points, bit for bit
def reference_exact_points(frame):
    """The straightforward computation the fast path in Frame.compute_exact_points must match
    bit for bit (issue 11): every pixel-centre ray, picked at the covered pixels, met in float64
    with the plane of the triangle the G-buffer saw; normals turned to the camera."""
    idx = np.flatnonzero(frame.covered)
    tri = frame.triangle_id.ravel()[idx]
    dirs = frame.camera.pixel_rays(frame.width, frame.height).reshape(-1, 3)[idx]
    origin, normals = frame.camera.eye, frame.triangle_normals[tri]
    denom = np.einsum("ij,ij->i", dirs, normals)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.einsum("ij,ij->i", frame.triangles[tri, 0] - origin, normals) / denom
    points = origin + t[:, None] * dirs
    facing = np.where((denom > 0)[:, None], -normals, normals)
    valid = np.isfinite(t) & (t > 0) & np.any(facing != 0, axis=1)
    return idx, points, facing, valid


def reference_offset_origins(frame, offset_scale):
    """The straightforward float32(P + offset_scale · max(‖P‖∞, extent) · N)."""
    p, n = frame.compact_position, frame.compact_normal
    scale = np.maximum(np.abs(p).max(axis=1), frame.scene.extent())
    return (p + (offset_scale * scale)[:, None] * n).astype(np.float32)


def same_bits(a, b):
    """Equal dtype, shape and bytes (NaNs and signed zeros included)."""
    a, b = np.ascontiguousarray(a), np.ascontiguousarray(b)
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


def assert_exact_points_match_reference(frame):
    idx, points, facing, valid = reference_exact_points(frame)
    assert same_bits(frame.pixel_index, idx)
    assert same_bits(frame.compact_position, points)
    assert same_bits(frame.compact_normal, facing)
    assert same_bits(frame.compact_valid, valid)
    assert same_bits(frame.compact_object, frame.object_id.ravel()[idx])
    for scale in (2.0 ** -18, 1e-3):
        assert same_bits(offset_origins(frame, scale, cached=False), reference_offset_origins(frame, scale))
    # the default origins, formed in the exact points' own pass (and replaced when it reruns)
    assert same_bits(offset_origins(frame), reference_offset_origins(frame, DEFAULT_OFFSET_SCALE))


@pytest.mark.parametrize("name", ["box_on_plane", "rm_bunny", "sm_far_origin"])
def test_exact_points_and_origins_are_bitwise_the_reference(name):
    """The fast exact points and offset origins equal the straightforward float64 computation
    bit for bit (positions, camera-facing normals, validity, float32 origins) on shipped scenes,
    at a size whose width and height share no factor with the tables' layout."""
    frame = Frame(load_scene(name), 203, 151)
    try:
        assert frame.covered.sum() > 1000
        assert_exact_points_match_reference(frame)
    finally:
        frame.release()


@pytest.mark.filterwarnings("ignore:invalid value:RuntimeWarning")
def test_exact_points_bitwise_on_degenerate_and_grazing_triangles():
    """The cases with no point (zero normal: 0/0 and x/0; a plane containing the ray: t = ±inf
    or NaN; hits behind the eye) give the reference's bits too, NaNs and infinities included:
    the frame's own triangles are altered after the G-buffer pass, then recomputed."""
    frame = Frame(load_scene("box_on_plane"), 160, 120)
    try:
        seen = np.unique(frame.triangle_id[frame.covered])
        assert len(seen) >= 4
        frame.triangle_normals = frame.triangle_normals.copy()
        frame.triangles = frame.triangles.copy()
        frame.triangle_normals[seen[0]] = 0.0                       # degenerate: no normal
        frame.triangle_normals[seen[1]] = -0.0                      # signed zeros
        frame.triangles[seen[2], 0] = frame.camera.eye              # plane through the eye: t = 0
        # a plane (nearly) containing the ray through one pixel of seen[3]: denom ≈ 0
        pix = np.flatnonzero(frame.triangle_id.ravel() == seen[3])[0]
        d = frame.camera.pixel_rays(frame.width, frame.height).reshape(-1, 3)[pix]
        n = np.cross(d, [0.0, 1.0, 0.0] if abs(d[1]) < 0.9 else [1.0, 0.0, 0.0])
        frame.triangle_normals[seen[3]] = n / np.linalg.norm(n)
        frame.compute_exact_points()
        assert not frame.compact_valid.all()
        assert not np.isfinite(frame.compact_position).all()
        assert_exact_points_match_reference(frame)
    finally:
        frame.release()
