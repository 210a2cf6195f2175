"""Headless OpenGL for the whole lab: the one place that makes the GL context.

moderngl drives programs, buffers and draws; PyOpenGL, on moderngl's current context, does
what moderngl has no API for: depth-stencil attachments, stencil state and depth textures of
a chosen precision (16-bit, 24-bit fixed point, 32-bit float). Framebuffers are built with
PyOpenGL and wrapped by ``ctx.detect_framebuffer`` so that both libraries can use them.

GL's window origin is the bottom-left pixel; every array this module returns is flipped so
that row 0 is the *top* of the image (docs/architecture.md#conventions).
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

# PyOpenGL calls glGetError after every call by default, which doubled the cost of setting a
# full pass state inside timed passes on llvmpipe. The lab checks the
# error flag itself — after every measured technique (pipeline) and after every test — so the
# per-call checks are off; SHADOWLAB_GL_DEBUG=1 turns them back on to find the offending call.
if "OpenGL.GL" not in sys.modules:
    OpenGL.ERROR_CHECKING = os.environ.get("SHADOWLAB_GL_DEBUG") == "1"

from . import glstate
from ..util.validation import did_you_mean

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

_INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"\s*(?://.*)?$')  # a line comment may follow
_ANY_INCLUDE = re.compile(r"^\s*#\s*include\b")
_CONDITIONAL = re.compile(r"^\s*#\s*(if|ifdef|ifndef|elif|else|endif)\b")
# A stage exists when the file has an `#ifdef <STAGE>_SHADER` line; the macro's name elsewhere
# (a comment, an #ifndef) makes none.
_STAGE_LINE = re.compile(r"^[ \t]*#[ \t]*ifdef[ \t]+(VERTEX_SHADER|GEOMETRY_SHADER|FRAGMENT_SHADER|COMPUTE_SHADER)\b",
                         re.M)
_STAGES = {"vertex": "VERTEX_SHADER", "geometry": "GEOMETRY_SHADER", "fragment": "FRAGMENT_SHADER",
           "compute": "COMPUTE_SHADER"}
# `//! glsl 430`: a file (or an include) that needs a newer GLSL than GLSL_VERSION (storage
# buffers, atomics and compute shaders are GLSL 4.30); the highest such line wins.
_VERSION_LINE = re.compile(r"^[ \t]*//![ \t]*glsl[ \t]+(\d+)[ \t]*$", re.M)
# `uniform <type> <name>[...], <name>...;` at the start of a line (block declarations are not used).
_UNIFORM = re.compile(r"^[ \t]*(?:layout\s*\([^)]*\)\s*)?uniform\s+(?:(?:lowp|mediump|highp)\s+)?\w+\s+([^;{]+);", re.M)
# A location in a driver's info log, at the start of a line after an optional "ERROR: ":
# Mesa "S:L(C): error", NVIDIA "S(L) : error", AMD/Intel "ERROR: S:L: ...".
_LOCATION = re.compile(r"^([ \t]*(?:[A-Za-z]+:[ \t]*)?)(\d+)(?::(\d+)|\((\d+)\))", re.M)
GLSL_VERSION = "#version 330 core"

#: Source-string number 0: the lines the lab puts before a file (#version, the defines, the stage
#: macro); the files of an expansion are numbered from 1 in the order they are first included.
PRELUDE = "<prelude>"
#: ``#line`` numbers of the file numbered k run from k · LINE_STRIDE + 1: the file is known from the
#: line number alone, so the markers name no source string (``#line N``): Mesa (22.x) reports
#: compiler errors as string 0 whatever ``#line`` said, and the line decides on every driver.
LINE_STRIDE = 10000


class ShaderError(RuntimeError):
    """A shader program did not build: a GLSL compile or link error (locations rewritten to
    ``file.glsl:line``), a missing include, an include cycle or a conflicting include."""


class UnknownUniformError(KeyError):
    """:func:`set_uniforms` was given a name the program's source never declares (a misspelt or
    stale uniform); the message names the program file and the close matches."""

    def __str__(self) -> str:
        return str(self.args[0]) if self.args else ""


#: The package's root: every folder under it that holds GLSL files is on the loader's search path.
PACKAGE_ROOT = Path(__file__).resolve().parents[1]


@lru_cache(maxsize=None)
def _package_shader_path() -> tuple[Path, ...]:
    folders = {p.parent for p in PACKAGE_ROOT.rglob("*.glsl")}
    if not folders:
        raise FileNotFoundError(f"no GLSL files under {PACKAGE_ROOT}: the installation is incomplete")
    core = Path(__file__).resolve().parent
    return tuple(sorted(folders, key=lambda f: (f != core, str(f))))


def shader_path() -> tuple[Path, ...]:
    """The loader's search path: every folder of the package that holds GLSL files — the shared
    programs beside :mod:`shadowlab.gpu` first, then each technique family's folder, where a
    technique's shaders sit beside its module (Falcor keeps a pass's shaders beside the pass).
    A program or ``#include`` is named by its file name alone; :func:`shader_files` makes sure
    each name means one file."""
    return _package_shader_path()


def _index(folders: tuple[Path, ...]) -> dict[str, Path]:
    found: dict[str, Path] = {}
    for folder in folders:
        for path in sorted(folder.glob("*.glsl")):
            if path.name in found:
                raise ShaderError(f"two shader files named {path.name}: {found[path.name]} and {path}; "
                                  f"a shader's file name must be unique on the search path")
            found[path.name] = path
    return found


def shader_files() -> dict[str, Path]:
    """File name → path of every GLSL file on :func:`shader_path` (ShaderError when a name is
    found in two folders: names alone pick files, so they must be unique)."""
    return _index(tuple(shader_path()))  # a glob of a handful of folders: cheap, and never stale


@dataclass(frozen=True)
class Expansion:
    """A GLSL file with its ``#include``s expanded: ``text`` (with ``#line`` markers, no
    #version) and ``files``, the table of source-string numbers (``files[k]`` is string k; 0 is
    :data:`PRELUDE`, 1 the file itself)."""

    text: str
    files: tuple[str, ...]

    def locate(self, string: int, line: int) -> tuple[str, int] | None:
        """The (file, line) of a location a driver reported as source string ``string``, line
        ``line``; None when it is none of this expansion's."""
        number, local = divmod(line, LINE_STRIDE)
        if 1 <= number < len(self.files):  # a marked line: the number says which file
            return self.files[number], local
        if number == 0 and string == 0:  # before the first marker: the prelude
            return PRELUDE, line
        return None

    def rewrite(self, log: str) -> str:
        """A compiler's or linker's info log with each ``S:L`` / ``S(L)`` location at the start
        of a line rewritten to ``file.glsl:L``."""
        def replace(m: re.Match) -> str:
            where = self.locate(int(m.group(2)), int(m.group(3) or m.group(4)))
            return m.group(0) if where is None else f"{m.group(1)}{where[0]}:{where[1]}"
        return _LOCATION.sub(replace, log)


