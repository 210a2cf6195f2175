"""Reading glTF 2.0 scenes (``.gltf`` and ``.glb``) into the scene model (docs/contracts.md#gltf-scenes).

Two readers share the work:

- **trimesh's glTF loader** decodes the meshes: accessors of every component type, strides,
  sparse accessors, triangle strips. It is given a rewritten copy of the file in which every
  primitive is a mesh of its own at the origin (named ``__m<mesh>p<primitive>``), so that each
  decoded geometry is found by name, whatever trimesh does to node names;
- **a small parser of the JSON** here (the glb header and chunks, or the .gltf text; buffers,
  data: URIs, index and extent checks) reads what trimesh does not give: the node hierarchy and
  its world transforms (TRS or matrix, parent chain), the ``KHR_lights_punctual`` lights, the
  cameras, the base-colour factors, and everything the lab leaves out, which becomes a note.

Each mesh node instance becomes one :class:`SceneObject` named by its node (made unique), its
primitives merged, in world space (float64), welded as a TOML scene's objects are. A light points
down its node's −Z; a camera looks down −Z with +Y up. glTF is metres, +Y up, right-handed: the
lab's axes, so nothing is converted. How lights are mapped (intensities, the inverse-square mode,
the spot's cone, exposure, ambient) is :func:`lab_lights`; a broken file raises one
:class:`SceneError` naming the file and the key.
"""
from __future__ import annotations

import base64
import io
import json
import math
import struct
import urllib.parse
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..util.validation import SceneError, did_you_mean
from .lights import INVERSE_SQUARE_NEAR
from .model import Camera, Material, SceneObject

#: The file suffixes read as glTF.
GLTF_SUFFIXES = (".gltf", ".glb")
#: The one extension whose content the lab reads; every other is named in a note.
LIGHTS_EXTENSION = "KHR_lights_punctual"
#: A glTF light's ambient, as a share of its brightest colour channel (after the exposure): the
#: lab's own default ratio (``Light.ambient`` 0.15 beside a colour of 1).
DEFAULT_AMBIENT_SHARE = 0.15
#: The widest spot cone the lab takes (full angle, degrees; its spot must stay under 180): a
#: glTF spot with outerConeAngle = π/2 is narrowed to this, with a note.
MAX_SPOT_ANGLE = 179.0

_GLB_MAGIC = 0x46546C67  # "glTF"
_CHUNK_JSON = 0x4E4F534A
_CHUNK_BIN = 0x004E4942
_COMPONENT_SIZES = {5120: 1, 5121: 1, 5122: 2, 5123: 2, 5125: 4, 5126: 4}
_TYPE_COUNTS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
_MODES = {0: "points", 1: "lines", 2: "line loops", 3: "line strips", 4: "triangles", 5: "triangle strips",
          6: "triangle fans"}


def is_gltf(path) -> bool:
    """Whether ``path`` names a glTF file (by its suffix)."""
    return Path(str(path)).suffix.lower() in GLTF_SUFFIXES


def split_reference(ref: str) -> tuple[str, str | None]:
    """``"scene.glb#Camera"`` → ``("scene.glb", "Camera")``: a glTF path with the camera chosen
    after ``#`` (a name or an index); any other reference is returned whole with None."""
    head, sep, tail = str(ref).rpartition("#")
    if sep and is_gltf(head):
        return head, tail
    return str(ref), None


@dataclass
class GltfLight:
    """One placed ``KHR_lights_punctual`` light, in world space, as the file gives it."""

    name: str
    type: str                 # directional | point | spot
    color: np.ndarray         # linear RGB, as in the file
    intensity: float          # candela (point, spot) or lux (directional)
    position: np.ndarray
    direction: np.ndarray     # unit: the node's −Z
    range: float | None = None
    inner: float = 0.0        # spot cone angles, radians (half angles, as KHR writes them)
    outer: float = math.pi / 4


@dataclass
class GltfCamera:
    """One placed camera: its name, the node's world frame and the projection."""

    name: str
    type: str                 # perspective | orthographic
    eye: np.ndarray
    forward: np.ndarray       # unit: the node's −Z
    up: np.ndarray            # unit: the node's +Y
    yfov: float | None = None  # radians
    znear: float | None = None
    zfar: float | None = None
    node: str = ""            # its node's name (a choice may name either)


@dataclass
class GltfFile:
    """What a glTF file holds for the lab: objects in world space, placed lights and cameras, and
    the notes naming what was left out."""

    path: Path
    generator: str
    objects: list[SceneObject]
    lights: list[GltfLight]
    cameras: list[GltfCamera]
    notes: list[str] = field(default_factory=list)


# --------------------------------------------------------------------------- the container

