"""Filtered shadow maps: variance (VSM), exponential (ESM), exponential variance (EVSM) and
moment (MSM) shadow maps.

All of them store, instead of one depth per texel, a function of depth that can be filtered linearly —
blurred, bilinearly sampled — before the comparison, so the shadow's edge comes out soft
(a filter-sized penumbra, not a physical one) and aliasing is smoothed away.

Depth is *linear* in [0, 1] over the fitted near/far planes of the map:
z = (d − near) / (far − near), d the distance along the view's axis (−z in view space); the
receiver's t the same. Light fitting and the atlas are the map toolkit's
(:func:`~shadowlab.techniques.maps.toolkit.fit_light_views`, :class:`~shadowlab.techniques.maps.toolkit.Atlas`): spot, point
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
- ``variant=evsm2`` / ``evsm4`` (exponential variance shadow maps: Lauritzen & McCool 2008,
  "Layered variance shadow maps"; Lauritzen 2007, thesis §4.6): depth is warped to
  z' = 2z − 1 ∈ [−1, 1] (:data:`EVSM_WARP`), then p = exp(c⁺ z') and n = −exp(−c⁻ z')
  (``positive_exponent`` c⁺, ``negative_exponent`` c⁻). The warp to [−1, 1] doubles the usable
  exponent: exp(c z') = e^(−c) · exp(2c z), an ESM of exponent 2c up to a constant factor that
  Chebyshev's bound ignores, while the stored values stay within [e^(−c), e^c]. evsm2 stores
  (p, p²), evsm4 (p, p², n, n²), each second moment biased by ¼ of the squared derivatives of
  its warped depth as VSM's. Visibility: VSM's Chebyshev bound (and linstep
  ``bleed_reduction``) on each warped pair with the receiver warped the same way; evsm4 takes
  the smaller of the two. Variance floor rule: ``min_variance`` is in linear-depth units², so
  each warp's floor is min_variance · (dw/dz)² at the receiver, dw/dz = 2c⁺·p (positive) and
  2c⁻·|n| (negative) — the factor 2 from z' = 2z − 1.
  Limits: the stored second moment reaches exp(2c) (at z' = ±1), so c ≤ ln(max)/2 of the
  storage format (:func:`max_evsm_exponent`): 44.36 for float32 (3.4028e38), 5.545 for float16
  (65504); a larger exponent is an error. The negative exponent is also bounded by the
  lookup's float32 arithmetic, c⁻ ≤ 35.69 (:func:`max_evsm_negative_exponent`: past it the
  far end's differences are subnormal and the result depends on the driver's flush-to-zero
  state). The defaults (40, 5) fit float32; ``precision=16`` needs ``positive_exponent`` ≤ 5.5.
- ``variant=msm`` (moment shadow maps, Peters & Klein 2015, the Hamburger 4MSM of their
  Algorithm 2): stores (z, z², z³, z⁴); the lookup biases the filtered moments
  b' = (1 − α) b + α (½, ½, ½, ½) (``moment_bias`` α, 3e-5 as in the paper), solves the 3x3
  Hankel system B c = (1, t, t²) by an LDLᵀ (Cholesky) factorisation, takes the roots
  z₂ ≤ z₃ of c₃ z² + c₂ z + c₁ and the shadow intensity G of the paper's three cases;
  visibility = 1 − clamp(G, 0, 1). ``precision=32`` stores raw moments in RGBA32F;
  ``precision=16`` the paper's 16-bit storage (§4 "Quantization"): RGBA16 UNORM of
  Θ b + o (:data:`MSM_QUANTIZE`, :data:`MSM_QUANTIZE_OFFSET`), which maps the moments of
  any depth in [0, 1] into [0, 1]; the lookup inverts it (:data:`MSM_DEQUANTIZE`) after
  filtering. The blur reads and writes the same format, so the blurred moments are quantised
  again after each blur direction.

``precision`` (32 or 16) picks the storage format of every variant: vsm RG32F / RG16F, esm
R32F / R16F (exp(c·z) < 65504 needs c ≤ ln(65504) = 11.09, :func:`max_esm_exponent`), evsm
RG(BA)32F / RG(BA)16F, msm RGBA32F / RGBA16 UNORM. Bits per texel: :func:`bits_per_texel`.
"""
from __future__ import annotations

