"""Where a figure came from: code revision, package versions, GL device, machine, command.

``run.json`` and every experiment's JSON record carry :func:`record`, so each figure can be
traced to the code, the renderer and the machine that made it (docs/contracts.md#run-directory).
"""
from __future__ import annotations

import datetime as _dt
import hashlib
import json
import os
import platform
import subprocess
import sys
from functools import lru_cache
from pathlib import Path

from .. import __version__


#: The package's folder (its parent is the checkout, in a source tree).
PACKAGE = Path(__file__).resolve().parents[1]


@lru_cache(maxsize=None)
def revision() -> str:
    """``git describe --always --dirty`` of the checkout the package runs from, else
    ``shadowlab <version>`` (an installed copy)."""
    root = PACKAGE.parent
    if (root / ".git").exists():
        try:
            out = subprocess.run(["git", "-C", str(root), "describe", "--always", "--dirty"], capture_output=True,
                                 text=True, timeout=10)
            if out.returncode == 0 and out.stdout.strip():
                return out.stdout.strip()
        except (OSError, subprocess.SubprocessError):
            pass
    return f"shadowlab {__version__}"


@lru_cache(maxsize=None)
def code_fingerprint() -> str:
    """:func:`revision`, plus a hash of whatever code it does not pin: in a git checkout the
    uncommitted changes (``git diff HEAD``) and the package's untracked files; in an installed
    copy (no git) every source file of the package (``*.py``, ``*.glsl``, ``*.toml``). What the
    study's cache keys its runs by, so that editing the code invalidates them even before a
    commit."""
    rev = revision()
    root = PACKAGE.parent
    digest, hashed = hashlib.sha256(), False
    try:
        if rev.startswith("shadowlab "):  # not a git checkout
            package = PACKAGE
            for path in sorted(p for ext in ("*.py", "*.glsl", "*.toml") for p in package.rglob(ext)):
                digest.update(str(path.relative_to(package)).encode())
                digest.update(path.read_bytes())
                hashed = True
        else:
            if rev.endswith("-dirty"):
                diff = subprocess.run(["git", "-C", str(root), "diff", "HEAD", "--binary"], capture_output=True,
                                      timeout=30)
                digest.update(diff.stdout)
                hashed = True
            untracked = subprocess.run(["git", "-C", str(root), "ls-files", "--others", "--exclude-standard", "-z",
                                        "--", "shadowlab"], capture_output=True, timeout=30)
            for name in sorted(filter(None, untracked.stdout.split(b"\0"))):
                digest.update(name)
                digest.update((root / name.decode()).read_bytes())
                hashed = True
    except (OSError, subprocess.SubprocessError):
        return rev
    return f"{rev}+{digest.hexdigest()[:12]}" if hashed else rev


def versions() -> dict:
    """Versions of Python, the platform and every package the lab's figures depend on."""
    import embreex
    import matplotlib
    import moderngl
    import numpy as np
    import pandas as pd
    import scipy
    import trimesh

    return {"shadowlab": __version__, "python": platform.python_version(), "numpy": np.__version__,
            "moderngl": moderngl.__version__, "trimesh": trimesh.__version__, "scipy": scipy.__version__,
            "pandas": pd.__version__, "matplotlib": matplotlib.__version__,
            "embreex": getattr(embreex, "__version__", "unknown"), "platform": platform.platform()}


@lru_cache(maxsize=None)
def cpu_model() -> str:
    """The CPU's model name (from /proc/cpuinfo where there is one)."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.lower().startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def machine() -> dict:
    """CPU model and logical core count of this machine."""
    return {"cpu": cpu_model(), "cores": os.cpu_count()}


def record(gl_info: bool = True) -> dict:
    """Revision, versions, machine, GL device (``gl_info``: creates the context if needed),
    exact command line and date — what every result file carries."""
    out = {"revision": revision(), "versions": versions(), "machine": machine(),
           "command": [sys.executable] + sys.argv,
           "date": _dt.datetime.now().astimezone().isoformat(timespec="seconds")}
    if gl_info:
        from ..gpu import gl

        out["gl"] = gl.gl_info()
    return out


def write_record(data_path: Path, extra: dict | None = None, gl_info: bool = True) -> Path:
    """Write :func:`record` (plus ``extra``) as JSON beside ``data_path`` (same stem, .json)."""
    path = Path(data_path).with_suffix(".json")
    path.write_text(json.dumps({**record(gl_info), **(extra or {})}, indent=2, default=str))
    return path


def json_default(obj):
    """``json.dumps(default=...)`` for the lab's records: numpy scalars and arrays as Python
    numbers and lists, paths as strings; anything else is a TypeError (no silent ``str()``)."""
    import numpy as np

    if isinstance(obj, (np.integer, np.floating, np.bool_)):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(type(obj).__name__)
