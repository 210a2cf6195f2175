"""How the city meshes shipped in ``shadowlab/scenes/meshes/city_sf_*.ply.gz`` were made (one-off).

Run it again to reproduce them byte for byte from the Python wheel they come from (standard
library, numpy and trimesh only; nothing here is imported by the package)::

    pip download --no-deps -d DIR sionna-rt==2.2.0
    python experiments/prepare_city.py --wheel DIR/sionna_rt-2.2.0-py3-none-any.whl [--out shadowlab/scenes/meshes]

``--wheel`` is the wheel of ``sionna-rt`` 2.2.0 (NVIDIA's radio ray tracer) exactly as published
(SHA-256 checked below). The script reads it in memory (a wheel is a zip file) and takes the
scene ``sionna/rt/scenes/san_francisco/``: ``san_francisco.xml`` (a Mitsuba scene) names 4,735
binary PLY shapes under ``meshes/``: one ``Terrain.ply`` (a 192,000-triangle height field of
the hills) and, per building, a ``<name>-wall.ply`` and a ``<name>-roof.ply`` (Coit Tower has
``-e0e0e0`` in place of a wall). Sionna's documentation of the scene says it was made from
OpenStreetMap data with Blender and the Blender-OSM and Mitsuba Blender add-ons and that the
data is under the Open Database License (ODbL); see shadowlab/scenes/meshes/README.md and
city_sf_NOTICE.txt for the terms and the attribution.

====================== ============================ ===========================================
source                 output                       what is done
====================== ============================ ===========================================
meshes/Terrain.ply     city_sf_terrain.ply.gz       positions only (the normals are dropped),
                                                    welded
every other shape      city_sf_buildings.ply.gz     the buildings' walls and roofs concatenated
                                                    in the XML's order, positions only, welded
====================== ============================ ===========================================

Nothing is decimated or cropped, moved, scaled or rotated: the files keep the source's
coordinates (metres, z up, the ground at z = 0 at its lowest); the scenes turn them y-up with
``rotate = [-90, 0, 0]``. Winding is kept as it is (the lab's surfaces are two-sided). The
output format is that of ``prepare_meshes.py`` (float32 binary little-endian PLY, gzipped with
a zero timestamp), whose helpers this script imports.

It prints, per output: triangles, vertices, connected components, boundary edges, bounds and
the compressed size, and the number of buildings (distinct shape-name prefixes) — the figures
in meshes/README.md and tests/scene/test_city.py.
"""
from __future__ import annotations

import argparse
import io
import re
import zipfile
from pathlib import Path

import numpy as np
import trimesh

from prepare_meshes import components, sha256, welded, write_outputs  # same directory

ROOT = Path(__file__).resolve().parent.parent

WHEEL_SHA256 = "ffd5b5fea0fd3fee9d64a9e2b0ff1f2f4b4bfc010fa3d59d7479955fbdfc0e8e"
SCENE_DIR = "sionna/rt/scenes/san_francisco/"
TERRAIN = "meshes/Terrain.ply"


def shapes(wheel: Path) -> tuple[list[str], dict[str, bytes]]:
    """The PLY paths the scene XML names, in its order, and their bytes, read from the wheel."""
    raw = wheel.read_bytes()
    if sha256(raw) != WHEEL_SHA256:
        raise SystemExit(f"{wheel}: SHA-256 {sha256(raw)} is not that of sionna-rt 2.2.0 ({WHEEL_SHA256})")
    with zipfile.ZipFile(io.BytesIO(raw)) as zf:
        xml = zf.read(SCENE_DIR + "san_francisco.xml").decode("utf-8")
        print(f"source {SCENE_DIR}san_francisco.xml: {len(xml)} chars, SHA-256 {sha256(xml.encode())}")
        names = re.findall(r'<string name="filename" value="([^"]+\.ply)"/>', xml)
        if len(names) != len(set(names)) or TERRAIN not in names:
            raise SystemExit("unexpected scene XML: repeated shapes or no terrain")
        if re.search(r"<transform|<matrix", xml):
            raise SystemExit("unexpected scene XML: a shape transform (the script assumes none)")
        return names, {n: zf.read(SCENE_DIR + n) for n in names}


def positions_mesh(blob: bytes) -> trimesh.Trimesh:
    """One PLY shape as a triangle mesh of its positions only."""
    m = trimesh.load(io.BytesIO(blob), file_type="ply", force="mesh", process=False)
    return trimesh.Trimesh(np.asarray(m.vertices, np.float64), np.asarray(m.faces, np.int64), process=False)


def concatenated(meshes: list[trimesh.Trimesh]) -> trimesh.Trimesh:
    """The meshes as one (faces in the given order), welded."""
    verts, faces, base = [], [], 0
    for m in meshes:
        verts.append(m.vertices)
        faces.append(m.faces + base)
        base += len(m.vertices)
    return welded(trimesh.Trimesh(np.concatenate(verts), np.concatenate(faces), process=False))


def boundary_edges(mesh: trimesh.Trimesh) -> int:
    """Edges with exactly one face."""
    edges = np.sort(mesh.edges, axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    return int((counts == 1).sum())


def describe(mesh: trimesh.Trimesh) -> str:
    """The figures printed per output."""
    return (f"{len(mesh.faces)} triangles, {len(mesh.vertices)} vertices, {components(mesh)} connected "
            f"component(s), boundary edges {boundary_edges(mesh)}, bounds {np.round(mesh.bounds, 3).tolist()}")


def main() -> None:
    """Read the wheel, write the two city meshes, print what was written."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--wheel", type=Path, required=True, help="sionna_rt-2.2.0-py3-none-any.whl")
    ap.add_argument("--out", type=Path, default=ROOT / "shadowlab/scenes/meshes")
    args = ap.parse_args()

    names, blobs = shapes(args.wheel)
    building_names = [n for n in names if n != TERRAIN]
    prefixes = {Path(n).stem.rsplit("-", 1)[0] for n in building_names}
    print(f"{len(names)} shapes: the terrain and {len(building_names)} building shapes of "
          f"{len(prefixes)} buildings")
    tag = "sionna-rt 2.2.0 scenes/san_francisco, (c) OpenStreetMap contributors, ODbL 1.0; shadowlab experiments/prepare_city.py"
    outputs = {
        "city_sf_terrain": (welded(positions_mesh(blobs[TERRAIN])), f"meshes/Terrain.ply {tag}"),
        "city_sf_buildings": (concatenated([positions_mesh(blobs[n]) for n in building_names]),
                              f"every building's walls and roofs {tag}"),
    }
    write_outputs(outputs, args.out, describe)


if __name__ == "__main__":
    main()
