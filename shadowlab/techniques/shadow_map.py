"""Depth-buffer shadow maps (Williams 1978) and their family of depth comparisons.

The map is an atlas of one face (spot, directional, target-direct, a point light's single
frustum) or six (a point light's cube, 90° faces, chosen in the lookup by the major axis of the
light-to-point vector). Passes: the casters' depth from the light (one per face and layer), an
optional resolve, then one lookup pass over the shared G-buffer writing visibility.

Variants (``variant=``), tuned by ``bias`` (window depth), ``slope_scale`` and ``normal_offset``
(texels):

- ``none``: compare with no offset — shows acne;
- ``constant``: subtract ``bias``;
- ``slope``: ``bias`` plus ``slope_scale`` × the depth change over one texel on the receiver's
  plane, computed in the shader from the receiver's normal (the shader-side form of slope-scaled
  bias); with ``hardware_offset=true`` the depth pass instead applies glPolygonOffset(factor =
  ``slope_scale``, units = ``offset_units``), the hardware form;
- ``normal_offset``: ``bias`` plus the lookup point moved along the normal by ``normal_offset``
  texels (world size of a texel at the point);
- ``second_depth`` (Wang & Molnar 1994): the map holds the back faces only (front faces culled),
  no bias — single-sided casters vanish from it;
- ``midpoint`` (Woo 1992): the average of the first and second depth layers (depth peeling);
- ``dual`` (Weiskopf & Ertl 2003): the first layer plus min(half the gap to the second, ``bias``).

Filters (``filter=``): ``nearest``; ``hw2x2`` (sampler2DShadow with linear filtering: hardware
bilinear PCF); ``pcf3`` / ``pcf5`` (texel-exact percentage-closer filtering, Reeves et al. 1987).
Filtered visibility is fractional; the metrics report ``visibility_mae`` beside thresholded rates.

Light frusta are fitted to what the scene and camera involve (DESIGN §11), never constants;
each light type fits its own (:meth:`shadowlab.lights.Light.shadow_views`,
:mod:`shadowlab.geometry.frusta`). The points to cover are (``fit=shadowable``, the default) the evaluated receiver points that can
be in shadow at all — those whose segment to the light crosses a caster's bounding box
(:func:`shadowable`) — or (``fit=receivers``, the classic fit) every evaluated receiver point;
then
- directional: orthographic along the light, x/y extent fitted to those points, depth range
  from the nearest caster to the farthest receiver;
- target-direct: orthographic over the light's cylinder (radius R), clipped to those points;
  near plane at the light's disc (nothing behind the light casts);
- spot: perspective with the cone's full angle α;
- point: ``projection=frustum`` — one frustum around those points; ``cube`` — six faces;
  ``auto`` — the frustum when the points fit in a cone of
  ``geometry.frusta.MAX_POINT_HALF_ANGLE``, else the cube.
Near planes sit in front of every caster point a view can see — along the view's axis, not at
the nearest caster's distance, which would clip an off-axis caster that is closer in depth
(:func:`shadowlab.geometry.frusta.perspective_range`) — unless ``near`` forces one (to show what
a too-close near plane does to depth precision); far planes just past the farthest receiver.
"""
from __future__ import annotations

import numpy as np

from .. import gl, glstate
from ..geometry.bounds import segments_hit_boxes
from ..geometry.frusta import LightView
from ..geometry.transforms import BIAS
from ..glstate import PassState
from .base import Param, Technique, TechniqueError

VARIANTS = ("none", "constant", "slope", "normal_offset", "second_depth", "midpoint", "dual")
FILTERS = {"nearest": 0, "pcf3": 1, "pcf5": 2, "hw2x2": None}
#: The shadowable test starts each segment this far off its surface (× the scene's extent), so
#: that a flat receiver's own bounding box does not count as a caster in its way.
SHADOWABLE_OFFSET = 1e-5
#: The window depth :func:`depth_pass` clears the map to: a texel still holding it saw no caster
#: between the light and the far plane (PCSS tells such empty texels from blockers by it).
CLEAR_DEPTH = 1.0
#: One step of each depth format: what "the same surface" means when peeling the second layer.
#: Fixed point: 1 / (2^bits − 1). Float: depths of perspective maps crowd into [0.5, 1), where a
#: float32 ulp is 2^-24; the rasteriser's interpolated depth of the same surface varies by a few
#: ulps between passes, so a layer must lie 4 ulps behind the first to count as a new surface.
DEPTH_STEP = {16: 1.0 / 65535, 24: 1.0 / 16777215, 32: 2.0 ** -22}


