"""Scene bundles: a scene file and the mesh files it names, as bytes, so that Dask workers need no
copy of the scene files. A study's tasks carry their scene's bundle to Dask workers, which may
share no disk with the machine that planned the study.

A bundle is content-addressed by the scene's content hash (:func:`shadowlab.output.cache.scene_content_hash`,
which covers the same files, listed by :func:`shadowlab.output.cache.scene_mesh_files`). A worker
writes it once under ``<root>/<hash>/`` (:func:`materialize`), keeping the files' relative layout
so the scene's mesh references resolve as they did where it was planned, and reuses that copy
for every later task of the same scene. The root is ``$SHADOWLAB_BUNDLE_DIR``, or
``shadowlab-bundles`` in the system's temporary folder.
"""
from __future__ import annotations

import os
import posixpath
import re
import shutil
import tempfile
from pathlib import Path, PurePosixPath

from ..output.cache import scene_content_hash, scene_mesh_files
from ..util.validation import RunError

#: Environment variable naming the folder where workers keep materialized bundles.
BUNDLE_DIR_ENV = "SHADOWLAB_BUNDLE_DIR"
#: The bundle folder's name under the system's temporary folder when the variable is not set.
DEFAULT_BUNDLE_FOLDER = "shadowlab-bundles"
#: A bundle's hash names its folder: hex digits only, so it cannot name a path of its own.
_HASH = re.compile(r"[0-9a-f]+")


def bundle_root() -> Path:
    """Where this process keeps materialized bundles: ``$SHADOWLAB_BUNDLE_DIR``, else
    ``<tempdir>/shadowlab-bundles``."""
    configured = os.environ.get(BUNDLE_DIR_ENV)
    return Path(configured) if configured else Path(tempfile.gettempdir()) / DEFAULT_BUNDLE_FOLDER


def scene_bundle(scene_path: Path) -> dict:
    """The bundle of a scene file: ``{"hash": content hash, "scene": the scene file's relative
    path in the bundle (its name), "files": {relative posix path: bytes}}``, with the scene file
    and every mesh file it names that exists (a missing one stays missing, so the worker fails
    as a local run would). Meshes named as paths relative to the scene (``meshes/x.ply.gz``)
    keep that path; meshes above the scene's folder (``../shared/x.obj``) lift the bundle's
    base folder so they still resolve. Raises ValueError for an absolute mesh path, which no
    bundle can reproduce on another machine."""
    scene_path = Path(scene_path)
    meshes = scene_mesh_files(scene_path)
    refs = []
    for ref, _ in meshes:
        if PurePosixPath(ref).is_absolute() or Path(ref).is_absolute():
            raise ValueError(f"{scene_path} names the mesh {ref!r} by an absolute path, which cannot be sent "
                             f"to Dask workers: name it relative to the scene file")
        refs.append(posixpath.normpath(PurePosixPath(ref).as_posix()))
    # how many folders above the scene's own folder its meshes reach
    lift = max((_levels_up(r) for r in refs), default=0)
    scene_dir = scene_path.resolve().parent
    base = scene_dir
    for _ in range(lift):
        base = base.parent
    scene_rel = PurePosixPath(scene_dir.relative_to(base).as_posix()) / scene_path.name
    files = {scene_rel.as_posix(): scene_path.read_bytes()}
    for ref, (_, mesh) in zip(refs, meshes):
        if mesh.is_file():
            files[posixpath.normpath((scene_rel.parent / ref).as_posix())] = mesh.read_bytes()
    return {"hash": scene_content_hash(scene_path), "scene": scene_rel.as_posix(), "files": files}


def _levels_up(ref: str) -> int:
    """How many leading ``..`` a normalized relative path has (folders above its start)."""
    parts = ref.split("/")
    count = 0
    while count < len(parts) and parts[count] == "..":
        count += 1
    return count


def _safe_relative(name: str) -> PurePosixPath:
    """``name`` as a relative path that stays inside the bundle's folder; ValueError otherwise
    (absolute, empty, or with a ``..`` part): a bundle must never write outside its folder."""
    path = PurePosixPath(name)
    if not name or path.is_absolute() or Path(name).is_absolute() or any(p in ("..", "") for p in path.parts) \
            or "\\" in name or path == PurePosixPath("."):
        raise ValueError(f"bundle file path {name!r} would leave the bundle's folder")
    return path


def materialize(bundle: dict, root: Path | None = None) -> Path:
    """Write a bundle's files under ``root/<hash>/`` (``root``: :func:`bundle_root` by default),
    keeping their relative paths, and return the scene file's path there. Written once: a folder
    for the same hash is reused. The files go to a temporary folder that is renamed into place,
    so a concurrent or interrupted write never leaves a partial bundle. Raises ValueError for a
    malformed bundle or a path that would escape the folder."""
    root = Path(root) if root is not None else bundle_root()
    digest = bundle.get("hash")
    if not isinstance(digest, str) or not _HASH.fullmatch(digest):
        raise ValueError(f"bundle hash {digest!r} is not a hex digest")
    files = bundle.get("files")
    if not isinstance(files, dict) or bundle.get("scene") not in files:
        raise ValueError("a bundle needs 'files' holding its 'scene' file")
    relative = {_safe_relative(name): data for name, data in files.items()}
    final = root / digest
    scene = final / _safe_relative(bundle["scene"])
    if final.is_dir():
        return scene
    root.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{digest}.tmp-", dir=root))
    try:
        for rel, data in relative.items():
            target = tmp / rel
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_bytes(data)
        try:
            os.rename(tmp, final)
        except OSError:
            if not final.is_dir():  # another process won the race only if the folder is now there
                raise
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
    return scene


class SceneBundles:
    """Each scene's bundle (:func:`shadowlab.study.bundle.scene_bundle`), built once per study and
    attached to every task of the scene sent to Dask workers, which may share no disk with this
    machine. A scene that cannot be bundled (an absolute mesh path) is a RunError."""

    def __init__(self):
        self._made: dict[str, dict] = {}

    def of(self, path) -> dict:
        """The bundle of the scene file at ``path``."""
        key = str(path)
        if key not in self._made:
            try:
                self._made[key] = scene_bundle(path)
            except ValueError as exc:
                raise RunError(str(exc)) from exc
        return self._made[key]
