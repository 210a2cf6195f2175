"""Blob shadows: the cheapest baseline's error on the standard scenes, and its obvious properties
(centred under a caster along the light's direction, nothing without casters, every light type,
strict parameters)."""
from __future__ import annotations

import numpy as np
import pytest

from conftest import make_scene
from shadowlab.techniques import TechniqueError, from_spec
from shadowlab.techniques.blob import BlobShadow, blob_falloff, blob_form

SIZE = (640, 480)

#: Measured at 640x480 (default blob: opacity 0.8, softness 0.25) against the truth: the bounds
#: are ~1.5x above and ~0.5x below the values measured when the test was written (error_rate,
#: false_lit_rate, mean boundary error in pixels), so the test fails both if the blob gets much
#: worse and if it suddenly matches the truth (it cannot: an ellipse is not a box's shadow).
#: Measured: box_on_plane 0.0074 / 0.086 / 5.6 px; multi_light 0.027 / 0.30 / 6.4 px;
#: spot_scene 0.010 / 0.042 / 6.2 px; sun_scene 0.017 / 0.026 / 9.6 px;
#: sm_contact 0.087 / 0.0145 / 15.6 px.
MEASURED = {
    "box_on_plane": (0.0074, 0.086, 5.6),
    "multi_light": (0.027, 0.30, 6.4),
    "spot_scene": (0.010, 0.042, 6.2),
    "sun_scene": (0.017, 0.026, 9.6),
    "sm_contact": (0.087, 0.0145, 15.6),
}


@pytest.mark.parametrize("scene", list(MEASURED))
def test_error_on_standard_scenes(lab, scene):
    df = lab.rows(scene, ["blob"], SIZE)
    row = df.loc["blob"]
    err, false_lit, boundary = MEASURED[scene]
    assert row["truth_shadowed_pixels"] > 1000
    assert 0.5 * err <= row["error_rate"] <= 1.5 * err, row["error_rate"]
    assert 0.5 * false_lit <= row["false_lit_rate"] <= 1.5 * false_lit, row["false_lit_rate"]
    assert 0.5 * boundary <= row["boundary_error_px"] <= 1.5 * boundary, row["boundary_error_px"]
    # the floor casts no blob: nothing receives below it
    assert "no receiver below" in row["notes"] and "floor" in row["notes"]


def test_worse_than_planar_on_its_home_ground(lab):
    """On a box resting on a floor planar shadows are exact (test_planar: error_rate ≤ 0.005);
    the blob's ellipse misses the box's shadow shape."""
    df = lab.rows("box_on_plane", ["planar", "blob"], SIZE)
    assert df.loc["blob", "error_rate"] > 1.2 * df.loc["planar", "error_rate"]


def high_box_scene(light: dict):
    """A 0.6 x 0.4 x 0.5 box 3 units above an 8 x 8 floor, under ``light``."""
    return make_scene([{"name": "floor", "mesh": "plane", "size": [8.0, 8.0]},
                       {"name": "box", "mesh": "box", "size": [0.6, 0.4, 0.5], "translate": [0.3, 3.0, -0.2]}],
                      [light], eye=(0.0, 7.0, 6.0), target=(0.0, 0.0, 0.0))