def _expand(folders: tuple[Path, ...], name: str) -> Expansion:
    """Expand the file ``name`` found on the search path ``folders``: each ``#include "file"`` is replaced by that file's text (itself
    expanded) between ``#line`` markers, so that every line keeps its file and line number.

    Include guard: a file already included in this expansion is not expanded again (the
    ``#include`` line becomes a comment). Because the first inclusion then serves the later
    ones, it must be live wherever they are: the conditionals (``#if*`` groups, by file and line)
    open at the first inclusion must all be open at the later one; otherwise it is an error
    (include the file once, where every user sees it). A cycle is an error.
    """
    index = _index(folders)
    files = [PRELUDE]
    first_site: dict[str, tuple] = {}   # included file -> the conditional groups open at its first #include
    open_groups: list[tuple[str, int, int]] = []  # (file, line of its #if*, branch: 0, 1 after #else/#elif ...)
    out: list[str] = []

    def marker(number: int, line: int) -> str:
        return f"#line {number * LINE_STRIDE + line}"

    def walk(fname: str, chain: tuple[str, ...], site: str | None) -> None:
        path = index.get(fname)
        if path is None or not path.is_file():
            known = index
            raise ShaderError(f"shader file not found: {fname}{did_you_mean(fname, known)} on the search path "
                              f"({', '.join(str(f) for f in folders)})" + (f" (#include at {site})" if site else ""))
        lines = path.read_text().splitlines()
        if len(lines) >= LINE_STRIDE:
            raise ShaderError(f"{fname}: {len(lines)} lines; the #line scheme allows {LINE_STRIDE - 1}")
        number = len(files)
        files.append(fname)
        out.append(marker(number, 1))
        # A #line inside a group the preprocessor skips is ignored, and it then counts on from the
        # last one it obeyed: once this file has expanded an include, each #else / #elif /
        # #endif is followed by a marker restating this file's line.
        resync = False
        for i, line in enumerate(lines, 1):
            inc = _INCLUDE.match(line)
            if inc is None and _ANY_INCLUDE.match(line):
                raise ShaderError(f'{fname}:{i}: an #include line must read #include "file.glsl"')
            if inc:
                child, here = inc.group(1), f"{fname}:{i}"
                if child in chain + (fname,):
                    raise ShaderError(f"#include cycle: {' -> '.join(chain + (fname, child))} (at {here})")
                if child in first_site:
                    first = first_site[child]
                    if tuple(open_groups[:len(first)]) != first:
                        raise ShaderError(f"{here}: {child} was first included under other #if conditions; "
                                          f"include it once where every user of it sees it")
                    out.append(f"// (already included: {child})")  # one line for one: numbering unchanged
                    continue
                first_site[child] = tuple(open_groups)
                walk(child, chain + (fname,), here)
                out.append(marker(number, i + 1))
                resync = True
                continue
            out.append(line)
            cond = _CONDITIONAL.match(line)
            if cond is None:
                continue
            kind = cond.group(1)
            if kind in ("if", "ifdef", "ifndef"):
                open_groups.append((fname, i, 0))
                continue
            if open_groups:
                group = open_groups.pop()
                if kind != "endif":
                    open_groups.append((group[0], group[1], group[2] + 1))
            if resync:
                out.append(marker(number, i + 1))

    walk(name, (), None)
    # The text ends with a line that is no directive: moderngl strips each stage's source, so a
    # marker after the file's last #endif would end it without a newline, and the NVIDIA
    # compiler (580.x) rejects a directive cut off by the end of the source (C0115).
    out.append(f"// end of {name}")
    return Expansion("\n".join(out) + "\n", tuple(files))


