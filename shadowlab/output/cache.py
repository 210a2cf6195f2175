"""The study's cache of finished runs (docs/contracts.md#study-directory), so that running a study again redoes only
what changed and an interrupted study resumes.

A run is keyed by a SHA-256 of (scene file content — the TOML and every mesh file it names —,
configuration spec, image size, code revision — with a hash of uncommitted changes —, GL
device: renderer, vendor and driver version); the timing of a run also by its repeat, warm-up and pass-timing settings, so that
asking for more repeats re-times without re-rendering. Entries live in ``<study>/cache/``:
``acc/<key>.npz`` (visibility, metrics rows, images) and ``time/<key>.json`` (timing columns).
Every entry is written to a temporary file and renamed into place, so an interrupted study
(Ctrl-C, a killed worker) leaves only complete entries. A truncated entry is a miss when the
study is planned (:meth:`Cache.has_result`) and redone; one damaged inside is found only when
it is read, and the run is then reported as failed ("run the study again"), never used.
Only the main process writes entries: workers — local or on a Dask cluster — return results.
"""
from __future__ import annotations

import hashlib
import json
import os
import posixpath
import tomllib
import zipfile
from pathlib import Path

import numpy as np

from ..output import provenance
from ..util.files import replacing
from ..scene import PRIMITIVES, gltf

#: Bumped when the layout or meaning of cached entries changes.
CACHE_FORMAT = 2


def scene_mesh_files(path: Path) -> list[tuple[str, Path]]:
    """The mesh files a scene file names: ``(reference as written in the file, resolved path)``
    per object mesh that is not a primitive, in file order. The one list of a scene's files that
    both its content hash and its Dask bundle (:mod:`shadowlab.study.bundle`) use, so a bundle
    always holds exactly what the hash covers. A file that is not valid TOML names none (loading
    it fails on its own). A glTF file's own buffer files count as its meshes, and a scene's
    ``[gltf]`` file as one of its meshes, with that file's buffer files
    (:func:`shadowlab.scene.gltf.buffer_files`)."""
    path = Path(path)
    if gltf.is_gltf(path):
        return gltf.buffer_files(path)
    try:
        data = tomllib.loads(path.read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError):
        return []
    files = []
    included = data.get("gltf") if isinstance(data.get("gltf"), dict) else {}
    if isinstance(included.get("file"), str):
        ref = included["file"]
        files.append((ref, (path.parent / ref).resolve()))
        folder = posixpath.dirname(ref)
        files += [(posixpath.join(folder, r) if folder else r, p) for r, p in gltf.buffer_files(path.parent / ref)]
    for obj in data.get("objects", []) if isinstance(data.get("objects"), list) else []:
        ref = obj.get("mesh") if isinstance(obj, dict) else None
        if isinstance(ref, str) and ref not in PRIMITIVES:
            files.append((ref, (path.parent / ref).resolve()))
    return files


def scene_content_hash(path: Path) -> str:
    """SHA-256 of a scene file and of every mesh file it references (relative to it); a mesh
    that is missing contributes its path, so the run fails again rather than hitting a cache."""
    path = Path(path)
    digest = hashlib.sha256(path.read_bytes())
    for ref, mesh in scene_mesh_files(path):
        digest.update(ref.encode())
        digest.update(mesh.read_bytes() if mesh.is_file() else b"<missing>")
    return digest.hexdigest()


def run_key(scene_hash: str, spec: str, size: tuple[int, int], revision: str, renderer: str, **extra) -> str:
    """The cache key of one run: hex SHA-256 of its identifying fields (``extra``: timing settings)."""
    fields = {"format": CACHE_FORMAT, "scene": scene_hash, "spec": spec, "size": list(size), "revision": revision,
              "renderer": renderer, **extra}
    return hashlib.sha256(json.dumps(fields, sort_keys=True).encode()).hexdigest()[:32]


def _atomic_write(path: Path, write) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with replacing(path) as (tmp,):
        with open(tmp, "wb") as fh:
            write(fh)
            fh.flush()
            os.fsync(fh.fileno())


class Cache:
    """Finished runs of a study, in ``root`` (``<study>/cache``)."""

    def __init__(self, root: Path):
        self.root = Path(root)

    def _acc(self, key: str) -> Path:
        return self.root / "acc" / f"{key}.npz"

    def _time(self, key: str) -> Path:
        return self.root / "time" / f"{key}.json"

    def has_result(self, key: str) -> bool:
        """Whether a complete accuracy entry exists: the file is there and its zip directory and
        metadata member can be read (a truncated file is a miss; reading the arrays themselves is
        left to :meth:`load_result`, which also returns None for an entry damaged inside)."""
        path = self._acc(key)
        if not path.is_file():
            return False
        try:
            with zipfile.ZipFile(path) as z:
                return "__meta__.npy" in z.namelist()
        except (OSError, zipfile.BadZipFile):
            return False

    def load_result(self, key: str) -> dict | None:
        """An accuracy entry: ``{"meta": dict, "arrays": {name: ndarray}, "files": {name: bytes}}``,
        or None when absent or unreadable."""
        path = self._acc(key)
        if not path.is_file():
            return None
        try:
            with np.load(path, allow_pickle=False) as z:
                meta = json.loads(bytes(z["__meta__"]).decode())
                arrays = {k[2:]: z[k] for k in z.files if k.startswith("a:")}
                files = {k[2:]: bytes(z[k]) for k in z.files if k.startswith("f:")}
        except (OSError, ValueError, KeyError, zipfile.BadZipFile, json.JSONDecodeError, EOFError):
            return None
        return {"meta": meta, "arrays": arrays, "files": files}

    def store_result(self, key: str, result: dict) -> None:
        """Write an accuracy entry (same layout as :meth:`load_result` returns), atomically."""
        payload = {"__meta__": np.frombuffer(json.dumps(result["meta"], default=provenance.json_default).encode(), np.uint8)}
        payload.update({f"a:{k}": np.asarray(v) for k, v in result.get("arrays", {}).items()})
        payload.update({f"f:{k}": np.frombuffer(v, np.uint8) for k, v in result.get("files", {}).items()})
        _atomic_write(self._acc(key), lambda fh: np.savez_compressed(fh, **payload))

    def load_timing(self, key: str) -> dict | None:
        """A timing entry (dict), or None when absent or unreadable."""
        path = self._time(key)
        try:
            return json.loads(path.read_text()) if path.is_file() else None
        except (OSError, json.JSONDecodeError, UnicodeDecodeError):
            return None

    def store_timing(self, key: str, timing: dict) -> None:
        """Write a timing entry, atomically."""
        data = json.dumps(timing, default=provenance.json_default).encode()
        _atomic_write(self._time(key), lambda fh: fh.write(data))