class _Reader:
    """The JSON document of a glTF file and its buffers' bytes, with the checks that turn a
    broken file into one SceneError naming the file and the key."""

    def __init__(self, path: Path):
        self.path = Path(path)
        self.file = str(path)
        try:
            raw = self.path.read_bytes()
        except OSError as exc:
            raise SceneError(self.file, "file", f"cannot read: {exc.strerror or exc}") from exc
        self.bin: bytes | None = None
        if self.path.suffix.lower() == ".glb":
            text = self._glb(raw)
        else:
            text = raw
        try:
            doc = json.loads(text)
        except (UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise SceneError(self.file, "json", f"not valid glTF JSON: {exc}") from exc
        if not isinstance(doc, dict):
            raise SceneError(self.file, "json", f"must be a JSON object, got {type(doc).__name__}")
        self.doc = doc
        version = str(self.get(doc, "asset", dict, "asset").get("version", ""))
        if not version.startswith("2."):
            raise SceneError(self.file, "asset.version", f"only glTF 2.x is read, got {version!r}")
        self.buffers = [self._buffer(i, b) for i, b in enumerate(self.array("buffers"))]

    def error(self, key: str, reason: str) -> SceneError:
        """A SceneError about ``key`` of this file."""
        return SceneError(self.file, key, reason)

    def _glb(self, raw: bytes) -> bytes:
        """The JSON chunk of a glb (and its BIN chunk into ``self.bin``), checking the header."""
        if len(raw) < 20:
            raise self.error("glb", f"truncated: {len(raw)} bytes, shorter than a glb header")
        magic, version, length = struct.unpack_from("<III", raw, 0)
        if magic != _GLB_MAGIC:
            raise self.error("glb", "not a glb file (no 'glTF' magic)")
        if version != 2:
            raise self.error("glb", f"glb version {version}; only version 2 is read")
        if length > len(raw):
            raise self.error("glb", f"truncated: the header says {length} bytes, the file has {len(raw)}")
        chunks, at = [], 12
        while at < length:
            if at + 8 > length:
                raise self.error("glb", f"truncated chunk header at byte {at}")
            size, kind = struct.unpack_from("<II", raw, at)
            if at + 8 + size > length:
                raise self.error("glb", f"truncated: a chunk of {size} bytes at byte {at} runs past the end")
            chunks.append((kind, raw[at + 8:at + 8 + size]))
            at += 8 + size
        if not chunks or chunks[0][0] != _CHUNK_JSON:
            raise self.error("glb", "the first chunk is not JSON")
        if len(chunks) > 1 and chunks[1][0] == _CHUNK_BIN:
            self.bin = chunks[1][1]
        return chunks[0][1]

    def get(self, table: dict, name: str, kind, key: str, default=None):
        """``table[name]`` checked to be of ``kind`` (``default`` when absent)."""
        value = table.get(name, default)
        if value is not None and not isinstance(value, kind):
            raise self.error(key, f"must be a JSON {_kind_name(kind)}, got {type(value).__name__}")
        return value

    def array(self, name: str) -> list:
        """A top-level array (empty when absent), each entry an object."""
        items = self.get(self.doc, name, list, name, [])
        for i, item in enumerate(items):
            if not isinstance(item, dict):
                raise self.error(f"{name}[{i}]", f"must be a JSON object, got {type(item).__name__}")
        return items

    def index(self, value, count: int, key: str, what: str) -> int:
        """``value`` as an index into ``count`` ``what`` (SceneError naming ``key`` otherwise)."""
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.error(key, f"must be an index, got {value!r}")
        if not 0 <= value < count:
            raise self.error(key, f"index {value} out of range ({count} {what})")
        return value

    def number(self, table: dict, name: str, key: str, default=None, *, positive=False) -> float:
        """A finite number (``default`` when absent); ``positive``: > 0."""
        value = table.get(name, default)
        if value is None:
            raise self.error(key, "required key is missing")
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise self.error(key, f"must be a finite number, got {value!r}")
        if positive and not value > 0:
            raise self.error(key, f"must be > 0, got {value!r}")
        return float(value)

    def count(self, table: dict, name: str, key: str, default=None, *, at_least: int = 0) -> int:
        """A whole number ≥ ``at_least`` (``default`` when absent): byte offsets, lengths, strides
        and element counts, which the spec makes non-negative integers."""
        value = self.number(table, name, key, default)
        if value != int(value) or value < at_least:
            raise self.error(key, f"must be a whole number >= {at_least}, got {table.get(name, default)!r}")
        return int(value)

    def numbers(self, table: dict, name: str, n: int, key: str, default=None) -> np.ndarray:
        """A list of ``n`` finite numbers as float64 (``default`` when absent)."""
        value = table.get(name, default)
        if (not isinstance(value, list) or len(value) != n
                or not all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
                           for x in value)):
            raise self.error(key, f"must be a list of {n} finite numbers, got {value!r}")
        return np.asarray(value, np.float64)

    def _buffer(self, i: int, buf: dict) -> bytes:
        key = f"buffers[{i}]"
        length = self.count(buf, "byteLength", f"{key}.byteLength")
        uri = buf.get("uri")
        if uri is None:
            if i != 0 or self.bin is None:
                raise self.error(key, "has no uri and the file has no glb BIN chunk")
            data = self.bin
        elif not isinstance(uri, str):
            raise self.error(f"{key}.uri", f"must be a string, got {uri!r}")
        elif uri.startswith("data:"):
            head, _, payload = uri.partition(",")
            if not head.endswith(";base64"):
                raise self.error(f"{key}.uri", "a data: URI must be base64")
            try:
                data = base64.b64decode(payload, validate=True)
            except ValueError as exc:
                raise self.error(f"{key}.uri", f"bad base64 data: {exc}") from exc
        else:
            file = self.path.parent / urllib.parse.unquote(uri)
            if not file.is_file():
                raise self.error(f"{key}.uri", f"buffer file not found: {file}")
            data = file.read_bytes()
        if len(data) < length:
            raise self.error(key, f"byteLength is {length} but the data holds {len(data)} bytes (truncated?)")
        return data[:length]

    def check_views_and_accessors(self) -> None:
        """Every buffer view inside its buffer, every accessor inside its view."""
        views = self.array("bufferViews")
        for i, v in enumerate(views):
            key = f"bufferViews[{i}]"
            b = self.index(v.get("buffer"), len(self.buffers), f"{key}.buffer", "buffers")
            start = self.count(v, "byteOffset", f"{key}.byteOffset", 0)
            size = self.count(v, "byteLength", f"{key}.byteLength", at_least=1)
            if "byteStride" in v:
                stride = self.count(v, "byteStride", f"{key}.byteStride", at_least=4)
                if stride > 252 or stride % 4:
                    raise self.error(f"{key}.byteStride", f"must be a multiple of 4 from 4 to 252, got {stride}")
            if start + size > len(self.buffers[b]):
                raise self.error(key, f"bytes {start}..{start + size} run past buffer {b} "
                                      f"({len(self.buffers[b])} bytes)")
        for i, a in enumerate(self.array("accessors")):
            key = f"accessors[{i}]"
            count = self.count(a, "count", f"{key}.count", at_least=1)
            if a.get("componentType") not in _COMPONENT_SIZES:
                raise self.error(f"{key}.componentType", f"unknown component type {a.get('componentType')!r}")
            if a.get("type") not in _TYPE_COUNTS:
                raise self.error(f"{key}.type", f"unknown type {a.get('type')!r}")
            if "bufferView" not in a:
                continue  # all zeros (or sparse): nothing to check against
            vi = self.index(a["bufferView"], len(views), f"{key}.bufferView", "bufferViews")
            element = _COMPONENT_SIZES[a["componentType"]] * _TYPE_COUNTS[a["type"]]
            stride = int(views[vi].get("byteStride", element)) or element
            end = self.count(a, "byteOffset", f"{key}.byteOffset", 0) + (stride * (count - 1) + element
                                                                              if count else 0)
            if end > int(views[vi]["byteLength"]):
                raise self.error(key, f"{count} elements need {end} bytes of bufferView {vi}, which has "
                                      f"{views[vi]['byteLength']}")

    def single_buffer_glb(self, doc: dict) -> bytes:
        """``doc`` (a rewritten copy of the JSON) as a glb whose one BIN chunk holds every buffer
        of the file end to end (each at a multiple of 16 bytes, so accessors stay aligned), the
        buffer views moved accordingly: what trimesh is handed."""
        starts, blob = [], bytearray()
        for data in self.buffers:
            starts.append(len(blob))
            blob += data + b"\0" * (-len(data) % 16)
        for v in doc.get("bufferViews", []):
            v["byteOffset"] = starts[v["buffer"]] + int(v.get("byteOffset", 0))
            v["buffer"] = 0
        doc["buffers"] = [{"byteLength": len(blob)}] if blob else []
        text = json.dumps(doc).encode()
        text += b" " * (-len(text) % 4)
        blob += b"\0" * (-len(blob) % 4)
        body = struct.pack("<II", len(text), _CHUNK_JSON) + text
        if blob:
            body += struct.pack("<II", len(blob), _CHUNK_BIN) + bytes(blob)
        return struct.pack("<III", _GLB_MAGIC, 2, 12 + len(body)) + body


