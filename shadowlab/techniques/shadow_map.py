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

Light frusta are fitted to what the scene and camera involve (DESIGN §11), never constants.
The points to cover are (``fit=shadowable``, the default) the evaluated receiver points that can
be in shadow at all — those whose segment to the light crosses a caster's bounding box
(:func:`shadowable`) — or (``fit=receivers``, the classic fit) every evaluated receiver point;
then
- directional: orthographic along the light, x/y extent fitted to those points, depth range
  from the nearest caster to the farthest receiver;
- target-direct: orthographic over the light's cylinder (radius R), clipped to those points;
  near plane at the light's disc (nothing behind the light casts);
- spot: perspective with the cone's full angle α;
- point: ``projection=frustum`` — one frustum around those points; ``cube`` — six faces;
  ``auto`` — the frustum when the points fit in a cone of ``MAX_POINT_HALF_ANGLE``, else the cube.
Near planes sit at the nearest caster bounding box (a caster in front of near would be clipped
and lose its shadow), unless ``near`` forces one (to show what a too-close near plane does to
depth precision); far planes just past the farthest receiver.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import gl
from .. import transforms as tf
from .base import Param, Technique, TechniqueError

#: Widest half-angle of the single point-light frustum (degrees): beyond it texels blow up.
MAX_POINT_HALF_ANGLE = 80.0
#: Relative padding of fitted ranges, so that fitted points do not sit exactly on a clip plane.
_PAD = 1e-3
#: Cube faces: look direction and up vector, in the order the lookup shader's face_of() uses.
CUBE_FACES = [((1, 0, 0), (0, -1, 0)), ((-1, 0, 0), (0, -1, 0)), ((0, 1, 0), (0, 0, 1)),
              ((0, -1, 0), (0, 0, -1)), ((0, 0, 1), (0, -1, 0)), ((0, 0, -1), (0, -1, 0))]
VARIANTS = ("none", "constant", "slope", "normal_offset", "second_depth", "midpoint", "dual")
FILTERS = {"nearest": 0, "pcf3": 1, "pcf5": 2, "hw2x2": None}


def _aabb_distance(p: np.ndarray, bounds: np.ndarray) -> np.ndarray:
    """Distance from point p to each box in ``bounds`` (K, 2, 3); 0 inside."""
    gap = np.maximum(0.0, np.maximum(bounds[:, 0] - p, p - bounds[:, 1]))
    return np.linalg.norm(gap, axis=1)


def _corners(bounds: np.ndarray) -> np.ndarray:
    """The 8 corners of each box in ``bounds`` (K, 2, 3) → (8K, 3)."""
    idx = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)])
    return np.concatenate([np.stack([b[idx[:, 0], 0], b[idx[:, 1], 1], b[idx[:, 2], 2]], 1) for b in bounds]) \
        if len(bounds) else np.zeros((0, 3))


def shadowable(points: np.ndarray, normals: np.ndarray, light, bounds: np.ndarray, eps: float) -> np.ndarray:
    """Bool (M,): receiver points whose segment to the light crosses some caster's bounding box.

    Conservative (a superset of the points that can be in shadow): a point whose segment
    misses every caster box is certainly lit, so the shadow map need not cover it. The
    segment starts ``eps`` off the surface, so a receiver's own flat box does not count.
    """
    origin = points + eps * normals
    dirs, dist = light.to_light(origin)
    dist = np.minimum(dist, 1e30)
    hit = np.zeros(len(points), bool)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / dirs
        for lo, hi in bounds:  # slab test (Kay & Kajiya 1986), one box at a time over all points
            t1, t2 = (lo - origin) * inv, (hi - origin) * inv
            t_near = np.nanmax(np.minimum(t1, t2), axis=1)
            t_far = np.nanmin(np.maximum(t1, t2), axis=1)
            hit |= (t_near <= t_far) & (t_far >= 0) & (t_near <= dist)
    return hit


@dataclass
class Face:
    """One face of the map: light view and projection (float64 4x4); ``texel_world`` is the
    world size of a texel (orthographic) and ``texel_angle`` its size per unit distance
    (perspective), at the map's resolution."""

    view: np.ndarray
    proj: np.ndarray
    texel_world: float = 0.0
    texel_angle: float = 0.0

    @property
    def view_proj(self) -> np.ndarray:
        """Projection · view."""
        return self.proj @ self.view


