"""Filtered shadow maps: variance (VSM) and exponential (ESM) shadow maps.

Both store, instead of one depth per texel, a function of depth that can be filtered linearly —
blurred, bilinearly sampled — before the comparison, so the shadow's edge comes out soft
(a filter-sized penumbra, not a physical one) and aliasing is smoothed away.

Depth is *linear* in [0, 1] over the fitted near/far planes of the map:
z = (d − near) / (far − near), d the distance along the view's axis (−z in view space); the
receiver's t the same. Light fitting is shadow_map's (:func:`fit_light_views`): spot, point
(one frustum, or a cube of six faces in an atlas), directional and target-direct lights.

Passes: the moments from the light (one per face), a separable box blur of ``kernel`` texels
(horizontal, vertical: two per face; none for ``kernel=1``), one lookup over the G-buffer.

- ``variant=vsm`` (Donnelly & Lauritzen 2006): RG32F moments (E[z], E[z²]), 64 bits per texel;
  visibility = Chebyshev's upper bound p_max = σ² / (σ² + (t − μ)²) for t > μ (1 otherwise),
  σ² = max(E[z²] − μ², ``min_variance``), then the light-bleeding reduction
  linstep(``bleed_reduction``, 1, p_max) (Lauritzen 2007, GPU Gems 3 ch. 8). Where two casters
  at different depths overlap inside the filter, σ² is large and light bleeds through the lower
  one's shadow (scene ``sm_light_bleeding``).
- ``variant=esm`` (Annen et al. 2008): R32F exp(c·z), 32 bits per texel; visibility =
  clamp(exp(−c·t) · E[exp(c·z)], 0, 1), computed as exp(log E − c·t). The exponent c
  (``exponent``) is bounded by float32: exp(c·z) overflows for c·z > 88.7 (FLT_MAX ≈ 3.4e38),
  so with z ≤ 1, c ≤ :data:`MAX_EXPONENT` = 88; a larger c is rejected. Where a receiver lies
  just behind its occluder (t − z small, near contacts) exp(−c(t − z)) stays near 1: ESM leaks
  light there, and filtering the receiver's own slope darkens lit surfaces near the edges.
"""
from __future__ import annotations

import numpy as np

from .. import gl, glstate
from ..geometry.transforms import BIAS
from ..glstate import PassState
from .base import Param, Technique, TechniqueError
from .shadow_map import fit_light_views

VARIANTS = ("vsm", "esm")
#: exp(c·z) with z ≤ 1 overflows float32 (max ≈ 3.4028e38 = exp(88.72)) for c > 88.72: the
#: largest whole exponent ESM accepts.
MAX_EXPONENT = 88.0
#: Bits per texel of each variant's map: VSM two float32 moments, ESM one float32.
BITS_PER_TEXEL = {"vsm": 64, "esm": 32}
#: Donnelly & Lauritzen 2006 §3.3: E[z²] += ¼ (∂z/∂x² + ∂z/∂y²), the depth variance over a texel.
DERIVATIVE_WEIGHT = 0.25
#: Bytes per texel of the moments pass's depth renderbuffer (24-bit depth stored in 4 bytes).
DEPTH_BUFFER_BYTES = 4


def linear_range(view) -> tuple[float, float]:
    """(near, far) of a :class:`LightView`'s projection in world units along its axis
    (perspective or orthographic, GL conventions)."""
    p = view.proj
    if p[3, 3] == 1.0:  # orthographic: z_ndc = p22 z_view + p23
        return float((p[2, 3] + 1.0) / p[2, 2]), float((p[2, 3] - 1.0) / p[2, 2])
    return float(p[2, 3] / (p[2, 2] - 1.0)), float(p[2, 3] / (p[2, 2] + 1.0))


