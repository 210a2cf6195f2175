"""Projective shadow textures: per caster a shadow image from the light, projected onto the
receivers (Segal et al. 1992, "Fast shadows and lighting effects using texture mapping";
Nguyen 1999, "Casting shadows on volumes", Game Developer; Akenine-Möller, Haines & Hoffman,
Real-Time Rendering 4th ed., §7.2, "projection shadows" / shadow textures).

Per caster object (``casts = true``), per frame (:meth:`ProjectiveShadow.render`):

1. **mask pass** — the caster alone is drawn from the light into its own binary shadow image
   (``resolution``² texels, R8: 1 where the caster covers a texel, 0 elsewhere; no depth),
   through a view fitted to the caster's bounding box (:func:`fit_caster_view`): a perspective
   frustum from a point or spot light's position around the box's 8 corners, an orthographic
   view along a directional or target-direct light around them;
2. **lookup pass** — a full-screen pass over the G-buffer projects the image onto the
   receivers: at each visible point P, (s, t, q) = bias · projection · view · P and
   visibility ·= 1 − mask(s/q, t/q) (multiplicative blending, ``PassState(blend=("zero",
   "src_color"))``: dst = dst · src, so the images of several casters multiply). One pass per
   caster rather than one pass over a texture array: each caster's image has its own view, and
   the multiplicative blend combines any number of casters without a loop bound or array size
   in the shader; the cost is one full-screen pass per caster (``passes`` = 2 per caster).

Area lights: ``LIGHT_SAMPLED`` — the pipeline averages the technique over points of the light.

Its limits, by construction or by toggle (measured in tests/techniques/maps/test_projective.py, scene
``pt_limits``):

- **No self-shadowing** (built in): a caster never takes its own image. Its image covers its
  whole silhouette from the light, and every point of its lit side projects inside that
  silhouette, so taking its own image would shadow all of its lit side; a concave caster's
  shadow on itself (the post of an L shading its foot) is therefore always missing.
- **A caster cannot receive another caster's shadow** — ``receivers``: ``others`` (default,
  the best the technique can do: every receiving object except the caster itself takes the
  image) or ``non_casters`` (the classic set-up: only objects that do not cast take images, so
  casters never get shadows). Which objects receive is a per-object flag texture (object id →
  flag, read with the G-buffer's object id), so any number of objects up to
  ``GL_MAX_TEXTURE_SIZE`` works; above it, a TechniqueError.
- **Back-projection** — ``clip``. A projective texture lands wherever its coordinates do:
  with ``clip=false`` points behind the light's centre of projection (q < 0: the divide
  mirrors them into the image) and points between the light and the caster take the image
  too. With ``clip=true`` (default) a point P takes caster k's image only if (a) q > 0 (it lies
  in front of the light's centre of projection) and (b) the segment from P to the light (the
  ray along −direction for lights at infinity) meets caster k's axis-aligned bounding box —
  P lies beyond some point of the box, as seen from the light (slab test in the shader).
  Rule (b) is stricter than "farther from the light than the box's nearest point": that
  weaker rule lets a wide flat caster (a floor, which casts in the standard scenes) shadow
  every object standing on it wherever that object is farther from the light than the floor's
  nearest point; with rule (b) the floor's box is never between the light and anything above it.
  Measured once with the weaker rule in place of (b): an error rate on box_on_plane and
  spot_scene many times the one with (b).
- **Resolution** — blocky edges from the ``resolution``² image, magnified by the projection;
  ``filter``: ``nearest`` (hard texel steps) or ``linear`` (bilinear: a one-texel ramp of
  fractional visibility along the edges).

Points outside a caster's image (s, t outside [0, 1]) never take it, clip or not.
"""
from __future__ import annotations

import numpy as np

from ...gpu import glstate, programs, targets
from ...geometry import frusta
from ...geometry.bounds import box_corners, box_distance
from ...geometry.frusta import LightView
from ...geometry.transforms import BIAS
from ...gpu.glstate import PassState
from ...scene.lights import T_INFINITE
from ..base import SUM, MAX, Param, PlotStyle, Technique
from .toolkit import check_texture_size
from .contact import ContactShadows

RECEIVERS = ("others", "non_casters")
FILTERS = ("nearest", "linear")
#: The mask's value where the caster covers a texel (full shadow: visibility 1 − this).
COVERED = 1.0
#: Visibility of a point no image darkens.
LIT = 1.0
#: Bytes per texel of a shadow image (R8 unsigned normalised).
MASK_BYTES = 1
#: Bytes per object of the receiver flag texture (R8).
FLAG_BYTES = 1
#: The clip test's slab method treats a towards-light component below this (world units; the
#: vector is L − P or −direction) as parallel to that slab instead of dividing by it.
PARALLEL_EPS = 1e-20