@lru_cache(maxsize=None)
def _expansion(folders: tuple[Path, ...], name: str) -> Expansion:
    return _expand(folders, name)


def expansion(name: str) -> Expansion:
    """The shader file ``name`` (found on :func:`shader_path`) expanded (:class:`Expansion`: its
    text and its table of files)."""
    return _expansion(tuple(shader_path()), name)


def shader_source(name: str) -> str:
    """The GLSL text of the shader file ``name`` with every ``#include "file"`` expanded once, between
    ``#line`` markers (no #version)."""
    return expansion(name).text


def declared_uniforms(stage_source: str) -> frozenset[str]:
    """Names of the uniforms a stage's source declares in the branches its ``#ifdef``s keep
    (:func:`shadowlab.gpu.glstate.active_source`), arrays by their bare name as moderngl lists them."""
    names = set()
    for declarators in _UNIFORM.findall(glstate.active_source(stage_source)):
        for part in declarators.split(","):
            m = re.match(r"\s*(\w+)", part)
            if m:
                names.add(m.group(1))
    return frozenset(names)


@dataclass(frozen=True)
class ProgramInfo:
    """What the lab knows of a program it compiled: its file, defines, the clip distances its
    vertex or geometry stage writes (each needs GL_CLIP_DISTANCEi enabled when it draws), the
    uniforms its compiled stages declare (the compiler may drop unused ones) and its table of
    source-string numbers (``files[k]``: string k of its ``#line`` markers)."""

    name: str
    defines: dict
    clip_distances: frozenset
    uniforms: frozenset = frozenset()
    files: tuple = ()

    def label(self) -> str:
        """The program file and its defines, e.g. ``shadow_lookup.glsl {FILTER_HW=1}``."""
        return f"{self.name} {{{', '.join(f'{k}={v}' for k, v in self.defines.items())}}}"


