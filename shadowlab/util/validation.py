"""Strict reading of TOML tables: typed keys, required keys, unknown keys, finite numbers.

Every failure raises :class:`SceneError` naming the file, the key and the reason, so a bad
scene file stops the run with one line before any GL work (docs/contracts.md#scene-files). :func:`did_you_mean` is
the one spelling hint for every name lookup (keys, choices, scenes, suites, techniques,
parameters, uniforms).
"""
from __future__ import annotations

import difflib
import math

import numpy as np

_REQUIRED = object()


def did_you_mean(word, known, n: int = 1) -> str:
    """The hint for a misspelt name: ``"; did you mean 'x'?"`` naming the entry of ``known``
    closest to ``word`` (:func:`difflib.get_close_matches`; up to ``n`` of them, joined by "or"),
    or ``""`` when none is close. Entries and ``word`` are compared as strings."""
    close = difflib.get_close_matches(str(word), [str(k) for k in known], n=n)
    return "; did you mean " + " or ".join(f"'{c}'" for c in close) + "?" if close else ""


class SceneError(ValueError):
    """A scene file (or a scene built in code) is malformed, incomplete or impossible."""

    def __init__(self, file: str, key: str, reason: str):
        self.file, self.key, self.reason = file, key, reason
        super().__init__(f"{file}: {key}: {reason}")


class TableReader:
    """Reads keys from one TOML table; ``finish()`` rejects the keys nobody asked for.

    ``where`` is the table's dotted name in the file (e.g. ``lights[0]``), used in messages.
    """

    def __init__(self, table, where: str, file: str):
        if not isinstance(table, dict):
            raise SceneError(file, where, f"must be a table, got {type(table).__name__}")
        self.table, self.where, self.file = table, where, file
        self.used: set[str] = set()

    def key(self, name: str) -> str:
        """The dotted name of key ``name`` in this table."""
        return f"{self.where}.{name}" if self.where else name

    def error(self, name: str, reason: str) -> SceneError:
        """A SceneError about key ``name`` of this table."""
        return SceneError(self.file, self.key(name), reason)

    def raw(self, name: str, default=_REQUIRED):
        """The untyped value of ``name`` (marks it used); a missing required key is an error."""
        self.used.add(name)
        if name not in self.table:
            if default is _REQUIRED:
                raise self.error(name, "required key is missing")
            return default
        return self.table[name]

    def number(self, name: str, default=_REQUIRED, *, min=None, max=None, min_open=False, integer=False):
        """A finite int/float, optionally bounded (``min_open`` makes the lower bound strict)."""
        val = self.raw(name, default)
        if val is default and default is not _REQUIRED:
            return val
        if isinstance(val, bool) or not isinstance(val, (int, float)):
            raise self.error(name, f"must be a number, got {val!r}")
        if integer and not (isinstance(val, int) or float(val).is_integer()):
            raise self.error(name, f"must be an integer, got {val!r}")
        if not math.isfinite(val):
            raise self.error(name, f"must be finite, got {val!r}")
        if min is not None and (val <= min if min_open else val < min):
            raise self.error(name, f"must be {'>' if min_open else '>='} {min}, got {val!r}")
        if max is not None and val > max:
            raise self.error(name, f"must be <= {max}, got {val!r}")
        return int(val) if integer else float(val)

    def vector(self, name: str, n: int, default=_REQUIRED, *, nonzero=False, positive=False) -> np.ndarray:
        """A list of ``n`` finite numbers as float64; ``nonzero`` rejects the zero vector."""
        val = self.raw(name, default)
        if val is default and default is not _REQUIRED:
            return None if val is None else np.asarray(val, np.float64)
        if not isinstance(val, list) or len(val) != n:
            raise self.error(name, f"must be a list of {n} numbers, got {val!r}")
        for x in val:
            if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x):
                raise self.error(name, f"must hold {n} finite numbers, got {val!r}")
        vec = np.asarray(val, np.float64)
        if nonzero and not np.abs(vec).max() > 0:  # not the norm: it under/overflows at 1e∓200
            raise self.error(name, "must not be the zero vector")
        if positive and not np.all(vec > 0):
            raise self.error(name, f"entries must be > 0, got {val!r}")
        return vec

    def boolean(self, name: str, default=_REQUIRED) -> bool:
        """A TOML boolean."""
        val = self.raw(name, default)
        if not isinstance(val, bool):
            raise self.error(name, f"must be true or false, got {val!r}")
        return val

    def string(self, name: str, default=_REQUIRED, choices=None) -> str:
        """A string, optionally one of ``choices``."""
        val = self.raw(name, default)
        if not isinstance(val, str):
            raise self.error(name, f"must be a string, got {val!r}")
        if choices is not None and val not in choices:
            raise self.error(name, f"must be one of {', '.join(choices)}, got {val!r}{did_you_mean(val, choices)}")
        return val

    def table_list(self, name: str, default=_REQUIRED) -> list:
        """An array of tables (``[[name]]``)."""
        val = self.raw(name, default)
        if not isinstance(val, list):
            raise self.error(name, f"must be an array of tables ([[{name}]]), got {type(val).__name__}")
        return val

    def finish(self) -> None:
        """Reject the keys of the table that were never read (pbrt's unused-parameter check)."""
        unknown = sorted(set(self.table) - self.used)
        if unknown:
            raise self.error(unknown[0], f"unknown key{did_you_mean(unknown[0], self.used)} "
                                         f"(known here: {', '.join(sorted(self.used))})")


class RunError(ValueError):
    """Bad run arguments (size, repeat, duplicate configurations, output location)."""


#: The largest image a run accepts, in pixels (GL's usual maximum framebuffer side, squared).
MAX_PIXELS = 8192 * 8192



def check_size(size: tuple[int, int]) -> tuple[int, int]:
    """``size`` = (width, height) if it is a sensible image size; RunError otherwise."""
    w, h = map(int, size)
    if w < 8 or h < 8 or w * h > MAX_PIXELS:
        raise RunError(f"--size {w}x{h} is out of range (each side >= 8, at most {MAX_PIXELS} pixels)")
    return w, h


def read_toml_file(path) -> dict:
    """The parsed TOML file ``path`` (a scene, a viewer script); a one-line SceneError naming the
    file when it cannot be read or is not valid TOML."""
    import tomllib
    from pathlib import Path

    path = Path(path)
    try:
        return tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(str(path), "toml", f"not valid TOML: {exc}") from exc
    except (OSError, UnicodeDecodeError) as exc:
        raise SceneError(str(path), "file", f"cannot read: {exc}") from exc