def shadowable(points: np.ndarray, normals: np.ndarray, light, bounds: np.ndarray, eps: float) -> np.ndarray:
    """Bool (M,): receiver points whose segment to the light crosses some caster's bounding box.

    Conservative (a superset of the points that can be in shadow): a point whose segment
    misses every caster box is certainly lit, so the shadow map need not cover it. The
    segment starts ``eps`` off the surface, so a receiver's own flat box does not count.
    """
    origin = points + eps * normals
    dirs, dist = light.to_light(origin)
    return segments_hit_boxes(origin, dirs, np.minimum(dist, 1e30), bounds)


def fit_light_views(frame, light_index: int, resolution: int, projection: str = "auto",
                    near_override: float = 0.0, fit: str = "shadowable") -> tuple[list[LightView], list[str]]:
    """The map's views (1, or 6 for a cube) fitted to the frame, and notes for the run.

    ``fit='shadowable'`` covers the evaluated receiver points that can be in shadow at all;
    ``fit='receivers'`` covers every evaluated receiver point (the classic fit to what the
    camera sees: coarser texels, and acne wherever the receivers are). The light decides the
    projection (:meth:`shadowlab.lights.Light.shadow_views`)."""
    light = frame.scene.lights[light_index]
    evaluated = frame.compact_evaluated(light_index)
    casters = frame.caster_bounds()
    receivers = frame.compact_position[evaluated]
    if fit == "shadowable":
        focus = shadowable(receivers, frame.compact_normal[evaluated], light, casters,
                           eps=SHADOWABLE_OFFSET * frame.scene.extent())
        receivers = receivers[focus]
    if len(receivers) == 0:
        receivers = frame.scene.bounds()  # nothing to answer: any valid frustum will do
    return light.shadow_views(receivers, casters, resolution, projection=projection, near=near_override)


def depth_pass(frame, layer: gl.DepthTexture, prog, faces: list[LightView], rects: list[tuple[int, int, int, int]],
               cull_front: bool = False, polygon_offset: tuple[float, float] | None = None) -> None:
    """Clear ``layer`` and render the frame's casters into it through each face's view, in its
    atlas rect (x0, y0, width, height; texels). ``prog`` is a ``shadow_depth.glsl`` program;
    ``polygon_offset`` = (factor, units) for glPolygonOffset, or None."""
    from OpenGL import GL

    layer.use_as_target()
    glstate.apply(PassState(depth_test=True, depth_func="<", depth_write=True, color_write=False,
                            cull="front" if cull_front else None, polygon_offset=polygon_offset))
    GL.glClearBufferfv(GL.GL_DEPTH, 0, (CLEAR_DEPTH,))
    for face, rect in zip(faces, rects):
        frame.ctx.viewport = rect
        prog["u_light_view_proj"].write(gl.mat_bytes(face.view_proj))
        frame.draw(prog, "casters")


def cube_face_index(points: np.ndarray, light_position, faces: int) -> np.ndarray:
    """Int (M,): the face of a map's atlas a lookup of each world point (M, 3) uses — for a cube
    (``faces`` = 6) the face of the major axis of the light-to-point vector, in
    :data:`shadowlab.geometry.frusta.CUBE_FACES` order (+x, −x, +y, −y, +z, −z), with the ties
    broken as ``face_of`` in shaders/cube_face.glsl breaks them; else 0 (a single face; maps
    with several faces of another kind, cascades, choose their own)."""
    points = np.asarray(points, np.float64)
    if faces != 6:
        return np.zeros(len(points), int)
    d = points - np.asarray(light_position, np.float64)
    a = np.abs(d)
    x = (a[:, 0] >= a[:, 1]) & (a[:, 0] >= a[:, 2])
    y = ~x & (a[:, 1] >= a[:, 2])
    axis = np.where(x, 0, np.where(y, 1, 2))
    positive = np.take_along_axis(d, axis[:, None], axis=1)[:, 0] > 0
    return 2 * axis + np.where(positive, 0, 1)


