"""The texel-footprint metric (Lloyd et al.'s m, shadowlab.evaluation.texel_footprint): closed-form cases
(a sun straight down on a floor under a camera straight down, and under a tilted camera),
the halving of m when the map's resolution doubles, a point light's cube map, the metrics
columns of the map techniques, the edge-on fallback and the Jacobian's singular values."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from helpers import MEDIUM, SMALL, floor_points
from shadowlab.measurement.pipeline import measure
from shadowlab.scene import parse_scene
from shadowlab.techniques import TechniqueError, from_spec
from shadowlab.techniques.maps.toolkit import cube_face_index
from shadowlab.evaluation.texel_footprint import (
    footprint_columns, footprint_from_jacobian, footprint_image, neighbour_rays, screen_neighbours,
    tangent_hits,
)

SUN_DOWN = {"type": "directional", "direction": [0.0, -1.0, 0.0]}


def floor_scene(eye, target, up, light=SUN_DOWN, fov_y=50.0):
    """A 10 x 10 floor (y = 0, the only receiver) under a box that casts but does not receive."""
    data = {"name": "footprint", "camera": {"eye": list(eye), "target": list(target), "up": list(up), "fov_y": fov_y},
            "lights": [light],
            "objects": [{"name": "floor", "mesh": "plane", "size": [10.0, 10.0]},
                        {"name": "box", "mesh": "box", "size": [1.0, 1.0, 1.0], "translate": [0.3, 1.5, -0.2],
                         "receives": False}]}
    return parse_scene(data, "<footprint>")


def measured_with_map(lab, scene, spec, size):
    """(Measurement, the map's face 0 (LightView), resolution) of ``spec`` on the shared frame."""
    tech = from_spec(spec)
    m = measure(tech, lab.frame(scene, size), 0, repeat=1, warmup=0, release=False)
    try:
        face = tech.atlas.faces[0]
    finally:
        tech.release()
    return m, face, tech.resolution


def predicted_footprint(face, resolution: int, here, right, below) -> np.ndarray:
    """m predicted for an orthographic map straight down onto the floor, from floor points
    (M, 3) of the pixel and of its neighbours: the light view's x/y axes scaled by the
    orthographic projection's texels per world unit give the texel offsets; m = 1/σ_min."""
    scale = np.array([face.proj[0, 0], face.proj[1, 1]]) * resolution / 2.0   # texels per world unit
    axes = face.view[:2, :3]
    j = np.stack([scale * ((right - here) @ axes.T), scale * ((below - here) @ axes.T)], axis=2)
    return 1.0 / np.linalg.svd(j, compute_uv=False)[:, 1]


def test_straight_down_is_texel_over_pixel(lab):
    """Camera and sun straight down on a floor: every floor pixel's m is the map's texel world
    size over the pixel's world size (height · 2 tan(fov/2) / image height) — measured to agree
    to 2.5e-9 relative (m is stored as float32); bound 1e-3."""
    scene = floor_scene((0.0, 6.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, -1.0))
    size = MEDIUM
    m, face, _ = measured_with_map(lab, scene, "shadow_map:resolution=512", size)
    frame = lab.frame(scene, size)
    pixel = 6.0 * 2.0 * np.tan(np.radians(50.0) / 2.0) / size[1]
    ev = frame.evaluated(0)
    assert ev.sum() > 0.5 * size[0] * size[1]
    values = m.footprint[ev]
    assert np.isfinite(values).all()
    np.testing.assert_allclose(values, face.texel_world / pixel, rtol=1e-3)
    assert np.isnan(m.footprint[~ev]).all()
    assert m.stats["texel_footprint_p50"] == pytest.approx(face.texel_world / pixel, rel=1e-3)


def test_tilted_camera_near_and_far(lab):
    """A camera looking down the floor at a slant: m per pixel as predicted from the floor
    points of the pixel-centre rays (written independently in conftest) through the fitted
    orthographic map (measured max relative difference 6e-8, float32 rounding; bound 1e-3), and near pixels
    (bottom of the image) see larger texels than far ones (top): measured ratio of the medians
    of the bottom and top tenths of the floor 2.87 (0.676 / 0.235 px); bound > 2."""
    scene = floor_scene((0.0, 3.0, 7.0), (0.0, 0.0, -1.0), (0.0, 1.0, 0.0))
    size = (321, 241)
    m, face, res = measured_with_map(lab, scene, "shadow_map:resolution=1024,fit=receivers", size)
    frame = lab.frame(scene, size)
    pts = floor_points(frame.camera, *size)
    ev = frame.evaluated(0)
    ev[-1, :] = False  # the prediction needs the neighbour below and to the right inside the image
    ev[:, -1] = False
    rows, cols = np.nonzero(ev)
    predicted = predicted_footprint(face, res, pts[rows, cols], pts[rows, cols + 1], pts[rows + 1, cols])
    np.testing.assert_allclose(m.footprint[rows, cols], predicted, rtol=1e-3)
    floor_rows = np.flatnonzero(ev.any(axis=1))
    tenth = max(1, len(floor_rows) // 10)
    far = np.nanmedian(m.footprint[floor_rows[:tenth]][ev[floor_rows[:tenth]]])
    near = np.nanmedian(m.footprint[floor_rows[-tenth:]][ev[floor_rows[-tenth:]]])
    assert near > 2.0 * far, (near, far)


@pytest.mark.parametrize("scene", ["sun_scene", "sm_aliasing"])
def test_doubling_the_resolution_halves_m(lab, scene):
    """A fitted map at twice the resolution has texels half the size: p50 halves (measured
    ratio 2.0000 on both scenes at 320x240; bound 2 %)."""
    df = lab.rows(scene, ["shadow_map:resolution=1024", "shadow_map:resolution=2048"], MEDIUM)
    coarse, fine = df["texel_footprint_p50"]
    assert coarse / fine == pytest.approx(2.0, rel=0.02)
    assert (df["texel_footprint_p50"] <= df["texel_footprint_p95"]).all()
    assert (df["texel_footprint_p95"] <= df["texel_footprint_max"]).all()


def test_cube_map_point_light_is_finite_everywhere(lab):
    """A point light's cube map (sm_point_cube): m finite and positive on every evaluated pixel,
    (measured 0.091 to 298 px), and the pixels use all six faces (measured 4152 to 19504 pixels each)."""
    size = MEDIUM
    tech = from_spec("shadow_map:projection=cube,resolution=512")
    frame = lab.frame("sm_point_cube", size)
    m = measure(tech, frame, 0, repeat=1, warmup=0, release=False)
    try:
        assert len(tech.atlas.faces) == 6
        faces = tech.face_index(frame.compact_position[frame.compact_evaluated(0)])
    finally:
        tech.release()
    values = m.footprint[frame.evaluated(0)]
    assert len(values) > 1000
    assert np.isfinite(values).all() and (values > 0).all()
    assert len(np.unique(faces)) == 6


def test_cube_face_index_follows_the_major_axis():
    """The face order of CUBE_FACES (+x, −x, +y, −y, +z, −z) and the shader's tie-breaking
    (x before y before z)."""
    light = np.array([1.0, 2.0, 3.0])
    d = np.array([[2, 1, 0], [-2, 1, 0], [0, 3, 1], [0, -3, 1], [0, 1, 2], [0, 1, -2], [1, 1, 1], [0, -1, 1]], float)
    np.testing.assert_array_equal(cube_face_index(light + d, light, 6), [0, 1, 2, 3, 4, 5, 0, 3])
    np.testing.assert_array_equal(cube_face_index(light + d, light, 1), np.zeros(8, int))


@pytest.mark.parametrize("scene,specs", [
    ("box_on_plane", ["shadow_map", "filtered_map", "shadow_volume"]),
    ("soft_contact_hardening", ["pcss", "shadow_map:light_samples=4"]),
])
def test_columns_for_map_techniques_only(lab, scene, specs):
    """texel_footprint_p50/p95/max on every map configuration (finite, positive), NaN on the
    others (shadow volumes have no texels)."""
    df = lab.rows(scene, specs, SMALL)
    cols = ["texel_footprint_p50", "texel_footprint_p95", "texel_footprint_max"]
    for spec in specs:
        values = df.loc[spec, cols].to_numpy(dtype=float)
        if spec == "shadow_volume":
            assert np.isnan(values).all()
        else:
            assert (np.isfinite(values) & (values > 0)).all(), (spec, values)


def test_no_map_no_footprint(lab):
    """A technique without texel coordinates gets a clear TechniqueError."""
    tech = from_spec("shadow_volume")
    with pytest.raises(TechniqueError, match="no shadow map"):
        footprint_image(lab.frame("box_on_plane", SMALL), 0, tech)


def test_edge_on_neighbour_uses_the_other_side(lab):
    """Where the tangent plane turns away from the right neighbour's ray (the ray meets it behind
    the eye), the left neighbour's hit is taken with the sign turned."""
    frame = lab.frame("box_on_plane", (160, 120))
    cam = frame.camera
    fake = SimpleNamespace(camera=cam, width=160, height=120)
    rows, cols = np.array([60]), np.array([80])
    eye = np.asarray(cam.eye, float)
    d = neighbour_rays(cam, 160, 120, rows, cols)[0]
    p = eye + 5.0 * d
    right = cam.view()[0, :3]
    perp = right - (right @ d) / (d @ d) * d
    n = -perp / np.linalg.norm(perp) + 1e-4 * d / np.linalg.norm(d)  # barely facing the camera's ray
    n /= np.linalg.norm(n)
    hits, sign = screen_neighbours(fake, p[None], n[None], rows, cols, axis=0)
    assert sign[0] == -1.0
    assert abs((hits[0] - p) @ n) < 1e-9 * np.linalg.norm(p)
    left = neighbour_rays(cam, 160, 120, rows, cols - 1)[0]
    np.testing.assert_allclose(np.cross(hits[0] - eye, left), 0.0, atol=1e-9)

def test_tangent_hits_miss_behind_and_parallel():
    """A ray parallel to the plane, or meeting it behind the eye, gives NaN; one in front the point."""
    eye = np.zeros(3)
    dirs = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, -1.0]])
    points = np.array([[0.0, 0.0, -2.0]] * 3)
    normals = np.array([[0.0, 0.0, 1.0]] * 3)
    hits = tangent_hits(eye, dirs, points, normals)
    assert np.isnan(hits[:2]).all()
    np.testing.assert_array_equal(hits[2], [0.0, 0.0, -2.0])


