"""The shared shading pass against docs/architecture.md#the-shading-pass-shadowlabgpushadingpy computed by hand for single pixels: two lights (a
point light and a spot with its footprint λ), fractional visibility, shadow density and colour."""
from __future__ import annotations

import numpy as np

from shadowlab.gpu.frame import Frame
from shadowlab.gpu.shading import ShadingPass

from helpers import floor_points, make_scene

KD, KS, KA, SHININESS = np.array([0.6, 0.5, 0.4]), np.array([0.3, 0.2, 0.1]), np.array([0.2, 0.25, 0.3]), 16.0
DENSITY, SHADOW_COLOR = 0.6, np.array([0.1, 0.2, 0.3])
LIGHTS = [
    {"type": "point", "position": [1.0, 4.0, 0.5], "color": [0.9, 0.8, 0.7], "ambient": 0.3},
    {"type": "spot", "position": [-1.0, 3.0, 1.0], "direction": [0.2, -1.0, -0.1], "alpha": 70.0, "beta": 30.0,
     "color": [0.5, 0.6, 0.9], "ambient": 0.1},
]


def by_hand(P, eye, light, v):
    """docs/architecture.md#the-shading-pass-shadowlabgpushadingpy for a floor point P (normal +y, facing the camera above it)."""
    N = np.array([0.0, 1.0, 0.0])
    Lpos = np.array(light["position"], float)
    L = (Lpos - P) / np.linalg.norm(Lpos - P)
    V = (eye - P) / np.linalg.norm(eye - P)
    I, Ia = np.array(light["color"]), light["ambient"]
    lam = 1.0
    if light["type"] == "spot":
        axis = np.array(light["direction"]) / np.linalg.norm(light["direction"])
        cos_phi = (P - Lpos) @ axis / np.linalg.norm(P - Lpos)
        c_o, c_i = np.cos(np.radians(light["alpha"] / 2)), np.cos(np.radians(light["beta"] / 2))
        lam = np.clip((cos_phi - c_o) / (c_i - c_o), 0, 1)
    ndl = N @ L
    D = KD * I * max(0.0, ndl)
    H = (L + V) / np.linalg.norm(L + V)
    S = KS * I * max(0.0, N @ H) ** SHININESS if ndl > 0 else np.zeros(3)
    A = KA * Ia
    sh, shade = DENSITY * (1 - v), 1 - v
    return lam * (A + (1 - sh) * D + sh * SHADOW_COLOR + (1 - shade) * S)


def test_shaded_pixels_follow_the_extended_blinn_model():
    floor = {"name": "floor", "mesh": "plane", "size": [12.0, 12.0],
             "material": {"diffuse": KD.tolist(), "specular": KS.tolist(), "ambient": KA.tolist(),
                          "shininess": SHININESS}}
    scene = make_scene([floor], LIGHTS, eye=(0.0, 5.0, 5.0), target=(0.0, 0.0, 0.0), fov_y=50.0)
    scene.shading.density, scene.shading.shadow_color = DENSITY, SHADOW_COLOR
    size = (96, 72)
    frame = Frame(scene, *size)
    shading = ShadingPass(frame)
    vis = [np.full((size[1], size[0]), 0.25, np.float32), np.full((size[1], size[0]), 0.8, np.float32)]
    image = shading.shade(vis)
    shading.release()
    frame.release()
    pts = floor_points(scene.camera, *size)
    on_floor = np.argwhere(np.all(np.abs(pts[..., [0, 2]]) < 5.9, axis=-1))    # inside the 12 x 12 floor
    pixels = on_floor[np.random.default_rng(3).choice(len(on_floor), 40, replace=False)]
    spot = []
    for r, c in pixels:
        expected = sum(by_hand(pts[r, c], scene.camera.eye, light, v[r, c]) for light, v in zip(LIGHTS, vis))
        # 2e-4: NVIDIA's pow/normalize (H200, driver 580.159.04) differ from float64 by 1.3e-4 relative
        assert np.allclose(image[r, c], expected, rtol=2e-4, atol=1e-5), (r, c, image[r, c], expected)
        spot.append(by_hand(pts[r, c], scene.camera.eye, LIGHTS[1], 1.0).sum())
    assert min(spot) == 0 and max(spot) > 0.1, "the pixels must cover the spot's footprint and beyond"
