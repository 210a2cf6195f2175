"""Depth-buffer shadow maps (Williams 1978), the classic two-pass form.

Pass 1 renders the casters' depth from the light into a depth texture of ``depth_bits``
precision; pass 2 (over the shared G-buffer) transforms each visible point into the light's
clip space with the bias matrix and compares its depth, minus a constant ``bias`` in
window-depth units, with the stored one.

Light frusta are fitted to what the scene and camera involve (DESIGN §11), never constants.
The points to cover are the evaluated receiver points that can be in shadow at all — those
whose segment to the light crosses a caster's bounding box (:func:`shadowable`); then
- directional: orthographic along the light, its x/y extent fitted to the evaluated receiver
  points, its depth range from the nearest caster to the farthest receiver;
- target-direct: orthographic over the light's cylinder (radius R), clipped to the receivers;
  near plane at the light's disc (nothing behind the light casts);
- spot: perspective with the cone's full angle α;
- point: a single perspective frustum around the receivers (a cube map comes later); when
  the receivers span more than ``MAX_POINT_HALF_ANGLE`` around the light, the frustum is
  clamped and the run reports how many evaluated pixels fall outside (treated as lit).
Near planes sit at the nearest caster bounding box (a caster in front of near would be
clipped and lose its shadow), far planes just past the farthest receiver.
"""
from __future__ import annotations

import numpy as np

from .. import gl
from .. import transforms as tf
from .base import Param, Technique, TechniqueError

#: Widest half-angle of the single point-light frustum (degrees): beyond it texels blow up.
MAX_POINT_HALF_ANGLE = 80.0
#: Relative padding of fitted ranges, so that fitted points do not sit exactly on a clip plane.
_PAD = 1e-3


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


def fit_light_frustum(frame, light_index: int) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """Light view and projection matrices (float64 4x4) fitted to the frame, and notes."""
    light = frame.scene.lights[light_index]
    evaluated = frame.compact_evaluated(light_index)
    casters = frame.caster_bounds()
    receivers = frame.compact_position[evaluated]
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
        return view, proj, notes
    # point and spot: perspective from the light's position
    p = light.position
    dist = np.linalg.norm(receivers - p, axis=1)
    far = float(dist.max()) * (1 + _PAD)
    nearest = float(_aabb_distance(p, casters).min()) if len(casters) else far * 0.5
    near = min(max(nearest * (1 - _PAD), far * 1e-4), far * 0.5)
    if light.type_name == "spot":
        view = tf.look_along(p, light.direction)
        fov = min(light.alpha * (1 + _PAD), 179.0)
    else:
        dirs = (receivers - p) / dist[:, None]
        axis = tf.normalize(dirs.mean(axis=0))
        half = float(np.degrees(np.arccos(np.clip(dirs @ axis, -1, 1))).max()) * (1 + _PAD)
        # A square frustum must contain the cone of this half-angle: its diagonal is wider.
        if half > MAX_POINT_HALF_ANGLE:
            outside = int(np.sum(np.degrees(np.arccos(np.clip(dirs @ axis, -1, 1))) > MAX_POINT_HALF_ANGLE))
            notes.append(f"point light: receivers span {half:.1f} degrees around the light, more than one "
                         f"frustum's {MAX_POINT_HALF_ANGLE}; {outside} evaluated pixels lie outside the "
                         f"shadow map and are treated as lit")
            half = MAX_POINT_HALF_ANGLE
        view = tf.look_along(p, axis)
        fov = 2 * half
    return view, tf.perspective(fov, 1.0, near, far), notes


class ShadowMap(Technique):
    """Classic two-pass depth-buffer shadow map with a constant depth bias."""

    name = "shadow_map"
    summary = "depth-buffer shadow map (Williams 1978), constant bias"
    PARAMS = {
        "resolution": Param(2048, "shadow map width and height in texels", min=16, max=16384),
        "bias": Param(0.002, "constant depth bias in window-depth units [0, 1]", min=0.0, max=1.0),
        "depth_bits": Param(24, "depth texture format: 16 / 24 fixed point, 32 float", choices=(16, 24, 32)),
    }

    def setup(self, frame, light_index: int) -> None:
        """Fit the light frustum, allocate the depth map and the visibility target."""
        ctx = frame.ctx
        max_size = int(ctx.info["GL_MAX_TEXTURE_SIZE"])
        if self.resolution > max_size:
            raise TechniqueError(f"{self.name}: resolution {self.resolution} exceeds GL_MAX_TEXTURE_SIZE {max_size}")
        self.frame = frame
        self.light_view, self.light_proj, notes = fit_light_frustum(frame, light_index)
        self.notes.extend(notes)
        self.light_view_proj = self.light_proj @ self.light_view
        self.depth = gl.DepthTexture.create((self.resolution, self.resolution), self.depth_bits)
        self.depth_prog = gl.program("shadow_depth.glsl")
        self.depth_prog["u_light_view_proj"].write(gl.mat_bytes(self.light_view_proj))
        self.lookup_prog = gl.program("shadow_lookup.glsl")
        self.lookup_prog["u_light_matrix"].write(gl.mat_bytes(tf.BIAS @ self.light_view_proj))
        self.lookup_prog["u_bias"].value = float(self.bias)
        self.lookup_prog["u_position"].value = 0
        self.lookup_prog["u_shadow_map"].value = 1
        self.quad = gl.fullscreen_quad(self.lookup_prog)
        self.vis_tex = ctx.texture((frame.width, frame.height), 1, dtype="f4")
        self.vis_fbo = ctx.framebuffer(color_attachments=[self.vis_tex])

    def render(self) -> None:
        """Depth pass from the light, then the comparison pass over the G-buffer."""
        ctx, frame = self.frame.ctx, self.frame
        self.depth.use_as_target()
        ctx.enable(ctx.DEPTH_TEST)
        ctx.disable(ctx.CULL_FACE | ctx.BLEND)
        ctx.depth_func = "<"
        ctx.clear(depth=1.0)
        frame.draw(self.depth_prog, "casters")
        self.vis_fbo.use()
        ctx.disable(ctx.DEPTH_TEST)
        frame.tex_position.use(0)
        self.depth.texture.use(1)
        self.quad.render()

    def visibility(self) -> np.ndarray:
        """Binary visibility read back from the lookup pass."""
        return gl.read_texture(self.vis_tex, 1)[..., 0]

    def stats(self) -> dict:
        """Shadow-map memory and passes."""
        return {"memory_bytes": self.depth.nbytes, "passes": 2}

    def release(self) -> None:
        """Free the depth map, programs and visibility target."""
        self.frame.target.use()  # moderngl re-binds its current framebuffer later: never leave a deleted one
        self.frame.forget(self.depth_prog)
        self.depth.release()
        for obj in (self.quad, self.vis_fbo, self.vis_tex, self.depth_prog, self.lookup_prog):
            obj.release()