class FilteredShadowMap(Technique):
    """Variance and exponential shadow maps: linear-depth moments, a box blur, and the VSM
    (Chebyshev) or ESM (exponential) visibility estimate."""

    name = "filtered_map"
    summary = "filtered shadow maps: variance (Donnelly & Lauritzen 2006) and exponential (Annen et al. 2008)"
    PASSES = ("moments", "blur", "lookup")
    PARAMS = {
        "variant": Param("vsm", "vsm (two moments, Chebyshev bound) or esm (exp(c z))", choices=VARIANTS),
        "resolution": Param(1024, "map width and height in texels (per cube face)", min=16, max=16384),
        "kernel": Param(5, "box blur width in texels (odd; 1 = no blur)", min=1, max=63),
        "min_variance": Param(1e-6, "vsm: the variance never goes below this (linear depth units squared)",
                              min=0.0, max=1.0),
        "bleed_reduction": Param(0.2, "vsm: p_max mapped through linstep(this, 1, p_max) against light bleeding",
                                 min=0.0, max=0.99),
        "exponent": Param(80.0, f"esm: c in exp(c z); float32 overflows for c > 88.7, so c <= {MAX_EXPONENT:g}",
                          min=0.0, min_open=True),
        "projection": Param("auto", "point lights: cube (six faces), frustum (one), auto",
                            choices=("auto", "cube", "frustum")),
    }

    def __init__(self, **params):
        super().__init__(**params)
        if self.kernel % 2 == 0:
            raise TechniqueError(f"{self.name}: kernel must be odd (a centred box of 2r+1 texels), got {self.kernel}")
        if self.exponent > MAX_EXPONENT:
            raise TechniqueError(f"{self.name}: exponent c={self.exponent:g} overflows float32: exp(c·z) with "
                                 f"linear depth z up to 1 exceeds 3.4e38 for c > 88.7; use c <= {MAX_EXPONENT:g}")

    # ------------------------------------------------------------------ setup
    def setup(self, frame, light_index: int) -> None:
        """Fit the faces (shadow_map's fitting), allocate the moments atlas, its ping-pong copy,
        the depth buffer and the programs."""
        ctx = frame.ctx
        self.frame, self.light = frame, frame.scene.lights[light_index]
        self.faces, notes = fit_light_views(frame, light_index, self.resolution, self.projection)
        self.notes.extend(notes)
        n = len(self.faces)
        ranges = {linear_range(f) for f in self.faces}
        self.near, self.far = linear_range(self.faces[0])
        if any(abs(a - self.near) > 1e-6 * abs(self.far) or abs(b - self.far) > 1e-6 * abs(self.far)
               for a, b in ranges):
            raise TechniqueError(f"{self.name}: the map's faces have different depth ranges {sorted(ranges)}")
        cols, rows = (3, 2) if n == 6 else (1, 1)
        r = self.resolution
        self.atlas = (cols * r, rows * r)
        max_size = int(ctx.info["GL_MAX_TEXTURE_SIZE"])
        if max(self.atlas) > max_size:
            raise TechniqueError(f"{self.name}: a {self.atlas[0]}x{self.atlas[1]} map exceeds GL_MAX_TEXTURE_SIZE "
                                 f"{max_size}; lower the resolution")
        self.rects = [((i % cols) * r, (i // cols) * r, r, r) for i in range(n)]
        esm = self.variant == "esm"
        comps = 1 if esm else 2
        self.moments = [ctx.texture(self.atlas, comps, dtype="f4") for _ in range(2)]
        for tex in self.moments:
            tex.filter = (ctx.LINEAR, ctx.LINEAR)
            tex.repeat_x = tex.repeat_y = False
        self.depth_rb = ctx.depth_renderbuffer(self.atlas)
        self.moments_fbo = gl.framebuffer([self.moments[0]], self.depth_rb)
        self.blur_fbos = [gl.framebuffer([tex]) for tex in self.moments]
        # Clear value: z = 1 (the far plane) — nothing casts there.
        self.clear = (float(np.exp(self.exponent)), 0.0) if esm else (1.0, 1.0)

        self.depth_prog = gl.program("filtered_depth.glsl")
        gl.set_uniforms(self.depth_prog, {"u_near": self.near, "u_far": self.far, "u_esm": int(esm),
                                          "u_exponent": float(self.exponent),
                                          "u_derivative_weight": DERIVATIVE_WEIGHT})
        self.blur_prog = gl.program("filtered_lookup.glsl", defines={"BLUR": 1})
        gl.set_uniforms(self.blur_prog, {"u_moments": 0, "u_radius": self.kernel // 2})
        self.blur_quad = gl.fullscreen_quad(self.blur_prog)

        self.lookup_prog = gl.program("filtered_lookup.glsl")
        mats = [BIAS @ f.view_proj for f in self.faces] + [np.eye(4)] * (6 - n)
        views = [f.view for f in self.faces] + [np.eye(4)] * (6 - n)
        self.lookup_prog["u_light_matrix"].write(b"".join(gl.mat_bytes(m) for m in mats))
        self.lookup_prog["u_light_view"].write(b"".join(gl.mat_bytes(m) for m in views))
        rects = np.zeros((6, 4), np.float32)
        rects[:n] = self.rects
        gl.set_uniforms(self.lookup_prog, self.light.uniforms())
        gl.set_uniforms(self.lookup_prog, {
            "u_position": 0, "u_moments": 1, "u_faces": n, "u_face_rect": rects,
            "u_atlas_size": tuple(map(float, self.atlas)), "u_near": self.near, "u_far": self.far,
            "u_esm": int(esm), "u_exponent": float(self.exponent),
            "u_min_variance": float(self.min_variance), "u_bleed_reduction": float(self.bleed_reduction),
        })
        self.quad = gl.fullscreen_quad(self.lookup_prog)
        self.vis_tex = ctx.texture((frame.width, frame.height), 1, dtype="f4")
        self.vis_fbo = gl.framebuffer([self.vis_tex])

    # ------------------------------------------------------------------ passes
    def render(self) -> None:
        """Moments from the light into every face, the two blur directions, the lookup."""
        from OpenGL import GL

        with self.timed_pass("moments"):
            self.moments_fbo.use()
            glstate.apply(PassState(depth_test=True, depth_func="<", depth_write=True))
            self.frame.ctx.viewport = (0, 0, *self.atlas)
            GL.glClearBufferfv(GL.GL_COLOR, 0, (*self.clear, 0.0, 0.0))
            GL.glClearBufferfv(GL.GL_DEPTH, 0, (1.0,))
            for face, rect in zip(self.faces, self.rects):
                self.frame.ctx.viewport = rect
                self.depth_prog["u_light_view_proj"].write(gl.mat_bytes(face.view_proj))
                self.depth_prog["u_light_view"].write(gl.mat_bytes(face.view))
                self.frame.draw(self.depth_prog, "casters")
        if self.kernel > 1:
            with self.timed_pass("blur"):
                # moments[0] → (horizontal) → moments[1] → (vertical) → moments[0]
                for src, dst, direction in ((0, 1, (1, 0)), (1, 0, (0, 1))):
                    self.blur_fbos[dst].use()
                    glstate.apply(PassState())
                    self.moments[src].use(0)
                    self.blur_prog["u_direction"].value = direction
                    for rect in self.rects:
                        self.frame.ctx.viewport = rect
                        self.blur_prog["u_rect"].value = rect
                        self.blur_quad.render()
        with self.timed_pass("lookup"):
            self.vis_fbo.use()
            glstate.apply(PassState())
            self.frame.tex_position.use(0)
            self.moments[0].use(1)
            self.quad.render()

    def visibility(self) -> np.ndarray:
        """Visibility in [0, 1], float32 (height, width), row 0 = top (fractional: filtered)."""
        return gl.read_texture(self.vis_tex, 1)[..., 0]

    def stats(self) -> dict:
        """Cost: memory (the moments atlas, its blur copy, the depth buffer), bits per texel of
        the map, passes per frame."""
        texels = self.atlas[0] * self.atlas[1]
        per_map = texels * BITS_PER_TEXEL[self.variant] // 8
        faces = len(self.faces)
        return {"memory_bytes": 2 * per_map + texels * DEPTH_BUFFER_BYTES,
                "bits_per_texel": BITS_PER_TEXEL[self.variant], "faces": faces,
                "passes": faces + (2 * faces if self.kernel > 1 else 0) + 1,  # moments, blur, lookup
                "depth_range": self.faces[0].depth_range,
                "texel_world": float(self.faces[0].texel_world) or None}

    def release(self) -> None:
        """Free the maps, framebuffers, programs and visibility target."""
        gl.park()
        self.frame.forget(self.depth_prog)
        for obj in [self.quad, self.blur_quad, self.vis_fbo, self.vis_tex, self.moments_fbo, *self.blur_fbos,
                    *self.moments, self.depth_rb, self.depth_prog, self.blur_prog, self.lookup_prog]:
            obj.release()
