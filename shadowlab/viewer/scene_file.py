"""The viewer's "save view" (key ``x``, script step ``save_view``): the scene as shown, from the
camera it is seen from, as a scene file that ``shadowlab compare`` and ``study`` read — so a view
found by flying can be measured properly, in a run directory or a suite.

For a TOML scene the file is a copy of the scene file with its ``[camera]`` table replaced and
every relative file path (``mesh`` of an object, ``file`` of a ``[gltf]`` table) rewritten to
resolve from the new file's folder; the opening comment is kept under a line saying where the view
came from. For a glTF scene (.glb / .gltf) the file is ``[gltf] file = "<path>"`` plus a
``[camera]`` table, which overrides the glTF file's camera (docs/your-scenes.md#gltf-scenes).
Either way the lights are the ones shown: a glTF file's automatic exposure does not depend on
the camera.

The camera is written with Python's shortest round-trip float text, so the file's camera is the
viewer's bit for bit, and near and far only where the scene file gave them (otherwise both are
fitted to the scene, as for the viewer's own frames).
"""
from __future__ import annotations

import json
import os
import re
import tomllib
from pathlib import Path

from ..scene import PRIMITIVES, Scene, gltf
from ..scene.model import Camera
from ..util.validation import RunError

_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")


def camera_table(camera: Camera) -> dict:
    """A ``[camera]`` table of ``camera``: eye, target, up and fov_y always; near and far only
    where they are set (None: fitted to the scene when read)."""
    table = {"eye": [float(x) for x in camera.eye], "target": [float(x) for x in camera.target],
             "up": [float(x) for x in camera.up], "fov_y": float(camera.fov_y)}
    for key in ("near", "far"):
        if getattr(camera, key) is not None:
            table[key] = float(getattr(camera, key))
    return table


def _key(name: str) -> str:
    return name if _BARE_KEY.fullmatch(name) else json.dumps(name)


def _value(v) -> str:
    """A TOML value: strings as JSON writes them (a subset of TOML's basic strings), floats in
    Python's round-trip form, arrays inline, tables inline (inside arrays only)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        text = repr(v)
        if text in ("inf", "-inf", "nan"):
            return text
        return text if any(c in text for c in ".en") else text + ".0"
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{_key(k)} = {_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(f"cannot write {type(v).__name__} as TOML")


def _is_table_array(v) -> bool:
    return isinstance(v, list) and bool(v) and all(isinstance(x, dict) for x in v)


def toml_text(data: dict, prefix: str = "") -> str:
    """``data`` (what :func:`tomllib.loads` returns) as TOML text: plain keys first, then
    sub-tables (``[a.b]``) and arrays of tables (``[[a]]``), nested as deep as they go."""
    lines = []
    plain = {k: v for k, v in data.items() if not isinstance(v, dict) and not _is_table_array(v)}
    for k, v in plain.items():
        lines.append(f"{_key(k)} = {_value(v)}")
    for k, v in data.items():
        name = f"{prefix}.{_key(k)}" if prefix else _key(k)
        if isinstance(v, dict):
            lines.append("")
            lines.append(f"[{name}]")
            lines.append(toml_text(v, name).rstrip("\n"))
        elif _is_table_array(v):
            for item in v:
                lines.append("")
                lines.append(f"[[{name}]]")
                lines.append(toml_text(item, name).rstrip("\n"))
    return "\n".join(line for line in lines) + "\n"


def _relative(path: Path, folder: Path) -> str:
    """``path`` as the new file writes it: relative to ``folder`` where it can be (POSIX
    separators), else absolute."""
    try:
        return Path(os.path.relpath(path.resolve(), folder.resolve())).as_posix()
    except ValueError:  # another drive (Windows)
        return path.resolve().as_posix()


def _opening_comment(text: str) -> list[str]:
    """The comment lines a scene file opens with (its purpose, :func:`shadowlab.scene.scene_purpose`)."""
    out = []
    for line in text.splitlines():
        if not line.startswith("#"):
            break
        out.append(line)
    return out


def view_scene_text(scene: Scene, camera: Camera, out: Path) -> str:
    """The text of the scene file ``out`` that holds ``scene`` seen from ``camera``
    (docstring of the module); RunError for a scene with no file."""
    if scene.path is None:
        raise RunError(f"scene {scene.name} has no file to save a view of")
    src, folder = Path(scene.path), Path(out).parent
    header = [f"# The view of {src.name} saved by `shadowlab view` (camera replaced; file paths resolve from "
              f"this file's folder)."]
    if gltf.is_gltf(src):
        return gltf_view_text(src, camera, out)
    text = src.read_text()
    data = tomllib.loads(text)
    data["name"] = Path(out).stem
    data["camera"] = camera_table(camera)
    for obj in data.get("objects", []):
        mesh = obj.get("mesh")
        if isinstance(mesh, str) and mesh not in PRIMITIVES:
            obj["mesh"] = _relative(src.parent / mesh, folder)
    included = data.get("gltf")
    if isinstance(included, dict) and isinstance(included.get("file"), str):
        included["file"] = _relative(src.parent / included["file"], folder)
    comment = _opening_comment(text)
    return "\n".join(header + (["#"] + comment if comment else [])) + "\n" + toml_text(data)


def gltf_view_text(gltf_file: Path, camera: Camera, out: Path) -> str:
    """The scene file of a glTF scene's view: ``[gltf] file = "<path>"`` (relative to ``out``'s
    folder) and the ``[camera]`` table that overrides the glTF file's camera."""
    data = {"name": Path(out).stem, "gltf": {"file": _relative(Path(gltf_file), Path(out).parent)},
            "camera": camera_table(camera)}
    return (f"# The view of {Path(gltf_file).name} saved by `shadowlab view`: the glTF scene, this camera.\n"
            + toml_text(data))


def save_view(scene: Scene, camera: Camera, out: Path) -> Path:
    """Write the view's scene file to ``out`` (folders made as needed); return its path."""
    out = Path(out)
    text = view_scene_text(scene, camera, out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(text)
    return out
