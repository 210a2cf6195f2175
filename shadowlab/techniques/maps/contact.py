"""Screen-space contact shadows on top of any map technique (the ``contact`` parameter).

What engines ship (Unreal's ``r.ContactShadows``, Unity HDRP, Days Gone): a short march through
the camera's depth buffer from each pixel towards the light catches the contacts a shadow map
loses to its bias and resolution (peter-panning), and its visibility multiplies the map's.
The formulation is Bend Studio's (Graham Aldridge, "Inside Bend: screen space shadows", 2023;
reference code v1.3, Apache-2.0), implemented here from its description
(``shadowlab/techniques/maps/contact_march.glsl`` has the per-pixel rule):

- ``contact_samples`` samples per pixel, one pixel apart along the major axis of the screen
  line to the light's projected point: the shadow's maximum length in pixels (default 60);
- the first ``contact_hard`` samples (4) can shadow the pixel on their own (a hard contact);
  the rest are averaged over four interleaved groups, so one sample cannot shadow fully;
- the last ``contact_fade`` samples (8) fade out, softening the cut at the maximum length;
- a sample shadows when its surface lies in front of the ray by about ``contact_thickness``
  (0.005: a fraction of the depth left to the far plane) — every surface is assumed that thick,
  so thin casters seen edge-on cast false shadows behind them (thickness halos) and anything
  thicker leaks;
- ``contact_bilinear`` (0.02): a depth step between the sample and its minor-axis neighbour
  above this fraction is an edge, not interpolated;
- ``contact_contrast`` (4, Bend's ShadowContrast) sharpens the window's edge.

Dispatches. Bend runs waves of 64 threads along lines radiating from the light's projected
point, sharing depth samples in group memory, and splits the screen into up to four quadrants
around that point, each cut in two where it is not square: "one or two dispatches when the light
is off-screen, 4 to 6 when on-screen". Here one invocation marches one pixel (no shared
samples; the same samples are read), dispatched once per non-empty quadrant of the screen
around the light's pixel (:func:`quadrant_rects`: 1-2 off-screen, up to 4 on), and
:func:`bend_dispatch_count` reproduces Bend's own dispatch list for the same light and viewport
(stat ``bend_dispatches``), so the published count can be checked without its wave layout.

The depth buffer is the G-buffer's exact points projected by the camera (window depth, float32),
uploaded once per light in ``setup`` — the depth an engine already has, not a pass of the
technique. Samples past the light's point or off the screen never shadow (an off-screen caster
is invisible to the march: the technique's known miss).
"""
from __future__ import annotations

import numpy as np

from ...gpu import programs
from ...gpu.targets import read_texture
from ..base import SUM, Param, TechniqueError, TuneRange

#: Pixels per Bend wave: the unit of its dispatch list.
BEND_WAVE = 64
#: Invocations per work group of contact_march.glsl (8 x 8).
LOCAL = 8

CONTACT_PARAMS = {
    "contact": Param(False, "screen-space contact shadows (Bend Studio's march over the depth buffer) multiplied "
                            "into the technique's visibility"),
    "contact_samples": Param(60, "contact: samples per pixel, one pixel apart: the contact shadow's maximum length "
                                 "in pixels", min=1, max=1024, tune=TuneRange(8, 256, log=True)),
    "contact_hard": Param(4, "contact: the first samples, each of which can shadow the pixel fully", min=0, max=1024),
    "contact_fade": Param(8, "contact: the last samples, whose shadow fades out", min=0, max=1024),
    "contact_thickness": Param(0.005, "contact: the thickness every surface is assumed to have, a fraction of the "
                                      "depth left to the far plane", min=0.0, max=1.0, min_open=True,
                               # 0.001-0.05 is the sweep of issue 39; past 0.05 halos dominate
                               tune=TuneRange(1e-4, 0.1, log=True)),
    "contact_bilinear": Param(0.02, "contact: depth step (a fraction of the depth left to the far plane) above which "
                                    "two neighbouring samples are an edge and not interpolated", min=0.0, max=1.0),
    "contact_contrast": Param(4.0, "contact: sharpness of the thickness window's edge (Bend's ShadowContrast)",
                              min=1.0, max=1e3),
}
#: The contact pass's cost figures: dispatches issued (here and by Bend's list), samples marched.
CONTACT_STATS = {"contact_dispatches": SUM, "bend_dispatches": SUM, "contact_samples": SUM}


