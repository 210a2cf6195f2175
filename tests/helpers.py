"""Helpers shared by the test folders (imported as ``from helpers import ...``; tests/ is on
pytest's ``pythonpath``): the standard image sizes, the session's shared frames and truths
(:class:`Lab`, handed out by conftest's ``lab`` fixture), scene builders and independent
camera-ray code written from the contract for the tests."""
from __future__ import annotations

import numpy as np
import pandas as pd

from shadowlab.gpu.frame import Frame
from shadowlab.measurement.pipeline import Evaluator, Measurement, measure, measure_configs
from shadowlab.scene import Scene, load_scene, parse_scene
from shadowlab.techniques import from_spec


#: The two standard image sizes of the behaviour tests: tests that use the same scene at the same
#: size share its frame and truth through ``lab`` (a test keeps another size only where its
#: thresholds were measured there and do not hold at these).
SMALL = (160, 120)
MEDIUM = (320, 240)

#: The ground truth of each test scene that needs other than the default ``raytrace`` (hard
#: lights: one exact ray per pixel; area lights: 1024 stratified samples, bound 0.5/√N = 0.0156).
#: Fewer samples only where every test of the scene states its tolerance so that it holds with
#: this truth's bound (the tests say which, and what was measured with it).
TRUTHS = {
    # test_pcss (penumbra widths within 25 % and visibility_mae below 0.008; soft_overlap's
    # tilted-map bounds were measured against 256 samples), test_projective (area light: within
    # 0.005 of shadow_map:light_samples=4), test_texel_footprint (columns only) — each holds with
    # this truth's bound 0.5/√256 = 0.031 (the tests give the values measured against it)
    "soft_contact_hardening": "raytrace:samples=256",
    "soft_overlap": "raytrace:samples=256",
}


class Lab:
    """Frames and ground truths shared by the whole session: one frame per (scene, size), its
    truth (``TRUTHS``, else the default ``raytrace``) measured once per light. Scenes are
    shipped names or Scene objects (kept by identity). Frames are read-only to tests and
    techniques alike (the stage contract)."""

    def __init__(self):
        self._frames: dict = {}
        self._evaluators: dict = {}

    def evaluator(self, scene: str | Scene, size: tuple[int, int], truth: str | None = None) -> Evaluator:
        """The evaluator (frame + truth per light) of a scene at a size; ``truth``: a raytrace spec
        other than the scene's (the frame is still the shared one)."""
        name = scene if isinstance(scene, str) else id(scene)
        truth = truth or (TRUTHS.get(scene, "raytrace") if isinstance(scene, str) else "raytrace")
        key = (name, tuple(size), truth)
        if key not in self._evaluators:
            fkey = (name, tuple(size))
            if fkey not in self._frames:
                s = load_scene(scene) if isinstance(scene, str) else scene
                self._frames[fkey] = (s, Frame(s, *size))  # the scene is kept alive with its key
            self._evaluators[key] = Evaluator(self._frames[fkey][1], truth=from_spec(truth))
        return self._evaluators[key]

    def frame(self, scene, size) -> Frame:
        """The shared frame of a scene at a size."""
        return self.evaluator(scene, size).frame

    def truth(self, scene, size, light: int = 0) -> np.ndarray:
        """The ground truth's visibility (float32 (H, W), row 0 = top) of one light."""
        return self.evaluator(scene, size).truth(light).visibility

    def measure(self, scene, spec: str, size, light: int = 0) -> Measurement:
        """One configuration measured on the shared frame (one untimed-in-effect render; no work
        counting render: tests/gpu/test_work.py measures the counters itself)."""
        return measure(from_spec(spec), self.frame(scene, size), light, repeat=1, warmup=0, count=False)

    def rows(self, scene, specs, size, light: int = 0) -> pd.DataFrame:
        """Metrics rows of several configurations (ground truth row dropped), indexed by the specs."""
        df = measure_configs(None, specs, light_index=light, evaluator=self.evaluator(scene, size))
        df = df[~df["reference"]].copy()
        df.index = list(specs)
        return df


def make_scene(objects, lights, eye=(4.0, 6.0, 7.0), target=(0.0, 0.0, 0.0), fov_y=50.0, name="test"):
    """A Scene from plain dicts, as a scene file would hold them."""
    data = {"name": name, "camera": {"eye": list(eye), "target": list(target), "fov_y": fov_y},
            "lights": lights, "objects": objects}
    return parse_scene(data, f"<{name}>")


def pixel_centre_rays(eye, target, up, fov_y, width, height) -> np.ndarray:
    """Unit world directions through every pixel centre, (height, width, 3), row 0 = top —
    written from docs/architecture.md#conventions for the tests, independently of shadowlab's camera code."""
    eye, target, up = (np.asarray(v, np.float64) for v in (eye, target, up))
    forward = (target - eye) / np.linalg.norm(target - eye)
    right = np.cross(forward, up)
    right /= np.linalg.norm(right)
    true_up = np.cross(right, forward)
    half_h = np.tan(np.radians(fov_y) / 2.0)
    half_w = half_h * width / height
    cols = (np.arange(width) + 0.5) / width * 2.0 - 1.0     # left → right
    rows = 1.0 - (np.arange(height) + 0.5) / height * 2.0   # top → bottom
    d = (forward[None, None] + cols[None, :, None] * half_w * right[None, None]
         + rows[:, None, None] * half_h * true_up[None, None])
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def floor_points(scene_camera, width, height) -> np.ndarray:
    """World points where each pixel-centre ray meets the plane y = 0, (height, width, 3);
    NaN where the ray does not go down to it."""
    cam = scene_camera
    d = pixel_centre_rays(cam.eye, cam.target, cam.up, cam.fov_y, width, height)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -cam.eye[1] / d[..., 1]
    pts = cam.eye + t[..., None] * d
    pts[~(t > 0)] = np.nan
    return pts


def scene_for(cls, default: str = "multi_light") -> str:
    """A shipped scene every light of which the technique class renders for (its ``LIGHTS``):
    ``default`` for the techniques that render every hard light, ``sun_scene`` for those that
    need a directional light, ``soft_overlap`` for those that need an area light."""
    if {"point", "spot", "directional"} <= cls.LIGHTS:
        return default
    return "sun_scene" if "directional" in cls.LIGHTS else "soft_overlap"


def mismatches(lab, scene, spec, size=SMALL, light=0) -> tuple[int, int, object]:
    """(wrong evaluated pixels, evaluated pixels, the measurement) of ``spec`` against the truth on
    ``scene`` (``lab``: the tests' session fixture), thresholded at 0.5 as error_rate counts them:
    the exact techniques' tests count the pixels where they and the truth disagree."""
    m = lab.measure(scene, spec, size, light)
    truth = lab.truth(scene, size, light)
    evaluated = lab.frame(scene, size).evaluated(light)
    wrong = int(np.sum((m.visibility[evaluated] < 0.5) != (truth[evaluated] < 0.5)))
    return wrong, int(evaluated.sum()), m


#: The most lights of one scene that the every-scene sweeps check (many-light scenes: issue 40).
SWEEP_LIGHTS = 8


def sweep_lights(scene, limit: int = SWEEP_LIGHTS) -> list[int]:
    """The light indices an every-shipped-scene sweep checks: all of them up to ``limit``, else
    ``limit`` evenly spaced ones (the first and the last included) — so the many-light scenes (40
    to 256 lights, every light of the same few kinds) are covered without multiplying a sweep's
    time by their light count."""
    n = len(scene.lights)
    if n <= limit:
        return list(range(n))
    return sorted({int(round(i)) for i in np.linspace(0, n - 1, limit)})