def _kind_name(kind) -> str:
    return {dict: "object", list: "array", str: "string"}.get(kind, getattr(kind, "__name__", str(kind)))


# --------------------------------------------------------------------------- transforms

def _quaternion_matrix(q: np.ndarray) -> np.ndarray:
    """3x3 rotation of the unit quaternion ``q`` = (x, y, z, w) (glTF's order), normalised first."""
    x, y, z, w = q / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def local_matrix(rd: _Reader, node: dict, key: str) -> np.ndarray:
    """A node's local 4x4 transform (float64): its ``matrix`` (16 numbers, column-major) or
    T · R · S from ``translation``, ``rotation`` (a unit quaternion x, y, z, w) and ``scale``."""
    if "matrix" in node:
        return rd.numbers(node, "matrix", 16, f"{key}.matrix").reshape(4, 4).T
    m = np.eye(4)
    t = rd.numbers(node, "translation", 3, f"{key}.translation", [0.0, 0.0, 0.0])
    q = rd.numbers(node, "rotation", 4, f"{key}.rotation", [0.0, 0.0, 0.0, 1.0])
    s = rd.numbers(node, "scale", 3, f"{key}.scale", [1.0, 1.0, 1.0])
    if not np.linalg.norm(q) > 0:
        raise rd.error(f"{key}.rotation", "must be a unit quaternion, got the zero vector")
    m[:3, :3] = _quaternion_matrix(q) * s[None, :]
    m[:3, 3] = t
    return m