def program_info(prog) -> ProgramInfo | None:
    """The :class:`ProgramInfo` of a program made by :func:`program` (kept on the program
    object itself, so it goes with it); None for other programs."""
    info = getattr(prog, "extra", None)
    return info if isinstance(info, ProgramInfo) else None


#: Compiled programs by (shader folder, file, defines, varyings) -> (program, uniform values at link).
_PROGRAMS: dict[tuple, tuple] = {}


def _canonical_defines(defines: dict | None) -> tuple[tuple[str, str], ...]:
    """Defines as sorted (name, text) pairs: the cache key, and the order of the #define lines."""
    return tuple(sorted((str(k), str(v)) for k, v in (defines or {}).items()))


def program_key(name: str, defines: dict | None = None, varyings: tuple[str, ...] = ()) -> tuple:
    """The cache key of :func:`program` for these arguments: (shader search path, file, canonical
    defines, varyings) — who holds a shared program can be asked before it is handed out."""
    return (tuple(str(f) for f in shader_path()), name, _canonical_defines(defines), tuple(varyings))


def program(name: str, defines: dict | None = None, varyings: tuple[str, ...] = ()):
    """The moderngl Program of the shader file ``name`` (on :func:`shader_path`), compiled once per process for each
    (file, defines, varyings).

    One file holds every stage of one program, each inside ``#ifdef VERTEX_SHADER`` /
    ``GEOMETRY_SHADER`` / ``FRAGMENT_SHADER``; a stage is built when the file (its includes
    expanded) has that ``#ifdef`` line. A compute program (a moderngl ComputeShader) has one
    ``#ifdef COMPUTE_SHADER`` section and nothing else. The #version is :data:`GLSL_VERSION`
    unless the file or an include asks for more with a ``//! glsl 430`` line. ``defines`` become ``#define KEY VALUE`` lines
    (compile-time switches between variants of the program; numeric parameters are uniforms);
    ``varyings`` make a transform-feedback program (no fragment stage).

    The cache owns the program: callers share it and must not ``release()`` it
    (:func:`release_programs` frees them all). Each call hands it back with every uniform at its
    value just after linking, as a fresh compile would; a caller sets the uniforms it needs
    after its own call, and two users alive at once share uniform values.

    A GLSL error raises :class:`ShaderError` naming the file, the defines and each error's
    ``file.glsl:line``.
    """
    import moderngl

    key = program_key(name, defines, varyings)
    folders, canonical = tuple(Path(f) for f in key[0]), key[2]
    cached = _PROGRAMS.get(key)
    if cached is not None and not isinstance(cached[0].mglo, moderngl.InvalidObject):
        prog, initial = cached
        for uniform, data in initial.items():
            prog[uniform].write(data)
        return prog
    exp = _expansion(folders, name)
    versions = [int(v) for v in _VERSION_LINE.findall(exp.text)]
    version = f"#version {max(versions)} core" if versions else GLSL_VERSION
    head = [version] + [f"#define {k} {v}" for k, v in canonical]
    macros = set(_STAGE_LINE.findall(exp.text))
    stages = {stage: "\n".join(head + [f"#define {macro} 1", exp.text])
              for stage, macro in _STAGES.items() if macro in macros}
    label = f"{name} {{{', '.join(f'{k}={v}' for k, v in canonical)}}}"
    if "compute" in stages and len(stages) > 1:
        raise ShaderError(f"{label}: a compute program has a '#ifdef COMPUTE_SHADER' section and no other stage")
    if "vertex" not in stages and "compute" not in stages:
        raise ShaderError(f"{label}: no '#ifdef VERTEX_SHADER' (or COMPUTE_SHADER) section (in the file or its "
                          f"includes)")
    if varyings:
        stages.pop("fragment", None)  # transform feedback: vertex (and geometry) only
    try:
        if "compute" in stages:
            prog = context().compute_shader(stages["compute"])
        else:
            prog = context().program(vertex_shader=stages["vertex"], geometry_shader=stages.get("geometry"),
                                     fragment_shader=stages.get("fragment"), varyings=tuple(varyings))
    except moderngl.Error as exc:
        raise ShaderError(f"{label} failed to build (locations as file:line):\n{exp.rewrite(str(exc)).strip()}"
                          ) from None
    declared = frozenset().union(*(declared_uniforms(src) for src in stages.values()))
    prog.extra = ProgramInfo(name, dict(defines or {}), glstate.clip_distances_written(stages), declared,
                             exp.files)
    initial = {u: prog[u].read() for u in prog if isinstance(prog[u], moderngl.Uniform)}
    _PROGRAMS[key] = (prog, initial)
    return prog


