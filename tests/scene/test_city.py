"""The city-scale scenes (issue 27): city_sf_sun / city_sf_spot (San Francisco from sionna-rt
2.2.0, OpenStreetMap data under the ODbL) and city_wires (generated thin casters) load with the
mesh sizes documented in shadowlab/scenes/meshes/README.md, carry their lights, ship their
licence notice (also in the package data), and the city suite names them."""
from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest
import trimesh

from shadowlab.scene import builtin_scene_dir, builtin_scenes, load_scene

MESHES = builtin_scene_dir() / "meshes"
ROOT = Path(__file__).resolve().parents[2]

# scene -> light type, {object name: (triangles, vertices)}, as in meshes/README.md
SCENES = {
    "city_sf_sun": ("directional", {"terrain": (192000, 96641), "buildings": (76041, 53722)}),
    "city_sf_spot": ("spot", {"terrain": (192000, 96641), "buildings": (76041, 53722)}),
    "city_wires": ("directional", {"floor": (2, 4), "power_lines": (2904, 1936),
                                   "fences": (18168, 12112), "grass": (6000, 18000)}),
}


@pytest.fixture(scope="module")
def scenes():
    return {name: load_scene(name) for name in SCENES}


def test_every_city_scene_is_listed_here():
    assert {n for n in builtin_scenes() if n.startswith("city_")} == set(SCENES)


@pytest.mark.parametrize("name", sorted(SCENES))
def test_city_scene_loads_with_documented_meshes(scenes, name):
    light, objects = SCENES[name]
    s = scenes[name]
    assert [type(l).__name__.lower() for l in s.lights] == [f"{light}light"]
    assert {o.name: (len(o.faces), len(o.vertices)) for o in s.objects} == objects


def test_san_francisco_is_city_scale(scenes):
    """Hundreds of thousands of triangles, thousands of separate buildings, about a kilometre
    across, turned y-up (the ground near y = 0, buildings up to ~170 m)."""
    s = scenes["city_sf_sun"]
    assert sum(len(o.faces) for o in s.objects) == 268041
    b = next(o for o in s.objects if o.name == "buildings")
    mesh = trimesh.Trimesh(b.vertices, b.faces, process=False)
    parts = len(trimesh.graph.connected_components(mesh.face_adjacency, nodes=np.arange(len(b.faces))))
    assert parts == 2362          # 2,367 buildings in the source; 5 pairs touch
    lo, hi = np.min([o.vertices.min(0) for o in s.objects], 0), np.max([o.vertices.max(0) for o in s.objects], 0)
    assert 1100 < hi[0] - lo[0] < 1300 and 850 < hi[2] - lo[2] < 1000
    assert abs(lo[1]) < 1e-3 and 150 < hi[1] < 200


def test_thin_casters_are_thin(scenes):
    """The wires' boxes are 2 cm across, the blades 1.2 cm at the root; the floor is 240 m wide."""
    s = scenes["city_wires"]
    floor = next(o for o in s.objects if o.name == "floor")
    assert np.ptp(floor.vertices[:, 0]) == pytest.approx(240.0)
    grass = next(o for o in s.objects if o.name == "grass")
    tri = grass.vertices[grass.faces]
    assert np.linalg.norm(tri[:, 1] - tri[:, 0], axis=1) == pytest.approx(0.012, abs=1e-6)  # float32


def test_city_licence_notice_ships_with_the_meshes():
    notice = (MESHES / "city_sf_NOTICE.txt").read_text(encoding="utf-8")
    for needle in ("OpenStreetMap contributors", "Open Database License", "ODbL 1.0", "sionna-rt 2.2.0",
                   "Apache License", "NVIDIA"):
        assert needle in notice
    readme = (MESHES / "README.md").read_text(encoding="utf-8")
    assert "city_sf_NOTICE.txt" in readme and "© OpenStreetMap contributors" in readme
    data = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    patterns = data["tool"]["setuptools"]["package-data"]["shadowlab.scenes"]
    for f in ("city_sf_NOTICE.txt", "city_sf_buildings.ply.gz", "city_wires_grass.ply.gz"):
        assert any(Path("meshes", f).match(p) for p in patterns), f


def test_city_suite_runs_the_city_scenes():
    from shadowlab.study.suite import load_suite

    suite = load_suite("city")
    assert {s.name for s in suite.scenes} == set(SCENES)
