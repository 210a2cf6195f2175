"""Generate the thin casters of the ``city_wires`` scene (``shadowlab/scenes/meshes/city_wires_*.ply.gz``).

Run it again to reproduce them byte for byte (numpy and trimesh only; a fixed random seed;
nothing here is imported by the package)::

    python experiments/make_city_wires.py [--out shadowlab/scenes/meshes]

Units are metres, y up, in the scene's own coordinates (the scene places them unmoved). Three
files, one scene object each:

* ``city_wires_lines.ply.gz`` — two overhead power lines: wooden poles (0.25 m square, 9 m tall,
  a 2.4 m cross-arm) every 35 m, with 4 conductors per line (2 cm square boxes) hanging between
  the arms in a parabolic sag of 0.6 m, 8 straight pieces per span. Line A runs along -z at
  x = 12 (its shadow falls along the middle of the view); line B crosses it at 35 degrees.
* ``city_wires_fences.ply.gz`` — a chain-link fence (posts every 3 m, top and bottom rails,
  a 10 cm diamond mesh of 4 mm wires at +-45 degrees, 2 m tall, 60 m long) and a picket fence
  (8 cm pickets with 5 cm gaps, 1.1 m tall, 40 m long, two rails).
* ``city_wires_grass.ply.gz`` — 6,000 grass blades: single triangles 1.2 cm wide at the root,
  20-40 cm tall, random heading and a lean of up to 25 degrees, scattered over a 24 x 12 m patch.

Every wire, post, rail and picket is a closed box (12 triangles); blades are open triangles. The
output format is that of ``prepare_meshes.py`` (float32 binary little-endian PLY, gzipped with
a zero timestamp), whose helpers this script imports. It prints each file's triangle count,
object count (boxes or blades) and size — the figures in meshes/README.md and tests/scene/test_city.py.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import trimesh

from prepare_meshes import gz, ply_bytes, sha256  # same directory

ROOT = Path(__file__).resolve().parent.parent
SEED = 27

# unit box: 8 corners in [-0.5, 0.5]^3 and 12 outward (counter-clockwise) triangles
_BOX = trimesh.creation.box()
BOX_V, BOX_F = np.asarray(_BOX.vertices), np.asarray(_BOX.faces)


def segment_box(a, b, width: float, height: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """A closed box from point ``a`` to point ``b`` with a ``width`` x ``height`` cross-section
    (square when ``height`` is None): its 8 vertices and 12 triangles."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    axis = b - a
    length = np.linalg.norm(axis)
    d = axis / length
    ref = np.array([0.0, 1.0, 0.0]) if abs(d[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    u = np.cross(d, ref)
    u /= np.linalg.norm(u)
    w = np.cross(u, d)
    m = np.column_stack([u * width, w * (height if height is not None else width), d * length])
    return BOX_V @ m.T + (a + b) / 2, BOX_F.copy()


class Builder:
    """Collects vertices and triangles of many parts; counts the parts."""

    def __init__(self) -> None:
        self.vertices: list[np.ndarray] = []
        self.faces: list[np.ndarray] = []
        self.count = 0
        self.parts = 0

    def add(self, part: tuple[np.ndarray, np.ndarray]) -> None:
        """Append one part (vertices, faces)."""
        v, f = part
        self.vertices.append(v)
        self.faces.append(f + self.count)
        self.count += len(v)
        self.parts += 1

    def mesh(self) -> trimesh.Trimesh:
        """Everything added, as one mesh (not welded: the parts touch nowhere by construction,
        except posts and rails, which only touch)."""
        return trimesh.Trimesh(np.concatenate(self.vertices), np.concatenate(self.faces), process=False)


def power_line(out: Builder, start, heading_deg: float, spans: int, span: float = 35.0,
               height: float = 9.0, arm: float = 2.4, sag: float = 0.6, pieces: int = 8) -> None:
    """Poles with cross-arms along a heading (degrees from +z towards +x) and 4 sagging wires."""
    start = np.asarray(start, float)
    h = np.radians(heading_deg)
    along = np.array([np.sin(h), 0.0, np.cos(h)])
    across = np.array([np.cos(h), 0.0, -np.sin(h)])
    offsets = [-1.1, -0.4, 0.4, 1.1]  # conductor positions along the arm
    tops = []
    for k in range(spans + 1):
        base = start + along * span * k
        top = base + [0.0, height, 0.0]
        out.add(segment_box(base, top, 0.25))
        out.add(segment_box(top - [0, 0.35, 0] - across * arm / 2, top - [0, 0.35, 0] + across * arm / 2,
                            0.12, 0.15))
        tops.append(top - [0, 0.25, 0])  # wires rest on the arm
    for k in range(spans):
        for o in offsets:
            a, b = tops[k] + across * o, tops[k + 1] + across * o
            ts = np.linspace(0.0, 1.0, pieces + 1)
            pts = a + np.outer(ts, b - a) - np.outer(4 * sag * ts * (1 - ts), [0.0, 1.0, 0.0])
            for p, q in zip(pts[:-1], pts[1:]):
                out.add(segment_box(p, q, 0.02))


def chain_link(out: Builder, start, end, height: float = 2.0, post_every: float = 3.0,
               pitch: float = 0.10, wire: float = 0.004) -> None:
    """A chain-link fence from ``start`` to ``end`` on the floor: posts, two rails and a diamond
    mesh of thin wires at +-45 degrees, clipped to the fence's rectangle."""
    start, end = np.asarray(start, float), np.asarray(end, float)
    length = np.linalg.norm(end - start)
    d = (end - start) / length
    up = np.array([0.0, 1.0, 0.0])
    for s in np.arange(0.0, length + 1e-9, post_every):
        out.add(segment_box(start + d * s, start + d * s + up * (height + 0.1), 0.06))
    for y in (0.05, height):
        out.add(segment_box(start + up * y, end + up * y, 0.04))
    # diagonals s - y = c (rising) and s + y = c (falling), clipped to 0 <= s <= length, 0 <= y <= height
    lo, hi = 0.1, height - 0.05
    for sign in (1.0, -1.0):
        for c in np.arange(-height if sign > 0 else 0.0, length + (0.0 if sign > 0 else height), pitch):
            # points (s, y) with s = c + sign * y ... solved per case
            y0, y1 = lo, hi
            s0, s1 = (c + y0, c + y1) if sign > 0 else (c - y0, c - y1)
            # clip s into [0, length]
            if sign > 0:
                if s0 < 0:
                    y0, s0 = y0 - s0, 0.0
                if s1 > length:
                    y1, s1 = y1 - (s1 - length), length
            else:
                if s0 > length:
                    y0, s0 = y0 + (s0 - length), length
                if s1 < 0:
                    y1, s1 = y1 + s1, 0.0
            if y1 - y0 < 0.05:
                continue
            out.add(segment_box(start + d * s0 + up * y0, start + d * s1 + up * y1, wire))


def picket_fence(out: Builder, start, end, height: float = 1.1, picket: float = 0.08,
                 gap: float = 0.05) -> None:
    """A picket fence from ``start`` to ``end``: 2 cm thick pickets with gaps, and two rails."""
    start, end = np.asarray(start, float), np.asarray(end, float)
    length = np.linalg.norm(end - start)
    d = (end - start) / length
    up = np.array([0.0, 1.0, 0.0])
    side = np.cross(up, d)
    for s in np.arange(picket / 2, length, picket + gap):
        p = start + d * s
        out.add(_picket(p, d, side, picket, height))
    for y in (0.25, height - 0.2):
        out.add(segment_box(start + up * y - side * 0.03, end + up * y - side * 0.03, 0.03, 0.08))


def _picket(p, d, side, width, height):
    """One picket: a box ``width`` along the fence, 2 cm thick, ``height`` tall, standing at p."""
    m = np.column_stack([d * width, np.array([0.0, height, 0.0]), side * 0.02])
    return BOX_V @ m.T + p + [0.0, height / 2, 0.0], BOX_F.copy()


def grass(out: Builder, rng: np.random.Generator, count: int, centre, size) -> None:
    """``count`` blades: one triangle each, rooted on the floor inside the rectangle ``size``
    (x, z) around ``centre``, 1.2 cm wide at the root, 20-40 cm tall, leaning up to 25 degrees."""
    centre = np.asarray(centre, float)
    for _ in range(count):
        root = centre + [rng.uniform(-size[0] / 2, size[0] / 2), 0.0, rng.uniform(-size[1] / 2, size[1] / 2)]
        heading = rng.uniform(0, 2 * np.pi)
        lean = np.radians(rng.uniform(0, 25))
        tall = rng.uniform(0.2, 0.4)
        flat = np.array([np.cos(heading), 0.0, np.sin(heading)])          # the blade's width
        bend = np.array([-np.sin(heading), 0.0, np.cos(heading)])        # it leans across its width
        tip = root + tall * (np.cos(lean) * np.array([0.0, 1.0, 0.0]) + np.sin(lean) * bend)
        v = np.array([root - flat * 0.006, root + flat * 0.006, tip])
        out.add((v, np.array([[0, 1, 2]])))


def main() -> None:
    """Build the three files and print what was written."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", type=Path, default=ROOT / "shadowlab/scenes/meshes")
    args = ap.parse_args()
    rng = np.random.default_rng(SEED)

    lines = Builder()
    power_line(lines, [12.0, 0.0, 20.0], 180.0, spans=4)               # along -z at x = 12
    power_line(lines, [-30.0, 0.0, 10.0], 180.0 - 55.0, spans=3)       # crossing at 35 degrees
    fences = Builder()
    chain_link(fences, [-4.0, 0.0, 8.0], [-4.0, 0.0, -52.0])
    picket_fence(fences, [-3.0, 0.0, -2.0], [30.0, 0.0, -2.0])
    blades = Builder()
    grass(blades, rng, 6000, [-1.0, 0.0, 7.0], [12.0, 10.0])

    for name, b, what in (("city_wires_lines", lines, "boxes"), ("city_wires_fences", fences, "boxes"),
                          ("city_wires_grass", blades, "blades")):
        mesh = b.mesh()
        data = gz(ply_bytes(mesh, f"generated by shadowlab experiments/make_city_wires.py (seed {SEED}); MIT"))
        path = args.out / f"{name}.ply.gz"
        path.write_bytes(data)
        print(f"{path.name}: {len(mesh.faces)} triangles, {len(mesh.vertices)} vertices, {b.parts} {what}, "
              f"bounds {np.round(mesh.bounds, 3).tolist()}, {len(data)} bytes, SHA-256 {sha256(data)}")


if __name__ == "__main__":
    main()