def fit_light_faces(frame, light_index: int, resolution: int, projection: str = "auto",
                    near_override: float = 0.0, fit: str = "shadowable") -> tuple[list[Face], list[str]]:
    """The map's faces (1, or 6 for a cube) fitted to the frame, and notes for the run.

    ``fit='shadowable'`` covers the evaluated receiver points that can be in shadow at all;
    ``fit='receivers'`` covers every evaluated receiver point (the classic fit to what the
    camera sees: coarser texels, and acne wherever the receivers are)."""
    light = frame.scene.lights[light_index]
    evaluated = frame.compact_evaluated(light_index)
    casters = frame.caster_bounds()
    receivers = frame.compact_position[evaluated]
    if fit == "shadowable":
        focus = shadowable(receivers, frame.compact_normal[evaluated], light, casters,
                           eps=1e-5 * frame.scene.extent())
        receivers = receivers[focus]
    notes: list[str] = []
    if len(receivers) == 0:
        receivers = frame.scene.bounds()  # nothing to answer: any valid frustum will do
    if light.type_name in ("directional", "target_direct"):
        if light.type_name == "directional":
            view = tf.look_along(receivers.mean(axis=0), light.direction)
        else:
            view = tf.look_along(light.position, light.direction)
        rv = tf.transform_points(view, receivers)
        lo, hi = rv[:, :2].min(0), rv[:, :2].max(0)
        if light.type_name == "target_direct":
            lo, hi = np.maximum(lo, -light.R), np.minimum(hi, light.R)
        pad = _PAD * max(float(np.max(hi - lo)), 1e-9)
        lo, hi = lo - pad, hi + pad
        depth_r = -rv[:, 2]
        far = float(depth_r.max())
        near = float(min(depth_r.min(), (-tf.transform_points(view, _corners(casters))[:, 2]).min()
                         if len(casters) else depth_r.min()))
        if light.type_name == "target_direct":
            near = max(near, 0.0)
        span = max(far - near, 1e-9)
        near, far = near - _PAD * span, far + _PAD * span
        proj = tf.orthographic(lo[0], hi[0], lo[1], hi[1], near, far)
        return [Face(view, proj, texel_world=float(max(hi - lo)) / resolution)], notes
    # point and spot: perspective from the light's position
    p = light.position
    dist = np.linalg.norm(receivers - p, axis=1)
    far = float(dist.max()) * (1 + _PAD)
    nearest = float(_aabb_distance(p, casters).min()) if len(casters) else far * 0.5
    near = min(max(nearest * (1 - _PAD), far * 1e-4), far * 0.5)
    if near_override > 0:
        near = near_override
    if light.type_name == "spot":
        fov = min(light.alpha * (1 + _PAD), 179.0)
        return [Face(tf.look_along(p, light.direction), tf.perspective(fov, 1.0, near, far),
                     texel_angle=2 * np.tan(np.radians(fov) / 2) / resolution)], notes
    dirs = (receivers - p) / dist[:, None]
    axis = tf.normalize(dirs.mean(axis=0))
    angles = np.degrees(np.arccos(np.clip(dirs @ axis, -1, 1)))
    half = float(angles.max()) * (1 + _PAD)
    if projection == "cube" or (projection == "auto" and half > MAX_POINT_HALF_ANGLE):
        proj = tf.perspective(90.0, 1.0, near, far)
        faces = [Face(tf.look_at(p, p + np.array(d, float), np.array(u, float)), proj,
                      texel_angle=2.0 / resolution) for d, u in CUBE_FACES]
        return faces, notes
    if half > MAX_POINT_HALF_ANGLE:
        outside = int(np.sum(angles > MAX_POINT_HALF_ANGLE))
        notes.append(f"point light: receivers span {half:.1f} degrees around the light, more than one "
                     f"frustum's {MAX_POINT_HALF_ANGLE}; {outside} shadowable pixels lie outside the shadow "
                     f"map and are treated as lit (use projection=cube)")
        half = MAX_POINT_HALF_ANGLE
    fov = 2 * half
    return [Face(tf.look_along(p, axis), tf.perspective(fov, 1.0, near, far),
                 texel_angle=2 * np.tan(np.radians(fov) / 2) / resolution)], notes