def map_texel_coordinates(faces: list[LightView], rects, face_of_point, points: np.ndarray,
                          reference: np.ndarray) -> np.ndarray:
    """Float64 (M, 2): texel coordinates of world ``points`` (M, 3) in the map face each matching
    ``reference`` point (M, 3) looks up (``face_of_point(reference)`` → int (M,) indices into
    ``faces`` / ``rects``). Texels of that face, from its lower-left corner, x right and y up as
    in the map: (u, v) = (BIAS · proj · view · p).xy / w × the face's (width, height) — the
    coordinates the lookup passes floor to a texel. NaN behind the face's centre of projection
    (w <= 0). Shared by every technique that renders a depth or moment map per face
    (:class:`TexelMapping`)."""
    points = np.asarray(points, np.float64)
    face = np.asarray(face_of_point(np.asarray(reference, np.float64)), int)
    out = np.full((len(points), 2), np.nan)
    homogeneous = np.concatenate([points, np.ones((len(points), 1))], axis=1)
    for i, (view, rect) in enumerate(zip(faces, rects)):
        sel = face == i
        if not sel.any():
            continue
        s = homogeneous[sel] @ (BIAS @ view.view_proj).T
        with np.errstate(divide="ignore", invalid="ignore"):
            uv = s[:, :2] / s[:, 3:4] * np.asarray(rect[2:4], np.float64)
        uv[s[:, 3] <= 0] = np.nan
        out[sel] = uv
    return out


class TexelMapping:
    """Mixin of the techniques that render a map per face (``self.faces``: LightViews,
    ``self.rects``: their atlas rects, ``self.light``): which face a world point looks up and
    where its texels lie — what the texel-footprint metric (:mod:`shadowlab.texel_footprint`)
    measures. Valid between ``setup`` and ``release``. Subclasses with another choice of face
    (cascades) override :meth:`face_index` only."""

    def face_index(self, points: np.ndarray) -> np.ndarray:
        """Int (M,): the face of ``self.faces`` the lookup of each world point (M, 3) uses."""
        return cube_face_index(points, getattr(self.light, "position", None), len(self.faces))

    def texel_coordinates(self, points: np.ndarray, reference: np.ndarray) -> np.ndarray:
        """Float64 (M, 2): texel coordinates (x right, y up, in texels of the face) of world
        ``points`` (M, 3), each projected through the face the matching ``reference`` point
        (M, 3) looks up (:func:`map_texel_coordinates`)."""
        return map_texel_coordinates(self.faces, self.rects, self.face_index, points, reference)


def lookup_pass(frame, target, quad, map_texture) -> None:
    """One full-screen lookup over ``frame``'s G-buffer into ``target`` (a framebuffer): world
    position on texture unit 0, normal on 1, ``map_texture`` (the depth atlas) on 2 — the layout
    of ``shadow_lookup.glsl`` and ``pcss.glsl``."""
    target.use()
    glstate.apply(PassState())
    frame.tex_position.use(0)
    frame.tex_normal.use(1)
    map_texture.use(2)
    quad.render()


