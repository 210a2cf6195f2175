"""Edge adjacency, silhouettes and multiplicities (no GL)."""
from __future__ import annotations

import numpy as np
import trimesh

from shadowlab.geometry import adjacency as adj
from shadowlab.scene.lights import DirectionalLight, PointLight


def cube_table():
    box = trimesh.creation.box()
    return adj.edge_table(box.vertices, box.faces)


def test_cube_silhouette_is_six_edges_in_general_position():
    t = cube_table()
    assert t.closed and len(t.edges) == 18
    for light in (PointLight(position=np.array([3.1, 2.3, 1.7])),
                  DirectionalLight(direction=-np.array([0.5, 0.7, 0.3]) / np.linalg.norm([0.5, 0.7, 0.3]))):
        lit = adj.facing(t, light)
        assert lit.sum() == 6  # three faces of the cube, two triangles each
        sil = adj.silhouette_edges(t, lit, two_sided=False)
        assert len(sil) == 6
        # The silhouette is a closed loop: every vertex starts one edge and ends one.
        assert sorted(sil[:, 0]) == sorted(sil[:, 1])


def test_face_on_light_gives_four_edges():
    t = cube_table()
    lit = adj.facing(t, PointLight(position=np.array([0.0, 5.0, 0.0])))
    assert len(adj.silhouette_edges(t, lit, two_sided=False)) == 4


def test_open_quad_extrudes_its_boundary_from_either_side():
    quad = trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [1, 0, 1], [0, 0, 1]], [[0, 2, 1], [0, 3, 2]], process=False)
    t = adj.edge_table(quad.vertices, quad.faces)
    assert not t.closed and t.boundary_edges == 4 and t.manifold
    for y in (3.0, -3.0):  # lit from its front, then from its back
        lit = adj.facing(t, PointLight(position=np.array([0.3, y, 0.4])))
        sil = adj.silhouette_edges(t, lit, two_sided=True)
        assert len(sil) == 4 and sorted(sil[:, 0]) == sorted(sil[:, 1])


def test_nonmanifold_and_inconsistent_are_detected():
    # three triangles on one edge
    v = np.array([[0, 0, 0], [1, 0, 0], [0.5, 1, 0], [0.5, -1, 0], [0.5, 0, 1.0]])
    t = adj.edge_table(v, np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]]))
    assert t.nonmanifold_edges == 1 and not t.manifold and not t.closed
    assert "non-manifold" in t.describe()
    box = trimesh.creation.box()
    faces = box.faces.copy()
    faces[0] = faces[0][::-1]
    t2 = adj.edge_table(box.vertices, faces)
    assert t2.inconsistent_edges == 3 and not t2.closed


def test_adjacency_indices_name_the_neighbours_third_vertex():
    box = trimesh.creation.box()
    t = adj.edge_table(box.vertices, box.faces)
    idx = t.adjacency_indices()
    assert idx.shape == (12, 6)
    for f, row in enumerate(idx):
        tri = row[0::2]
        for k in range(3):
            a, b, opp = tri[k], tri[(k + 1) % 3], row[2 * k + 1]
            # some other face holds (b, a, opp) in its cyclic order
            found = any(set(box.faces[g]) == {a, b, opp} and g != f for g in range(12))
            assert found


def test_light_inside_closed_mesh():
    t = cube_table()
    assert adj.light_inside_closed_mesh(t, np.array([0.1, 0.2, -0.1]))
    assert not adj.light_inside_closed_mesh(t, np.array([2.0, 0.2, -0.1]))


def test_degenerate_faces_never_face_the_light():
    v = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0]])
    t = adj.edge_table(v, np.array([[0, 1, 2], [0, 1, 3]]))
    assert t.degenerate_faces == 1
    lit = adj.facing(t, PointLight(position=np.array([0.2, 0.2, 5.0])))
    assert lit.tolist() == [False, True]


def test_silhouette_equals_brute_force_on_a_sphere():
    """On a 20480-face sphere and a point light, the silhouette is exactly the set of edges
    between a lit and an unlit face — found here with a dictionary of edges and a loop — each
    walked in the direction its lit face walks it, and it forms closed loops."""
    sphere = trimesh.creation.icosphere(subdivisions=5)
    t = adj.edge_table(sphere.vertices, sphere.faces)
    light = np.array([3.0, 2.0, 1.0])
    sil = adj.silhouette_edges(t, adj.facing(t, PointLight(position=light)), two_sided=False)
    tri = sphere.vertices[sphere.faces]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    lit = np.einsum("ij,ij->i", n, light - tri[:, 0]) > 0
    faces_of: dict = {}
    for f, face in enumerate(sphere.faces):
        for k in range(3):
            a, b = int(face[k]), int(face[(k + 1) % 3])
            faces_of.setdefault((min(a, b), max(a, b)), []).append((f, a, b))
    expected = set()
    for incidences in faces_of.values():
        (f, a, b), (g, _, _) = incidences
        if lit[f] != lit[g]:
            expected.add((a, b) if lit[f] else (b, a))  # as the lit face walks it
    assert t.closed and len(expected) > 50
    assert set(map(tuple, sil.tolist())) == expected and len(sil) == len(expected)
    assert sorted(sil[:, 0]) == sorted(sil[:, 1])
