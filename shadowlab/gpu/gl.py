"""Headless OpenGL for the whole lab: the one place that makes the GL context (or, for the
viewer, adopts its window's: :func:`adopt`).

moderngl drives programs, buffers and draws; PyOpenGL, on moderngl's current context, does
what moderngl has no API for. This module makes the context (EGL, no window), names the device
it runs on, checks the GL error flag and keeps the query objects that live as long as the
context. What draws with it lives beside it: the GLSL loader (:mod:`.glsl`), the program cache
and uniforms (:mod:`.programs`) and the render targets (:mod:`.targets`).
"""
from __future__ import annotations

import os
import re
import sys

import OpenGL

# PyOpenGL calls glGetError after every call by default, which doubled the cost of setting a
# full pass state inside timed passes on llvmpipe. The lab checks the
# error flag itself — after every measured technique (pipeline) and after every test — so the
# per-call checks are off; SHADOWLAB_GL_DEBUG=1 turns them back on to find the offending call.
if "OpenGL.GL" not in sys.modules:
    OpenGL.ERROR_CHECKING = os.environ.get("SHADOWLAB_GL_DEBUG") == "1"

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


def adopt(ctx) -> None:
    """Make ``ctx`` — a moderngl context on a window, current on this thread — the lab's context
    instead of a headless one: ``shadowlab view`` renders the lab's passes on its window's context
    (docs/your-scenes.md#the-viewer). A process with two GL contexts would have to switch between
    them around every call (moderngl contexts do not make themselves current; an EGL and a GLX
    context on one thread do not restore each other reliably through libglvnd), so the viewer
    has one. GLContextError when the lab has already made its own context, or when ``ctx`` is
    older than OpenGL 3.3."""
    global _CONTEXT
    if _CONTEXT is not None and _CONTEXT is not ctx:
        raise GLContextError("the lab's GL context already exists; adopt a window's context before any GL work")
    if ctx.version_code < 330:
        raise GLContextError(f"the window's OpenGL context is {ctx.version_code}, the lab needs 330 or later")
    _CONTEXT = ctx


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


_QUERIES: dict = {}


def query(key, **kinds):
    """A GL query object (moderngl ``ctx.query(**kinds)``) kept for reuse under ``key``:
    moderngl cannot release query objects, so timing code reuses one per purpose instead of
    making one per measurement."""
    if (key, tuple(sorted(kinds.items()))) not in _QUERIES:
        _QUERIES[(key, tuple(sorted(kinds.items())))] = context().query(**kinds)
    return _QUERIES[(key, tuple(sorted(kinds.items())))]



_PROCS: dict = {}


def proc(name: str, restype, *argtypes):
    """The GL entry point ``name`` as a ctypes function (``restype``, ``argtypes``), from the
    driver's own address, looked up once per process. For the core functions PyOpenGL will not
    call on this context: it decides whether an entry point exists from the version and
    extensions of the current *GLX* context, which the lab's EGL context is not, and so reports
    GL 4.1's ``glViewportArrayv`` missing on a 4.5 context that has it. GLError when the driver
    has no such function."""
    if name not in _PROCS:
        import ctypes

        from OpenGL import platform

        context()
        address = platform.PLATFORM.getExtensionProcedure(name.encode())
        if not address:
            raise GLError(f"the GL driver has no {name}")
        _PROCS[name] = ctypes.CFUNCTYPE(restype, *argtypes)(address)
    return _PROCS[name]
