"""Headless OpenGL for the whole lab: the one place that makes the GL context.

moderngl drives programs, buffers and draws; PyOpenGL, on moderngl's current context, does
what moderngl has no API for: depth-stencil attachments, stencil state and depth textures of
a chosen precision (16-bit, 24-bit fixed point, 32-bit float). Framebuffers are built with
PyOpenGL and wrapped by ``ctx.detect_framebuffer`` so that both libraries can use them.

GL's window origin is the bottom-left pixel; every array this module returns is flipped so
that row 0 is the *top* of the image (DESIGN §5).
"""
from __future__ import annotations

import os
import re
import sys
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np
import OpenGL

# PyOpenGL calls glGetError after every call by default, which doubles the cost of the state
# changes inside timed passes (a full pass state: 44 µs → 20 µs on llvmpipe). The lab checks the
# error flag itself — after every measured technique (pipeline) and after every test — so the
# per-call checks are off; SHADOWLAB_GL_DEBUG=1 turns them back on to find the offending call.
if "OpenGL.GL" not in sys.modules:
    OpenGL.ERROR_CHECKING = os.environ.get("SHADOWLAB_GL_DEBUG") == "1"

from . import glstate

_CONTEXT = None

#: Debian packages that provide headless EGL + Mesa's software rasteriser.
EGL_HINT = "install EGL and Mesa (on Debian/Ubuntu: apt-get install libegl1 libgl1-mesa-dri)"


class GLContextError(RuntimeError):
    """No OpenGL 3.3+ context could be created headlessly through EGL."""


class GLError(RuntimeError):
    """A GL call left an error flag set (see :func:`check_errors`)."""


def context():
    """Return the process-wide headless moderngl context (created on first use).

    Raises GLContextError with what to install when EGL or a GL driver is missing.
    """
    global _CONTEXT
    if _CONTEXT is None:
        try:
            import moderngl
        except ImportError as exc:  # pragma: no cover - dependency missing
            raise GLContextError(f"moderngl is not installed ({exc})") from exc
        try:
            _CONTEXT = moderngl.create_standalone_context(backend="egl", require=330)
        except Exception as exc:  # moderngl raises plain Exceptions here
            raise GLContextError(f"cannot create a headless OpenGL context through EGL: {exc}; {EGL_HINT}") from exc
    return _CONTEXT


_PARKING = None


def park() -> None:
    """Bind a 1x1 framebuffer that lives as long as the context. moderngl re-binds its current
    framebuffer after creating or using others, so whoever deletes framebuffers calls this
    first: the current one is then never a deleted name (INVALID_OPERATION on the next
    moderngl framebuffer otherwise). EGL standalone contexts have no default framebuffer."""
    global _PARKING
    ctx = context()
    if _PARKING is None:
        _PARKING = framebuffer([ctx.renderbuffer((1, 1))])
    _PARKING.use()


def renderer() -> str:
    """The GL_RENDERER string of the lab's context (e.g. 'llvmpipe (LLVM 15.0.6, 256 bits)')."""
    return context().info["GL_RENDERER"]


def gl_info() -> dict:
    """The GL device of the lab's context, for run records: vendor, renderer, version, GLSL
    version, the driver (GL_VERSION after the version number, e.g. 'Mesa 22.3.6' or
    'NVIDIA 580.159.04'), and the EGL vendor and version."""
    info = context().info
    out = {k: info[k] for k in ("GL_VENDOR", "GL_RENDERER", "GL_VERSION")}
    from OpenGL import GL

    out["GL_SHADING_LANGUAGE_VERSION"] = GL.glGetString(GL.GL_SHADING_LANGUAGE_VERSION).decode()
    # "4.5 (Core Profile) Mesa 22.3.6" → "Mesa 22.3.6"; "4.6.0 NVIDIA 580.159.04" → "NVIDIA 580.159.04"
    out["driver"] = re.sub(r"^\s*[\d.]+\s*(\([^)]*\))?\s*", "", out["GL_VERSION"]) or out["GL_VENDOR"]
    try:
        from OpenGL import EGL

        display = EGL.eglGetCurrentDisplay()
        out["EGL_VENDOR"] = EGL.eglQueryString(display, EGL.EGL_VENDOR).decode()
        out["EGL_VERSION"] = EGL.eglQueryString(display, EGL.EGL_VERSION).decode()
    except Exception:  # noqa: BLE001 - the EGL strings are a courtesy; GL_* above identify the device
        pass
    return out


