"""How the real meshes shipped in ``shadowlab/scenes/meshes/*.ply.gz`` were made (one-off).

Run it again to reproduce them byte for byte from the Debian package they come from (it needs
only the standard library, numpy and trimesh, all runtime dependencies already; nothing here is
imported by the package)::

    python experiments/prepare_meshes.py --deb libcgal-demo_5.5.1-2_all.deb [--out shadowlab/scenes/meshes]

``--deb`` is the Debian binary package ``libcgal-demo`` 5.5.1-2 (architecture ``all``), exactly
as published (SHA-256 checked below). The script reads it in memory, in pure Python: the ``.deb``
is an ``ar`` archive whose member ``data.tar.xz`` holds
``usr/share/doc/libcgal-dev/data.tar.gz`` (CGAL 5.5.1's data directory); from that it takes three
OFF files of ``data/meshes/`` (SHA-256 checked too; see shadowlab/scenes/meshes/README.md for
the terms, CC0 1.0):

====================== ===================== ====================================================
source                 output                what is done
====================== ===================== ====================================================
bunny00.off            bunny_closed.ply.gz   nothing (a closed, genus-0 remeshing of the Stanford
                                             bunny: 37,706 vertices, 75,408 triangles)
bunny00.off            bunny_open.ply.gz     the triangles of 5 patches of the base deleted
                                             (:func:`open_base`): 5 holes, one boundary loop each
knot1.off              knot.ply.gz           nothing (a trefoil-knotted tube, closed, genus 1;
                                             knot2.off is two rings, not a knot)
refined_elephant.off   elephant_dense.ply.gz nothing (88,928 triangles, closed, genus 3; not
                                             decimated: the source is already that dense)
====================== ===================== ====================================================

Every mesh is welded (exact duplicate positions merged; unreferenced vertices dropped), checked
to be wound counter-clockwise seen from outside (positive signed volume of the closed source;
flipped if not — none of these needs it), and its vertex positions stored as float32
little-endian binary PLY (``x y z`` only, faces as ``uchar count + int32 indices``), gzipped
with a zero timestamp and no file name, so the output is reproducible. Geometry is never moved,
scaled or rotated here: the scenes place the models with their ``scale`` / ``rotate`` /
``translate`` keys.

It prints, for each output: triangles, vertices, connected components, watertight, Euler
characteristic, boundary edges and loops, genus, signed volume, bounds, and the compressed size
(the figures in meshes/README.md and tests/scene/test_real_meshes.py).
"""
from __future__ import annotations

import argparse
import gzip
import hashlib
import io
import tarfile
from pathlib import Path

import numpy as np
import trimesh

ROOT = Path(__file__).resolve().parent.parent

DEB_SHA256 = "78b09b23d4d6d1bf15552a1060b419ab3fc09918486462faed197e5fc6ac3735"
DATA_TARBALL = "usr/share/doc/libcgal-dev/data.tar.gz"
SOURCES = {  # data/meshes/<name> in CGAL's data.tar.gz -> SHA-256
    "bunny00.off": "ab651cb04955c161efaeb079035a1e5e1f0e0d1f816a2df67beaea68f393ff2b",
    "knot1.off": "13d9d2f3459189630680dad6a3b5528d5cc794967b791580a0e1f6642903d030",
    "refined_elephant.off": "a170eed4ef33ef412a72b824d791f69ea59ee5f5a7c12dc1ae9077b6eb030650",
}

# open_base(): the holes' sizes (model units: bunny00 spans about 1 unit; its mean edge is
# 0.0081) and how far above the lowest point a deleted triangle may reach.
HOLE_RADII = (0.07, 0.05, 0.045, 0.04, 0.035)
HOLE_HEIGHT = 0.01
BASE_HEIGHT = 0.005  # the "base": vertices at most this far above the lowest point


def sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def ar_members(data: bytes) -> dict[str, bytes]:
    """The members of an ``ar`` archive (the format of a .deb): an 8-byte magic, then for each
    member a 60-byte header (name 16, mtime 12, uid 6, gid 6, mode 8, size 10, ``\\x60\\n``)
    and its data, padded to an even length."""
    if not data.startswith(b"!<arch>\n"):
        raise SystemExit("not an ar archive (a .deb)")
    members, pos = {}, 8
    while pos < len(data):
        header = data[pos:pos + 60]
        if len(header) < 60 or header[58:60] != b"`\n":
            raise SystemExit(f"bad ar member header at byte {pos}")
        name = header[:16].decode("ascii").strip().rstrip("/")
        size = int(header[48:58].decode("ascii").strip())
        members[name] = data[pos + 60:pos + 60 + size]
        pos += 60 + size + (size & 1)
    return members


