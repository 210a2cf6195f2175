"""The GLSL loader: shader files found by name on the package's search path, ``#include``s
expanded between ``#line`` markers (so that a compiler's error names ``file.glsl:line``), the
stages a file holds and the uniforms a stage declares.

A program's file holds every stage, each inside ``#ifdef VERTEX_SHADER`` / ``GEOMETRY_SHADER`` /
``FRAGMENT_SHADER`` / ``COMPUTE_SHADER``; :func:`stage_sources` turns an :class:`Expansion` into
the source of each stage. Nothing here touches GL: :mod:`.programs` compiles what this module
reads.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

from . import glstate
from ..util.validation import did_you_mean

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


def expansion(name: str, folders: tuple[Path, ...] | None = None) -> Expansion:
    """The shader file ``name`` (found on :func:`shader_path`, or on ``folders`` when given)
    expanded (:class:`Expansion`: its text and its table of files); each expansion is made once
    per process."""
    return _expansion(tuple(shader_path()) if folders is None else tuple(folders), name)


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




def stage_sources(exp: Expansion, defines: tuple[tuple[str, str], ...] = ()) -> dict[str, str]:
    """Stage ("vertex", "geometry", "fragment", "compute") → its full source, for every stage
    the expanded file has an ``#ifdef <STAGE>_SHADER`` line for: the #version (:data:`GLSL_VERSION`
    unless the file or an include asks for more with a ``//! glsl 430`` line; the highest wins),
    a ``#define KEY VALUE`` line per pair of ``defines`` in their order, the stage's macro, then
    the expanded text."""
    versions = [int(v) for v in _VERSION_LINE.findall(exp.text)]
    version = f"#version {max(versions)} core" if versions else GLSL_VERSION
    head = [version] + [f"#define {k} {v}" for k, v in defines]
    macros = set(_STAGE_LINE.findall(exp.text))
    return {stage: "\n".join(head + [f"#define {macro} 1", exp.text])
            for stage, macro in _STAGES.items() if macro in macros}
