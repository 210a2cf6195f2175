"""Fixed-function GL state, set in full by every pass, and the checks that hold it (docs/architecture.md#full-pass-state-shadowlabgpuglstatepy).

GL 4.5 core gives some shader outputs and some settings no effect unless a capability is
enabled (``gl_ClipDistance[i]`` is ignored unless ``GL_CLIP_DISTANCEi`` is on; depth clamp
also switches off near-plane clipping), and leaves others undefined (a clip distance enabled
but not written; a comparison sampler on a texture without a compare mode). Mesa's llvmpipe is
lenient where the spec is not — it clips with clip distances that were never enabled — so a
technique that relies on inherited or default state can pass every test on llvmpipe and be
wrong on a GPU. The rule here: every pass binds its target, then applies one :class:`PassState`
that names *every* fixed-function state below, defaults included; nothing is inherited from
the previous pass or technique. ``tests/gpu/test_gl_state.py`` runs every technique with polluted
state and checks its output does not change, and (through :func:`draw_problems`, installed
around every draw in the test suite) that each draw's clip distances, framebuffer and sampler
compare modes agree with the program that draws.

The states, and who sets what (the audit of the GL 4.5 core spec for this lab):

- depth test, function, write mask — every pass; depth range [0, 1] and GL's clip-space
  convention (z in [−w, w], lower-left origin, where GL 4.5's glClipControl exists) — every pass;
- ``GL_DEPTH_CLAMP`` — on only for shadow volumes with ``far=clamp`` (their depth pre-pass and
  volume passes alike); since it also disables near-plane clipping, those passes restore the
  near plane as clip distance 0;
- ``GL_CLIP_DISTANCEi`` — exactly the distances the drawing program writes (planar shadows'
  light and receiver planes; the shadow volumes' near plane under depth clamp), off otherwise;
- colour write mask — every pass (off for depth-only and stencil-only passes);
- face culling and the front-face winding (counter-clockwise) — every pass (only second-depth
  shadow maps cull, front faces; two-sided stencil counting also reads the winding);
- polygon mode (filled) — every pass;
- blending and its equation (add) — every pass (planar darkening multiplies; shading adds lights);
- polygon offset (fill) — planar shadows' offset fix, hardware slope-scaled shadow maps;
- stencil test, functions, operations (two-sided) and write mask — shadow volumes and planar
  shadows; off elsewhere;
- scissor test and rasterizer discard — always off; provoking vertex — last (flat ids are
  constant per triangle, so the convention cannot change a result, but it is named);
- sampler objects — none bound on the first :data:`TEXTURE_UNITS` units unless the pass binds
  its own (the hardware-filtered shadow map's comparison sampler);
- not used, hence never enabled: seamless cube maps (the point light's cube map is an atlas of
  2D faces chosen in the shader), sRGB framebuffers, multisampling (single-sample targets),
  primitive restart. Clears come after :func:`apply` (``glClear`` is skipped under rasterizer
  discard and obeys the write masks). Precision qualifiers have no effect in desktop GLSL 3.30 (all float is
  IEEE single); integer varyings are ``flat`` as required.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

#: Texture units a pass may use; sampler objects are unbound on all of them by :func:`apply`.
TEXTURE_UNITS = 8
#: Clip distances :func:`apply` manages (GL guarantees at least 8).
MAX_CLIP_DISTANCES = 8

_FUNCS = {"never": "GL_NEVER", "<": "GL_LESS", "<=": "GL_LEQUAL", "==": "GL_EQUAL", ">": "GL_GREATER",
          ">=": "GL_GEQUAL", "!=": "GL_NOTEQUAL", "always": "GL_ALWAYS"}
_OPS = {"keep": "GL_KEEP", "zero": "GL_ZERO", "replace": "GL_REPLACE", "incr": "GL_INCR", "decr": "GL_DECR",
        "incr_wrap": "GL_INCR_WRAP", "decr_wrap": "GL_DECR_WRAP", "invert": "GL_INVERT"}
_BLEND = {"zero": "GL_ZERO", "one": "GL_ONE", "src_color": "GL_SRC_COLOR", "dst_color": "GL_DST_COLOR"}


@dataclass(frozen=True)
class Stencil:
    """Stencil test and operations: ``func`` against ``ref`` under ``mask``; per face the
    operations (stencil fail, depth fail, depth pass); ``write_mask`` of the stencil bits."""

    func: str = "always"
    ref: int = 0
    mask: int = 0xFF
    front: tuple[str, str, str] = ("keep", "keep", "keep")
    back: tuple[str, str, str] = ("keep", "keep", "keep")
    write_mask: int = 0xFF

    def both(self, ops: tuple[str, str, str]) -> "Stencil":
        """The same test with ``ops`` on both faces."""
        return Stencil(self.func, self.ref, self.mask, ops, ops, self.write_mask)


@dataclass(frozen=True)
class PassState:
    """Every fixed-function state a pass relies on (see the module docstring). Defaults: depth
    test off, writes on, nothing else enabled."""

    depth_test: bool = False
    depth_func: str = "<"
    depth_write: bool = True
    depth_clamp: bool = False
    color_write: bool = True
    cull: str | None = None                      # None, "front" or "back"
    blend: tuple[str, str] | None = None         # (source, destination) factors
    polygon_offset: tuple[float, float] | None = None  # (factor, units)
    stencil: Stencil | None = None
    clip_distances: int = 0                      # GL_CLIP_DISTANCE0 .. n-1 on, the rest off
    samplers: tuple[int, ...] = field(default=())  # units whose sampler objects the pass binds itself


def _gl():
    from OpenGL import GL

    return GL


def _cap(GL, cap, on: bool) -> None:
    (GL.glEnable if on else GL.glDisable)(cap)


def apply(state: PassState) -> None:
    """Set every state of ``state`` (after binding the pass's framebuffer: moderngl's
    ``use()`` re-applies its own colour and depth masks)."""
    GL = _gl()
    _cap(GL, GL.GL_RASTERIZER_DISCARD, False)
    if bool(GL.glClipControl):  # GL 4.5: keep OpenGL's own conventions, whatever was set before
        GL.glClipControl(GL.GL_LOWER_LEFT, GL.GL_NEGATIVE_ONE_TO_ONE)
    GL.glDepthRange(0.0, 1.0)
    GL.glPolygonMode(GL.GL_FRONT_AND_BACK, GL.GL_FILL)
    GL.glFrontFace(GL.GL_CCW)
    _cap(GL, GL.GL_DEPTH_TEST, state.depth_test)
    GL.glDepthFunc(getattr(GL, _FUNCS[state.depth_func]))
    GL.glDepthMask(bool(state.depth_write))
    _cap(GL, GL.GL_DEPTH_CLAMP, state.depth_clamp)
    GL.glColorMask(*(4 * [bool(state.color_write)]))
    _cap(GL, GL.GL_CULL_FACE, state.cull is not None)
    GL.glCullFace(GL.GL_FRONT if state.cull == "front" else GL.GL_BACK)
    _cap(GL, GL.GL_BLEND, state.blend is not None)
    GL.glBlendEquation(GL.GL_FUNC_ADD)
    if state.blend is not None:
        GL.glBlendFunc(*(getattr(GL, _BLEND[f]) for f in state.blend))
    _cap(GL, GL.GL_POLYGON_OFFSET_FILL, state.polygon_offset is not None)
    GL.glPolygonOffset(*(state.polygon_offset or (0.0, 0.0)))
    set_stencil(state.stencil)
    for i in range(MAX_CLIP_DISTANCES):
        _cap(GL, GL.GL_CLIP_DISTANCE0 + i, i < state.clip_distances)
    _cap(GL, GL.GL_SCISSOR_TEST, False)
    GL.glProvokingVertex(GL.GL_LAST_VERTEX_CONVENTION)
    for unit in range(TEXTURE_UNITS):
        if unit not in state.samplers:
            GL.glBindSampler(unit, 0)


def set_viewports(rects) -> None:
    """Viewport i = ``rects[i]`` (x, y, width, height, texels) for i < len(rects)
    (glViewportArrayv, core since GL 4.1): the viewports an instanced draw picks from with
    ``gl_ViewportIndex`` (the map toolkit's one-pass depth pass). Viewports are set by the pass,
    not by :func:`apply`: ``glViewport`` — moderngl's ``ctx.viewport`` and a framebuffer's
    ``use()`` — sets every viewport at once, so the next pass that binds its target starts with
    one viewport again."""
    import ctypes

    from . import gl

    values = np.ascontiguousarray(np.asarray(rects, np.float32).reshape(-1, 4))
    gl.proc("glViewportArrayv", None, ctypes.c_uint, ctypes.c_int, ctypes.POINTER(ctypes.c_float))(
        0, len(values), values.ctypes.data_as(ctypes.POINTER(ctypes.c_float)))


def set_stencil(stencil: Stencil | None) -> None:
    """Stencil test on with ``stencil``'s functions and operations, or off (None). Used by
    :func:`apply`, and within a pass where only the stencil operations change."""
    GL = _gl()
    if stencil is None:
        GL.glDisable(GL.GL_STENCIL_TEST)
        GL.glStencilMask(0xFF)
        return
    GL.glEnable(GL.GL_STENCIL_TEST)
    GL.glStencilFunc(getattr(GL, _FUNCS[stencil.func]), stencil.ref, stencil.mask)
    for face, ops in ((GL.GL_FRONT, stencil.front), (GL.GL_BACK, stencil.back)):
        GL.glStencilOpSeparate(face, *(getattr(GL, _OPS[o]) for o in ops))
    GL.glStencilMask(stencil.write_mask)


# --------------------------------------------------------------------------- what programs need

_DIRECTIVE = re.compile(r"^\s*#\s*(ifdef|ifndef|if|elif|else|endif|define|undef)\b\s*(\w*)", re.M)
_CLIP_WRITE = re.compile(r"gl_ClipDistance\s*\[\s*(\d+)\s*\]\s*=(?!=)")


def active_source(source: str) -> str:
    """``source`` with the lines that ``#ifdef`` / ``#ifndef`` / ``#else`` / ``#endif`` leave
    out removed, given the ``#define``s (and ``#undef``s) it contains. Conditions this reader
    does not evaluate (``#if`` / ``#elif`` expressions) keep every branch: a program is then
    assumed to write what any branch writes, which the draw checks report rather than miss."""
    defined: set[str] = set()
    stack: list[tuple[bool, bool]] = []  # per open conditional: (current branch kept, condition known)
    out = []
    for line in source.splitlines():
        m = _DIRECTIVE.match(line)
        live = all(kept for kept, _ in stack)
        if not m:
            if live:
                out.append(line)
            continue
        kind, name = m.groups()
        if kind == "define" and live:
            defined.add(name)
        elif kind == "undef" and live:
            defined.discard(name)
        elif kind in ("ifdef", "ifndef"):
            stack.append(((name in defined) == (kind == "ifdef"), True))
        elif kind in ("if", "elif"):
            if kind == "elif" and stack:
                stack.pop()
            stack.append((True, False))
        elif kind == "else" and stack:
            kept, known = stack.pop()
            stack.append((not kept if known else True, known))
        elif kind == "endif" and stack:
            stack.pop()
    return "\n".join(out)


def clip_distances_written(stage_sources: dict[str, str]) -> frozenset[int]:
    """Indices i for which the last stage before rasterisation (the geometry stage if there is
    one, else the vertex stage) writes ``gl_ClipDistance[i]``."""
    stage = "geometry" if stage_sources.get("geometry") else "vertex"
    return frozenset(int(i) for i in _CLIP_WRITE.findall(active_source(stage_sources.get(stage) or "")))


def draw_problems(program_clip_distances: frozenset[int], shadow_units: dict[int, bool]) -> list[str]:
    """What is wrong with the current GL state for a draw by a program that writes
    ``program_clip_distances`` and samples on ``shadow_units`` ({unit: True for a
    sampler2DShadow, False for a sampler2D}) — empty when the draw is well defined by the GL
    4.5 core spec. Checks: clip distances written ⇔ enabled; the draw framebuffer is complete;
    depth textures read through sampler2DShadow have a compare mode, through sampler2D none."""
    GL = _gl()
    problems = []
    for i in range(MAX_CLIP_DISTANCES):
        on = bool(GL.glIsEnabled(GL.GL_CLIP_DISTANCE0 + i))
        if i in program_clip_distances and not on:
            problems.append(f"the program writes gl_ClipDistance[{i}] but GL_CLIP_DISTANCE{i} is disabled "
                            f"(the GL spec then ignores it; Mesa clips anyway)")
        elif on and i not in program_clip_distances:
            problems.append(f"GL_CLIP_DISTANCE{i} is enabled but the program does not write gl_ClipDistance[{i}] "
                            f"(undefined clipping)")
    status = GL.glCheckFramebufferStatus(GL.GL_DRAW_FRAMEBUFFER)
    if status != GL.GL_FRAMEBUFFER_COMPLETE:
        problems.append(f"draw framebuffer incomplete (status {hex(int(status))})")
    for unit, shadow in shadow_units.items():
        mode = _compare_mode(GL, unit)
        if mode is None:
            continue
        if shadow and mode != GL.GL_COMPARE_REF_TO_TEXTURE:
            problems.append(f"texture unit {unit}: sampler2DShadow without GL_COMPARE_REF_TO_TEXTURE (undefined)")
        if not shadow and mode != GL.GL_NONE:
            problems.append(f"texture unit {unit}: sampler2D reads a depth texture with a compare mode (undefined)")
    return problems


def _compare_mode(GL, unit: int):
    """The compare mode in effect on ``unit`` for a depth texture (the bound sampler object's,
    else the texture's), or None when the unit holds no depth texture."""
    GL.glActiveTexture(GL.GL_TEXTURE0 + unit)
    tex = int(GL.glGetIntegerv(GL.GL_TEXTURE_BINDING_2D))
    sampler = int(GL.glGetIntegerv(GL.GL_SAMPLER_BINDING))
    mode = None
    if tex:
        fmt = int(GL.glGetTexLevelParameteriv(GL.GL_TEXTURE_2D, 0, GL.GL_TEXTURE_INTERNAL_FORMAT))
        if fmt in (GL.GL_DEPTH_COMPONENT16, GL.GL_DEPTH_COMPONENT24, GL.GL_DEPTH_COMPONENT32F, GL.GL_DEPTH_COMPONENT):
            mode = int(GL.glGetSamplerParameteriv(sampler, GL.GL_TEXTURE_COMPARE_MODE) if sampler
                       else GL.glGetTexParameteriv(GL.GL_TEXTURE_2D, GL.GL_TEXTURE_COMPARE_MODE))
    GL.glActiveTexture(GL.GL_TEXTURE0)
    return mode