import numpy as np

from ...gpu import glstate, programs, targets
from ...gpu.glstate import PassState
from ..base import FIRST, MAX, SUM, Param, PlotStyle, Technique, TechniqueError, TuneRange
from .toolkit import ATLAS_DEFINES, Atlas, TexelMapping, fit_light_views
from .contact import ContactShadows

VARIANTS = ("vsm", "esm", "evsm2", "evsm4", "msm")
#: The variant's number in the shaders (u_variant; the shaders get these as #defines).
VARIANT_ID = {v: i for i, v in enumerate(VARIANTS)}
#: exp(c·z) with z ≤ 1 overflows float32 (max ≈ 3.4028e38 = exp(88.72)) for c > 88.72: the
#: largest whole exponent ESM accepts.
MAX_EXPONENT = 88.0
#: Storage precisions (bits per stored component) and the moderngl dtype of each variant's map.
PRECISIONS = (32, 16)
#: Moments stored per texel (texture components).
COMPONENTS = {"vsm": 2, "esm": 1, "evsm2": 2, "evsm4": 4, "msm": 4}
#: Texture dtype per (variant, precision): floats, except 16-bit MSM, stored quantised in
#: 16-bit unsigned normalised channels (RGBA16, Peters & Klein 2015 §4).
DTYPES = {(v, 32): "f4" for v in VARIANTS} | {(v, 16): "f2" for v in VARIANTS} | {("msm", 16): "nu2"}
#: Largest finite value of each float storage format.
FORMAT_MAX = {32: float(np.finfo(np.float32).max), 16: float(np.finfo(np.float16).max)}
#: EVSM's depth warp z' = scale · z + offset, from [0, 1] to [−1, 1] (Lauritzen & McCool 2008).
EVSM_WARP = (2.0, -1.0)
#: Peters & Klein 2015 §4 ("Quantization"), the optimised transform of the Hamburger 4MSM
#: moments for 16-bit storage, as published with the paper's code: stored = Θ b + o maps the
#: moments b = (z, z², z³, z⁴) of any depth z in [0, 1] into [0, 1]. Θ is written here as it
#: acts on a column vector (stored_i = Σ_j Θ[i, j] b_j).
MSM_QUANTIZE = np.array([
    [-2.07224649, 32.23703778, -68.571074599, 39.3703274134],
    [13.7948857237, -59.4683975703, 82.0359750338, -35.364903257],
    [0.105877704, -1.9077466311, 9.3496555107, -6.6543490743],
    [9.7924062118, -33.7652110555, 47.9456096605, -23.9728048165]])
MSM_QUANTIZE_OFFSET = np.array([0.035955884801, 0.0, 0.0, 0.0])
#: The published inverse of :data:`MSM_QUANTIZE` (b = Θ⁻¹ (stored − o)), as printed (10 digits).
MSM_DEQUANTIZE = np.array([
    [0.2227744146, 0.0771972861, 0.7926986636, 0.0319417555],
    [0.1549679261, 0.1394629426, 0.7963415838, -0.1722823173],
    [0.1451988946, 0.2120202157, 0.7258694464, -0.2758014811],
    [0.163127443, 0.2591432266, 0.6539092497, -0.3376131734]])
#: Peters & Klein 2015, Algorithm 2: the moments are pulled towards those of this vector by the
#: moment bias α (b' = (1 − α) b + α · this), which keeps the Hankel matrix positive definite.
MSM_BIAS_TARGET = (0.5, 0.5, 0.5, 0.5)


#: The variant ids as #defines of the shaders (VARIANT_VSM 0, ...), so both sides share one table.
VARIANT_DEFINES = {f"VARIANT_{v.upper()}": i for v, i in VARIANT_ID.items()}


def bits_per_texel(variant: str, precision: int) -> int:
    """Bits per texel of a variant's moments map: components × bits per component (vsm 64/32,
    esm 32/16, evsm2 64/32, evsm4 128/64, msm 128/64 for precision 32/16)."""
    return COMPONENTS[variant] * precision


