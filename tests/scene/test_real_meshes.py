"""The shipped real meshes (shadowlab/scenes/meshes/*.ply.gz, documented in meshes/README.md)
and their rm_* scenes: they load, have the documented sizes and topology, stand on the floor,
and a broken gzipped mesh is refused with a SceneError naming the file."""
from __future__ import annotations

import gzip
import os
import textwrap
from pathlib import Path

import numpy as np
import pytest
import trimesh

from shadowlab.scene import builtin_scene_dir, builtin_scenes, load_scene
from shadowlab.util.validation import SceneError

# scene -> (object name, triangles, vertices, boundary edges, genus), as in meshes/README.md
SCENES = {
    "rm_bunny": ("bunny", 75408, 37706, 0, 0),
    "rm_open_bunny": ("bunny", 74379, 37291, 209, 0),
    "rm_knot": ("knot", 6400, 3200, 0, 1),
    "rm_dense": ("elephant", 88928, 44460, 0, 3),
}


def topology(obj):
    """(boundary edges, boundary loops, genus) of a connected, orientable, edge-manifold mesh."""
    e = obj.edges
    assert e.nonmanifold_edges == 0
    boundary = e.edges[e.face_count == 1]
    # boundary loops = connected components of the boundary edges' graph (each vertex on one loop)
    loops = 0
    if len(boundary):
        nodes = np.unique(boundary)
        loops = len(trimesh.graph.connected_components(boundary, nodes=nodes))
    chi = len(obj.vertices) - len(e.edges) + len(obj.faces)  # Euler characteristic V - E + F
    genus, odd = divmod(2 - chi - loops, 2)
    assert odd == 0
    return len(boundary), loops, genus


@pytest.fixture(scope="module")
def scenes():
    return {name: load_scene(name) for name in SCENES}


def test_every_rm_scene_is_listed_here():
    assert {n for n in builtin_scenes() if n.startswith("rm_")} == set(SCENES)


@pytest.mark.parametrize("name", sorted(SCENES))
def test_rm_scene_loads_with_documented_mesh(scenes, name):
    obj_name, tris, verts, boundary, genus = SCENES[name]
    s = scenes[name]
    model = next(o for o in s.objects if o.name == obj_name)
    assert (len(model.faces), len(model.vertices)) == (tris, verts)
    b, loops, g = topology(model)
    assert (b, g) == (boundary, genus)
    # it stands on the floor (y = 0), centred near the y axis, 1-2.5 units tall
    lo, hi = model.bounds()
    assert abs(lo[1]) < 1e-3 and 1.0 <= hi[1] <= 2.5
    assert np.all(np.abs((lo + hi)[[0, 2]] / 2) < 0.05)
    floor = next(o for o in s.objects if o.name == "floor")
    assert np.allclose(floor.vertices[:, 1], 0.0)
    # one light, above the model
    assert len(s.lights) == 1


def test_the_hard_cases_are_there(scenes):
    dense = scenes["rm_dense"].objects[1]
    assert 80_000 <= len(dense.faces) <= 110_000
    open_bunny = scenes["rm_open_bunny"].objects[1]
    assert topology(open_bunny)[:2] == (209, 5)  # the 5 holes cut in the base
    # ... and they are in the base: every boundary vertex within 1.5% of the height of the floor
    lo, hi = open_bunny.bounds()
    e = open_bunny.edges
    rim = np.unique(e.edges[e.face_count == 1])
    assert np.all(open_bunny.vertices[rim, 1] < lo[1] + 0.015 * (hi[1] - lo[1]))
    closed = scenes["rm_bunny"].objects[1]
    assert topology(closed)[0] == 0  # its closed twin
    assert len(closed.faces) - len(open_bunny.faces) == 1029  # the triangles deleted
    assert topology(scenes["rm_knot"].objects[1])[2] >= 1


def test_shipped_meshes_are_small_and_documented():
    meshes = builtin_scene_dir() / "meshes"
    shipped = sorted(meshes.glob("*.ply.gz"))
    assert len(shipped) >= 3
    assert sum(p.stat().st_size for p in meshes.iterdir() if p.is_file()) < 10 * 2**20
    # the sources, terms and counts of every shipped mesh (read from the source tree)
    readme = (Path(__file__).resolve().parents[2] / "shadowlab/scenes/meshes/README.md").read_text()
    for p in shipped + sorted(meshes.glob("*.obj")):
        assert p.name in readme, p.name


SCENE = textwrap.dedent("""
    name = "t"
    [camera]
    eye = [4.0, 3.0, 5.0]
    target = [0.0, 0.5, 0.0]
    [[lights]]
    type = "point"
    position = [2.0, 6.0, 1.0]
    [[objects]]
    mesh = "plane"
    [[objects]]
    mesh = "MESH"
""")

PLY_TRIANGLE = (b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                b"property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
                b"0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
PLY_BINARY = (b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
              b"property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
              + np.array([0, 0, 0, 1, 0, 0, 0, 1, 0], "<f4").tobytes() + b"\x03" + np.array([0, 1, 2], "<i4").tobytes())
PLY_EMPTY = (b"ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\n"
             b"property float z\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n")


def scene_with(tmp_path, name: str, data: bytes):
    (tmp_path / name).write_bytes(data)
    path = tmp_path / "scene.toml"
    path.write_text(SCENE.replace("MESH", name))
    return path


@pytest.mark.parametrize("data", [PLY_TRIANGLE, PLY_BINARY])
def test_gzipped_mesh_loads(tmp_path, data):
    s = load_scene(scene_with(tmp_path, "tri.ply.gz", gzip.compress(data)))
    assert len(s.objects[1].faces) == 1


@pytest.mark.parametrize("name,data,reason", [
    ("noise.ply.gz", os.urandom(4096), "is not a readable mesh file"),                      # not gzip at all
    ("cut.ply.gz", gzip.compress(PLY_TRIANGLE * 50)[:-40], "is not a readable mesh file"),  # truncated stream
    ("short.ply.gz", gzip.compress(PLY_BINARY[:-5]), "is not a readable mesh file"),       # whole gzip, cut PLY
    ("junk.ply.gz", gzip.compress(b"this is not a ply file\n" * 20), "is not a readable mesh file"),
    ("nofmt.gz", gzip.compress(PLY_TRIANGLE), "must name its format"),
    ("empty.ply.gz", gzip.compress(PLY_EMPTY), ""),
    ("gone.ply.gz", None, "not found"),
], ids=lambda v: v if isinstance(v, str) and v.endswith(".gz") else "")  # ids by file name: the data hold random and time-stamped bytes, and pytest-xdist needs the same ids in every worker
def test_broken_gzipped_mesh_is_a_scene_error_naming_the_file(tmp_path, name, data, reason):
    if data is None:
        path = tmp_path / "scene.toml"
        path.write_text(SCENE.replace("MESH", name))
    else:
        path = scene_with(tmp_path, name, data)
    with pytest.raises(SceneError) as info:
        load_scene(path)
    err = info.value
    assert err.key == "objects[1].mesh", str(err)
    assert str(path) in str(err) and name in err.reason and reason in err.reason, str(err)