@pytest.mark.parametrize("light", [
    {"type": "directional", "direction": [0.4, -1.0, 0.2]},
    {"type": "point", "position": [-1.0, 6.0, -0.8]},
    {"type": "spot", "position": [-1.0, 6.0, -0.8], "direction": [0.4, -1.0, 0.2], "alpha": 60.0,
     "beta": 40.0},
    {"type": "area", "shape": "rect", "position": [-1.0, 6.0, -0.8], "u": [0.5, 0.0, 0.0], "v": [0.0, 0.0, -0.5]},
    {"type": "area", "shape": "sphere", "position": [-1.0, 6.0, -0.8], "radius": 0.2},
], ids=["directional", "point", "spot", "rect", "sphere"])
def test_blob_centred_under_a_high_caster_along_the_light(lab, light):
    """The darkening-weighted centroid of the blob's points is the caster's centre carried along
    the light's direction (from the light's position, or the area light's centre) onto the floor
    y = 0, within 1 % of the box-to-floor distance; its area is the projected bounding box's."""
    scene = high_box_scene(light)
    frame = lab.frame(scene, (320, 240))
    m = lab.measure(scene, "blob:softness=0.0", (320, 240))
    dark = (1.0 - m.visibility) > 0
    pts = frame.position[dark]
    assert len(pts) > 200 and np.allclose(pts[:, 1], 0.0, atol=1e-9)  # on the floor only
    centre = np.array([0.3, 3.0, -0.2])
    d = np.array(light["direction"], float) if light["type"] == "directional" \
        else centre - np.array(light["position"], float)
    d /= np.linalg.norm(d)
    expected = centre + (-centre[1] / d[1]) * d
    assert np.linalg.norm(pts.mean(axis=0) - expected) < 0.01 * 3.0 / abs(d[1])
    assert np.allclose(m.visibility[dark], 0.2, atol=1e-6)  # 1 − opacity everywhere: a hard edge
    # area: pixels' floor areas (footprint² · cos³ of the ray's angle off the view axis — a pixel's
    # solid angle — / cos of the ray to the floor's normal) against
    # the projected box's area Σ_{i<j} |det(g'_i, g'_j)| (xz components, g' = g − d g_y / d_y)
    g = np.diag([0.6, 0.4, 0.5]) - np.outer(np.array([0.0, 0.4, 0.0]) / d[1], d)
    xz = g[:, [0, 2]]
    area = sum(abs(np.linalg.det(xz[[i, j]])) for i, j in ((0, 1), (0, 2), (1, 2)))
    rays = pts - frame.camera.eye
    unit = rays / np.linalg.norm(rays, axis=1)[:, None]
    axis = np.asarray(frame.camera.target, float) - frame.camera.eye
    off_axis = unit @ (axis / np.linalg.norm(axis))
    pixel_area = frame.pixel_footprint()[dark] ** 2 * off_axis ** 3 / np.abs(unit[:, 1])
    assert np.sum(pixel_area) == pytest.approx(area, rel=0.03)
    assert m.stats["blobs"] == 1


def test_no_caster_no_darkening(lab):
    scene = make_scene([{"mesh": "plane", "size": [8.0, 8.0]},
                        {"mesh": "box", "size": [1.0, 1.0, 1.0], "translate": [0.0, 2.0, 0.0], "casts": False}],
                       [{"type": "point", "position": [0.0, 5.0, 0.0]}])
    m = lab.measure(scene, "blob", (160, 120))
    assert lab.frame(scene, (160, 120)).evaluated(0).sum() > 1000
    assert np.all(m.visibility == 1.0) and m.stats["blobs"] == 0


def test_blob_form_of_a_box_seen_straight_down():
    """A w x h x l box projected straight down: the ellipse of area w·l with semi-axes w/√π, l/√π."""
    form = blob_form(np.array([[0.0, 0.0, 0.0], [2.0, 5.0, 0.5]]), np.array([0.0, -1.0, 0.0]),
                     np.array([0.0, 1.0, 0.0]))
    rho = lambda x: np.sqrt(x @ form @ x)  # noqa: E731
    assert rho(np.array([2.0 / np.sqrt(np.pi), 0.0, 0.0])) == pytest.approx(1.0, rel=1e-12)
    assert rho(np.array([0.0, 0.0, 0.5 / np.sqrt(np.pi)])) == pytest.approx(1.0, rel=1e-12)
    assert rho(np.array([0.0, 7.0, 0.0])) == pytest.approx(0.0, abs=1e-12)  # flat along the normal
    assert blob_form(np.array([[0.0, 0.0, 0.0], [2.0, 5.0, 0.0]]), np.array([1.0, 0.0, 0.0]),
                     np.array([0.0, 0.0, 1.0])) is None  # a flat box seen edge-on has no area


def test_falloff():
    rho = np.array([0.0, 0.875, 1.0, 1.125, 2.0])
    assert blob_falloff(rho, 0.25) == pytest.approx([1.0, 1.0, 0.5, 0.0, 0.0], abs=1e-12)
    assert blob_falloff(rho, 0.0) == pytest.approx([1.0, 1.0, 1.0, 0.0, 0.0], abs=0)


def test_params_round_trip_and_errors():
    t = from_spec("blob:opacity=0.5,softness=0.1,plane_tolerance=0.01")
    assert isinstance(t, BlobShadow) and t.cpu
    assert from_spec(t.spec()).params() == t.params() == {"opacity": 0.5, "softness": 0.1, "plane_tolerance": 0.01}
    with pytest.raises(TechniqueError, match="unknown parameter 'radius'"):
        from_spec("blob:radius=2")
    for bad in ("opacity=0", "opacity=1.5", "softness=-0.1", "softness=3", "plane_tolerance=-1"):
        with pytest.raises(TechniqueError):
            from_spec(f"blob:{bad}")