def light_coordinate(light, view_projection: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """The light's projected point as the march needs it: (pixel x, pixel y — GL window
    coordinates, y up — window depth, +1 when in front of the camera or −1 behind). A light at
    infinity projects its direction towards the light (its vanishing point). As Bend does, a w
    too close to 0 is pushed to ±2e-6 · 64 so the divide stays finite."""
    h = np.asarray(view_projection, np.float64) @ np.asarray(light.homogeneous(), np.float64)
    w = float(h[3])
    limit = 2e-6 * BEND_WAVE
    w_xy = limit if 0 <= w < limit else (-limit if -limit < w < 0 else w)
    width, height = size
    return np.array([(h[0] / w_xy * 0.5 + 0.5) * width, (h[1] / w_xy * 0.5 + 0.5) * height,
                     (h[2] / w * 0.5 + 0.5) if w != 0 else 0.5, 1.0 if w > 0 else -1.0])


def quadrant_rects(light_xy, size: tuple[int, int]) -> list[tuple[int, int, int, int]]:
    """The screen cut at the light's pixel into up to four rectangles (x0, y0, width, height),
    the empty ones dropped: one dispatch each (1 when the light's point is beyond a corner, 2
    beyond an edge, 4 inside)."""
    width, height = size
    cx = int(np.clip(np.floor(light_xy[0]), 0, width))
    cy = int(np.clip(np.floor(light_xy[1]), 0, height))
    rects = []
    for x0, x1 in ((0, cx), (cx, width)):
        for y0, y1 in ((0, cy), (cy, height)):
            if x1 > x0 and y1 > y0:
                rects.append((x0, y0, x1 - x0, y1 - y0))
    return rects


def bend_dispatch_count(light_xy, size: tuple[int, int], wave: int = BEND_WAVE) -> int:
    """How many compute dispatches Bend's dispatch list issues for a light whose projected point
    is ``light_xy`` (pixels, y down as in Bend) on a viewport of ``size``, rewritten from the
    reference's description: the viewport, relative to the light's pixel, is cut into four
    quadrants, each padded by one wave of 64 pixels (two on its minor axis), so a quadrant lying
    off the screen within a wave or two of the light still dispatches; a quadrant with any wave
    is a dispatch, and it is cut in two (a second dispatch) when the diagonal through the light
    crosses it — when its far corner is farther from the light on one axis than on the other, by
    any amount. Bend's comment: "one or two when the light is off-screen, 4 to 6 when on-screen"."""
    width, height = size
    lx, ly = int(light_xy[0] + 0.5), int(light_xy[1] + 0.5)
    # the viewport's inclusive bounds relative to the light; y flipped so +y is up
    left, bottom, right, top = -lx, -(height - ly), width - lx, ly
    count = 0
    for q in range(4):
        vertical = q in (0, 3)
        east, north = bool(q & 1), bool(q & 2)
        x0 = max(0, left if east else -right) // wave
        y0 = max(0, bottom if north else -top) // wave
        x1 = max(0, (right if east else -left) + wave * (1 if vertical else 2) - 1) // wave
        y1 = max(0, (top if north else -bottom) + wave * (2 if vertical else 1) - 1) // wave
        if x1 - x0 <= 0 or y1 - y0 <= 0:
            continue
        count += 1
        nx, ny = x1 - x0, y1 - y0
        # the far corner of the quadrant relative to the light: where the diagonal leaves it
        delta = {0: left - bottom, 1: right + bottom, 2: -left - top, 3: -right + top}[q]
        delta = -(-delta // wave) if delta > 0 else 0
        if delta > 0:
            # the split takes min(count, delta) waves of one axis and grows one on the other
            if q in (0, 3):
                second = (nx + 1, min(ny, delta))
                first = (nx, ny - second[1])
            else:
                second = (min(nx, delta), ny + 1)
                first = (nx - second[0], ny)
            count += 1
            count -= sum(1 for a, b in (first, second) if a <= 0 or b <= 0)
    return count


def samples_marched(pixels_xy: np.ndarray, light: np.ndarray, samples: int, size: tuple[int, int]) -> int:
    """The samples the march reads for pixel centres ``pixels_xy`` (N, 2) (GL window coordinates):
    per pixel ``samples``, fewer where the light's point (in front of the camera) or the screen's
    edge comes first; 0 where the pixel holds the light's point."""
    if not len(pixels_xy):
        return 0
    p = np.asarray(pixels_xy, np.float64)
    to = (light[:2] - p) if light[3] > 0 else (p - light[:2])
    s0 = np.abs(to).max(axis=1)
    ok = s0 >= 1.0
    n = np.full(len(p), float(samples))
    if light[3] > 0:
        n = np.minimum(n, np.ceil(s0) - 1.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        step = to / np.where(ok, s0, 1.0)[:, None]
        # steps until the sample leaves the screen, per axis (inf when not moving on it)
        limits = []
        for axis, extent in ((0, size[0]), (1, size[1])):
            st = step[:, axis]
            room = np.where(st > 0, extent - p[:, axis], np.where(st < 0, p[:, axis], np.inf))
            limits.append(np.where(st != 0, np.floor(room / np.abs(np.where(st != 0, st, 1.0))), np.inf))
    n = np.minimum(n, np.minimum(*limits))
    return int(np.where(ok, np.maximum(n, 0.0), 0.0).sum())


def _contact_setup(self, frame, slot) -> None:
    """After the technique's setup (``contact``): the depth buffer, the contact image and the
    march's program and uniforms."""
    self._contact_image = None
    if not self.contact:
        return
    ctx = frame.ctx
    size = (frame.width, frame.height)
    pts = frame.compact_position
    clip = np.c_[pts, np.ones(len(pts))] @ np.asarray(frame.view_projection, np.float64).T
    with np.errstate(invalid="ignore", divide="ignore"):
        depth = clip[:, 2] / clip[:, 3] * 0.5 + 0.5
    # a covered pixel without an exact hit (compact_valid False) has NaN: nothing there, as far
    # as the march knows (the far plane), never a NaN fed to the shader's min()
    depth = np.where(frame.compact_valid & np.isfinite(depth), depth, 1.0)
    image = frame.to_image(depth, fill=1.0)  # row 0 = top; GL's row 0 is the bottom
    self.contact_depth = self.own(ctx.texture(size, 1, np.ascontiguousarray(image[::-1]).astype("f4").tobytes(),
                                              dtype="f4"))
    self.contact_depth.filter = (ctx.NEAREST, ctx.NEAREST)
    self.contact_texture = self.own(ctx.texture(size, 1, dtype="f4"))
    self.contact_prog = self.program("contact_march.glsl")
    self.contact_light = light_coordinate(slot.light, frame.view_projection, size)
    programs.set_uniforms(self.contact_prog, {
        "u_depth": 0, "u_contact": 0, "u_size": size, "u_light": tuple(map(float, self.contact_light)),
        "u_samples": int(self.contact_samples), "u_hard": int(self.contact_hard),
        "u_fade": int(self.contact_fade), "u_thickness": float(self.contact_thickness),
        "u_bilinear": float(self.contact_bilinear), "u_contrast": float(self.contact_contrast)})
    self.contact_rects = quadrant_rects(self.contact_light[:2], size)


def _contact_render(self) -> None:
    """After the technique's passes (``contact``): the march, one dispatch per quadrant."""
    if not self.contact:
        return
    self._contact_image = None  # a new render: the images read back before are stale
    with self.timed_pass("contact"):
        self.contact_depth.use(0)
        self.contact_texture.bind_to_image(0, read=False, write=True)
        for x0, y0, w, h in self.contact_rects:
            self.contact_prog["u_origin"].value = (x0, y0)
            self.contact_prog["u_extent"].value = (w, h)
            self.contact_prog.run(-(-w // LOCAL), -(-h // LOCAL))
        self.frame.ctx.memory_barrier()


def _contact_stats(self) -> dict:
    """The dispatches issued here and by Bend's list for this light, and the samples marched over
    the evaluated pixels."""
    size = (self.frame.width, self.frame.height)
    idx = self.frame.pixel_index[self.slot.evaluated]
    xy = np.c_[idx % self.frame.width + 0.5, (self.frame.height - 1 - idx // self.frame.width) + 0.5]
    bend_xy = (self.contact_light[0], self.frame.height - self.contact_light[1])  # Bend's y runs down
    return {"contact_dispatches": len(self.contact_rects), "bend_dispatches": bend_dispatch_count(bend_xy, size),
            "contact_samples": samples_marched(xy, self.contact_light, int(self.contact_samples), size)}


def _wrap(name: str, original):
    """``original`` (the class's own method ``name``) followed by the contact pass's part. A
    subclass that overrides the method and calls ``super()`` gets a wrapper of its own around the
    parent's: only the outermost acts (a per-instance flag), so the contact part runs once."""
    inner = _contact_part(name, original)
    flag = f"_contact_in_{name}"

    def method(self, *args, **kwargs):
        if self.__dict__.get(flag):
            return original(self, *args, **kwargs)
        self.__dict__[flag] = True
        try:
            return inner(self, *args, **kwargs)
        finally:
            self.__dict__[flag] = False

    method.__name__, method.__qualname__ = name, f"{getattr(original, '__qualname__', name)}+contact"
    method.__doc__ = (original.__doc__ or "") + _WRAPPED_DOC[name]
    method.contact_wrapped = True
    return method


def _contact_part(name: str, original):
    """The method ``name``: ``original`` and then the contact pass's part of it."""
    if name == "__init__":
        def method(self, **params):
            original(self, **params)
            _check_contact_params(self, params)
    elif name == "setup":
        def method(self, frame, slot):
            original(self, frame, slot)
            _contact_setup(self, frame, slot)
    elif name == "render":
        def method(self):
            original(self)
            _contact_render(self)
    elif name == "visibility":
        def method(self):
            base = original(self)
            if not self.contact:
                return base
            self._contact_image = (base, read_texture(self.contact_texture, 1)[..., 0])
            return base * self._contact_image[1]
    elif name == "component_images":
        def method(self):
            out = dict(original(self))
            if self.contact:
                if self._contact_image is None:
                    self.visibility()
                out["base"], out["contact_shadow"] = self._contact_image
            return out
    elif name == "stats":
        def method(self):
            out = dict(original(self))
            if self.contact:
                out.update(_contact_stats(self))
            return out
    else:  # work: two depth reads per sample and the pixel's own depth, per invocation
        def method(self, counted, stats):
            out = dict(original(self, counted, stats))
            if self.contact and "contact" in counted:
                out.update(self.taps_work(counted, {"contact": 2 * int(self.contact_samples) + 1}))
            return out
    return method


def _check_contact_params(self, given: dict) -> None:
    """TechniqueError when the hard or the fade-out samples are more than the march has; a note
    when contact parameters are given with ``contact=false`` (they do nothing then). Hard and
    fade-out samples may overlap in a short march (8 samples at the defaults' 4 + 8): the hard
    ones keep their rule, the rest fade."""
    for key in ("contact_hard", "contact_fade"):
        if getattr(self, key) > self.contact_samples:
            raise TechniqueError(f"{self.name}: {key} ({getattr(self, key)}) must not exceed contact_samples "
                                 f"({self.contact_samples})")
    idle = sorted(k for k in given if k.startswith("contact_") and k in CONTACT_PARAMS)
    if idle and not self.contact:
        self.notes.append(f"{self.name}: {', '.join(idle)} set but contact=false: no contact shadows are drawn")


#: What each wrapped method adds, appended to the technique's own docstring.
_WRAPPED_DOC = {
    "__init__": "\n\nThen checks the contact parameters (hard and fade-out samples within the march).",
    "setup": "\n\nWith ``contact``: then the contact march's depth buffer, image and program.",
    "render": "\n\nWith ``contact``: then the contact march (pass ``contact``).",
    "visibility": "\n\nWith ``contact``: multiplied by the contact shadow's visibility.",
    "component_images": "\n\nWith ``contact``: ``base`` (the technique alone) and ``contact_shadow``.",
    "stats": "\n\nWith ``contact``: ``contact_dispatches``, ``bend_dispatches``, ``contact_samples``.",
    "work": "\n\nWith ``contact``: the march's texture taps.",
}


class ContactShadows:
    """Mixin of every map technique: the :data:`CONTACT_PARAMS`, the ``contact`` pass after the
    technique's own, and its visibility multiplied in. When a class that lists it is made, its
    parameters, pass and stats are added to the class's declarations and the class's
    ``setup``, ``render``, ``visibility``, ``component_images``, ``stats`` and ``work`` — wherever
    in its bases they are defined — are wrapped to run the contact part after their own, so a
    technique declares nothing for it. It reads no G-buffer channel: its depth buffer is made from
    the frame's exact points, which every technique may read."""

    def __init_subclass__(cls, **kwargs):
        """Merge the contact declarations into the new class's (after its own, before the shared
        ``light_samples``, which stays last) and wrap the methods the contact pass follows: the
        class's own, and inherited ones not wrapped yet (the wrapper's flag makes a ``super()``
        chain of wrapped methods run the contact part once)."""
        super().__init_subclass__(**kwargs)
        own = {k: p for k, p in cls.PARAMS.items() if k not in CONTACT_PARAMS and k != "light_samples"}
        shared = {k: p for k, p in cls.PARAMS.items() if k == "light_samples"}  # the pipeline's, kept last
        cls.PARAMS = {**own, **CONTACT_PARAMS, **shared}
        cls.PASSES = tuple(p for p in cls.PASSES if p != "contact") + ("contact",)
        cls.STATS = {**cls.STATS, **CONTACT_STATS}
        for name in _WRAPPED_DOC:
            original = cls.__dict__.get(name)
            if original is None:  # inherited: wrapped once where the MRO has it unwrapped
                original = getattr(cls, name)
                if getattr(original, "contact_wrapped", False):
                    continue
            setattr(cls, name, _wrap(name, original))

    def contact_visibility(self) -> np.ndarray:
        """The contact shadow alone, float32 (height, width), row 0 = top, 1 = lit (after render)."""
        return read_texture(self.contact_texture, 1)[..., 0]
