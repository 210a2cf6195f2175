"""Generate the furnished room of the ``sm_room_lamp`` scene (``shadowlab/scenes/meshes/room.obj``).

Run it again to reproduce the file byte for byte (numpy and trimesh only; no randomness;
nothing here is imported by the package)::

    python experiments/make_room_mesh.py [--out shadowlab/scenes/meshes]

Issue 35: a lamp inside a room. An interior arrives from a modelling tool as ONE mesh — walls,
floor and furniture in a single file — so its bounding box holds every lamp hung in the room,
and a shadow-map near plane fitted to caster *bounding boxes* has nothing to stand on. This
script writes such a mesh: one OBJ with an ``o`` group per part, the groups loaded together as
one object. Units are metres, y up; the room is open towards +z (where the camera stands).

Parts, each a closed box wound counter-clockwise seen from outside (trimesh's ``box``):

* floor: a slab 6 x 0.1 x 5 (x in [-3, 3], z in [-2.55, 2.5], top at y = 0);
* three walls 3 m high, 0.1 m thick: the back wall across the whole width behind z = -2.5, the
  side walls (inner faces at x = +-2.98) butting against its front face; their feet sink 4 cm
  into the floor slab, whose back edge sinks 5 cm into the back wall;
* a table 1.4 x 0.9 m, top 0.76 m high, centred under the spot lamp at (0.5, -0.5): a 4 cm top
  and four 6 cm legs (the legs reach 2 cm into the top and 1 cm into the floor);
* a cabinet 1.0 x 1.2 x 0.6 m in the back left corner, 5 cm from both walls;
* a chair beside the table: a seat 0.45 m high, four legs and a back rest.

The floor and the walls are subdivided once (each triangle into four) as a modelling tool's
grid would have them; the furniture keeps 12 triangles per box. Parts only interpenetrate or
touch face to face: no two parts share a vertex position, so welding on load (which merges equal
positions) keeps every part a closed, edge-manifold component. The script checks that, and the
outward winding (positive volume per part), and prints the triangle and vertex counts (the
figures in meshes/README.md and docs/hard-cases.md).
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import trimesh

ROOT = Path(__file__).resolve().parent.parent


def box(lo, hi, subdivide: int = 0) -> trimesh.Trimesh:
    """A closed axis-aligned box from corner ``lo`` to corner ``hi``, outward wound, its
    triangles split into four ``subdivide`` times."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    m = trimesh.creation.box(extents=hi - lo)
    m.apply_translation((lo + hi) / 2)
    v, f = np.asarray(m.vertices), np.asarray(m.faces)
    for _ in range(subdivide):
        v, f = trimesh.remesh.subdivide(v, f)
    return trimesh.Trimesh(np.round(v, 6), f, process=False)


def legs(x0, x1, z0, z1, inset: float, width: float, y0: float, y1: float) -> list[trimesh.Trimesh]:
    """Four square legs of ``width`` under the rectangle [x0, x1] x [z0, z1], ``inset`` from its corners."""
    out = []
    for x in (x0 + inset, x1 - inset - width):
        for z in (z0 + inset, z1 - inset - width):
            out.append(box([x, y0, z], [x + width, y1, z + width]))
    return out


def room_parts() -> list[tuple[str, trimesh.Trimesh]]:
    """(name, mesh) of every part, in file order."""
    parts = [
        ("floor", box([-3.0, -0.1, -2.55], [3.0, 0.0, 2.5], subdivide=1)),
        ("wall_back", box([-3.1, -0.04, -2.6], [3.1, 3.0, -2.5], subdivide=1)),
        ("wall_left", box([-3.08, -0.04, -2.5], [-2.98, 3.0, 2.5], subdivide=1)),
        ("wall_right", box([2.98, -0.04, -2.5], [3.08, 3.0, 2.5], subdivide=1)),
        ("table_top", box([-0.2, 0.72, -0.95], [1.2, 0.76, -0.05])),
    ]
    parts += [(f"table_leg_{k}", m) for k, m in enumerate(legs(-0.2, 1.2, -0.95, -0.05, 0.05, 0.06, -0.01, 0.74))]
    parts.append(("cabinet", box([-2.95, -0.01, -2.45], [-1.95, 1.2, -1.85])))
    parts.append(("chair_seat", box([1.5, 0.43, -0.72], [1.95, 0.47, -0.27])))
    parts += [(f"chair_leg_{k}", m) for k, m in enumerate(legs(1.5, 1.95, -0.72, -0.27, 0.02, 0.04, -0.01, 0.44))]
    parts.append(("chair_back", box([1.9, 0.45, -0.71], [1.94, 0.95, -0.28])))
    return parts


def obj_text(parts) -> str:
    """The OBJ file: a header comment, then per part an ``o`` line, its vertices and faces."""
    lines = ["# A furnished room for shadowlab's sm_room_lamp scene, one mesh of closed boxes",
             "# (floor, three walls, a table, a cabinet, a chair). Made by experiments/make_room_mesh.py."]
    base = 1
    for name, m in parts:
        lines.append(f"o {name}")
        lines += [f"v {x:.6g} {y:.6g} {z:.6g}" for x, y, z in m.vertices]
        lines += [f"f {a + base} {b + base} {c + base}" for a, b, c in m.faces]
        base += len(m.vertices)
    return "\n".join(lines) + "\n"


def check(path: Path, parts) -> trimesh.Trimesh:
    """Load the file as the scene loader does (one mesh, welded) and check every part."""
    mesh = trimesh.load(path, force="mesh", process=False)
    welded = trimesh.Trimesh(mesh.vertices, mesh.faces, process=False)
    welded.merge_vertices()
    comps = welded.split(only_watertight=False)
    assert len(comps) == len(parts), (len(comps), len(parts))
    for c in comps:
        assert c.is_watertight and c.is_winding_consistent and c.volume > 0, "a part is open or inward"
    assert welded.is_winding_consistent and welded.edges_unique.shape[0] * 2 == welded.faces.shape[0] * 3
    return welded


def main() -> None:
    """Write the file, check it and print its counts."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", type=Path, default=ROOT / "shadowlab/scenes/meshes")
    args = ap.parse_args()
    parts = room_parts()
    path = args.out / "room.obj"
    path.write_text(obj_text(parts))
    welded = check(path, parts)
    print(f"{path}: {len(welded.faces)} triangles, {len(welded.vertices)} vertices, {len(parts)} parts, "
          f"each closed and wound outward; {path.stat().st_size} bytes; bounds {welded.bounds.tolist()}")


if __name__ == "__main__":
    main()
