"""Files written whole or not at all: under a temporary name beside the final one, then renamed
onto it.

The rename is an atomic replace on one file system, so a reader (a browser, a resumed study,
another worker) sees the old file or the new one, never half of one.

:func:`replacing` writes any number of files that way, replacing them only once every one was
written; :func:`write_text_atomic` is the one-text-file case; :func:`temporary_path` names the
temporary file (or folder) beside a path.
"""
from __future__ import annotations

import contextlib
import os
from pathlib import Path
from typing import Iterator


def temporary_path(path) -> Path:
    """The temporary name beside ``path`` that it is written under before the rename:
    ``.<name>.tmp-<pid>`` (hidden, one per process, in the same folder so the rename is atomic)."""
    path = Path(path)
    return path.with_name(f".{path.name}.tmp-{os.getpid()}")


@contextlib.contextmanager
def replacing(*paths) -> Iterator[list[Path]]:
    """Yield the temporary path of each of ``paths`` (:func:`temporary_path`) to write to; when
    the block ends normally, rename each onto its path, in order, after all were written (a set
    of files that go together is replaced together); when it raises, remove the temporary files
    and replace nothing."""
    tmps = [temporary_path(p) for p in paths]
    try:
        yield tmps
        for tmp, path in zip(tmps, paths):
            os.replace(tmp, path)
    finally:
        for tmp in tmps:
            tmp.unlink(missing_ok=True)


def write_text_atomic(path, text: str) -> None:
    """Write ``text`` (UTF-8) to a temporary name beside ``path`` and rename it into place."""
    with replacing(path) as (tmp,):
        tmp.write_text(text, encoding="utf-8")
