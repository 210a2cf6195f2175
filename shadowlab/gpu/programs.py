"""The program cache: each shader file compiled once per process for each set of defines and
varyings, and uniforms set by name, a misspelt name caught.

:func:`program` compiles and caches, :class:`ProgramInfo` is what the lab knows of each program
it compiled, :func:`set_uniforms` and :func:`mat_bytes` set uniform values.

The GLSL files themselves are read by :mod:`.glsl` (search path, ``#include``s, stages);
this module compiles their stages on the context of :mod:`.gl`.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import gl, glsl, glstate
from ..util.validation import did_you_mean


class UnknownUniformError(KeyError):
    """:func:`set_uniforms` was given a name the program's source never declares (a misspelt or
    stale uniform); the message names the program file and the close matches."""

    def __str__(self) -> str:
        return str(self.args[0]) if self.args else ""


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
    return (tuple(str(f) for f in glsl.shader_path()), name, _canonical_defines(defines), tuple(varyings))


def program(name: str, defines: dict | None = None, varyings: tuple[str, ...] = ()):
    """The moderngl Program of the shader file ``name`` (on :func:`.glsl.shader_path`), compiled once per process for each
    (file, defines, varyings).

    One file holds every stage of one program, each inside ``#ifdef VERTEX_SHADER`` /
    ``GEOMETRY_SHADER`` / ``FRAGMENT_SHADER``; a stage is built when the file (its includes
    expanded) has that ``#ifdef`` line. A compute program (a moderngl ComputeShader) has one
    ``#ifdef COMPUTE_SHADER`` section and nothing else. The #version is :data:`.glsl.GLSL_VERSION`
    unless the file or an include asks for more with a ``//! glsl 430`` line. ``defines`` become ``#define KEY VALUE`` lines
    (compile-time switches between variants of the program; numeric parameters are uniforms);
    ``varyings`` make a transform-feedback program (no fragment stage).

    The cache owns the program: callers share it and must not ``release()`` it
    (:func:`release_programs` frees them all). Each call hands it back with every uniform at its
    value just after linking, as a fresh compile would; a caller sets the uniforms it needs
    after its own call, and two users alive at once share uniform values.

    A GLSL error raises :class:`.glsl.ShaderError` naming the file, the defines and each error's
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
    exp = glsl.expansion(name, folders)
    stages = glsl.stage_sources(exp, canonical)
    label = f"{name} {{{', '.join(f'{k}={v}' for k, v in canonical)}}}"
    if "compute" in stages and len(stages) > 1:
        raise glsl.ShaderError(f"{label}: a compute program has a '#ifdef COMPUTE_SHADER' section and no other stage")
    if "vertex" not in stages and "compute" not in stages:
        raise glsl.ShaderError(f"{label}: no '#ifdef VERTEX_SHADER' (or COMPUTE_SHADER) section (in the file or its "
                               f"includes)")
    if varyings:
        stages.pop("fragment", None)  # transform feedback: vertex (and geometry) only
    try:
        if "compute" in stages:
            prog = gl.context().compute_shader(stages["compute"])
        else:
            prog = gl.context().program(vertex_shader=stages["vertex"], geometry_shader=stages.get("geometry"),
                                        fragment_shader=stages.get("fragment"), varyings=tuple(varyings))
    except moderngl.Error as exc:
        raise glsl.ShaderError(f"{label} failed to build (locations as file:line):\n{exp.rewrite(str(exc)).strip()}"
                               ) from None
    declared = frozenset().union(*(glsl.declared_uniforms(src) for src in stages.values()))
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



def mat_bytes(m: np.ndarray) -> bytes:
    """A 4x4 row-major float64 matrix as the column-major float32 bytes GLSL's mat4 expects."""
    return np.ascontiguousarray(np.asarray(m, dtype=np.float64).T, dtype="f4").tobytes()


#: Loop iterations after which llvmpipe silently ends a shader invocation (Mesa's
#: LP_MAX_TGSI_LOOP_ITERATIONS; every loop of the invocation counts, nested ones included): a
#: shader whose loops could run longer must stop early and resume in another dispatch, or its
#: caller must refuse the configuration (docs/architecture.md). The GL spec sets no such limit, so
#: other drivers run on: results must not depend on it either way.
LLVMPIPE_LOOP_LIMIT = 65535

#: Work groups GL guarantees in one dimension of a dispatch (GL 4.6 core, table 23.64): larger
#: dispatches are split over y (the shaders' invocation index counts rows of x groups).
MAX_GROUPS_X = 65535


def dispatch(prog, invocations: int, local_size: int) -> None:
    """Run compute ``prog`` (``local_size`` invocations per work group, in x) over at least
    ``invocations`` invocations, as (x, y) groups within :data:`MAX_GROUPS_X`; the shader skips
    the surplus. Shared by the compute techniques of several families."""
    groups = max(1, -(-invocations // local_size))
    rows = -(-groups // MAX_GROUPS_X)
    prog.run(-(-groups // rows), rows)