def max_esm_exponent(precision: int) -> float:
    """ESM's largest c: exp(c·z) with z ≤ 1 stays below the format's max (ln max: 88.72 for
    float32, 11.09 for float16). For float32 the technique keeps the whole :data:`MAX_EXPONENT`."""
    return MAX_EXPONENT if precision == 32 else float(np.log(FORMAT_MAX[precision]))


def max_evsm_exponent(precision: int) -> float:
    """EVSM's largest exponent c: the stored second moment exp(2c·z') with z' ≤ 1 must stay
    below the format's max, c ≤ ln(max)/2 (44.36 for float32, 5.545 for float16)."""
    return float(np.log(FORMAT_MAX[precision]) / 2.0)


def max_evsm_negative_exponent() -> float:
    """The largest negative EVSM exponent c⁻ whose arithmetic stays in normal float32 numbers:
    at the map's far end (z' = 1) the negative warp's second moment is exp(−2c⁻), and the
    lookup's Chebyshev bound subtracts numbers of that size, so it needs exp(−2c⁻) · 2⁻²³ (its
    last mantissa bit) ≥ FLT_MIN = 1.18e-38: c⁻ ≤ (ln(1/FLT_MIN) − 23 ln 2)/2 = 35.70. Past it the
    differences are subnormal — flushed to zero or not depending on the floating-point mode of
    the CPU/GPU thread — and the verdict would depend on the driver's state: on llvmpipe
    (box_on_plane) evsm4 with c⁻ well past the bound changed pixels, and its false-shadow rate,
    after a float16 EVSM had run in the same process (near the bound the bits stayed the
    same). The shader computes in float32 whatever the storage, so this bound holds for both
    precisions."""
    f32 = np.finfo(np.float32)
    return float((np.log(1.0 / f32.tiny) - f32.nmant * np.log(2.0)) / 2.0)


def msm_quantize(moments: np.ndarray) -> np.ndarray:
    """The 16-bit MSM storage transform Θ b + o of moments (..., 4) float64 (:data:`MSM_QUANTIZE`)."""
    return np.asarray(moments, np.float64) @ MSM_QUANTIZE.T + MSM_QUANTIZE_OFFSET


def msm_dequantize(stored: np.ndarray) -> np.ndarray:
    """The inverse of :func:`msm_quantize` with the published inverse matrix, (..., 4) float64."""
    return (np.asarray(stored, np.float64) - MSM_QUANTIZE_OFFSET) @ MSM_DEQUANTIZE.T


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


