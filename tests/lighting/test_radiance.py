"""The shaded image as per-light terms (shadowlab.lighting.radiance) against the GL shading pass
it twins, and the radiance metrics (shadowlab.evaluation.radiance) on images whose answer is known."""
from __future__ import annotations

import numpy as np
import pytest

from shadowlab.evaluation import radiance
from shadowlab.gpu.frame import Frame
from shadowlab.gpu.shading import ShadingPass
from shadowlab.lighting.radiance import RadianceTerms
from shadowlab.lighting.selection import LUMA

from helpers import make_scene

LIGHTS = [
    {"type": "point", "position": [1.0, 4.0, 0.5], "color": [0.9, 0.8, 0.7], "ambient": 0.3},
    {"type": "spot", "position": [-1.0, 3.0, 1.0], "direction": [0.2, -1.0, -0.1], "alpha": 70.0, "beta": 30.0,
     "color": [0.5, 0.6, 0.9], "ambient": 0.1},
    {"type": "directional", "direction": [0.3, -1.0, -0.2], "color": [0.3, 0.3, 0.2], "ambient": 0.0},
]
OBJECTS = [
    {"name": "floor", "mesh": "plane", "size": [12.0, 12.0],
     "material": {"diffuse": [0.6, 0.5, 0.4], "specular": [0.3, 0.2, 0.1], "shininess": 16.0}},
    {"name": "box", "mesh": "box", "size": [1.0, 1.0, 1.0], "translate": [0.0, 0.5, 0.0],
     "material": {"diffuse": [0.2, 0.7, 0.3]}},
    {"name": "shown", "mesh": "box", "size": [0.5, 2.0, 0.5], "translate": [1.5, 1.0, -1.0], "receives": False},
]


@pytest.fixture(scope="module")
def frame():
    scene = make_scene(OBJECTS, LIGHTS, eye=(3.0, 5.0, 6.0), target=(0.0, 0.5, 0.0))
    scene.shading.density, scene.shading.shadow_color = 0.7, np.array([0.1, 0.05, 0.2])
    f = Frame(scene, 96, 72)
    yield f
    f.release()


def test_terms_equal_the_shading_pass(frame, rng):
    """Σ w·(a + b·v) in numpy equals the GL pass's image for random visibilities and weights (the
    GL reads float32 G-buffer positions; the terms use the exact float64 points: 1e-3 relative)."""
    h, w = frame.height, frame.width
    vis = [rng.random((h, w)).astype(np.float32) for _ in LIGHTS]
    weights = [None, (rng.random((h, w)) > 0.5).astype(np.float32), None]
    shading = ShadingPass(frame)
    try:
        image = shading.shade(vis, weights)
        unweighted = shading.shade(vis)
    finally:
        shading.release()
    terms = RadianceTerms(frame)
    total = np.zeros((len(frame.pixel_index), 3))
    for i, light in enumerate(frame.scene.lights):
        a, b = terms.rgb(light)
        v = terms.compact(vis[i]).astype(np.float64)[:, None]
        wt = 1.0 if weights[i] is None else terms.compact(weights[i])[:, None]
        total += wt * (a + b * v)
    gl = image.reshape(-1, 3)[frame.pixel_index]
    assert np.allclose(total, gl, rtol=1e-3, atol=1e-4), np.abs(total - gl).max()
    # the weight left the light out where it is 0 (the unweighted image is brighter there)
    assert (unweighted.reshape(-1, 3)[frame.pixel_index].sum() - gl.sum()) > 1.0
    # the luminance terms are the RGB terms' luminance
    a, b = terms.rgb(frame.scene.lights[0])
    la, lb = terms.luminance(0)
    assert np.allclose(la, a @ LUMA, rtol=1e-6) and np.allclose(lb, b @ LUMA, rtol=1e-6)


def test_a_non_receiver_is_shaded_lit_whatever_the_visibility(frame):
    terms = RadianceTerms(frame)
    shown = frame.compact_object == 2
    assert shown.any()
    _, b = terms.rgb(frame.scene.lights[0])
    assert np.all(b[shown] == 0.0) and np.any(b[~shown] != 0.0)


def test_radiance_metrics_of_known_images(frame):
    """The truth against itself is 0; every shadow dropped brightens (bias > 0, equal to the error);
    every light left out darkens to 0 (error 1 = bias −1 where the truth is above the floor)."""
    h, w = frame.height, frame.width
    rng = np.random.default_rng(0)
    truth = [np.where(rng.random((h, w)) < 0.3, 0.0, 1.0).astype(np.float32) for _ in LIGHTS]
    image, per_light = radiance.radiance_columns(frame, truth, truth)
    assert image == {"radiance_error": 0.0, "radiance_error_p95": 0.0, "radiance_bias": 0.0}
    assert sum(p["light_share"] for p in per_light) == pytest.approx(1.0)
    lit = [np.ones((h, w), np.float32) for _ in LIGHTS]
    image, per_light = radiance.radiance_columns(frame, lit, truth)
    assert image["radiance_error"] > 0.01
    # brighter almost everywhere (a shadow colour brighter than a dim diffuse term darkens a few pixels)
    assert 0.9 * image["radiance_error"] < image["radiance_bias"] <= image["radiance_error"]
    assert sum(p["radiance_error_light"] for p in per_light) >= image["radiance_error"] - 1e-12
    zero = [np.zeros((h, w), np.float32) for _ in LIGHTS]
    image, _ = radiance.radiance_columns(frame, truth, truth, weights=zero)
    assert image["radiance_bias"] < 0 and image["radiance_error"] == pytest.approx(-image["radiance_bias"])
    # relative to max(L*, floor): a pixel at or above the floor darkened to 0 has error exactly 1
    lum = radiance.luminance_image(frame, truth)
    bright = np.isfinite(lum) & (lum >= radiance.DARK_FLOOR * np.nanmean(lum))
    assert bright.mean() > 0.5 and image["radiance_error_p95"] == pytest.approx(1.0)


def test_visibility_off_the_evaluated_pixels_does_not_count(frame):
    """A light's visibility where it is not evaluated (facing away, outside the spot's cone) is
    ignored: changing it there leaves every radiance column at 0."""
    h, w = frame.height, frame.width
    truth = [np.ones((h, w), np.float32) for _ in LIGHTS]
    other = [t.copy() for t in truth]
    off = ~frame.evaluated(1)
    assert (off & frame.covered).any()
    other[1][off] = 0.0
    image, _ = radiance.radiance_columns(frame, other, truth)
    assert image["radiance_error"] == 0.0