def device() -> str:
    """One line naming the GL device: renderer, vendor and driver."""
    i = gl_info()
    return f"{i['GL_RENDERER']} ({i['GL_VENDOR']}; driver {i['driver']})"


def is_software_renderer() -> bool:
    """True on CPU rasterisers (llvmpipe, softpipe, swrast), whose timer queries are not meaningful."""
    return is_software_name(renderer())


def is_software_name(renderer_name: str) -> bool:
    """True when a GL_RENDERER string names a CPU rasteriser."""
    name = renderer_name.lower()
    return any(s in name for s in ("llvmpipe", "softpipe", "swrast", "lavapipe"))


def check_errors(where: str = "") -> None:
    """Raise GLError if the GL error flag is set (drains every queued error)."""
    from OpenGL import GL

    errors = []
    while True:
        code = GL.glGetError()
        if code == GL.GL_NO_ERROR:
            break
        errors.append(hex(int(code)))
        if len(errors) > 16:
            break
    if errors:
        raise GLError(f"GL error(s) {', '.join(errors)}" + (f" after {where}" if where else ""))


# --------------------------------------------------------------------------- shaders

_INCLUDE = re.compile(r'^\s*#include\s+"([^"]+)"\s*$', re.M)
_STAGES = {"vertex": "VERTEX_SHADER", "geometry": "GEOMETRY_SHADER", "fragment": "FRAGMENT_SHADER"}
GLSL_VERSION = "#version 330 core"


def shader_dir() -> Path:
    """Folder that holds the GLSL files (the repository's ``shaders/`` or the installed copy)."""
    here = Path(__file__).resolve().parent
    for folder in (here.parent / "shaders", here / "shaders"):  # source checkout, installed package
        if (folder / "lights.glsl").is_file():
            return folder
    raise FileNotFoundError(f"no shaders/ folder beside {here}: the installation is incomplete")


def _expand(name: str, seen: tuple[str, ...] = ()) -> str:
    if name in seen:
        raise ValueError(f"#include cycle: {' -> '.join(seen + (name,))}")
    path = shader_dir() / name
    if not path.is_file():
        raise FileNotFoundError(f"shader file not found: {path}")
    text = path.read_text()
    return _INCLUDE.sub(lambda m: _expand(m.group(1), seen + (name,)), text)


@lru_cache(maxsize=None)
def shader_source(name: str) -> str:
    """The GLSL text of ``shaders/<name>`` with every ``#include "file"`` expanded (no #version)."""
    return _expand(name)


_PROGRAMS: dict = {}


def program(name: str, defines: dict | None = None, varyings: tuple[str, ...] = ()):
    """The moderngl Program of ``shaders/<name>`` with ``defines``, compiled once per process
    (cached per (file, defines, varyings); the cache owns it: callers never release it).

    One file holds every stage, each inside ``#ifdef VERTEX_SHADER`` / ``GEOMETRY_SHADER`` /
    ``FRAGMENT_SHADER``; a stage is built when its macro appears in the file. ``defines`` become
    ``#define KEY VALUE`` lines (compile-time switches only; numeric parameters are uniforms).
    """
    key = (name, tuple(sorted((str(k), str(v)) for k, v in (defines or {}).items())), tuple(varyings))
    if key not in _PROGRAMS:
        _PROGRAMS[key] = _compile(name, defines, varyings)
    return _PROGRAMS[key]


