"""The viewer's pictures, made by the lab's own pipeline on the window's GL context.

For each camera the viewer stands at, :class:`LabRenderer` makes one :class:`shadowlab.gpu.frame.Frame`
(the G-buffer and exact points, as ``compare`` does for a scene file's camera), measures the shown
configuration on every light through :func:`shadowlab.measurement.pipeline.measure` (one timed
render, no warm-up, no work count), shades the result with the one shading pass
(:class:`shadowlab.gpu.shading.ShadingPass`) and draws the pictures with the compare pages' own
functions (:mod:`shadowlab.output.pictures`): so the viewer's shaded image of a view is compare's
shaded image of the same view, pixel for pixel (tests/viewer/test_view.py holds it to that).
The truth is the pipeline's :class:`shadowlab.measurement.pipeline.Evaluator` truth, measured only
when asked (:meth:`LabRenderer.truth`), and the error rate is the metrics' own ``error_rate``.

The lab renders on the window's own GL context, which the viewer hands to the lab before any GL
work (:func:`shadowlab.gpu.gl.adopt`), rather than on a headless EGL context of its own beside the
window's GLX one: moderngl contexts do not make themselves current, and glcontext's enter/exit
save and restore only their own API's current context, so after a GLX context is made current an
EGL ``with ctx:`` can silently leave the GLX one current (tried: the lab's passes then ran on the
window's context and failed its error checks). One context removes the switching; the lab's passes
lose nothing, since each binds its own target and applies a full pass state
(:mod:`shadowlab.gpu.glstate`), and on Mesa the same driver (llvmpipe) draws either way — the
pixel-equality test against ``compare``, which renders headless, holds that.
"""
from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field

import numpy as np

from ..evaluation import metrics, texel_footprint
from ..gpu import gl
from ..gpu.frame import Frame
from ..gpu.shading import ShadingPass
from ..measurement.pipeline import Evaluator, build_techniques, check_lights, measure
from ..output import pictures
from ..scene import Scene
from ..scene.model import Camera


@dataclass
class TechniqueImages:
    """One configuration at one camera: its shaded picture (sRGB-encoded float (H, W, 3), row 0
    = top, :func:`shadowlab.output.pictures.to_display`), its visibility image per light, the
    first light's texel footprint (None unless asked for and the technique has a texel mapping),
    the technique's timed render summed over the lights (``render_ms``; for a light-sampled
    technique on an area light, over its samples), the wall time of making it all (``lab_ms``:
    set-up, render, read-back, shading) and its notes."""

    shaded: np.ndarray
    visibility: list[np.ndarray]
    footprint: np.ndarray | None
    render_ms: float
    lab_ms: float
    notes: list[str] = field(default_factory=list)


@dataclass
class TruthImages:
    """The truth at one camera: visibility per light, shaded picture, wall time."""

    visibility: list[np.ndarray]
    shaded: np.ndarray
    lab_ms: float


