"""Reading scene files (TOML, the contract of docs/contracts.md#scene-files) into the scene model.

A glTF 2.0 file (``.gltf``, ``.glb``) is a scene file too, read by :mod:`shadowlab.scene.gltf`,
either on its own (``scene.glb``, ``scene.glb#Camera`` choosing its camera) or included by a TOML
scene's ``[gltf]`` table, which may add or override lights, camera, objects and animation.

A loaded :class:`~shadowlab.scene.model.Scene` is plain data: every object's triangles are
already in world space (float64), welded (vertices merged, so seams do not break edge
adjacency) and validated. A shipped scene is named by its file stem (``box_on_plane``); any
other argument is a path. Bad input raises :class:`shadowlab.util.validation.SceneError` naming the
file and the key. Defaults come from the model's dataclasses (:func:`default_of`), so a key
left out of a file and a field left out in Python get the same value.
"""
from __future__ import annotations

import gzip
import io
from importlib import resources
from pathlib import Path

import numpy as np
import trimesh

from ..geometry import transforms as tf
from ..util.text import first_sentence
from ..util.validation import SceneError, TableReader, did_you_mean, read_toml_file
from . import gltf
from .animation import parse_animation
from .area_lights import AREA_SHAPES
from .lights import LIGHT_TYPES, Light
from .model import GENERAL_FAMILY, SCENE_FAMILIES, Camera, Material, Scene, SceneObject, Shading, default_of


# --------------------------------------------------------------------------- primitives

def _plane(size, divisions) -> trimesh.Trimesh:
    n = divisions + 1
    xs = np.linspace(-size[0] / 2, size[0] / 2, n)
    zs = np.linspace(-size[1] / 2, size[1] / 2, n)
    gx, gz = np.meshgrid(xs, zs, indexing="xy")
    verts = np.stack([gx.ravel(), np.zeros(gx.size), gz.ravel()], axis=1)
    idx = np.arange(n * n).reshape(n, n)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel()
    # CCW seen from +y: (a, c, b) and (b, c, d) with z growing towards the viewer.
    faces = np.concatenate([np.stack([a, c, b], 1), np.stack([b, c, d], 1)])
    return trimesh.Trimesh(verts, faces, process=False)


_Z_TO_Y = tf.euler_xyz([-90.0, 0.0, 0.0])  # trimesh builds round primitives along z; ours stand on y