def fit_caster_view(light, bounds: np.ndarray, resolution: int) -> tuple[LightView | None, str | None]:
    """The view of one caster's ``resolution``² shadow image, fitted to its bounding box
    ``bounds`` (2, 3) float64 (the 8 corners are the points to cover), and a note or None.

    Lights at infinity (directional, target-direct): the light's own orthographic fit
    (:meth:`shadowlab.scene.lights.Light.shadow_views` with the corners as the points: sideways around
    them, depth from the box). Lights at a position (point, spot): a perspective frustum from
    the light's position along the mean direction to the corners, full angle twice the largest
    corner angle (padded by :data:`frusta.PAD`), near and far planes from
    :func:`frusta.perspective_range`. Not ``shadow_views`` here: a spot light's map covers the
    whole cone α, which would spend the image's texels on empty space. A frustum cannot be wider
    than 2 × :data:`frusta.MAX_POINT_HALF_ANGLE`: a caster around the light is cut to that (a
    note). A light inside the box gets no view (None and a note): no frustum encloses the box."""
    corners = box_corners(bounds[None])
    if light.at_infinity:
        views, notes = light.shadow_views(corners, frusta.Casters(bounds[None], np.zeros((0, 3, 3))), resolution)
        return views[0], (notes[0] if notes else None)
    p = np.asarray(light.position, np.float64)
    if box_distance(p, bounds[None])[0] == 0.0:
        return None, "the light is inside the bounding box"
    dirs = corners - p
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    mean = dirs.mean(axis=0)
    norm = float(np.linalg.norm(mean))
    if norm == 0.0:
        return None, "the bounding box surrounds the light's directions"
    axis = mean / norm
    half = float(np.degrees(np.arccos(np.clip(dirs @ axis, -1.0, 1.0))).max()) * (1 + frusta.PAD)
    note = None
    if half > frusta.MAX_POINT_HALF_ANGLE:
        note = (f"the box spans {half:.1f} degrees around the light; its image is cut to "
                f"{frusta.MAX_POINT_HALF_ANGLE} degrees")
        half = frusta.MAX_POINT_HALF_ANGLE
    near, far = frusta.perspective_range(p, corners, bounds[None], axis[None], 2 * half)
    return frusta.perspective_view(p, axis, 2 * half, near, far, resolution), note


