"""Penumbra wedges: soft shadow volumes from a rectangular area light.

Assarsson & Akenine-Möller, "A Geometry-based Soft Shadow Volume Algorithm using Graphics
Hardware", SIGGRAPH 2003; Assarsson, Dougherty, Mounier & Akenine-Möller, "An optimized soft
shadow volume algorithm with real-time performance", Graphics Hardware 2003.

1. The hard shadow from the light's centre: the stencil shadow volumes of
   :class:`~shadowlab.techniques.volumes.shadow_volume.ShadowVolume` (its planning, z-pass / z-fail /
   auto counting and far-plane modes, CPU silhouettes), counted in the G-buffer's stencil.
2. One wedge per silhouette edge (the silhouette seen from the light's centre, the same edges
   the hard volume extrudes): a conservative convex hull of every point from which the edge,
   projected onto the light, can meet it (:func:`wedge_hulls`). Its back faces are rasterised
   with additive blending into a float target; each fragment reads its pixel's surface point P
   and adds the signed fraction of the light that the edge's projection from P moves across the
   centre's decision (``shadowlab/techniques/volumes/penumbra_wedges.glsl``): the light inside the cone from the
   centre through the clipped projected edge and beyond it — the paper's "area between the
   projected edge and the centre".
3. V = V_hard + Σ wedges, clamped to [0, 1] (``clamp=false``: the raw sum, to show how far the
   approximation leaves [0, 1]).

What is exact and what is not. For a single caster whose silhouette is the same from every
point of the light, V is exact (the signed crossings of a segment from the centre to a light
point x count [centre in S] − [x in S] for the projected silhouette S; integrated over the
light it is the formula above). The two known approximations:

- *Occlusion added per edge* (docs/hard-cases.md SS1; Forest, Barthe & Paulin 2006): with two casters
  the wedges subtract each caster's covered area separately, so where their projections on the
  light overlap the light is hidden twice — too dark (clamped at 0) — or, inside both hard
  shadows, given back twice — too bright.
- *Single silhouette*: the silhouette is taken from the light's centre only; where another light
  point sees other edges (a box's sides, a cylinder), the wedges miss or add area (Assarsson &
  Akenine-Möller 2003 name it among their approximations). ``single_silhouette=false`` corrects
  it per pixel: every edge of a closed manifold caster that is a silhouette from some point of
  the light gets a wedge (:func:`potential_silhouettes`), and a fragment counts it only where it
  is a silhouette seen from P — the projection of a closed caster from P is bounded by P's own
  silhouette (Laine et al., "Soft Shadow Volumes for Ray Tracing", SIGGRAPH 2005, §3) — directed
  by its face turned away from P. Exact for one closed convex caster; more wedges (the
  cylinder's sides), more fill.

The receiver's horizon (light below P's tangent plane, occluded in the truth) is not in the
paper; ``horizon=true`` treats the tangent plane as one more occluder in the same additive
scheme, which comes to subtracting the light's fraction below it (shadowlab/techniques/volumes/penumbra_wedges_combine.glsl).
Lights: rect only (its corners bound the wedges and its square is what the fragments clip);
disc and sphere lights raise :class:`TechniqueError`.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from ...gpu import gl, glstate, programs, targets
from ...geometry import adjacency as adj
from ...gpu.glstate import PassState, Stencil
from ...scene.area_lights import RectLight
from ..base import FIRST, SUM, Param, PlotStyle, TechniqueError
from .shadow_volume import ShadowVolume

#: Edges above this height below the light's plane (× the scene's extent) are cut off before
#: their wedge is built: a part above the plane cannot hide the light from the emitting side,
#: and the wedge's extrusion, reach / height, stays finite.
MIN_EDGE_HEIGHT = 1e-4
#: The shortest extrusion (× the edge's distance to the light's plane) of an edge below every
#: receiver: its hull stays a solid Qhull can build, and covers nothing a pixel needs.
MIN_EXTRUSION = 1e-4
#: Wedges end this fraction below the deepest scene point (height below the light's plane),
#: so that every receiver lies strictly inside the hull's far end.
DEPTH_MARGIN = 1e-2
#: The fragment stage cuts each edge to heights [m·h_P, (1 − m)·h_P] between the light's plane and
#: P's parallel plane (central projection is only defined strictly between them; the exact
#: oracle's slab, tests/soft_oracle.py). Float32: well above its rounding, far below any gap.
SLAB_MARGIN = 1e-4
#: An edge whose ends both lie within this × their distance from P of P's tangent plane is taken
#: to lie in it and adds nothing (float32 G-buffer points of a plane stray ~1e-7 relative).
COPLANAR_TOLERANCE = 1e-4
#: Floats per wedge vertex: hull corner, edge start, edge end (world), the planes (n, n·v) of the
#: faces that walk the edge a → b and b → a.
VERTEX_FLOATS = 17
#: Planes that make every point "see" the face walking b → a and not the one walking a → b: the
#: fragment stage then keeps the edge's direction a → b (the centre's silhouette, as given).
FIXED_PLANES = np.array([[0.0, 0.0, 0.0, 1.0], [0.0, 0.0, 0.0, -1.0]])


def wedge_hulls(a: np.ndarray, b: np.ndarray, corners: np.ndarray, centre: np.ndarray, normal: np.ndarray,
                extent: float, depth: float, planes: np.ndarray | None = None) -> tuple[np.ndarray, int]:
    """Triangles of the wedges of the directed edges a → b (K, 3) each, float32 (3·T, 17): per
    vertex its hull corner, the edge's two ends (what the fragment stage projects) and the planes
    (K, 2, 4) of its faces (:data:`FIXED_PLANES` when not given: the direction a → b kept); and
    how many wedges were made. Each wedge is the convex hull, faces wound counter-clockwise seen
    from outside, of the edge and its extrusions away from the light's four ``corners`` (4, 3)
    (``normal``: unit, towards the emitting side; ``extent``: the scene's size; ``depth``: the
    greatest height below the light's plane of any receiver).

    Why it is conservative: a point P sees the edge's projection meet the light when
    P = e + t·(e − x) for an edge point e = λa + (1−λ)b, a light point x = Σ μ_k x_k and t ≥ 0;
    then P = λ Σ μ_k (a + t(a − x_k)) + (1−λ) Σ μ_k (b + t(b − x_k)), a convex combination of
    the extrusions at one t. P's height below the light's plane is h_P = (1 + t)·h_e (x is on
    the plane), so every P no deeper than ``depth`` has t ≤ depth / min(h_a, h_b) − 1: extruding
    that far (and DEPTH_MARGIN more) covers them all, and the hull ends just below the deepest
    receiver instead of far beyond it (less fill: its back faces cover fewer pixels)."""
    a, b = np.asarray(a, np.float64).reshape(-1, 3), np.asarray(b, np.float64).reshape(-1, 3)
    if planes is None:
        planes = np.broadcast_to(FIXED_PLANES, (len(a), 2, 4))
    h_min = MIN_EDGE_HEIGHT * extent
    ha, hb = (a - centre) @ normal, (b - centre) @ normal
    # Cut each edge to h >= h_min (the part nearer the light than that, or beyond it, is dropped).
    lo, hi = np.minimum(ha, hb), np.maximum(ha, hb)
    keep = hi > h_min
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(hb != ha, (h_min - ha) / (hb - ha), 0.0)
    ca, cb = a.copy(), b.copy()
    cut_a = keep & (ha < h_min)
    cut_b = keep & (hb < h_min)
    ca[cut_a] = a[cut_a] + t[cut_a, None] * (b[cut_a] - a[cut_a])
    cb[cut_b] = a[cut_b] + t[cut_b, None] * (b[cut_b] - a[cut_b])
    tris, made = [], 0
    for k in np.flatnonzero(keep):
        ea, eb = ca[k], cb[k]
        if not np.linalg.norm(eb - ea) > 1e-9 * extent:
            continue
        # t at which the cut edge's highest end (lowest height h) reaches the deepest receiver
        ext = max(depth / max(lo[k], h_min) - 1.0, MIN_EXTRUSION) * (1.0 + DEPTH_MARGIN)
        pts = np.concatenate([[ea, eb], ea + ext * (ea - corners), eb + ext * (eb - corners)])
        try:
            hull = ConvexHull(pts)
        except QhullError:  # flat (an edge in a plane through the light's edge): joggle it
            hull = ConvexHull(pts, qhull_options="QJ")
        simp = hull.simplices.copy()
        p0, p1, p2 = pts[simp[:, 0]], pts[simp[:, 1]], pts[simp[:, 2]]
        inward = np.einsum("ij,ij->i", np.cross(p1 - p0, p2 - p0), hull.equations[:, :3]) < 0
        simp[inward] = simp[inward][:, ::-1]
        verts = np.empty((len(simp) * 3, VERTEX_FLOATS), np.float64)
        verts[:, :3] = pts[simp.ravel()]
        verts[:, 3:6] = a[k]
        verts[:, 6:9] = b[k]
        verts[:, 9:17] = planes[k].ravel()
        tris.append(verts)
        made += 1
    out = np.concatenate(tris) if tris else np.zeros((0, VERTEX_FLOATS))
    return out.astype(np.float32), made


def potential_silhouettes(table, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For a closed, consistently wound manifold mesh (an :class:`~shadowlab.geometry.adjacency.
    EdgeTable`): the edges that are a silhouette from some point of a convex light whose corners
    and centre are ``points`` (M, 3) — an edge is a silhouette from x when its two faces face x
    differently, so its status can change over the light only where one of its faces' planes
    crosses the light (a face's facing differs between two corners), and is constant (that of any
    corner) otherwise. Returns their ends a, b (K, 3) as stored (low, high vertex index) and the
    planes (K, 2, 4) (normal, normal·v0) of the face walking a → b and of the face walking b → a."""
    plus = np.empty(len(table.edges), np.int64)
    minus = np.empty(len(table.edges), np.int64)
    up = table.inc_sign > 0
    plus[table.inc_edge[up]] = table.inc_face[up]
    minus[table.inc_edge[~up]] = table.inc_face[~up]
    facing = table.normals @ np.asarray(points, np.float64).T - table.plane_d[:, None] > 0  # (F, M)
    fp, fm = facing[plus], facing[minus]
    potential = (fp != fm).any(axis=1) | (fp != fp[:, :1]).any(axis=1) | (fm != fm[:, :1]).any(axis=1)
    keep = np.flatnonzero(potential)
    planes = np.stack([np.concatenate([table.normals[f], table.plane_d[f, None]], axis=1)
                       for f in (plus[keep], minus[keep])], axis=1)
    e = table.edges[keep]
    return table.vertices[e[:, 0]], table.vertices[e[:, 1]], planes


def light_dual_basis(light: RectLight) -> tuple[np.ndarray, np.ndarray]:
    """(du, dv) (3,) each: the dual basis of the rect's full edges u, v in their plane, so that a
    point x of the plane is centre + s·u + t·v with s = (x − centre)·du, t = (x − centre)·dv
    (the light is s, t ∈ [−½, ½]; the edges need not be perpendicular)."""
    m = np.stack([np.asarray(light.u, np.float64), np.asarray(light.v, np.float64)], axis=1)  # (3, 2)
    dual = np.linalg.solve(m.T @ m, m.T)  # (2, 3)
    return dual[0], dual[1]


class PenumbraWedges(ShadowVolume):
    """Soft shadow volumes: the hard stencil volume from the light's centre plus one penumbra
    wedge per silhouette edge, accumulating signed light fractions in a float target."""

    name = "penumbra_wedges"
    summary = "penumbra wedges / soft shadow volumes (Assarsson & Akenine-Möller 2003): hard volume + per-edge wedges"
    PARAMS = {
        **{k: p for k, p in ShadowVolume.PARAMS.items() if k not in ("light_samples", "silhouette")},
        "clamp": Param(True, "clamp V_hard + Σ wedges to [0, 1] (the paper); false: the raw sum, which "
                             "leaves [0, 1] where casters' penumbrae overlap"),
        "single_silhouette": Param(True, "true: the silhouette seen from the light's centre (the paper); false: "
                                         "per-pixel correction — every edge that is a silhouette from some light "
                                         "point gets a wedge, and counts at P only if it is a silhouette seen from "
                                         "P, directed by its face turned away from P (closed manifold casters; "
                                         "others keep the centre's silhouette)"),
        "horizon": Param(False, "subtract the light's fraction below the receiver's tangent plane (not in the "
                                "paper; the truth counts it as occluded): the tangent plane as one more occluder "
                                "in the same additive scheme"),
    }
    #: The wedges need the silhouette edges on the CPU; the hard volume takes them from there too.
    silhouette = "cpu"
    LIGHT_SAMPLED = False
    LIGHTS = frozenset({"area"})
    PASSES = ("silhouette", "volume", "caps", "wedges", "combine")
    STYLE = PlotStyle("#e377c2", "d")
    STATS = {**ShadowVolume.STATS, "wedges": SUM, "wedge_triangles": SUM, "wedge_fragments": SUM,
             "wedge_fill_per_pixel": SUM, "outside_unit_share": FIRST}
    #: The wedge and combine passes read each pixel's surface point and normal (units 0 and 1);
    #: the hard volume's stencil counts borrow the frame's depth-stencil (``WRITES``, inherited).
    READS = frozenset({"position", "normal"})

    def setup(self, frame, slot) -> None:
        """The hard volume's setup (programs, buffers, depth pre-pass), then the wedge and
        combine programs, the wedges' float target and the light's frame."""
        light = slot.light
        if not isinstance(light, RectLight):
            raise TechniqueError(f"{self.name}: the wedges clip against a rectangle; a {light.shape} light is "
                                 f"not supported (rect lights only)")
        super().setup(frame, slot)
        self.centre = np.asarray(light.position, np.float64)
        self.normal = np.asarray(light.normal, np.float64)
        self.corners = light.corners()
        du, dv = light_dual_basis(light)
        self.wedge_prog = self.program("penumbra_wedges.glsl")
        self.wedge_prog["u_view"].write(programs.mat_bytes(frame.view))
        self.wedge_prog["u_proj"].write(programs.mat_bytes(self.proj))  # the depth pre-pass's projection
        common = {"u_light_centre": tuple(self.centre), "u_light_normal": tuple(self.normal)}
        programs.set_uniforms(self.wedge_prog, {**common, "u_light_du": tuple(du), "u_light_dv": tuple(dv),
                                          "u_slab_margin": SLAB_MARGIN, "u_coplanar": COPLANAR_TOLERANCE})
        self.combine_prog = self.program("penumbra_wedges_combine.glsl")
        programs.set_uniforms(self.combine_prog, {**common, "u_wedges": 2, "u_clamp": bool(self.clamp),
                                            "u_horizon": bool(self.horizon), "u_light_u": tuple(map(float, light.u)),
                                            "u_light_v": tuple(map(float, light.v)),
                                            "u_eye": tuple(map(float, frame.camera.eye))})
        self.combine_quad = self.fullscreen_quad(self.combine_prog)
        # The wedges' sum, drawn with the hard volume's depth pre-pass as its depth buffer.
        size = (frame.width, frame.height)
        self.acc_tex = self.own(frame.ctx.texture(size, 1, dtype="f4"))
        self.acc_fbo = self.own(targets.ScreenTarget.create(size, [self.acc_tex],
                                                            share_depth_stencil=frame.depth_stencil_for(self)))
        self.wedge_buffers: dict = {}
        self.extent = frame.scene.extent()
        corners = np.stack(np.meshgrid(*frame.scene.bounds().T, indexing="ij"), -1).reshape(-1, 3)
        self.depth = float(np.max((corners - self.centre) @ self.normal))

    def wedge_geometry(self) -> tuple[np.ndarray, int]:
        """The wedges of every caster's silhouette edges seen from the light's centre (the edges
        the hard volume extrudes, with their multiplicities), as :func:`wedge_hulls`; with
        ``single_silhouette=false``, a closed manifold caster's potential silhouette edges
        (:func:`potential_silhouettes`) instead, with their faces' planes for the per-pixel test."""
        a, b, planes = [], [], []
        points = np.concatenate([self.corners, self.centre[None]])
        for p in self.plans:
            t = p.table
            if not self.single_silhouette and not p.two_sided and t.manifold:
                pa, pb, pl = potential_silhouettes(t, points)
                a.append(pa)
                b.append(pb)
                planes.append(pl)
                continue
            sil = adj.silhouette_edges(t, adj.facing(t, self.light), p.two_sided)
            a.append(t.vertices[sil[:, 0]])
            b.append(t.vertices[sil[:, 1]])
            planes.append(np.broadcast_to(FIXED_PLANES, (len(sil), 2, 4)))
        if not a:
            return np.zeros((0, VERTEX_FLOATS), np.float32), 0
        return wedge_hulls(np.concatenate(a), np.concatenate(b), self.corners, self.centre, self.normal, self.extent,
                           self.depth, np.concatenate(planes))

    def _draw_wedges(self) -> None:
        """The wedges' back faces (one fragment per pixel whose view ray crosses a hull)."""
        verts = self._wedges
        if not len(verts):
            return
        vbo, vao = self._dynamic(self.wedge_buffers, "wedges", verts.nbytes, lambda buf: self.frame.ctx.vertex_array(
            self.wedge_prog, [(buf, "3f 3f 3f 4f 4f", "in_pos", "in_edge_a", "in_edge_b", "in_plane_ab",
                                "in_plane_ba")]))
        vbo.write(verts.tobytes())
        vao.render(vertices=len(verts))

    def _wedge_state(self) -> PassState:
        """Back faces only (cull the front: each ray leaves a convex hull once), additive
        blending into the float target, and the depth test ">=" against the depth pre-pass: a
        ray that leaves the hull in front of its pixel's surface point has that point outside
        the wedge (R_e empty, nothing to add), so early depth testing drops it (the paper's
        culling, Assarsson & Akenine-Möller 2003 §4). Depth clamp: the hull's far end may pass a
        finite far plane (``far=clamp`` / ``finite``); clamped to 1 it still passes the test, and
        the part before the near plane, no longer clipped, gets depth 0 and fails it (a ray
        leaving the hull there has its surface point outside the wedge)."""
        return PassState(depth_test=True, depth_func=">=", depth_write=False, depth_clamp=True, cull="front",
                         blend=("one", "one"))

    def render(self) -> None:
        """Silhouettes and wedges (CPU), the hard volume's stencil counts, the wedges' sum, then
        V = V_hard + Σ, clamped."""
        from OpenGL import GL

        frame = self.frame
        with self.timed_pass("silhouette", cpu=True):
            self._geometry = self.cpu_volume_geometry()
            self._wedges, self._wedge_count = self.wedge_geometry()
        with self.timed_pass("volume"):  # the stencil clear is the volume pass's first step
            self.target.use()
            glstate.apply(self._volume_state(zfail=True))
            GL.glClearStencil(0)
            GL.glClear(GL.GL_STENCIL_BUFFER_BIT)
        for zfail, geometry in self._geometry.items():
            glstate.apply(self._volume_state(zfail))
            self._draw_volumes(zfail, *geometry)
        with self.timed_pass("wedges"):
            self.acc_fbo.use()
            frame.ctx.viewport = (0, 0, frame.width, frame.height)
            glstate.apply(self._wedge_state())
            GL.glClearBufferfv(GL.GL_COLOR, 0, (0.0, 0.0, 0.0, 0.0))
            self.bind_gbuffer(self.wedge_prog)
            self._draw_wedges()
        with self.timed_pass("combine"):
            # V_hard is 1 where the centre's count is 0, else 0: one draw under each stencil test.
            self.target.use()
            frame.ctx.viewport = (0, 0, frame.width, frame.height)
            glstate.apply(PassState(depth_write=False, stencil=Stencil("==", 0, 0xFF)))
            self.bind_gbuffer(self.combine_prog)
            self.acc_tex.use(2)
            self.combine_prog["u_hard"].value = 1.0
            self.combine_quad.render()
            glstate.set_stencil(Stencil("!=", 0, 0xFF))
            self.combine_prog["u_hard"].value = 0.0
            self.combine_quad.render()

    def work(self, counted: dict, stats: dict) -> dict:
        """The hard volume's stencil updates and CPU triangles (:meth:`ShadowVolume.work`), and
        texture taps: a wedge fragment reads its surface point and normal, a combine fragment its
        point and the wedges' sum, and its normal with ``horizon=true`` (the fragments themselves
        are counted by the pipeline)."""
        out = super().work(counted, stats)
        out.update(self.taps_work(counted, {"wedges": 2, "combine": 3 if self.horizon else 2}))
        return out

    def stats(self) -> dict:
        """The hard volume's figures, the wedges made and their triangles, the fragments they
        drew (an untimed extra draw under a samples query), and the share of evaluated pixels
        whose V left [0, 1] before clamping (``clamp=false`` reads its own output)."""
        out = super().stats()
        acc_fbo = self.acc_fbo
        acc_fbo.use()
        glstate.apply(self._wedge_state())
        q = gl.query("penumbra_wedges fill", samples=True)
        with self.timed_pass("wedges"):
            with q:
                self._draw_wedges()
        # The draw above added the wedges once more; the sum is read from visibility, not here.
        out["wedges"] = int(self._wedge_count)
        out["wedge_triangles"] = len(self._wedges) // 3
        out["wedge_fragments"] = int(q.samples)
        out["wedge_fill_per_pixel"] = out["wedge_fragments"] / (self.frame.width * self.frame.height)
        vis, mask = self.visibility(), self.frame.evaluated_image(self.slot)
        out["outside_unit_share"] = None if self.clamp else float(((vis < 0) | (vis > 1))[mask].mean())
        return out