def _walk(rd: _Reader) -> list[tuple[int, np.ndarray]]:
    """(node index, world matrix) of every node of the file's scene (``scene``, else the first),
    depth first in file order; a node reached twice (a cycle, or two parents) is an error."""
    nodes = rd.array("nodes")
    scenes = rd.array("scenes")
    if scenes:
        si = rd.index(rd.doc.get("scene", 0), len(scenes), "scene", "scenes")
        roots = rd.get(scenes[si], "nodes", list, f"scenes[{si}].nodes", [])
        root_key = f"scenes[{si}].nodes"
    else:  # no scene: every node that is no one's child is a root
        children = {c for n in nodes for c in n.get("children", []) if isinstance(c, int)}
        roots, root_key = [i for i in range(len(nodes)) if i not in children], "nodes"
    out, seen = [], set()
    stack = [(rd.index(r, len(nodes), f"{root_key}[{k}]", "nodes"), np.eye(4)) for k, r in enumerate(roots)][::-1]
    while stack:
        i, parent = stack.pop()
        if i in seen:
            raise rd.error(f"nodes[{i}]", "reached twice in the node hierarchy (a cycle or two parents)")
        seen.add(i)
        world = parent @ local_matrix(rd, nodes[i], f"nodes[{i}]")
        if not np.all(np.isfinite(world)):
            raise rd.error(f"nodes[{i}]", "world transform is not finite")
        out.append((i, world))
        kids = rd.get(nodes[i], "children", list, f"nodes[{i}].children", [])
        stack.extend((rd.index(c, len(nodes), f"nodes[{i}].children[{k}]", "nodes"), world)
                     for k, c in reversed(list(enumerate(kids))))
    return out


def _axis(world: np.ndarray, v) -> np.ndarray:
    """The unit world direction of the node-local direction ``v``."""
    d = world[:3, :3] @ np.asarray(v, np.float64)
    n = np.linalg.norm(d)
    return d / n if n > 0 else d


def _unique(name: str, taken: set[str]) -> str:
    """``name``, or ``name_2``, ``name_3``, ... : the first not in ``taken`` (which it joins)."""
    out, k = name, 1
    while out in taken:
        k += 1
        out = f"{name}_{k}"
    taken.add(out)
    return out


# --------------------------------------------------------------------------- reading

def read_gltf(path) -> GltfFile:
    """Read a ``.gltf`` or ``.glb`` file: objects (world space, welded), placed lights and
    cameras, and notes on everything left out. SceneError naming the file and the key on a broken
    file; nothing is rendered or chosen here (:func:`choose_camera`, :func:`lab_lights`)."""
    rd = _Reader(Path(path))
    rd.check_views_and_accessors()
    name = rd.path.name
    notes: list[str] = []
    walk = _walk(rd)
    nodes, meshes, materials = rd.array("nodes"), rd.array("meshes"), rd.array("materials")
    for i, m in enumerate(meshes):
        for j, p in enumerate(rd.get(m, "primitives", list, f"meshes[{i}].primitives", [])):
            key = f"meshes[{i}].primitives[{j}]"
            attributes = rd.get(p, "attributes", dict, f"{key}.attributes", {})
            if "POSITION" not in attributes:
                raise rd.error(f"{key}.attributes", "has no POSITION")
            for a, ai in attributes.items():
                rd.index(ai, len(rd.array("accessors")), f"{key}.attributes.{a}", "accessors")
            if "indices" in p:
                rd.index(p["indices"], len(rd.array("accessors")), f"{key}.indices", "accessors")
            if "material" in p:
                rd.index(p["material"], len(materials), f"{key}.material", "materials")
    geometry = _trimesh_geometry(rd, meshes)
    objects, taken = [], set()
    light_defs = _light_definitions(rd)
    lights, cameras = [], []
    camera_defs = rd.array("cameras")
    for i, world in walk:
        node = nodes[i]
        node_name = str(node.get("name") or f"node{i}")
        if "mesh" in node:
            mi = rd.index(node["mesh"], len(meshes), f"nodes[{i}].mesh", "meshes")
            obj = _object(rd, _unique(node_name, taken), mi, meshes[mi], world, geometry, materials, notes)
            if obj is not None:
                objects.append(obj)
        if "camera" in node:
            ci = rd.index(node["camera"], len(camera_defs), f"nodes[{i}].camera", "cameras")
            cameras.append(_camera(rd, ci, camera_defs[ci], node_name, world))
        ext = rd.get(node, "extensions", dict, f"nodes[{i}].extensions", {})
        if LIGHTS_EXTENSION in ext:
            entry = ext[LIGHTS_EXTENSION]
            li = rd.index(entry.get("light") if isinstance(entry, dict) else entry, len(light_defs),
                          f"nodes[{i}].extensions.{LIGHTS_EXTENSION}.light", "lights")
            light = _light(rd, li, light_defs[li], node_name, world, notes)
            if light is not None:
                lights.append(light)
    if not objects:
        raise rd.error("meshes", "the scene holds no triangle meshes")
    generator = str(rd.get(rd.doc, "asset", dict, "asset").get("generator", ""))
    notes += [f"camera {c.name!r} is orthographic and cannot be chosen (the lab's camera is perspective)"
              for c in cameras if c.type != "perspective"]
    notes[:0] = _unsupported(rd, nodes, meshes, materials, walk)
    return GltfFile(rd.path, generator, objects, lights, cameras, [f"glTF {name}: {n}" for n in notes])