def cgal_meshes(deb: Path) -> dict[str, bytes]:
    """The source OFF files, read from the .deb in memory, each checked against SOURCES."""
    raw = deb.read_bytes()
    if sha256(raw) != DEB_SHA256:
        raise SystemExit(f"{deb}: SHA-256 {sha256(raw)} is not that of libcgal-demo 5.5.1-2 ({DEB_SHA256})")
    members = ar_members(raw)
    data_name = next((n for n in members if n.startswith("data.tar")), None)
    if data_name is None:
        raise SystemExit(f"{deb}: no data.tar.* member (members: {sorted(members)})")
    with tarfile.open(fileobj=io.BytesIO(members[data_name]), mode="r:*") as outer:  # .xz here
        inner_bytes = outer.extractfile(outer.getmember("./" + DATA_TARBALL)).read()
    out = {}
    with tarfile.open(fileobj=io.BytesIO(inner_bytes), mode="r:gz") as inner:
        for name, digest in SOURCES.items():
            blob = inner.extractfile(inner.getmember(f"data/meshes/{name}")).read()
            if sha256(blob) != digest:
                raise SystemExit(f"data/meshes/{name}: SHA-256 {sha256(blob)}, expected {digest}")
            out[name] = blob
    return out


def welded(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """Exact duplicates merged and unreferenced vertices dropped, face order kept."""
    m = trimesh.Trimesh(np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces, np.int64),
                        process=False)
    m.merge_vertices()
    m.remove_unreferenced_vertices()
    return m


def read_off(data: bytes) -> trimesh.Trimesh:
    return welded(trimesh.load(io.BytesIO(data), file_type="off", force="mesh", process=False))


def outward(mesh: trimesh.Trimesh, name: str) -> trimesh.Trimesh:
    """``mesh`` (closed) wound counter-clockwise seen from outside: flipped if its signed volume
    is negative."""
    if not mesh.is_watertight or not mesh.is_winding_consistent:
        raise SystemExit(f"{name}: expected a closed, consistently wound mesh")
    if mesh.volume < 0:
        mesh = trimesh.Trimesh(mesh.vertices, mesh.faces[:, ::-1], process=False)
    assert mesh.volume > 0
    return mesh


def components(mesh: trimesh.Trimesh) -> int:
    return len(trimesh.graph.connected_components(mesh.face_adjacency, nodes=np.arange(len(mesh.faces))))


def boundary_loops(faces: np.ndarray) -> list[list[int]]:
    """Boundary loops as vertex lists, each in the direction of its faces' directed edges
    (every boundary vertex of these meshes has exactly one outgoing boundary edge)."""
    directed = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    _, inverse, counts = np.unique(np.sort(directed, axis=1), axis=0, return_inverse=True,
                                   return_counts=True)
    if counts.max() > 2:
        raise SystemExit("an edge with more than two faces: not edge-manifold")
    boundary = directed[counts[inverse.ravel()] == 1]
    nxt = {int(a): int(b) for a, b in boundary}
    if len(nxt) != len(boundary):
        raise SystemExit("a boundary vertex with two outgoing boundary edges: not handled")
    loops, seen = [], set()
    for start in sorted(nxt):
        if start in seen:
            continue
        loop, v = [], start
        while v not in seen:
            seen.add(v)
            loop.append(v)
            v = nxt[v]
        loops.append(loop)
    return loops


def open_base(mesh: trimesh.Trimesh) -> tuple[trimesh.Trimesh, str]:
    """The closed bunny with 5 holes cut in its base (y is up in bunny00.off), like the 5 holes
    in the base of the original scan, deterministically:

    * seeds: the lowest vertex, then 4 more by farthest-point sampling (in the x-z plane) of the
      base vertices (at most BASE_HEIGHT above the lowest point), each the base vertex farthest
      from the seeds so far (first index on ties);
    * hole k deletes every triangle whose three vertices lie within HOLE_RADII[k] of seed k in
      the x-z plane and at most HOLE_HEIGHT above the lowest point (nearly all face the floor);
    * then unreferenced vertices are dropped. It checks the result: edge-manifold, one
      connected component, every boundary vertex on exactly one loop, one loop per hole.
    """
    v, f = np.asarray(mesh.vertices), np.asarray(mesh.faces)
    y, xz = v[:, 1], v[:, [0, 2]]
    ymin = y.min()
    base = np.nonzero(y <= ymin + BASE_HEIGHT)[0]
    seeds = [int(np.argmin(y))]
    dist = np.linalg.norm(xz[base] - xz[seeds[0]], axis=1)
    while len(seeds) < len(HOLE_RADII):
        seeds.append(int(base[np.argmax(dist)]))
        dist = np.minimum(dist, np.linalg.norm(xz[base] - xz[seeds[-1]], axis=1))
    gone = np.zeros(len(f), bool)
    per_hole = []
    for seed, radius in zip(seeds, HOLE_RADII):
        near = (np.linalg.norm(xz - xz[seed], axis=1) < radius) & (y <= ymin + HOLE_HEIGHT)
        hole = near[f].all(axis=1)
        per_hole.append(int(hole.sum()))
        gone |= hole
    opened = welded(trimesh.Trimesh(v, f[~gone], process=False))
    loops = boundary_loops(np.asarray(opened.faces))
    if len(loops) != len(HOLE_RADII) or components(opened) != 1:
        raise SystemExit(f"open_base: {len(loops)} loops, {components(opened)} components")
    note = (f"seeds (x, z) {np.round(xz[seeds], 4).tolist()}; triangles deleted per hole {per_hole} "
            f"(total {int(gone.sum())}); vertices dropped {len(v) - len(opened.vertices)}; "
            f"loop lengths {sorted((len(l) for l in loops), reverse=True)}")
    return opened, note