class LabRenderer:
    """The lab's side of the viewer: a scene, its configurations (spec strings, checked against
    the scene's lights as compare checks them) and an image size; :meth:`look_from` moves the
    camera, the other methods return the pictures of the current camera, cached until it moves.

    Make it after the window's context is adopted (:func:`shadowlab.gpu.gl.adopt`): the lab
    otherwise makes its own headless context on first use."""

    def __init__(self, scene: Scene, specs: list[str], size: tuple[int, int]):
        self.scene, self.size = scene, (int(size[0]), int(size[1]))
        self.techniques = build_techniques(specs)
        check_lights(self.techniques, scene)
        self.ctx = gl.context()
        self.frame: Frame | None = None
        self.frame_ms = float("nan")
        self.camera_key = None
        self._evaluator: Evaluator | None = None
        self._images: dict[tuple[int, bool], TechniqueImages] = {}
        self._truth: TruthImages | None = None
        self._errors: dict[int, float] = {}
        self._measured: list[TechniqueImages] = []

    # ------------------------------------------------------------------ camera
    def look_from(self, camera: Camera, key) -> bool:
        """Stand at ``camera`` (``key`` names it: the view state's camera version); a new frame
        only when the key changed. True when it made one."""
        if key == self.camera_key and self.frame is not None:
            return False
        t0 = time.perf_counter()
        self._release_frame()
        self.frame = Frame(dataclasses.replace(self.scene, camera=camera), *self.size)
        self._evaluator = Evaluator(self.frame)
        self.frame_ms = 1e3 * (time.perf_counter() - t0)
        self.camera_key = key
        return True

    def _release_frame(self) -> None:
        self._images.clear()
        self._errors.clear()
        self._truth = None
        self._evaluator = None
        if self.frame is not None:
            self.frame.release()
            self.frame = None

    def release(self) -> None:
        """Free the frame's GL objects."""
        self._release_frame()

    # ------------------------------------------------------------------ pictures
    def has_footprint(self, i: int) -> bool:
        """Whether configuration ``i`` has a texel footprint (a map technique: ``texel_mapping``)."""
        return texel_footprint.has_texel_mapping(self.techniques[i])

    def images(self, i: int, footprint: bool = False) -> TechniqueImages:
        """Configuration ``i`` at the current camera (measured on first use; ``footprint``: with
        the first light's texel footprint, where the technique has one)."""
        footprint = footprint and self.has_footprint(i)
        for key in ((i, True), (i, footprint)):
            if key in self._images:
                return self._images[key]
        tech, frame = self.techniques[i], self.frame
        t0 = time.perf_counter()
        tech.notes.clear()  # the viewer measures one object again and again: this render's notes only
        ms = [measure(tech, frame, li, repeat=1, warmup=0, count=False, footprint=footprint and li == 0)
              for li in range(len(frame.scene.lights))]
        shaded = self._shade([m.visibility for m in ms], [m.weight for m in ms])
        lab_ms = 1e3 * (time.perf_counter() - t0)
        render_ms = float(sum(m.timing.columns()["time_ms_median"] for m in ms))
        notes = list(dict.fromkeys(n for m in ms for n in m.notes))
        out = TechniqueImages(shaded, [m.visibility for m in ms], ms[0].footprint, render_ms, lab_ms, notes)
        self._images[(i, footprint)] = out
        self._measured.append(out)
        return out

    def cached(self, i: int) -> TechniqueImages | None:
        """Configuration ``i``'s pictures at the current camera if made, else None (measures nothing)."""
        return self._images.get((i, False)) or self._images.get((i, True))

    def take_measured(self) -> list[TechniqueImages]:
        """The configurations measured since the last call (the frame-time records' render times)."""
        out, self._measured = self._measured, []
        return out

    def _shade(self, visibilities, weights=None) -> np.ndarray:
        shading = ShadingPass(self.frame)
        try:
            return pictures.to_display(shading.shade(visibilities, weights), self.frame.covered)
        finally:
            shading.release()

    @property
    def has_truth(self) -> bool:
        """Whether the truth of the current camera has been computed."""
        return self._truth is not None

    def truth(self) -> TruthImages:
        """The ray-traced truth at the current camera (the pipeline's Evaluator: every light,
        measured on first use)."""
        if self._truth is None:
            t0 = time.perf_counter()
            vis = [self._evaluator.truth(li).visibility for li in range(len(self.frame.scene.lights))]
            shaded = self._shade(vis)
            self._truth = TruthImages(vis, shaded, 1e3 * (time.perf_counter() - t0))
        return self._truth

    def error_rate(self, i: int) -> float | None:
        """Configuration ``i``'s ``error_rate`` on light 0 against the truth (the metrics' own
        column: wrong / evaluated pixels); None while the truth of this camera is not computed."""
        if self._truth is None:
            return None
        if i not in self._errors:
            vis = self.images(i).visibility[0]
            self._errors[i] = float(metrics.compare(vis, self._truth.visibility[0], self.frame.evaluated(0))["error_rate"])
        return self._errors[i]

    def picture(self, view: str, i: int) -> tuple[np.ndarray | None, str]:
        """The picture of ``view`` (:data:`shadowlab.viewer.state.VIEWS`) for configuration ``i``:
        RGB float in [0, 1] (H, W, 3), row 0 = top, and a HUD line about it ('' when none).
        None (with the reason) where the view does not apply or needs the truth not yet computed."""
        frame = self.frame
        if view == "truth":
            return (self._truth.shaded, "") if self._truth is not None else (None, "truth: computing once still")
        if view == "footprint":
            if not self.has_footprint(i):
                return None, f"footprint: does not apply to {self.techniques[i].name} (no texel mapping)"
            m = self.images(i, footprint=True).footprint
            return (pictures.footprint_picture(m, frame.evaluated(0), frame.covered),
                    "footprint: texel footprint m of light 0 (log scale: <= 1 alias-free, > 10 severe)")
        images = self.images(i)
        if view == "shaded":
            return images.shaded, ""
        if view == "visibility":
            return pictures.visibility_picture(images.visibility[0], frame.evaluated(0), frame.covered), \
                "visibility of light 0 (white lit, black shadowed)"
        if view == "error":
            if self._truth is None:
                return None, "error: the truth is computed once the camera is still"
            classes = metrics.error_classes(images.visibility[0], self._truth.visibility[0], frame.evaluated(0))
            return pictures.error_picture(classes, images.shaded), \
                "error of light 0: orange false shadow, blue false lit"
        raise ValueError(f"unknown view {view!r}")


def to_bytes(rgb: np.ndarray) -> np.ndarray:
    """An RGB float picture in [0, 1] as uint8, quantised as the run directories' PNGs are
    (matplotlib's ``imsave``: clip, times 255, truncate), so that a screenshot of the shaded view
    equals compare's ``images/<config>_shaded.png``."""
    return (np.clip(rgb, 0.0, 1.0) * 255).astype(np.uint8)