def _trimesh_geometry(rd: _Reader, meshes: list) -> dict:
    """The decoded geometry of every primitive, keyed ``__m<mesh>p<primitive>``, from trimesh's
    glTF loader on a rewritten copy of the file: one mesh per primitive, each on a node of its
    own at the origin, materials, skins, cameras and animations dropped (the lab reads those
    from the JSON, or leaves them out with a note)."""
    import trimesh

    doc = json.loads(json.dumps(rd.doc))  # a deep copy we may rewrite
    flat, nodes = [], []
    for i, m in enumerate(meshes):
        for j, p in enumerate(m.get("primitives", [])):
            prim = {k: v for k, v in p.items() if k not in ("material", "targets")}
            flat.append({"name": f"__m{i}p{j}", "primitives": [prim]})
            nodes.append({"name": f"__m{i}p{j}", "mesh": len(flat) - 1})
    for drop in ("materials", "textures", "images", "samplers", "skins", "animations", "cameras", "extensions"):
        doc.pop(drop, None)
    doc.update(meshes=flat, nodes=nodes, scenes=[{"nodes": list(range(len(nodes)))}], scene=0)
    try:
        scene = trimesh.load(io.BytesIO(rd.single_buffer_glb(doc)), file_type="glb", force="scene", process=False)
    except Exception as exc:  # trimesh raises anything on a bad accessor
        raise rd.error("meshes", f"trimesh cannot decode the meshes ({' '.join(str(exc).split()) or type(exc).__name__})"
                       ) from exc
    return dict(scene.geometry)


def _object(rd: _Reader, name: str, mi: int, mesh: dict, world: np.ndarray, geometry: dict, materials: list,
            notes: list) -> SceneObject | None:
    """One mesh node instance as a SceneObject: its triangle primitives merged, in world space,
    welded; None (with a note) when it has no triangles."""
    import trimesh

    verts, faces, used, n = [], [], [], 0
    for j, p in enumerate(mesh.get("primitives", [])):
        mode = p.get("mode", 4)
        geom = geometry.get(f"__m{mi}p{j}")
        if mode not in (4, 5) or not isinstance(geom, trimesh.Trimesh):
            notes.append(f"mesh {mesh.get('name', mi)!r} (node {name!r}): a primitive of "
                         f"{_MODES.get(mode, f'mode {mode}')} left out (the lab draws triangles)")
            continue
        v = np.asarray(geom.vertices, np.float64)
        f = np.asarray(geom.faces, np.int64)
        if len(f) and (f.min() < 0 or f.max() >= len(v)):
            raise rd.error(f"meshes[{mi}].primitives[{j}].indices", f"index {int(f.max())} out of range "
                                                                    f"({len(v)} vertices)")
        verts.append(v)
        faces.append(f + n)
        n += len(v)
        used.append(p.get("material"))
    if not faces or not sum(len(f) for f in faces):
        return None
    v = np.concatenate(verts) @ world[:3, :3].T + world[:3, 3]
    f = np.concatenate(faces)
    if np.linalg.det(world[:3, :3]) < 0:  # a mirroring transform turns the winding: glTF says flip it
        f = f[:, ::-1]
    welded = trimesh.Trimesh(v, f, process=False)
    welded.merge_vertices()
    if not np.all(np.isfinite(welded.vertices)):
        raise rd.error(f"meshes[{mi}]", "non-finite vertices")
    if len(set(used)) > 1:
        notes.append(f"node {name!r}: primitives with different materials merged; the first one's base colour is used")
    return SceneObject(name, np.asarray(welded.vertices, np.float64), np.asarray(welded.faces, np.int64),
                       _material(rd, used[0], materials), True, True, f"{rd.path.name}#{name}")