def test_jacobian_singular_values(rng):
    """m = 1/σ_min(J) against numpy's SVD (measured max relative difference 8e-14; bound 1e-10),
    inf for a singular J."""
    j = rng.normal(size=(500, 2, 2))
    expected = 1.0 / np.linalg.svd(j, compute_uv=False)[:, 1]
    np.testing.assert_allclose(footprint_from_jacobian(j), expected, rtol=1e-10)
    assert footprint_from_jacobian(np.array([[[1.0, 2.0], [2.0, 4.0]]]))[0] == np.inf


def test_columns_with_infinite_footprints():
    """An edge-on texel (m = inf) stays inf in the percentiles it reaches and does not turn the
    others into NaN (np.percentile alone gives NaN for the median of [1, 2, inf]); NaN pixels
    are left out."""
    image = np.array([[1.0, 2.0, np.inf], [np.nan, np.nan, np.nan]], np.float32)
    cols = footprint_columns(image)
    assert cols == {"texel_footprint_p50": 2.0, "texel_footprint_p95": np.inf, "texel_footprint_max": np.inf}
    cols = footprint_columns(np.array([[1.0, 3.0, 5.0, np.nan]]))
    assert cols["texel_footprint_p50"] == 3.0 and cols["texel_footprint_p95"] == pytest.approx(4.8, rel=1e-12)