def release_programs() -> None:
    """Release every program :func:`program` compiled and empty its cache (tests, shutdown): the
    next call compiles afresh. Nothing may draw with the released programs afterwards (a
    frame's vertex arrays of them go with the frame)."""
    for prog, _ in _PROGRAMS.values():
        prog.release()
    _PROGRAMS.clear()


_QUERIES: dict = {}


def query(key, **kinds):
    """A GL query object (moderngl ``ctx.query(**kinds)``) kept for reuse under ``key``:
    moderngl cannot release query objects, so timing code reuses one per purpose instead of
    making one per measurement."""
    if (key, tuple(sorted(kinds.items()))) not in _QUERIES:
        _QUERIES[(key, tuple(sorted(kinds.items())))] = context().query(**kinds)
    return _QUERIES[(key, tuple(sorted(kinds.items())))]


def set_uniforms(prog, values: dict) -> None:
    """Set the uniforms in ``values`` on ``prog``: numpy arrays are written as float32 / int32
    bytes (arrays of uniforms), other values through moderngl's ``.value``.

    A name the program's compiled stages declare but the compiler dropped (unused) is skipped.
    For a program made by :func:`program`, a name they do not declare at all raises
    :class:`UnknownUniformError` (a ``KeyError``) naming the program file and close matches.
    """
    info = program_info(prog)
    for key, val in values.items():
        if key not in prog:
            if info is not None and key not in info.uniforms:
                hint = did_you_mean(key, sorted(info.uniforms), n=3)
                raise UnknownUniformError(f"{info.label()} declares no uniform {key!r}{hint}")
            continue
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


_FULLSCREEN_VBO = None


def fullscreen_quad(prog):
    """A VertexArray drawing one screen-covering triangle pair; ``prog`` needs ``in vec2 in_pos``.
    Every quad reads one vertex buffer that lives as long as the context (releasing the
    VertexArray leaves it for the next quad)."""
    global _FULLSCREEN_VBO
    ctx = context()
    if _FULLSCREEN_VBO is None:
        _FULLSCREEN_VBO = ctx.buffer(np.array([-1, -1, 1, -1, 1, 1, -1, -1, 1, 1, -1, 1], dtype="f4").tobytes())
    return ctx.vertex_array(prog, [(_FULLSCREEN_VBO, "2f", "in_pos")])