def _compile(name: str, defines: dict | None, varyings: tuple[str, ...]):
    """:func:`program`, compiled."""
    ctx = context()
    src = shader_source(name)
    head = [GLSL_VERSION] + [f"#define {k} {v}" for k, v in (defines or {}).items()]
    stages = {}
    for stage, macro in _STAGES.items():
        if macro in src:
            stages[stage] = "\n".join(head + [f"#define {macro} 1", "#line 1", src])
    if "vertex" not in stages:
        raise ValueError(f"{name}: no VERTEX_SHADER section")
    kwargs = dict(vertex_shader=stages["vertex"], geometry_shader=stages.get("geometry"))
    if varyings:
        kwargs["varyings"] = varyings
    else:
        kwargs["fragment_shader"] = stages.get("fragment")
    prog = ctx.program(**kwargs)
    prog.extra = ProgramInfo(name, dict(defines or {}), glstate.clip_distances_written(stages))
    return prog


@dataclass(frozen=True)
class ProgramInfo:
    """What the lab knows of a program it compiled: its file, defines, and the clip distances
    its vertex or geometry stage writes (each needs GL_CLIP_DISTANCEi enabled when it draws)."""

    name: str
    defines: dict
    clip_distances: frozenset


def program_info(prog) -> ProgramInfo | None:
    """The :class:`ProgramInfo` of a program made by :func:`program` (kept on the program
    object itself, so it goes with it); None for other programs."""
    info = getattr(prog, "extra", None)
    return info if isinstance(info, ProgramInfo) else None


_QUERIES: dict = {}


def query(key, **kinds):
    """A GL query object (moderngl ``ctx.query(**kinds)``) kept for reuse under ``key``:
    moderngl cannot release query objects, so timing code reuses one per purpose instead of
    making one per measurement."""
    if (key, tuple(sorted(kinds.items()))) not in _QUERIES:
        _QUERIES[(key, tuple(sorted(kinds.items())))] = context().query(**kinds)
    return _QUERIES[(key, tuple(sorted(kinds.items())))]


def set_uniforms(prog, values: dict) -> None:
    """Set the uniforms in ``values`` that ``prog`` uses (the compiler drops unused ones)."""
    for key, val in values.items():
        if key in prog:
            member = prog[key]
            if isinstance(val, np.ndarray):
                member.write(np.ascontiguousarray(val, dtype="f4" if val.dtype.kind == "f" else "i4").tobytes())
            else:
                member.value = val


# --------------------------------------------------------------------------- render targets

def mat_bytes(m: np.ndarray) -> bytes:
    """A 4x4 row-major float64 matrix as the column-major float32 bytes GLSL's mat4 expects."""
    return np.ascontiguousarray(np.asarray(m, dtype=np.float64).T, dtype="f4").tobytes()


_DEPTH_FORMATS = {16: "GL_DEPTH_COMPONENT16", 24: "GL_DEPTH_COMPONENT24", 32: "GL_DEPTH_COMPONENT32F"}