def _along_y(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    mesh.vertices = mesh.vertices @ _Z_TO_Y.T
    return mesh


#: The most triangles one procedural primitive may make (2²², about 4.2 million: the largest
#: shipped primitive, the scaling suite's 2000 × 1000 torus, makes 4 million). Sections beyond it
#: would not show in any image the lab renders and would only exhaust memory, so they are a scene
#: error naming the key, before anything is built; a finer mesh comes from a mesh file.
MAX_PRIMITIVE_TRIANGLES = 1 << 22


def _bounded(rd: TableReader, kind: str, key: str, triangles: int, how: str) -> None:
    """SceneError naming ``key`` when the primitive would make more than
    :data:`MAX_PRIMITIVE_TRIANGLES` triangles (``how``: the count's formula, for the message)."""
    if triangles > MAX_PRIMITIVE_TRIANGLES:
        raise rd.error(key, f"a {kind} with {how} would make {triangles:,} triangles; at most "
                            f"{MAX_PRIMITIVE_TRIANGLES:,} per primitive (use a mesh file for more)")


def _build_primitive(kind: str, rd: TableReader) -> trimesh.Trimesh:
    """Builtin primitive centred at the origin, from its parameters in the object's table; its
    triangle count is bounded (:data:`MAX_PRIMITIVE_TRIANGLES`) before it is built."""
    if kind == "box":
        return trimesh.creation.box(extents=rd.vector("size", 3, default=[1.0, 1.0, 1.0], positive=True))
    if kind == "sphere":
        return trimesh.creation.icosphere(subdivisions=rd.number("subdivisions", 3, min=0, max=7, integer=True),
                                          radius=rd.number("radius", 0.5, min=0, min_open=True))
    if kind == "plane":
        size = rd.vector("size", 2, default=[10.0, 10.0], positive=True)
        divisions = rd.number("divisions", 1, min=1, integer=True)
        _bounded(rd, kind, "divisions", 2 * divisions * divisions, f"divisions = {divisions} (2 × divisions²)")
        return _plane(size, divisions)
    if kind == "cylinder":
        radius = rd.number("radius", 0.5, min=0, min_open=True)
        height = rd.number("height", 1.0, min=0, min_open=True)
        sections = rd.number("sections", 32, min=3, integer=True)
        _bounded(rd, kind, "sections", 4 * sections, f"sections = {sections} (4 × sections)")
        return _along_y(trimesh.creation.cylinder(radius=radius, height=height, sections=sections))
    if kind == "torus":
        major_radius = rd.number("major_radius", 1.0, min=0, min_open=True)
        minor_radius = rd.number("minor_radius", 0.25, min=0, min_open=True)
        major = rd.number("major_sections", 48, min=3, integer=True)
        minor = rd.number("minor_sections", 24, min=3, integer=True)
        key = "major_sections" if major >= minor else "minor_sections"
        _bounded(rd, kind, key, 2 * major * minor,
                 f"major_sections = {major} and minor_sections = {minor} (2 × major × minor)")
        return _along_y(trimesh.creation.torus(major_radius=major_radius, minor_radius=minor_radius,
                                               major_sections=major, minor_sections=minor))
    if kind == "capsule":
        return _along_y(trimesh.creation.capsule(height=rd.number("height", 1.0, min=0, min_open=False),
                                                 radius=rd.number("radius", 0.5, min=0, min_open=True),
                                                 count=[32, 16]))
    raise AssertionError(kind)


PRIMITIVES = ("box", "sphere", "plane", "cylinder", "torus", "capsule")


def _read_mesh(path: Path) -> trimesh.Trimesh:
    """trimesh's reading of ``path``; a gzipped file (``name.ply.gz``) is decompressed and
    parsed as the format its inner extension names. Raises on any problem."""
    if path.suffix.lower() != ".gz":
        return trimesh.load(path, force="mesh", process=False)
    inner = Path(path.stem).suffix.lower().lstrip(".")
    if not inner:
        raise ValueError("a gzipped mesh must name its format before .gz (e.g. bunny.ply.gz)")
    with gzip.open(path, "rb") as fh:
        data = fh.read()  # a corrupt or truncated stream raises here (BadGzipFile / EOFError)
    return trimesh.load(io.BytesIO(data), file_type=inner, force="mesh", process=False)


def _unreadable_reason(exc: Exception) -> str:
    """A short reason why trimesh could not read a mesh file. Bytes that are not text in a text
    format (OBJ, ASCII PLY/STL) surface as a UnicodeDecodeError, or as the ImportError of the
    optional charset detector trimesh then falls back on: both mean "not UTF-8 text"."""
    if isinstance(exc, UnicodeDecodeError) or (isinstance(exc, ImportError)
                                               and isinstance(exc.__context__, UnicodeDecodeError)):
        return "not UTF-8 text"
    if isinstance(exc, ImportError):
        return f"trimesh needs the missing module {exc.name or exc}"
    return " ".join(str(exc).split()) or type(exc).__name__


def _load_mesh_file(rd: TableReader, ref: str, base: Path) -> trimesh.Trimesh:
    path = (base / ref).resolve()
    if not path.is_file():
        raise rd.error("mesh", f"mesh file not found: {path}")
    try:
        mesh = _read_mesh(path)
    except Exception as exc:  # trimesh raises anything (ImportError, IndexError, ...) on a bad file
        raise rd.error("mesh", f"{path} is not a readable mesh file ({_unreadable_reason(exc)})") from exc
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise rd.error("mesh", f"{path} holds no triangles")
    faces = np.asarray(mesh.faces)
    if faces.ndim != 2 or faces.shape[1] != 3 or faces.min() < 0 or faces.max() >= len(mesh.vertices):
        raise rd.error("mesh", f"{path} has faces indexing vertices that are not there")
    return mesh


def _parse_object(table, i: int, file: str, base: Path) -> SceneObject:
    rd = TableReader(table, f"objects[{i}]", file)
    ref = rd.string("mesh")
    mesh = _build_primitive(ref, rd) if ref in PRIMITIVES else _load_mesh_file(rd, ref, base)
    scale = rd.raw("scale", 1.0)
    if isinstance(scale, list):
        scale = rd.vector("scale", 3, positive=True)
    else:
        scale = np.full(3, rd.number("scale", 1.0, min=0, min_open=True))
    rot = tf.euler_xyz(rd.vector("rotate", 3, default=[0.0, 0.0, 0.0]))
    trans = rd.vector("translate", 3, default=[0.0, 0.0, 0.0])
    mat = _parse_material(rd.raw("material", {}), f"objects[{i}].material", file)
    name = rd.string("name", default=f"{ref if ref in PRIMITIVES else Path(ref).stem}_{i}")
    casts = rd.boolean("casts", default_of(SceneObject, "casts"))
    receives = rd.boolean("receives", default_of(SceneObject, "receives"))
    rd.finish()
    # Scale, then rotate, then translate (docs/contracts.md#scene-files).
    verts = (np.asarray(mesh.vertices, np.float64) * scale) @ rot.T + trans
    faces = np.asarray(mesh.faces, np.int64)  # scales are positive: no mirroring, winding kept
    welded = trimesh.Trimesh(verts, faces, process=False)
    welded.merge_vertices()
    if not np.all(np.isfinite(welded.vertices)):
        raise rd.error("mesh", "mesh has non-finite vertices")
    return SceneObject(name, np.asarray(welded.vertices, np.float64), np.asarray(welded.faces, np.int64),
                       mat, casts, receives, ref)


def _parse_material(table, where: str, file: str) -> Material:
    rd = TableReader(table, where, file)
    mat = Material(
        diffuse=rd.vector("diffuse", 3, default=default_of(Material, "diffuse")),
        specular=rd.vector("specular", 3, default=default_of(Material, "specular")),
        shininess=rd.number("shininess", default_of(Material, "shininess"), min=0.0),
        ambient=rd.vector("ambient", 3, default=default_of(Material, "ambient")),
    )
    rd.finish()
    for key in ("diffuse", "specular", "ambient"):
        val = getattr(mat, key)
        if val is not None and np.any(val < 0):
            raise rd.error(key, "entries must be >= 0")
    return mat


def _parse_camera(table, file: str) -> Camera:
    rd = TableReader(table, "camera", file)
    cam = Camera(eye=rd.vector("eye", 3), target=rd.vector("target", 3),
                 up=rd.vector("up", 3, default=default_of(Camera, "up"), nonzero=True),
                 fov_y=rd.number("fov_y", default_of(Camera, "fov_y"), min=0.0, min_open=True, max=179.0),
                 near=rd.number("near", default_of(Camera, "near"), min=0.0, min_open=True),
                 far=rd.number("far", default_of(Camera, "far"), min=0.0, min_open=True))
    rd.finish()
    forward = cam.target - cam.eye
    if not np.linalg.norm(forward) > 0:
        raise rd.error("target", "must differ from eye")
    if np.linalg.norm(np.cross(forward / np.linalg.norm(forward), cam.up / np.linalg.norm(cam.up))) < 1e-6:
        raise rd.error("up", "must not be parallel to the viewing direction")
    if cam.near is not None and cam.far is not None and cam.near >= cam.far:
        raise rd.error("near", f"must be < far ({cam.far}), got {cam.near}")
    return cam


def parse_light(table, where: str, file: str) -> Light:
    """Build a Light from one ``[[lights]]`` table (any type, area lights included), rejecting
    impossible values; colour and ambient default to :class:`~shadowlab.scene.lights.Light`'s."""
    rd = TableReader(table, where, file)
    kind = rd.string("type", choices=list(LIGHT_TYPES) + ["area"])
    color = rd.vector("color", 3, default=default_of(Light, "color"))
    if np.any(color < 0):
        raise rd.error("color", "entries must be >= 0")
    common = dict(color=color, ambient=rd.number("ambient", default_of(Light, "ambient"), min=0.0))
    if kind == "area":
        light = AREA_SHAPES[rd.string("shape", choices=list(AREA_SHAPES))].parse(rd, common)
    else:
        light = LIGHT_TYPES[kind].parse(rd, common)
    rd.finish()
    return light


def parse_scene(data: dict, file: str = "<scene>", base: Path | None = None) -> Scene:
    """Build a Scene from a parsed TOML dict; ``base`` is the folder mesh paths (and a ``[gltf]``
    file) are relative to."""
    rd = TableReader(data, "", file)
    name = rd.string("name", default=Path(file).stem)
    metric = _scene_metric(rd)
    family = scene_family_key(rd)
    imported = None if "gltf" not in rd.table else _GltfPart(rd.raw("gltf"), file, base or Path.cwd())
    if imported is None:
        camera = _parse_camera(rd.raw("camera"), file)
        light_tables = rd.table_list("lights")
        if not light_tables:
            raise rd.error("lights", "at least one [[lights]] table is required")
        lights = [parse_light(t, f"lights[{i}]", file) for i, t in enumerate(light_tables)]
        obj_tables = rd.table_list("objects")
        if not obj_tables:
            raise rd.error("objects", "at least one [[objects]] table is required")
        objects = [_parse_object(t, i, file, base or Path.cwd()) for i, t in enumerate(obj_tables)]
    else:  # objects first: the file's camera aims at their bounds, the exposure at their centre
        objects = imported.objects + [_parse_object(t, i, file, base or Path.cwd())
                                      for i, t in enumerate(rd.table_list("objects", []))]
        taken = {o.name for o in imported.objects}
        for i, o in enumerate(objects[len(imported.objects):]):
            if o.name in taken:
                raise rd.error(f"objects[{i}].name", f"{o.name!r} is already an object of the glTF file "
                                                     f"(animation keyframes name objects: give another name)")
        camera = imported.camera(_bounds(objects)) if "camera" not in rd.table else _parse_camera(rd.raw("camera"), file)
        lights = imported.lights(_bounds(objects).mean(0)) + [parse_light(t, f"lights[{i}]", file)
                                                   for i, t in enumerate(rd.table_list("lights", []))]
        if not lights:
            raise rd.error("lights", "at least one light is required: the glTF file has none (or [gltf] lights = "
                                     "false), so add [[lights]]")
    shading_rd = TableReader(rd.raw("shading", {}), "shading", file)
    shading = Shading(density=shading_rd.number("density", default_of(Shading, "density"), min=0.0, max=1.0),
                      shadow_color=shading_rd.vector("shadow_color", 3, default=default_of(Shading, "shadow_color")))
    shading_rd.finish()
    anim_table = rd.raw("animation", None)
    animation = None if anim_table is None else parse_animation(anim_table, file, lights, [o.name for o in objects])
    rd.finish()
    return Scene(name, camera, lights, objects, shading, Path(file) if file != "<scene>" else None, animation,
                 metric, family, imported.notes if imported else [])


def _bounds(objects: list[SceneObject]) -> np.ndarray:
    b = np.stack([o.bounds() for o in objects])
    return np.stack([b[:, 0].min(0), b[:, 1].max(0)])


class _GltfPart:
    """A scene file's ``[gltf]`` table (docs/contracts.md#gltf-scenes): the file it includes,
    read at once, and what the scene takes from it — objects, a camera (unless the scene gives
    a ``[camera]``), lights (unless ``lights = false``), scaled by the exposure, with the
    overrides of ``[gltf.light_overrides.<name>]`` applied — and the file's notes."""

    def __init__(self, table, file: str, base: Path, path: Path | None = None, camera=None):
        rd = TableReader(table, "gltf", file)
        self.rd, self.file = rd, file
        # the key an unknown camera is named by: the [gltf] table's, or the "#camera" of a bare file
        self.camera_key = "gltf.camera" if path is None else "camera"
        if path is None:
            ref = rd.string("file")
            path = (base / ref).resolve()
            if not gltf.is_gltf(path):
                raise rd.error("file", f"must name a .gltf or .glb file, got {ref!r}")
            if not path.is_file():
                raise rd.error("file", f"glTF file not found: {path}")
        self.source = gltf.read_gltf(path)
        choice = rd.raw("camera", camera)
        if choice is not None and (isinstance(choice, bool) or not isinstance(choice, (str, int))):
            raise rd.error("camera", f"must be a camera's name or index, got {choice!r}")
        self.camera_choice = choice
        self.import_lights = rd.boolean("lights", True)
        exposure = rd.raw("exposure", "auto")
        if exposure != "auto":
            exposure = rd.number("exposure", min=0.0, min_open=True)
        self.exposure = exposure
        self.ambient = rd.number("ambient", gltf.DEFAULT_AMBIENT_SHARE, min=0.0)
        overrides = rd.raw("light_overrides", {})
        if not isinstance(overrides, dict) or not all(isinstance(v, dict) for v in overrides.values()):
            raise rd.error("light_overrides", "must be a table of tables ([gltf.light_overrides.<light name>])")
        names = [l.name for l in self.source.lights]
        for key, value in overrides.items():
            if key not in names:
                raise rd.error(f"light_overrides.{key}", f"no light {key!r} in {path.name}{did_you_mean(key, names)} "
                                                          f"(lights: {', '.join(names) or 'none'})")
            if "type" in value:
                raise rd.error(f"light_overrides.{key}.type", "an override changes a light's values, not its type "
                                                              "(set lights = false and add [[lights]] instead)")
        self.overrides = overrides
        rd.finish()
        self.objects = self.source.objects
        self.notes = list(self.source.notes)

    def camera(self, bounds: np.ndarray) -> Camera:
        """The chosen camera of the file (SceneError naming ``gltf.camera`` when it has none)."""
        cam, _ = gltf.choose_camera(self.source, self.camera_choice, key=self.camera_key)
        return gltf.lab_camera(cam, bounds)

    def lights(self, target: np.ndarray) -> list[Light]:
        """The file's lights (none with ``lights = false``), the exposure fixed at ``target`` (the
        centre of the scene's bounds: one exposure whatever camera looks at the scene, so a view
        saved from another camera keeps the lights), each read through :func:`parse_light` after
        its override."""
        if not self.import_lights:
            return []
        exposure = self.exposure
        if exposure == "auto":
            exposure = gltf.auto_exposure(self.source.lights, target)
            if self.source.lights:
                self.notes.append(f"glTF {self.source.path.name}: exposure 'auto' = {exposure:.6g} "
                                  f"(each light's colour = colour · intensity · exposure)")
        out = []
        for light in self.source.lights:
            table = gltf.light_table(light, exposure, self.ambient)
            override = self.overrides.get(light.name, {})
            if "range" in override and "inverse_square" not in override:
                table.pop("inverse_square", None)  # a range brings its own (windowed) falloff
            table.update(override)
            out.append(parse_light(table, f"gltf.light_overrides.{light.name}" if override else
                                   f"{self.source.path.name}#{light.name}", self.file))
        return out


def gltf_scene(path: Path, camera=None) -> Scene:
    """A glTF file as a scene on its own: its objects, its lights at the automatic exposure, the
    camera ``camera`` names (None: the first); family general."""
    part = _GltfPart({}, str(path), path.parent, path=Path(path), camera=camera)
    bounds = _bounds(part.objects)
    cam = part.camera(bounds)
    lights = part.lights(bounds.mean(0))
    if not lights:
        raise SceneError(str(path), "lights", f"{Path(path).name} has no lights; write a TOML scene that includes "
                                              f"it ([gltf] file = ...) and adds [[lights]]")
    return Scene(Path(path).stem, cam, lights, part.objects, Shading(), Path(path), None, None, GENERAL_FAMILY,
                 part.notes)


def _scene_metric(rd: TableReader) -> str | None:
    """The optional ``metric`` key: the name of a metrics column (docs/contracts.md#scene-files).
    Read here as a string; that it names a metric column is checked by the layer that owns the
    columns (:func:`shadowlab.evaluation.scene_metric.check_scene_metric`, called by
    :func:`shadowlab.measurement.scenes.load_measured_scene`), so reading a scene needs no
    metrics."""
    return rd.string("metric", default=None) if "metric" in rd.table else None


def scene_family_key(rd: TableReader) -> str | None:
    """The optional ``family`` key of a scene file's top-level table ``rd``: one of
    :data:`~shadowlab.scene.model.SCENE_FAMILIES` (a SceneError naming the file and the key, with
    the closest family, otherwise), or None when the file has none. Read strictly here so that a
    misspelt family stops a study before it runs rather than regrouping its scene; the study's
    suite loader reads it with this same function."""
    return rd.string("family", choices=SCENE_FAMILIES) if "family" in rd.table else None


def builtin_scene_dir() -> Path:
    """The folder of the shipped scene files (package data)."""
    return Path(str(resources.files("shadowlab.scenes")))


def builtin_scenes() -> dict[str, Path]:
    """Shipped scenes: name (file stem) → path, sorted by name."""
    return {p.stem: p for p in sorted(builtin_scene_dir().glob("*.toml"))}


def resolve_scene_path(ref: str | Path) -> Path:
    """A shipped scene's name or a path to a scene file → the file's path (SceneError if neither).
    A glTF file's path may carry a camera choice after ``#`` (``scene.glb#Camera``), dropped here."""
    ref = str(ref)
    shipped = builtin_scenes()
    if ref in shipped:
        return shipped[ref]
    path = Path(ref)
    if path.is_file():
        return path
    head, choice = gltf.split_reference(ref)
    if choice is not None and Path(head).is_file():
        return Path(head)
    raise SceneError(ref, "scene", f"no such scene file, and not a shipped scene{did_you_mean(ref, shipped)} "
                                   f"({', '.join(shipped)})")


def load_scene(ref: str | Path) -> Scene:
    """Load and validate a scene by shipped name or path; raises SceneError on any problem. The
    ``metric`` key is kept as read: commands and studies load through
    :func:`shadowlab.measurement.scenes.load_measured_scene`, which also checks that it names a
    metrics column. A ``.gltf``/``.glb`` path is read by :func:`gltf_scene`, with the camera a
    ``#name`` or ``#index`` after the path chooses."""
    path = resolve_scene_path(ref)
    if gltf.is_gltf(path):
        head, choice = gltf.split_reference(str(ref))
        return gltf_scene(path, choice if Path(head).is_file() and not Path(str(ref)).is_file() else None)
    return parse_scene(read_toml_file(path), str(path), path.parent)


def scene_summary(path: Path) -> str:
    """One line about a scene file: name, lights, objects, triangles (loads it)."""
    s = load_scene(path)
    tris = sum(len(o.faces) for o in s.objects)
    lights = ", ".join(l.type_name for l in s.lights)
    return f"{len(s.objects)} objects, {tris} triangles, lights: {lights}"


#: The longest purpose line :func:`scene_purpose` returns (longer ones are shortened).
PURPOSE_LENGTH = 100


def scene_purpose(path: Path) -> str:
    """What a scene file is for, in one line: the first sentence of the ``#`` comment that opens
    it (every shipped scene has one), shortened to about :data:`PURPOSE_LENGTH` characters the
    way the README's summaries are (:func:`shadowlab.util.text.first_sentence`: parentheses
    dropped first, then cut at a dash or colon or at a word boundary with "…"); "" when the
    file opens with no comment. Reads only the comment: the scene is not loaded. A glTF file's
    purpose is what wrote it (``asset.generator``)."""
    if gltf.is_gltf(path):
        return first_sentence(gltf.describe(path), limit=PURPOSE_LENGTH)
    lines = []
    for line in Path(path).read_text(encoding="utf-8").splitlines():
        if not line.strip() and not lines:
            continue  # blank lines before the comment
        if not line.lstrip().startswith("#"):
            break
        lines.append(line.lstrip().lstrip("#").strip())
    return first_sentence("\n".join(lines), limit=PURPOSE_LENGTH)