def _material(rd: _Reader, index, materials: list) -> Material:
    """A glTF material as the lab's: ``baseColorFactor``'s RGB → diffuse (and so ambient); the
    lab's default specular and shininess. No material: glTF's default (white)."""
    if index is None:
        return Material(diffuse=np.ones(3))
    key = f"materials[{index}].pbrMetallicRoughness"
    pbr = rd.get(materials[index], "pbrMetallicRoughness", dict, key, {})
    base = rd.numbers(pbr, "baseColorFactor", 4, f"{key}.baseColorFactor", [1.0, 1.0, 1.0, 1.0])
    if np.any(base < 0):
        raise rd.error(f"{key}.baseColorFactor", f"entries must be >= 0, got {base.tolist()}")
    return Material(diffuse=base[:3].copy())


def _light_definitions(rd: _Reader) -> list:
    """The file's ``extensions.KHR_lights_punctual.lights`` (empty when absent)."""
    ext = rd.get(rd.doc, "extensions", dict, "extensions", {})
    table = rd.get(ext, LIGHTS_EXTENSION, dict, f"extensions.{LIGHTS_EXTENSION}", {})
    lights = rd.get(table, "lights", list, f"extensions.{LIGHTS_EXTENSION}.lights", [])
    for i, l in enumerate(lights):
        if not isinstance(l, dict):
            raise rd.error(f"extensions.{LIGHTS_EXTENSION}.lights[{i}]", "must be a JSON object")
    return lights


def _light(rd: _Reader, li: int, d: dict, node_name: str, world: np.ndarray, notes: list) -> GltfLight | None:
    """One placed light (None, with a note, for a type the lab does not know)."""
    key = f"extensions.{LIGHTS_EXTENSION}.lights[{li}]"
    kind = d.get("type")
    name = str(d.get("name") or node_name)
    if kind not in ("directional", "point", "spot"):
        notes.append(f"light {name!r} of unknown type {kind!r} left out")
        return None
    color = rd.numbers(d, "color", 3, f"{key}.color", [1.0, 1.0, 1.0])
    intensity = rd.number(d, "intensity", f"{key}.intensity", 1.0)
    if np.any(color < 0) or intensity < 0:
        raise rd.error(key, "color and intensity must be >= 0")
    light = GltfLight(node_name, kind, color, intensity, world[:3, 3].copy(), _axis(world, [0.0, 0.0, -1.0]))
    if "range" in d and kind != "directional":
        light.range = rd.number(d, "range", f"{key}.range", positive=True)
    if kind == "spot":
        spot = rd.get(d, "spot", dict, f"{key}.spot", {})
        light.inner = rd.number(spot, "innerConeAngle", f"{key}.spot.innerConeAngle", 0.0)
        light.outer = rd.number(spot, "outerConeAngle", f"{key}.spot.outerConeAngle", math.pi / 4)
        if not 0 <= light.inner < light.outer <= math.pi / 2:
            raise rd.error(f"{key}.spot", f"needs 0 <= innerConeAngle < outerConeAngle <= pi/2, got "
                                          f"{light.inner} and {light.outer}")
        for what, angle in (("outer", light.outer), ("inner", light.inner)):
            if math.degrees(2 * angle) > MAX_SPOT_ANGLE:
                notes.append(f"spot light {name!r}: {what} cone {math.degrees(2 * angle):.6g}° wide, narrowed to "
                             f"{MAX_SPOT_ANGLE:g}° (the lab's spot cone is below a half space)")
    return light


def _camera(rd: _Reader, ci: int, d: dict, node_name: str, world: np.ndarray) -> GltfCamera:
    """One placed camera (an orthographic one is kept, to be refused if chosen)."""
    key = f"cameras[{ci}]"
    kind = d.get("type")
    if kind not in ("perspective", "orthographic"):
        raise rd.error(f"{key}.type", f"must be perspective or orthographic, got {kind!r}")
    cam = GltfCamera(str(d.get("name") or node_name), kind, world[:3, 3].copy(), _axis(world, [0.0, 0.0, -1.0]),
                     _axis(world, [0.0, 1.0, 0.0]), node=node_name)
    if kind == "perspective":
        p = rd.get(d, "perspective", dict, f"{key}.perspective", None)
        if p is None:
            raise rd.error(f"{key}.perspective", "required key is missing")
        cam.yfov = rd.number(p, "yfov", f"{key}.perspective.yfov", positive=True)
        cam.znear = rd.number(p, "znear", f"{key}.perspective.znear", positive=True)
        cam.zfar = rd.number(p, "zfar", f"{key}.perspective.zfar", positive=True) if "zfar" in p else None
    return cam