def ply_bytes(mesh: trimesh.Trimesh, comment: str) -> bytes:
    """Binary little-endian PLY: float32 x y z, faces as uchar count + int32 indices."""
    v = np.ascontiguousarray(mesh.vertices, dtype="<f4")
    f = np.asarray(mesh.faces, dtype=np.int64)
    if f.min() < 0 or f.max() >= len(v) or f.max() > np.iinfo(np.int32).max:
        raise SystemExit("face index out of range")
    header = (f"ply\nformat binary_little_endian 1.0\ncomment {comment}\n"
              f"element vertex {len(v)}\nproperty float x\nproperty float y\nproperty float z\n"
              f"element face {len(f)}\nproperty list uchar int vertex_indices\nend_header\n")
    rec = np.empty(len(f), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    rec["n"], rec["i"] = 3, f
    return header.encode("ascii") + v.tobytes() + rec.tobytes()


def gz(data: bytes) -> bytes:
    buf = io.BytesIO()
    with gzip.GzipFile(fileobj=buf, mode="wb", compresslevel=9, mtime=0, filename="") as fh:
        fh.write(data)
    return buf.getvalue()


def describe(mesh: trimesh.Trimesh) -> str:
    loops = boundary_loops(np.asarray(mesh.faces))
    chi = int(mesh.euler_number)
    # connected orientable surface: chi = 2 - 2g - b (b boundary loops)
    genus = (2 - chi - len(loops)) // 2
    return (f"{len(mesh.faces)} triangles, {len(mesh.vertices)} vertices, {components(mesh)} component(s), "
            f"watertight={mesh.is_watertight}, winding consistent={mesh.is_winding_consistent}, "
            f"Euler characteristic={chi}, boundary edges={sum(len(l) for l in loops)} in {len(loops)} loops, "
            f"genus={genus}, signed volume={'n/a (open)' if loops else f'{mesh.volume:.6g}'}, "
            f"bounds={np.round(mesh.bounds, 5).tolist()}")


def write_outputs(outputs: dict, out: Path, describe_mesh) -> None:
    """Write each ``name: (mesh, comment)`` of ``outputs`` as ``out/<name>.ply.gz`` (:func:`ply_bytes`,
    :func:`gz`), read it back exactly as the scene loader does and print its size, SHA-256 and
    ``describe_mesh(mesh)``; then the total (also prepare_city.py's writer)."""
    total = 0
    for name, (mesh, comment) in outputs.items():
        data = gz(ply_bytes(mesh, comment))
        path = out / f"{name}.ply.gz"
        path.write_bytes(data)
        total += len(data)
        back = welded(trimesh.load(io.BytesIO(gzip.decompress(data)), file_type="ply", force="mesh",
                                   process=False))
        print(f"{path.name}: {len(data)} bytes, SHA-256 {sha256(data)}; {describe_mesh(back)}")
    print(f"total {total} bytes")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--deb", type=Path, required=True, help="libcgal-demo_5.5.1-2_all.deb")
    ap.add_argument("--out", type=Path, default=ROOT / "shadowlab/scenes/meshes")
    args = ap.parse_args()

    src = cgal_meshes(args.deb)
    for name, blob in src.items():
        print(f"source data/meshes/{name}: {len(blob)} bytes, SHA-256 {sha256(blob)}")
    bunny = outward(read_off(src["bunny00.off"]), "bunny00.off")
    bunny_open, note = open_base(bunny)
    print(f"bunny_open: {note}")
    tag = "(Debian libcgal-demo 5.5.1-2), CC0 1.0; shadowlab experiments/prepare_meshes.py"
    outputs = {
        "bunny_closed": (bunny, f"CGAL 5.5.1 data/meshes/bunny00.off, unchanged {tag}"),
        "bunny_open": (bunny_open, f"CGAL 5.5.1 data/meshes/bunny00.off, 5 holes cut in the base {tag}"),
        "knot": (outward(read_off(src["knot1.off"]), "knot1.off"),
                 f"CGAL 5.5.1 data/meshes/knot1.off, unchanged {tag}"),
        "elephant_dense": (outward(read_off(src["refined_elephant.off"]), "refined_elephant.off"),
                           f"CGAL 5.5.1 data/meshes/refined_elephant.off, unchanged {tag}"),
    }
    write_outputs(outputs, args.out, describe)


if __name__ == "__main__":
    main()