@dataclass
class DepthTexture:
    """A depth texture of 16, 24 (fixed point) or 32 (float) bits, sampled with texelFetch/texture.

    ``texture`` is a moderngl wrapper (``.use(unit)``); ``fbo`` renders depth only into it.
    """

    size: tuple[int, int]
    bits: int
    glo: int
    texture: object
    fbo: object
    fbo_glo: int

    @classmethod
    def create(cls, size: tuple[int, int], bits: int) -> "DepthTexture":
        """Allocate a ``size`` = (width, height) depth texture with ``bits`` in {16, 24, 32}."""
        from OpenGL import GL

        if bits not in _DEPTH_FORMATS:
            raise ValueError(f"depth_bits must be one of {sorted(_DEPTH_FORMATS)}, got {bits}")
        ctx = context()
        w, h = size
        tid = int(GL.glGenTextures(1))
        GL.glBindTexture(GL.GL_TEXTURE_2D, tid)
        GL.glTexImage2D(GL.GL_TEXTURE_2D, 0, getattr(GL, _DEPTH_FORMATS[bits]), w, h, 0,
                        GL.GL_DEPTH_COMPONENT, GL.GL_FLOAT, None)
        for pname in (GL.GL_TEXTURE_MIN_FILTER, GL.GL_TEXTURE_MAG_FILTER):
            GL.glTexParameteri(GL.GL_TEXTURE_2D, pname, GL.GL_NEAREST)
        for pname in (GL.GL_TEXTURE_WRAP_S, GL.GL_TEXTURE_WRAP_T):
            GL.glTexParameteri(GL.GL_TEXTURE_2D, pname, GL.GL_CLAMP_TO_EDGE)
        GL.glTexParameteri(GL.GL_TEXTURE_2D, GL.GL_TEXTURE_COMPARE_MODE, GL.GL_NONE)
        GL.glBindTexture(GL.GL_TEXTURE_2D, 0)
        fid = int(GL.glGenFramebuffers(1))
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, fid)
        GL.glFramebufferTexture2D(GL.GL_FRAMEBUFFER, GL.GL_DEPTH_ATTACHMENT, GL.GL_TEXTURE_2D, tid, 0)
        GL.glDrawBuffer(GL.GL_NONE)
        GL.glReadBuffer(GL.GL_NONE)
        _check_complete(GL)
        fbo = ctx.detect_framebuffer(fid)
        tex = ctx.external_texture(tid, (w, h), 1, 0, "f4")
        check_errors("DepthTexture.create")
        return cls((w, h), bits, tid, tex, fbo, fid)

    @property
    def nbytes(self) -> int:
        """GPU memory of the texture in bytes (24-bit formats are counted as stored, 4 bytes)."""
        per = {16: 2, 24: 4, 32: 4}[self.bits]
        return self.size[0] * self.size[1] * per

    def use_as_target(self) -> None:
        """Bind for a depth-only pass and set the viewport to the whole texture."""
        self.fbo.use()
        context().viewport = (0, 0, *self.size)

    def read(self) -> np.ndarray:
        """Depth values as float32 (height, width), row 0 = top (slow; for tests and debugging)."""
        return _read_pixels(self.fbo_glo, self.size, "depth")

    def release(self) -> None:
        """Free the GL objects."""
        from OpenGL import GL

        GL.glDeleteFramebuffers(1, [self.fbo_glo])
        GL.glDeleteTextures(1, [self.glo])


def _read_pixels(fbo_glo: int, size: tuple[int, int], what: str) -> np.ndarray:
    """Depth (float32) or stencil (uint8) of a framebuffer as (height, width), row 0 = top."""
    from OpenGL import GL

    fmt, gltype, dtype = {"depth": (GL.GL_DEPTH_COMPONENT, GL.GL_FLOAT, np.float32),
                          "stencil": (GL.GL_STENCIL_INDEX, GL.GL_UNSIGNED_BYTE, np.uint8)}[what]
    GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, fbo_glo)
    GL.glPixelStorei(GL.GL_PACK_ALIGNMENT, 1)
    data = GL.glReadPixels(0, 0, size[0], size[1], fmt, gltype)
    return np.frombuffer(data, dtype).reshape(size[1], size[0])[::-1].copy()


def _check_complete(GL) -> None:
    status = GL.glCheckFramebufferStatus(GL.GL_FRAMEBUFFER)
    if status != GL.GL_FRAMEBUFFER_COMPLETE:
        raise GLError(f"framebuffer incomplete (status {hex(int(status))})")