def _unsupported(rd: _Reader, nodes: list, meshes: list, materials: list, walk) -> list[str]:
    """Notes naming what the file holds and the lab leaves out."""
    notes = []
    used = [e for e in rd.get(rd.doc, "extensionsUsed", list, "extensionsUsed", []) if e != LIGHTS_EXTENSION]
    required = set(rd.get(rd.doc, "extensionsRequired", list, "extensionsRequired", []))
    if used:
        notes.append("extensions not read: " + ", ".join(
            f"{e} (required by the file)" if e in required else str(e) for e in used))
    placed = {i for i, _ in walk}
    skinned = sorted(str(nodes[i].get("name", i)) for i in placed if "skin" in nodes[i])
    if rd.array("skins"):
        notes.append(f"{len(rd.array('skins'))} skin(s) ignored: meshes are read in their bind pose"
                     + (f" (nodes {', '.join(skinned)})" if skinned else ""))
    morphed = [str(m.get("name", i)) for i, m in enumerate(meshes) if any("targets" in p for p in m.get("primitives", []))]
    if morphed:
        notes.append(f"morph targets ignored (meshes {', '.join(morphed)}): the base shape is read")
    if rd.array("animations"):
        notes.append(f"{len(rd.array('animations'))} animation(s) ignored (an [animation] table in a TOML "
                     f"scene that includes the file animates it)")
    textured = [str(m.get("name", i)) for i, m in enumerate(materials)
                if any(k.endswith("Texture") for k in (m.get("pbrMetallicRoughness") or {}))
                or any(k.endswith("Texture") for k in m)]
    if rd.array("textures") or rd.array("images") or textured:
        notes.append(f"textures and images not used ({len(rd.array('images'))} image(s)"
                     + (f"; textured materials: {', '.join(textured)}" if textured else "") + "): only base colour factors")
    blended = [str(m.get("name", i)) for i, m in enumerate(materials) if m.get("alphaMode", "OPAQUE") != "OPAQUE"]
    if blended:
        notes.append(f"materials {', '.join(blended)}: alphaMode ignored, drawn opaque")
    if len(rd.array("scenes")) > 1:
        notes.append(f"{len(rd.array('scenes'))} scenes in the file; only scene {rd.doc.get('scene', 0)} is read")
    return notes


def buffer_files(path) -> list[tuple[str, Path]]:
    """The files a ``.gltf`` file's buffers name (``(uri as written, resolved path)``, data: URIs
    left out; none for a glb, or for a file that cannot be read as JSON): what a study's cache
    hash and Dask bundle must carry with it."""
    path = Path(path)
    if path.suffix.lower() != ".gltf":
        return []
    try:
        doc = json.loads(path.read_bytes())
    except (OSError, ValueError):
        return []
    buffers = doc.get("buffers") if isinstance(doc, dict) and isinstance(doc.get("buffers"), list) else []
    return [(urllib.parse.unquote(b["uri"]), (path.parent / urllib.parse.unquote(b["uri"])).resolve())
            for b in buffers if isinstance(b, dict) and isinstance(b.get("uri"), str)
            and not b["uri"].startswith("data:")]


def describe(path) -> str:
    """One line on a glTF file for listings: "glTF 2.0 scene written by <generator>" (the file's
    ``asset.generator``); only the JSON is read, and a broken file says so instead of raising."""
    try:
        generator = str(_Reader(Path(path)).doc.get("asset", {}).get("generator", "")).strip()
    except SceneError as exc:
        return f"glTF file that cannot be read ({exc.key}: {exc.reason})"
    return f"glTF 2.0 scene written by {generator}" if generator else "glTF 2.0 scene"


# --------------------------------------------------------------------------- into the lab

def choose_camera(g: GltfFile, choice: str | int | None = None, *, key: str = "camera") -> tuple[GltfCamera, int]:
    """The camera ``choice`` names (a camera's or its node's name, or an index into the placed
    cameras in file order; None: the first perspective one) and its index. SceneError naming
    ``key`` when there is none, the choice names none, or it is orthographic."""
    file = str(g.path)
    if not g.cameras:
        raise SceneError(file, key, f"{g.path.name} has no camera; write a TOML scene that includes it "
                                    f"([gltf] file = ...) and adds a [camera]")
    names = [c.name for c in g.cameras]
    if choice is None:
        persp = [i for i, c in enumerate(g.cameras) if c.type == "perspective"]
        if not persp:
            raise SceneError(file, key, f"{g.path.name} has only orthographic cameras and the lab's camera is "
                                        f"perspective; write a TOML scene that includes it and adds a [camera]")
        i = persp[0]
    elif str(choice) in names:
        i = names.index(str(choice))
    elif str(choice) in [c.node for c in g.cameras]:
        i = [c.node for c in g.cameras].index(str(choice))
    elif str(choice).lstrip("-").isdigit() and 0 <= int(choice) < len(g.cameras):
        i = int(choice)
    else:
        raise SceneError(file, key, f"no camera {choice!r}{did_you_mean(choice, names)} (cameras: "
                                    f"{', '.join(f'{k}: {n}' for k, n in enumerate(names))})")
    cam = g.cameras[i]
    if cam.type != "perspective":
        raise SceneError(file, key, f"camera {cam.name!r} is orthographic and the lab's camera is perspective; "
                                    f"choose another or give a [camera] in a TOML scene that includes the file")
    return cam, i