class FilteredShadowMap(ContactShadows, TexelMapping, Technique):
    """Filtered shadow maps: linear-depth moments (VSM, ESM, EVSM 2/4, MSM), a box blur, and
    the variant's visibility estimate (Chebyshev, exponential, Chebyshev on warped depths,
    Hamburger 4-moment bound)."""

    name = "filtered_map"
    summary = ("filtered shadow maps: variance (Donnelly & Lauritzen 2006), exponential (Annen et al. 2008), "
               "exponential variance (Lauritzen & McCool 2008), moment (Peters & Klein 2015)")
    PASSES = ("moments", "blur", "lookup")
    STYLE = PlotStyle("#e377c2", "X")
    STATS = {"memory_bytes": MAX, "bits_per_texel": FIRST, "faces": FIRST, "passes": SUM, "depth_range": FIRST,
             "texel_world": FIRST}
    READS = frozenset({"position"})
    PROVIDES = frozenset({"texel_mapping"})
    PARAMS = {
        "variant": Param("vsm", "vsm (two moments, Chebyshev bound), esm (exp(c z)), evsm2 / evsm4 (Chebyshev on "
                                "exp-warped depth: positive, positive and negative), msm (Hamburger 4 moments)",
                         choices=VARIANTS),
        "resolution": Param(1024, "map width and height in texels (per cube face)", min=16, max=16384,
                            # powers of two; the blur's cost grows with the area, 4096 is already costly
                            tune=TuneRange(256, 4096, log=True)),
        "kernel": Param(5, "box blur width in texels (odd; 1 = no blur)", min=1, max=63,
                        # from no blur to a wide one; even widths are refused (and cost the search nothing)
                        tune=TuneRange(1, 15)),
        "min_variance": Param(1e-6, "vsm: the variance never goes below this (linear depth units squared)",
                              # from float32 noise (acne) to a floor that lights every contact
                              min=0.0, max=1.0, tune=TuneRange(1e-8, 1e-3, log=True)),
        "bleed_reduction": Param(0.2, "vsm: p_max mapped through linstep(this, 1, p_max) against light bleeding",
                                 # off to near-binary: past 0.9 the soft edge is all but gone
                                 min=0.0, max=0.99, tune=TuneRange(0.0, 0.9)),
        "exponent": Param(80.0, f"esm: c in exp(c z); float32 overflows for c > 88.7, so c <= {MAX_EXPONENT:g}",
                          # below 5 the exponential test barely darkens (light leaks); 85 stays under the 88 cap
                          min=0.0, min_open=True, tune=TuneRange(5.0, 85.0)),
        "projection": Param("auto", "point lights: cube (six faces), frustum (one), auto",
                            choices=("auto", "cube", "frustum")),
        "positive_exponent": Param(40.0, f"evsm: c+ in exp(c+ z'), z' = 2z - 1; c+ <= ln(max)/2 of the storage "
                                         f"({max_evsm_exponent(32):.2f} float32, {max_evsm_exponent(16):.3f} float16)",
                                   # 42 stays under the float32 bound 44.36 (float16: 5.54, refused above)
                                   min=0.0, min_open=True, tune=TuneRange(5.0, 42.0)),
        "negative_exponent": Param(5.0, "evsm4: c- in -exp(-c- z'); the same bound as positive_exponent",
                                   # evsm4 refuses c- above 35.69 (subnormal arithmetic at the far end)
                                   min=0.0, min_open=True, tune=TuneRange(1.0, 35.0)),
        "moment_bias": Param(3e-5, "msm: alpha in b' = (1 - alpha) b + alpha (1/2, 1/2, 1/2, 1/2) (Peters & Klein 2015); "
                                   "alpha = 1 leaves only the target's singular Hankel matrix",
                             # from float32 round-off to a bias that visibly lightens the shadows
                             min=0.0, max=0.99, min_open=True, tune=TuneRange(1e-6, 1e-2, log=True)),
        "precision": Param(32, "bits per stored moment: 32 (float) or 16 (half float; msm: the paper's quantised "
                               "16-bit unsigned normalised storage)", choices=PRECISIONS),
    }

    def __init__(self, **params):
        super().__init__(**params)
        if self.kernel % 2 == 0:
            raise TechniqueError(f"{self.name}: kernel must be odd (a centred box of 2r+1 texels), got {self.kernel}")
        if self.exponent > MAX_EXPONENT:
            raise TechniqueError(f"{self.name}: exponent c={self.exponent:g} overflows float32: exp(c·z) with "
                                 f"linear depth z up to 1 exceeds 3.4e38 for c > 88.7; use c <= {MAX_EXPONENT:g}")
        fmt = f"float{self.precision}"
        if self.variant == "esm" and self.exponent > max_esm_exponent(self.precision):
            raise TechniqueError(f"{self.name}: exponent c={self.exponent:g} overflows {fmt}: exp(c·z) with z up to "
                                 f"1 exceeds {FORMAT_MAX[self.precision]:g} for c > ln({FORMAT_MAX[self.precision]:g}) "
                                 f"= {max_esm_exponent(self.precision):.3f}; use exponent <= "
                                 f"{np.floor(max_esm_exponent(self.precision) * 100) / 100:g}")
        if self.variant.startswith("evsm"):
            bound = max_evsm_exponent(self.precision)
            used = ["positive_exponent"] + (["negative_exponent"] if self.variant == "evsm4" else [])
            for key in used:
                c = self._params[key]
                if c > bound:
                    raise TechniqueError(
                        f"{self.name}: {key}={c:g} overflows {fmt}: the stored second moment exp(2c) exceeds "
                        f"{FORMAT_MAX[self.precision]:g} for c > ln({FORMAT_MAX[self.precision]:g})/2 = {bound:.3f}; "
                        f"use {key} <= {bound:.3f}" + (" (e.g. 5.5 for precision=16)" if self.precision == 16 else ""))
            negative_bound = max_evsm_negative_exponent()
            if self.variant == "evsm4" and self.negative_exponent > negative_bound:
                raise TechniqueError(
                    f"{self.name}: negative_exponent={self.negative_exponent:g} makes the lookup's arithmetic "
                    f"subnormal in float32 at the map's far end (exp(-2c)·2^-23 < 1.18e-38), where the result "
                    f"depends on the driver's flush-to-zero mode; use negative_exponent <= "
                    f"{np.floor(negative_bound * 100) / 100:g}")

    # ------------------------------------------------------------------ setup
    def setup(self, frame, slot) -> None:
        """Fit the faces (the map toolkit's fitting), allocate the moments atlas, its ping-pong
        copy, the depth buffer and the programs."""
        ctx = frame.ctx
        faces, notes = fit_light_views(frame, slot, self.resolution, self.projection)
        self.notes.extend(notes)
        ranges = {linear_range(f) for f in faces}
        self.near, self.far = linear_range(faces[0])
        if any(abs(a - self.near) > 1e-6 * abs(self.far) or abs(b - self.far) > 1e-6 * abs(self.far)
               for a, b in ranges):
            raise TechniqueError(f"{self.name}: the map's faces have different depth ranges {sorted(ranges)}")
        self.atlas = Atlas.grid(faces, self.resolution, self.name)
        size = self.atlas.size
        comps = COMPONENTS[self.variant]
        self.moments = [self.own(ctx.texture(size, comps, dtype=DTYPES[(self.variant, self.precision)]))
                        for _ in range(2)]
        for tex in self.moments:
            tex.filter = (ctx.LINEAR, ctx.LINEAR)
            tex.repeat_x = tex.repeat_y = False
        self.depth_rb = self.own(ctx.depth_renderbuffer(size))
        self.moments_fbo = self.own(targets.framebuffer([self.moments[0]], self.depth_rb))
        self.blur_fbos = [self.own(targets.framebuffer([tex])) for tex in self.moments]
        # Clear value: the moments of z = 1 (the far plane) — nothing casts there.
        self.clear = self._far_moments()

        self.depth_prog = self.program("filtered_depth.glsl", defines=VARIANT_DEFINES)
        programs.set_uniforms(self.depth_prog, {"u_near": self.near, "u_far": self.far,
                                                "u_exponent": float(self.exponent),
                                                "u_derivative_weight": DERIVATIVE_WEIGHT,
                                                "u_moment_max": FORMAT_MAX[self.precision]})
        self._set_variant_uniforms(self.depth_prog)
        self.blur_prog = self.program("filtered_blur.glsl")
        programs.set_uniforms(self.blur_prog, {"u_moments": 0, "u_radius": self.kernel // 2})
        self.blur_quad = self.fullscreen_quad(self.blur_prog)

        self.lookup_prog = self.program("filtered_lookup.glsl", defines={**VARIANT_DEFINES, **ATLAS_DEFINES})
        self.atlas.write_uniforms(self.lookup_prog)
        self.lookup_prog["u_light_view"].write(self.atlas.view_matrices())
        programs.set_uniforms(self.lookup_prog, self.light.uniforms())
        programs.set_uniforms(self.lookup_prog, {
            "u_moments": 1, "u_near": self.near, "u_far": self.far,
            "u_exponent": float(self.exponent),
            "u_min_variance": float(self.min_variance), "u_bleed_reduction": float(self.bleed_reduction),
            "u_moment_bias": float(self.moment_bias), "u_moment_bias_target": MSM_BIAS_TARGET,
        })
        self._set_variant_uniforms(self.lookup_prog)
        self.quad = self.fullscreen_quad(self.lookup_prog)
        self.vis_tex, self.vis_fbo = self.visibility_target((frame.width, frame.height))

    def _quantized(self) -> bool:
        """True for the 16-bit MSM map, stored through the quantisation transform."""
        return self.variant == "msm" and self.precision == 16

    def _far_moments(self) -> tuple[float, float, float, float]:
        """The stored moments of depth z = 1 (the far plane: the map's clear value), as the moments
        pass would write them."""
        if self.variant == "esm":
            return (float(np.exp(self.exponent)), 0.0, 0.0, 0.0)
        if self.variant == "vsm":
            return (1.0, 1.0, 0.0, 0.0)
        if self.variant == "msm":
            b = np.ones(4)
            return tuple(float(v) for v in (msm_quantize(b) if self._quantized() else b))
        warped = EVSM_WARP[0] * 1.0 + EVSM_WARP[1]
        p, n = np.exp(self.positive_exponent * warped), -np.exp(-self.negative_exponent * warped)
        return (float(p), float(p * p), float(n), float(n * n))

    def _set_variant_uniforms(self, prog) -> None:
        """Set the uniforms of the moments or the lookup program that depend on the variant: its
        id, EVSM's warp and exponents, MSM's storage transform (identity and zero for 32-bit).
        (The moments pass's clamp u_moment_max is set with its other uniforms in setup.)"""
        quantize = self._quantized()
        values = {
            "u_variant": VARIANT_ID[self.variant],
            "u_warp": EVSM_WARP,
            "u_exponents": (float(self.positive_exponent), float(self.negative_exponent)),
            "u_quantize_offset": tuple(float(v) for v in (MSM_QUANTIZE_OFFSET if quantize else np.zeros(4))),
        }
        programs.set_uniforms(prog, values)
        for key, matrix in (("u_quantize", MSM_QUANTIZE), ("u_dequantize", MSM_DEQUANTIZE)):
            if key in prog:
                prog[key].write(programs.mat_bytes(matrix if quantize else np.eye(4)))

    # ------------------------------------------------------------------ passes
    def render(self) -> None:
        """Moments from the light into every face, the two blur directions, the lookup."""
        from OpenGL import GL

        with self.timed_pass("moments"):
            self.moments_fbo.use()
            glstate.apply(PassState(depth_test=True, depth_func="<", depth_write=True))
            self.frame.ctx.viewport = (0, 0, *self.atlas.size)
            GL.glClearBufferfv(GL.GL_COLOR, 0, self.clear)
            GL.glClearBufferfv(GL.GL_DEPTH, 0, (1.0,))
            for face, rect in zip(self.atlas.faces, self.atlas.rects):
                self.frame.ctx.viewport = rect
                self.depth_prog["u_light_view_proj"].write(programs.mat_bytes(face.view_proj))
                self.depth_prog["u_light_view"].write(programs.mat_bytes(face.view))
                self.frame.draw(self.depth_prog, "casters")
        if self.kernel > 1:
            with self.timed_pass("blur"):
                # moments[0] → (horizontal) → moments[1] → (vertical) → moments[0]
                for src, dst, direction in ((0, 1, (1, 0)), (1, 0, (0, 1))):
                    self.blur_fbos[dst].use()
                    glstate.apply(PassState())
                    self.moments[src].use(0)
                    self.blur_prog["u_direction"].value = direction
                    for rect in self.atlas.rects:
                        self.frame.ctx.viewport = rect
                        self.blur_prog["u_rect"].value = rect
                        self.blur_quad.render()
        with self.timed_pass("lookup"):
            self.vis_fbo.use()
            glstate.apply(PassState())
            self.bind_gbuffer(self.lookup_prog)
            self.moments[0].use(1)
            self.quad.render()

    def work(self, counted: dict, stats: dict) -> dict:
        """Texture taps: each blur direction reads ``kernel`` texels per fragment; the lookup the
        G-buffer's position and one bilinear fetch (four texels)."""
        return self.taps_work(counted, {"blur": self.kernel, "lookup": 1 + 4})

    def stats(self) -> dict:
        """Cost: memory (the moments atlas, its blur copy, the depth buffer), bits per texel of
        the map, passes per frame."""
        texels = self.atlas.texels
        bits = bits_per_texel(self.variant, self.precision)
        per_map = texels * bits // 8
        faces = len(self.atlas.faces)
        return {"memory_bytes": 2 * per_map + texels * DEPTH_BUFFER_BYTES,
                "bits_per_texel": bits, "faces": faces,
                "passes": faces + (2 * faces if self.kernel > 1 else 0) + 1,  # moments, blur, lookup
                "depth_range": self.atlas.faces[0].depth_range,
                "texel_world": float(self.atlas.faces[0].texel_world) or None}