class ProjectiveShadow(ContactShadows, Technique):
    """Projective shadow textures: per caster a binary image from the light, multiplied onto the
    other receivers through a projective texture lookup (module docstring)."""

    name = "projective"
    summary = ("projective shadow textures (Segal et al. 1992; Nguyen 1999): per caster a shadow image from the "
               "light projected onto the receivers; no self-shadowing")
    PASSES = ("mask", "lookup")
    STYLE = PlotStyle("#bcbd22", "<")
    STATS = {"memory_bytes": MAX, "shadow_images": SUM, "passes": SUM}
    READS = frozenset({"position", "ids"})
    LIGHT_SAMPLED = True  # light_samples=N: averaged over N points of an area light (shadowlab.measurement.light_sampling)
    PARAMS = {
        "resolution": Param(512, "width and height of each caster's shadow image in texels", min=16, max=8192),
        "receivers": Param("others", "who takes a caster's image: others (every receiver but the caster) or "
                                     "non_casters (only objects that cast nothing: casters get no shadow)",
                           choices=RECEIVERS),
        "clip": Param(True, "true: only points in front of the light whose segment to it crosses the caster's "
                            "bounding box take its image; false: wherever the projection lands (back-projection)"),
        "filter": Param("nearest", "sampling of the shadow image: nearest or linear (bilinear)", choices=FILTERS),
    }

    # ------------------------------------------------------------------ setup
    def setup(self, frame, slot) -> None:
        """Fit each caster's view, allocate its image and framebuffer, the receiver flags and
        the programs (untimed)."""
        ctx = frame.ctx
        objects = frame.scene.objects
        check_texture_size((len(objects), 1), self.name, "receiver flag texture (one texel per object)",
                           "the scene has too many objects for projective")
        check_texture_size((self.resolution, self.resolution), self.name, "shadow image")
        takes = [o.receives and (self.receivers == "others" or not o.casts) for o in objects]
        self.flags = self.own(ctx.texture((max(len(objects), 1), 1), 1,
                                          (np.array(takes or [False]) * 255).astype(np.uint8), dtype="f1"))
        self.flags.filter = (ctx.NEAREST, ctx.NEAREST)

        self.casters: list[tuple[int, LightView, np.ndarray]] = []  # (object index, view, bounds)
        skipped = []
        for i, obj in enumerate(objects):
            if not obj.casts or frame.object_ranges[i].count == 0:
                continue
            bounds = obj.bounds().astype(np.float64)
            view, note = fit_caster_view(self.light, bounds, self.resolution)
            if note:
                (skipped if view is None else self.notes).append(f"{obj.name}: {note}")
            if view is not None:
                self.casters.append((i, view, bounds))
        if skipped:
            self.notes.append(f"{self.name}: no shadow image for " + "; ".join(skipped))

        size = (self.resolution, self.resolution)
        filt = ctx.LINEAR if self.filter == "linear" else ctx.NEAREST
        self.masks = []
        for _ in self.casters:
            tex = self.own(ctx.texture(size, 1, dtype="f1"))
            tex.filter = (filt, filt)
            tex.repeat_x = tex.repeat_y = False
            self.masks.append((tex, self.own(targets.framebuffer([tex]))))

        self.mask_prog = self.program("projective_mask.glsl")
        programs.set_uniforms(self.mask_prog, {"u_covered": COVERED})
        self.lookup_prog = self.program("projective_lookup.glsl")
        light_h = self.light.homogeneous()
        programs.set_uniforms(self.lookup_prog, {
            "u_receives": 2, "u_mask": 3,
            "u_clip": 1 if self.clip else 0, "u_light": tuple(map(float, light_h)),
            "u_segment_end": 1.0 if light_h[3] != 0 else float(T_INFINITE),
            "u_parallel": PARALLEL_EPS, "u_lit": LIT,
        })
        self.quad = self.fullscreen_quad(self.lookup_prog)
        self.vis_tex, self.vis_fbo = self.visibility_target((frame.width, frame.height))

    # ------------------------------------------------------------------ passes
    def render(self) -> None:
        """Visibility cleared to 1; then per caster its mask pass and its multiplicative lookup."""
        from OpenGL import GL

        frame, ctx = self.frame, self.frame.ctx
        with self.timed_pass("lookup"):  # visibility starts lit; each lookup multiplies it
            self.vis_fbo.use()
            glstate.apply(PassState())
            GL.glClearBufferfv(GL.GL_COLOR, 0, (LIT, LIT, LIT, LIT))
        vao = frame.vertex_array(self.mask_prog)
        for (index, view, bounds), (tex, fbo) in zip(self.casters, self.masks):
            with self.timed_pass("mask"):
                fbo.use()
                glstate.apply(PassState())
                ctx.viewport = (0, 0, self.resolution, self.resolution)
                GL.glClearBufferfv(GL.GL_COLOR, 0, (0.0, 0.0, 0.0, 0.0))
                self.mask_prog["u_light_view_proj"].write(programs.mat_bytes(view.view_proj))
                rng = frame.object_ranges[index]
                vao.render(vertices=rng.count, first=rng.first)
            with self.timed_pass("lookup"):
                self.vis_fbo.use()
                glstate.apply(PassState(blend=("zero", "src_color")))  # dst = dst · src
                ctx.viewport = (0, 0, frame.width, frame.height)
                self.bind_gbuffer(self.lookup_prog)
                self.flags.use(2)
                tex.use(3)
                self.lookup_prog["u_light_matrix"].write(programs.mat_bytes(BIAS @ view.view_proj))
                programs.set_uniforms(self.lookup_prog, {"u_caster": index, "u_box_min": tuple(map(float, bounds[0])),
                                                         "u_box_max": tuple(map(float, bounds[1]))})
                self.quad.render()

    def work(self, counted: dict, stats: dict) -> dict:
        """Texture taps per lookup fragment: the G-buffer's position and ids, the receiver
        flags and the caster's shadow image."""
        return self.taps_work(counted, {"lookup": 4})

    def stats(self) -> dict:
        """Cost: memory of every shadow image (R8, ``resolution``² each) and the receiver flags,
        the number of shadow images, passes per frame (mask + lookup per caster)."""
        images = len(self.casters)
        return {"memory_bytes": images * self.resolution ** 2 * MASK_BYTES + self.flags.width * FLAG_BYTES,
                "shadow_images": images, "passes": 2 * images}