def camera_target(cam: GltfCamera, bounds: np.ndarray) -> np.ndarray:
    """A look-at target for a glTF camera (which has none): the point on its viewing ray nearest
    the centre of the scene's ``bounds`` (2, 3), or one unit ahead when that centre is behind it."""
    centre = bounds.mean(axis=0)
    t = float(np.dot(centre - cam.eye, cam.forward))
    return cam.eye + (t if t > 0 else 1.0) * cam.forward


def lab_camera(cam: GltfCamera, bounds: np.ndarray) -> Camera:
    """A glTF perspective camera as the lab's: eye at the node, target on its −Z
    (:func:`camera_target`), up its +Y, ``fov_y`` = yfov in degrees, near/far = znear/zfar (far
    fitted to the scene when the file gives none)."""
    return Camera(eye=cam.eye.copy(), target=camera_target(cam, bounds), up=cam.up.copy(),
                  fov_y=math.degrees(cam.yfov), near=cam.znear, far=cam.zfar)


def light_strength(light: GltfLight, at: np.ndarray) -> float:
    """A light's unshadowed brightness at point ``at``, for the automatic exposure: its
    brightest colour channel times its intensity, over the squared distance (point and spot;
    held at :data:`INVERSE_SQUARE_NEAR`; a spot's cone and a range's window are not counted, so
    the figure is never 0), or times 1 (directional, lux)."""
    peak = float(light.color.max()) * light.intensity
    if light.type == "directional":
        return peak
    d2 = float(np.sum((np.asarray(at, np.float64) - light.position) ** 2))
    return peak / max(d2, INVERSE_SQUARE_NEAR ** 2)


def auto_exposure(lights: list[GltfLight], at: np.ndarray) -> float:
    """The ``exposure = "auto"`` factor: 1 over the sum of the lights' :func:`light_strength` at
    ``at`` (the centre of the scene's bounds, the same for every camera), so that all of them
    together light a white surface facing them there at 1 — the picture neither washes out nor goes dark, whatever units the exporter
    wrote; 1 when no light has any strength."""
    total = sum(light_strength(l, at) for l in lights)
    return 1.0 / total if total > 0 else 1.0


def light_table(light: GltfLight, exposure: float, ambient_share: float = DEFAULT_AMBIENT_SHARE) -> dict:
    """A glTF light as the keys of a lab ``[[lights]]`` table, which
    :func:`shadowlab.scene.reading.parse_light` then reads as any scene file's (the same table a
    light override edits):

    - ``color`` = color · intensity · exposure (candela or lux times the exposure);
    - ``ambient`` = ``ambient_share`` · the brightest channel of that colour;
    - directional → ``directional`` along the node's −Z;
    - point → ``point`` at the node, with ``range`` when the file gives one (the lab's range is
      Karis's squared window over 1/d²; KHR recommends it unsquared: see the mapping table in
      docs/contracts.md#gltf-scenes) and ``inverse_square = true`` when it does not (KHR: an
      infinite range with 1/d² falloff);
    - spot → ``spot`` with ``alpha`` = 2 · outerConeAngle, ``beta`` = 2 · innerConeAngle (degrees;
      alpha at most :data:`MAX_SPOT_ANGLE`) and ``cone_falloff = "squared"`` (KHR's ramp).
    """
    color = light.color * light.intensity * exposure
    table = {"type": light.type, "color": color.tolist(), "ambient": float(ambient_share * color.max())}
    if light.type == "directional":
        table["direction"] = light.direction.tolist()
        return table
    table["position"] = light.position.tolist()
    if light.range is not None:
        table["range"] = light.range
    else:
        table["inverse_square"] = True
    if light.type == "spot":
        table.update(direction=light.direction.tolist(), alpha=min(math.degrees(2 * light.outer), MAX_SPOT_ANGLE),
                     beta=min(math.degrees(2 * light.inner), MAX_SPOT_ANGLE), cone_falloff="squared")
    return table


__all__ = ["GLTF_SUFFIXES", "GltfFile", "GltfLight", "GltfCamera", "is_gltf", "split_reference", "read_gltf", "describe", "buffer_files",
           "choose_camera", "lab_camera", "camera_target", "auto_exposure", "light_strength", "light_table",
           "local_matrix", "DEFAULT_AMBIENT_SHARE", "MAX_SPOT_ANGLE"]