class ShadowMap(TexelMapping, Technique):
    """Depth-buffer shadow maps: every light type, the bias family, two-layer variants, filters."""

    name = "shadow_map"
    summary = "depth-buffer shadow maps (Williams 1978): bias variants, second-depth, midpoint, dual, PCF"
    PASSES = ("depth", "peel", "resolve", "lookup")
    LIGHT_SAMPLED = True  # light_samples=N: averaged over N points of an area light (shadowlab.light_sampling)
    PARAMS = {
        "resolution": Param(2048, "shadow map width and height in texels (per cube face)", min=16, max=16384),
        "bias": Param(0.002, "constant depth bias in window-depth units [0, 1] (dual: the offset cap)",
                      min=0.0, max=1.0),
        "depth_bits": Param(24, "depth format: 16 / 24 fixed point, 32 float", choices=(16, 24, 32)),
        "variant": Param("constant", "depth comparison", choices=VARIANTS),
        "slope_scale": Param(2.0, "slope variant: multiple of the receiver's depth change over one texel",
                             min=0.0, max=1e4),
        "normal_offset": Param(1.0, "normal_offset variant: lookup point moved along the normal, in texels",
                               min=0.0, max=1e3),
        "hardware_offset": Param(False, "slope variant: glPolygonOffset in the depth pass instead of the shader form"),
        "offset_units": Param(4.0, "hardware_offset: glPolygonOffset units", min=0.0, max=1e6),
        "filter": Param("nearest", "nearest, hw2x2 (hardware bilinear comparison), pcf3, pcf5",
                        choices=tuple(FILTERS)),
        "projection": Param("auto", "point lights: cube (six faces), frustum (one), auto",
                            choices=("auto", "cube", "frustum")),
        "near": Param(0.0, "perspective maps: force this near plane (0 = fitted to the casters)", min=0.0),
        "fit": Param("shadowable", "cover the receivers that can be shadowed (shadowable) or all visible "
                                   "receivers (receivers, the classic fit)", choices=("shadowable", "receivers")),
    }

    # ------------------------------------------------------------------ setup
    def fit_views(self, frame, light_index: int) -> tuple[list[LightView], list[str]]:
        """The map's faces and notes for the run (:func:`fit_light_views`); subclasses that warp
        or split the map (LiSPSM, cascades) override this one step and keep the rest of setup."""
        return fit_light_views(frame, light_index, self.resolution, self.projection, self.near, self.fit)

    def setup(self, frame, light_index: int) -> None:
        """Fit the faces, allocate the atlas layers and programs."""
        ctx = frame.ctx
        self.frame, self.light = frame, frame.scene.lights[light_index]
        self.faces, notes = self.fit_views(frame, light_index)
        self.notes.extend(notes)
        n = len(self.faces)
        cols, rows = (3, 2) if n == 6 else (1, 1)
        self.atlas = (cols * self.resolution, rows * self.resolution)
        max_size = int(ctx.info["GL_MAX_TEXTURE_SIZE"])
        if max(self.atlas) > max_size:
            raise TechniqueError(f"{self.name}: a {self.atlas[0]}x{self.atlas[1]} map exceeds GL_MAX_TEXTURE_SIZE "
                                 f"{max_size}; lower the resolution")
        self.rects = [((i % cols) * self.resolution, (i // cols) * self.resolution, self.resolution, self.resolution)
                      for i in range(n)]
        two_layer = self.variant in ("midpoint", "dual")
        self.layers = [gl.DepthTexture.create(self.atlas, self.depth_bits) for _ in range(3 if two_layer else 1)]
        self.map = self.layers[-1]  # the layer the lookup compares with
        self.depth_prog = gl.program("shadow_depth.glsl")
        if two_layer:
            self.peel_prog = gl.program("shadow_depth.glsl", defines={"PEEL": 1})
            self.resolve_prog = gl.program("shadow_resolve.glsl")
            self.resolve_quad = gl.fullscreen_quad(self.resolve_prog)
            gl.set_uniforms(self.peel_prog, {"u_first_layer": 0, "u_peel_epsilon": DEPTH_STEP[self.depth_bits]})
            gl.set_uniforms(self.resolve_prog, {"u_first_layer": 0, "u_second_layer": 1,
                                                "u_resolve": 1 if self.variant == "dual" else 0,
                                                "u_dual_offset": float(self.bias)})
        hw = self.filter == "hw2x2"
        self.lookup_prog = gl.program("shadow_lookup.glsl", defines={"FILTER_HW": 1} if hw else None)
        self.sampler = None
        if hw:
            self.sampler = ctx.sampler(texture=self.map.texture, filter=(ctx.LINEAR, ctx.LINEAR),
                                       compare_func="<=", repeat_x=False, repeat_y=False)
        mats = np.concatenate([BIAS @ f.view_proj for f in self.faces] +
                              [np.eye(4)] * (6 - n))
        gl.set_uniforms(self.lookup_prog, self.light.uniforms())
        self.lookup_prog["u_light_matrix"].write(
            np.ascontiguousarray(np.stack([m.T for m in mats.reshape(6, 4, 4)]), dtype="f4").tobytes())
        rects = np.zeros((6, 4), np.float32)
        rects[:n] = self.rects
        face = self.faces[0]
        gl.set_uniforms(self.lookup_prog, {
            "u_position": 0, "u_normal": 1, "u_map": 2, "u_faces": n, "u_face_rect": rects,
            "u_atlas_size": tuple(map(float, self.atlas)),
            "u_bias": 0.0 if self.variant in ("none", "second_depth", "midpoint", "dual") else float(self.bias),
            "u_slope_scale": float(self.slope_scale) if self.variant == "slope" and not self.hardware_offset else 0.0,
            "u_normal_offset": float(self.normal_offset) if self.variant == "normal_offset" else 0.0,
            "u_texel_world": float(face.texel_world), "u_texel_angle": float(face.texel_angle),
            "u_kernel_radius": FILTERS[self.filter] or 0,
        })
        self.quad = gl.fullscreen_quad(self.lookup_prog)
        self.vis_tex, self.vis_fbo = gl.visibility_target((frame.width, frame.height))

    # ------------------------------------------------------------------ passes
    def _depth_pass(self, layer: gl.DepthTexture, prog, name: str, cull_front: bool = False) -> None:
        """Render the casters into every face of ``layer`` (pass ``name``: depth or peel)."""
        with self.timed_pass(name):
            hardware = self.variant == "slope" and self.hardware_offset
            depth_pass(self.frame, layer, prog, self.faces, self.rects, cull_front,
                       (float(self.slope_scale), float(self.offset_units)) if hardware else None)

    def render(self) -> None:
        """Depth pass(es) from the light, the resolve (two-layer variants), the lookup."""
        if self.variant == "second_depth":
            self._depth_pass(self.map, self.depth_prog, "depth", cull_front=True)
        elif self.variant in ("midpoint", "dual"):
            first, second, comparison = self.layers
            self._depth_pass(first, self.depth_prog, "depth")
            first.texture.use(0)
            self._depth_pass(second, self.peel_prog, "peel")
            with self.timed_pass("resolve"):
                comparison.use_as_target()
                # every texel gets the resolved depth (written by the shader, test always passes)
                glstate.apply(PassState(depth_test=True, depth_func="always", depth_write=True, color_write=False))
                first.texture.use(0)
                second.texture.use(1)
                self.resolve_quad.render()
        else:
            self._depth_pass(self.map, self.depth_prog, "depth")
        with self.timed_pass("lookup"):
            self.vis_fbo.use()
            glstate.apply(PassState(samplers=(2,) if self.sampler is not None else ()))
            self.frame.tex_position.use(0)
            self.frame.tex_normal.use(1)
            if self.sampler is not None:
                self.sampler.use(2)
            else:
                self.map.texture.use(2)
            self.quad.render()
            if self.sampler is not None:
                self.sampler.clear(2)

    def visibility(self) -> np.ndarray:
        """Visibility in [0, 1] from the lookup pass (fractional when filtered)."""
        return gl.read_texture(self.vis_tex, 1)[..., 0]

    def stats(self) -> dict:
        """Map memory (every layer) and passes per frame."""
        two_layer = len(self.layers) == 3
        depth_passes = len(self.faces) * (2 if two_layer else 1)
        return {"memory_bytes": sum(l.nbytes for l in self.layers), "faces": len(self.faces),
                "passes": depth_passes + (1 if two_layer else 0) + 1,  # depth (and peel), resolve, lookup
                "depth_range": self.faces[0].depth_range,
                "texel_world": float(self.faces[0].texel_world) or None}

    def release(self) -> None:
        """Free the depth layers and visibility target (gl.program's cache keeps the programs)."""
        gl.park()
        if len(self.layers) == 3:
            self.resolve_quad.release()
        for layer in self.layers:
            layer.release()
        if self.sampler is not None:
            self.sampler.release()
        for obj in [self.quad, self.vis_fbo, self.vis_tex]:
            obj.release()