@dataclass
class ScreenTarget:
    """Colour attachments plus a 24-bit depth / 8-bit stencil renderbuffer, at screen size.

    The G-buffer lives here; techniques that need the stencil (shadow volumes) use
    :meth:`read_stencil` and PyOpenGL's stencil calls while this target is bound.
    """

    size: tuple[int, int]
    colors: list
    fbo: object
    fbo_glo: int
    depth_stencil_glo: int
    owns_depth_stencil: bool = True

    @classmethod
    def create(cls, size: tuple[int, int], colors: list, share_depth_stencil: "ScreenTarget | None" = None
               ) -> "ScreenTarget":
        """Wrap moderngl textures ``colors`` (all of ``size``) with a new depth-stencil attachment,
        or with the one of ``share_depth_stencil`` (e.g. a technique drawing on the G-buffer's stencil)."""
        from OpenGL import GL

        ctx = context()
        w, h = size
        fid = int(GL.glGenFramebuffers(1))
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, fid)
        for i, tex in enumerate(colors):
            GL.glFramebufferTexture2D(GL.GL_FRAMEBUFFER, GL.GL_COLOR_ATTACHMENT0 + i, GL.GL_TEXTURE_2D, tex.glo, 0)
        GL.glDrawBuffers(len(colors), [GL.GL_COLOR_ATTACHMENT0 + i for i in range(len(colors))])
        if share_depth_stencil is not None:
            if tuple(share_depth_stencil.size) != (w, h):
                raise ValueError(f"shared depth-stencil is {share_depth_stencil.size}, target is {size}")
            rb = share_depth_stencil.depth_stencil_glo
        else:
            rb = int(GL.glGenRenderbuffers(1))
            GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, rb)
            GL.glRenderbufferStorage(GL.GL_RENDERBUFFER, GL.GL_DEPTH24_STENCIL8, w, h)
        GL.glFramebufferRenderbuffer(GL.GL_FRAMEBUFFER, GL.GL_DEPTH_STENCIL_ATTACHMENT, GL.GL_RENDERBUFFER, rb)
        _check_complete(GL)
        fbo = ctx.detect_framebuffer(fid)
        check_errors("ScreenTarget.create")
        return cls((w, h), list(colors), fbo, fid, rb, share_depth_stencil is None)

    def use(self) -> None:
        """Bind as the draw target with a full-size viewport."""
        self.fbo.use()
        context().viewport = (0, 0, *self.size)

    def clear_depth_stencil(self, depth: float = 1.0, stencil: int = 0) -> None:
        """Clear depth and stencil of this target (it must be bound, and the pass state applied:
        rasterizer discard off). Sets the depth and stencil write masks to all-on."""
        from OpenGL import GL

        GL.glDepthMask(GL.GL_TRUE)
        GL.glStencilMask(0xFF)
        GL.glClearDepth(depth)
        GL.glClearStencil(stencil)
        GL.glClear(GL.GL_DEPTH_BUFFER_BIT | GL.GL_STENCIL_BUFFER_BIT)

    def read_stencil(self) -> np.ndarray:
        """The stencil buffer as uint8 (height, width), row 0 = top."""
        return _read_pixels(self.fbo_glo, self.size, "stencil")

    def release(self) -> None:
        """Free the framebuffer and its own depth-stencil renderbuffer (not colour textures, not a shared one)."""
        from OpenGL import GL

        GL.glDeleteFramebuffers(1, [self.fbo_glo])
        if self.owns_depth_stencil:
            GL.glDeleteRenderbuffers(1, [self.depth_stencil_glo])


def framebuffer(color_attachments: list, depth_attachment=None):
    """A moderngl framebuffer, checked complete (GLError otherwise)."""
    from OpenGL import GL

    ctx = context()
    fbo = ctx.framebuffer(color_attachments=color_attachments, depth_attachment=depth_attachment)
    current = ctx.fbo  # moderngl re-bound its current framebuffer (if any) after creating this one
    GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, fbo.glo)
    try:
        _check_complete(GL)
    finally:
        (current or fbo).use()
    return fbo


def visibility_target(size: tuple[int, int]):
    """A technique's visibility image: an R32F texture of ``size`` (width, height) and a checked
    framebuffer drawing into it, as (texture, framebuffer)."""
    tex = context().texture(tuple(size), 1, dtype="f4")
    return tex, framebuffer([tex])


def read_texture(tex, components: int, dtype: str = "f4") -> np.ndarray:
    """A moderngl texture as an array (height, width, components), row 0 = top."""
    w, h = tex.size
    data = np.frombuffer(tex.read(), dtype=np.dtype(dtype))
    return data.reshape(h, w, components)[::-1].copy()


def fullscreen_quad(prog):
    """A VertexArray drawing one screen-covering triangle pair; ``prog`` needs ``in vec2 in_pos``."""
    ctx = context()
    vbo = ctx.buffer(np.array([-1, -1, 1, -1, 1, 1, -1, -1, 1, 1, -1, 1], dtype="f4").tobytes())
    return ctx.vertex_array(prog, [(vbo, "2f", "in_pos")])