class ShadowMap(Technique):
    """Depth-buffer shadow maps: every light type, the bias family, two-layer variants, filters."""

    name = "shadow_map"
    summary = "depth-buffer shadow maps (Williams 1978): bias variants, second-depth, midpoint, dual, PCF"
    fractional = True
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
    def setup(self, frame, light_index: int) -> None:
        """Fit the faces, allocate the atlas layers and programs."""
        ctx = frame.ctx
        self.frame, self.light = frame, frame.scene.lights[light_index]
        self.faces, notes = fit_light_faces(frame, light_index, self.resolution, self.projection, self.near,
                                            self.fit)
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
            gl.set_uniforms(self.peel_prog, {"u_first_layer": 0, "u_peel_epsilon": self._depth_step()})
            gl.set_uniforms(self.resolve_prog, {"u_first_layer": 0, "u_second_layer": 1,
                                                "u_resolve": 1 if self.variant == "dual" else 0,
                                                "u_dual_offset": float(self.bias)})
        hw = self.filter == "hw2x2"
        self.lookup_prog = gl.program("shadow_lookup.glsl", defines={"FILTER_HW": 1} if hw else None)
        self.sampler = None
        if hw:
            self.sampler = ctx.sampler(texture=self.map.texture, filter=(ctx.LINEAR, ctx.LINEAR),
                                       compare_func="<=", repeat_x=False, repeat_y=False)
        mats = np.concatenate([tf.BIAS @ f.view_proj for f in self.faces] +
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
        self.vis_tex = ctx.texture((frame.width, frame.height), 1, dtype="f4")
        self.vis_fbo = ctx.framebuffer(color_attachments=[self.vis_tex])

    def _depth_step(self) -> float:
        """One step of the depth format (what 'the same surface' means when peeling)."""
        return {16: 1.0 / 65535, 24: 1.0 / 16777215, 32: 2.0 ** -22}[self.depth_bits]

    # ------------------------------------------------------------------ passes
    def _depth_pass(self, layer: gl.DepthTexture, prog, cull_front: bool = False) -> None:
        """Render the casters into every face of ``layer``."""
        from OpenGL import GL

        ctx, frame = self.frame.ctx, self.frame
        layer.use_as_target()
        ctx.enable(ctx.DEPTH_TEST)
        ctx.disable(ctx.BLEND)
        ctx.depth_func = "<"
        ctx.clear(depth=1.0)
        if cull_front:
            ctx.enable(ctx.CULL_FACE)
            ctx.cull_face = "front"
        else:
            ctx.disable(ctx.CULL_FACE)
        hardware = self.variant == "slope" and self.hardware_offset
        if hardware:
            GL.glEnable(GL.GL_POLYGON_OFFSET_FILL)
            GL.glPolygonOffset(float(self.slope_scale), float(self.offset_units))
        for face, rect in zip(self.faces, self.rects):
            ctx.viewport = rect
            prog["u_light_view_proj"].write(gl.mat_bytes(face.view_proj))
            frame.draw(prog, "casters")
        if hardware:
            GL.glDisable(GL.GL_POLYGON_OFFSET_FILL)
        ctx.disable(ctx.CULL_FACE)
        ctx.cull_face = "back"

    def render(self) -> None:
        """Depth pass(es) from the light, the resolve (two-layer variants), the lookup."""
        ctx = self.frame.ctx
        if self.variant == "second_depth":
            self._depth_pass(self.map, self.depth_prog, cull_front=True)
        elif self.variant in ("midpoint", "dual"):
            first, second, comparison = self.layers
            self._depth_pass(first, self.depth_prog)
            first.texture.use(0)
            self._depth_pass(second, self.peel_prog)
            comparison.use_as_target()
            ctx.enable(ctx.DEPTH_TEST)
            ctx.depth_func = "1"  # always: every texel gets the resolved depth
            first.texture.use(0)
            second.texture.use(1)
            self.resolve_quad.render()
            ctx.depth_func = "<"
        else:
            self._depth_pass(self.map, self.depth_prog)
        self.vis_fbo.use()
        ctx.disable(ctx.DEPTH_TEST)
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
        layers = len(self.layers) if self.variant in ("midpoint", "dual") else 1
        depth_passes = len(self.faces) * (2 if layers == 3 else 1)
        proj = self.faces[0].proj
        if proj[3, 3] == 1.0:  # orthographic: depth = (z - near) / (far - near)
            depth_range = 2.0 / abs(proj[2, 2])
        else:  # perspective: far - near from the matrix
            near, far = proj[2, 3] / (proj[2, 2] - 1.0), proj[2, 3] / (proj[2, 2] + 1.0)
            depth_range = abs(far - near)
        return {"memory_bytes": sum(l.nbytes for l in self.layers), "faces": len(self.faces),
                "passes": depth_passes + (1 if layers == 3 else 0) + 1,
                "depth_range": float(depth_range),
                "texel_world": float(self.faces[0].texel_world) or None}

    def release(self) -> None:
        """Free the depth layers, programs and visibility target."""
        self.frame.target.use()  # moderngl re-binds its current framebuffer later: never leave a deleted one
        progs = [self.depth_prog, self.lookup_prog]
        if self.variant in ("midpoint", "dual"):
            progs += [self.peel_prog, self.resolve_prog]
            self.resolve_quad.release()
        for prog in (self.depth_prog, getattr(self, "peel_prog", None)):
            if prog is not None:
                self.frame.forget(prog)
        for layer in self.layers:
            layer.release()
        if self.sampler is not None:
            self.sampler.release()
        for obj in [self.quad, self.vis_fbo, self.vis_tex] + progs:
            obj.release()
