"""CC shadow volumes: stencil shadow volumes culled and clamped to the visible receivers (Lloyd,
Wendt, Govindaraju & Manocha, "CC Shadow Volumes", EGSR 2004).

The plain stencil volume (:mod:`shadowlab.techniques.volumes.shadow_volume`) rasterises every
caster's volume out to infinity, although the stencil only matters where a volume holds a point
that the camera sees. Lloyd et al. save that fill in two ways, per light and per frame:

- **Culling**: a caster whose volume holds no visible receiver changes no count that
  is read, so its volume is not drawn. Two tests, both conservative, in this order:

  * *view frustum*: the caster's bounding box swept away from the light (a convex body: the
    box and its copy pushed past the frustum, or scaled from a point light past it) misses the
    camera's frustum — shown by a separating axis (the faces of both bodies and the cross
    products of their edges: :func:`volumes_may_meet_frustum`);
  * *receivers*: Lloyd et al.'s receiver map. Every covered G-buffer point is projected into a
    coarse light-space grid (``grid`` texels a side) that keeps per texel the largest
    light-space key of its points — the depth along the light's direction for a light at
    infinity (one orthographic face over the scene's bounds), the distance to the light for a
    light at a position (six cube faces) — built on the GPU each frame by a compute pass
    (``shadowlab/techniques/volumes/cc_volume_receivers.glsl``, ``atomicMax`` on
    order-preserving bits) and read back. A point x lies in a caster's volume only if the
    segment from x to the light meets the caster, so x projects inside the caster's projected
    bounds and its key exceeds the key of the caster's nearest point; a caster is kept iff
    some texel overlapping its projected (grown) bounds holds a key at least the (grown) box's
    nearest key. Every point falls in exactly one texel, so a caster whose volume holds a
    visible point is never culled.

  Lloyd et al. also cull casters that lie wholly in the shadow of others, testing their bounds
  against a shadow map of the casters. That test is not left out by oversight: texel sampling
  is not conservative (a caster lit through a gap narrower than a texel would be culled and its
  shadow lost), and an exact version needs conservative rasterisation, which the lab's GL does
  not have. The receiver cull already drops the casters whose volumes hold nothing visible.

- **Clamping** (their "continuous clamping", by receiver bounds): each kept caster's volume is
  cut at the deepest visible receiver it can reach — D, the largest key in the texels of its
  footprint, plus margins — instead of running to infinity: silhouette vertices are pushed to
  the plane at depth D (light at infinity: the plane across the light's direction; light at a
  position: the plane z = D along the axis from the light to the box's centre, when the box lies
  wholly in front of the light across that axis; a box that does not is not clamped), and the
  volume is closed there by a far cap (the light-facing triangles pushed to the same plane,
  turned round; for two-sided casters also the others as stored — or, where its triangles would
  not fold over each other, the fan of triangles from one point of the plane over the clamped
  silhouette edges, which has the same boundary and so gives the same counts off the plane, with
  one triangle per silhouette edge instead of one per lit face). Far caps are drawn for z-pass
  as well as z-fail: a finite volume's far end can lie between the camera and a receiver. Every
  visible point of the infinite volume lies in front of that plane, so each visible point's
  count, and the mask, stays the plain volume's. A far cap is fill of its own: where it would
  cover more of the view than the sides it cuts off (compared as solid angles seen from the eye:
  a caster with nothing behind it, a wall of a room), the caster keeps its infinite volume
  (``clamps_declined``) — an estimate that only chooses between two exact geometries. Clamping
  by discrete depth intervals (Lloyd et al.'s "discrete clamping", several slabs per volume) is
  not done.

Exactness. The counts are decided by the depth buffer's points, not by the G-buffer's float32
positions the map holds, so every test runs with margins: boxes grow by g = 16·d²/n·2⁻²⁴ +
10⁻⁴·extent (d the farthest visible point from the eye, read from the map pass; n the near
plane; 2⁻²⁴ a 24-bit depth step — a window-depth step is d²/n·2⁻²⁴ along the ray), which
covers the depth quantisation of both the receivers and the volume faces and the float32
rounding of positions; a point within g of a volume lies in the volume of the box grown by g
(for a light at infinity by translation, for a point light by scaling towards the light). The
clamping plane lies g beyond the deepest key and g beyond the grown box. Clamped vertices are
computed in float64 per welded vertex (so every triangle that shares a vertex gets the same
float32 position) and drawn as surface points (w = 1) by the plain volume's own program, so the
near caps and the depth pre-pass still tie bit for bit. The clamped side quads lie on the
planes of the plain volume's but are rasterised from other far vertices: where a side meets a
receiver (a contact line) they may round differently, which the tests list.

Everything else is the plain volume's, inherited: per-caster z-pass/z-fail/auto (auto decides
on the unclamped volume, so it keeps z-fail wherever the plain volume takes it), the
infinite-far-plane projection, the two-sided scheme for open meshes, the depth pre-pass and its
tie rules. Silhouettes are extracted on the CPU only (``silhouette=cpu``): culling and clamping
rebuild each caster's volume geometry per frame, which the geometry-shader path cannot be told.
``stats()`` counts the volume fragments that are left with the plain volume's occlusion
queries, and what was culled and clamped.
"""
from __future__ import annotations

import numpy as np

from ...geometry import adjacency as adj
from ...geometry import transforms as tf
from ...gpu import programs
from ..base import FIRST, MAX, SUM, Param, PlotStyle, TuneRange
from .shadow_volume import ShadowVolume, _flagged, _triangle_indices, near_plane_quad, pack_volume_geometry

#: Invocations per side of a receiver-map work group (LOCAL_SIZE in cc_volume_receivers.glsl).
LOCAL_SIZE = 8
#: Pixels per side of the block one receiver-map invocation takes (BLOCK in the shader).
BLOCK = 4
#: Header slots of the receiver-map pass (HEADER_* in cc_volume_receivers.glsl).
HEADER_EYE_DISTANCE, HEADER_POINTS, HEADER_UNMAPPED = 0, 1, 2
HEADER_WORDS = 4
#: Depth-buffer steps of margin: a window-depth step of a 24-bit buffer is 2⁻²⁴, which moves a
#: point by d²/n·2⁻²⁴ along its ray; the receiver's and the volume face's roundings and the
#: interpolation of both fit well within this many steps.
DEPTH_STEPS = 16.0
#: Float32 rounding margin of positions (G-buffer, volume vertices, clip transforms), as a
#: fraction of the scene's extent (float32 rounding is about 6e-8 of a coordinate).
FLOAT_MARGIN = 1e-4
#: A clamped volume's far cap is the fan over its silhouette (one triangle per silhouette edge)
#: instead of its light-facing triangles where the fan's triangles cover at most this many times
#: the cap's net solid angle (they barely fold over each other).
FAN_SLACK = 1.05
#: Texel-space slack on the casters' texel ranges: the GPU computes a point's texel in float32.
TEXEL_SLACK = 0.01


class CCVolume(ShadowVolume):
    """Stencil shadow volumes culled (view frustum, receiver map) and clamped to the deepest
    visible receiver they can reach, per caster (module docstring)."""

    name = "cc_volume"
    summary = ("CC shadow volumes (Lloyd et al. 2004): volumes culled where they hold no visible receiver and "
               "clamped to the receivers' depth; shadow_volume's masks up to depth ties")
    PARAMS = {
        "cull": Param(True, "cull casters whose volume misses the view frustum or holds no point of the receiver map"),
        "clamp": Param(True, "clamp each kept volume at the deepest visible receiver in its footprint, closed by a "
                             "far cap, where the cap costs less than the sides it cuts (else: extruded to infinity "
                             "as shadow_volume)"),
        "grid": Param(256, "receiver-map texels per side (one orthographic face, or six cube faces for a light at a "
                           "position)", min=1, max=4096,
                      tune=TuneRange(16, 1024, log=True)),  # coarse maps cull less; fine maps cost read-back
        "mode": ShadowVolume.PARAMS["mode"],
        "silhouette": Param("cpu", "silhouette extraction: cpu only (culling and clamping rebuild the volume geometry "
                                   "on the CPU each frame; shadow_volume has the geometry-shader path)",
                            choices=("cpu",)),
        "far": ShadowVolume.PARAMS["far"],
    }
    PASSES = ("receivers", "cull", "silhouette", "volume", "caps", "count")
    READS = frozenset({"position"})  # the receiver-map pass reads the G-buffer's points
    STYLE = PlotStyle("#ff9896", "s")
    STATS = {**ShadowVolume.STATS, "casters_culled": SUM, "frustum_culled": SUM, "receiver_culled": SUM,
             "casters_kept": SUM, "casters_clamped": SUM, "clamps_declined": SUM, "fan_caps": SUM,
             "unbounded_casters": SUM, "culled_triangles": SUM, "pixel_ops": SUM, "receiver_map_bytes": MAX,
             "receiver_map_texels": FIRST, "receiver_map_filled": SUM}

    # ------------------------------------------------------------------ setup
    def setup(self, frame, slot) -> None:
        """The plain volume's setup (plans, programs, depth pre-pass), then the receiver map's
        program, buffers and light-space frame, and the casters' bounds."""
        super().setup(frame, slot)
        objs = frame.scene.objects
        self.boxes = np.stack([objs[p.index].bounds() for p in self.plans]) if self.plans else np.zeros((0, 2, 3))
        self.extent = float(frame.scene.extent())
        self.cube = not self.light.at_infinity
        self.faces = 6 if self.cube else 1
        self.needs_map = self.cull or self.clamp
        self._kept_plans = list(self.plans)
        self._clamp: dict[int, tuple] = {}
        self._counts = {"frustum": 0, "receivers": 0, "unbounded": 0}
        self._declined = self._fans = 0
        self.map_filled = 0
        if not self.needs_map:
            return
        ctx = frame.ctx
        self.map_prog = self.program("cc_volume_receivers.glsl", defines={"LOCAL_SIZE": LOCAL_SIZE, "BLOCK": BLOCK})
        uniforms = {"u_size": (frame.width, frame.height), "u_grid": self.grid, "u_cube": self.cube,
                    "u_eye": tuple(map(float, frame.camera.eye))}
        if self.cube:
            self.light_position = np.asarray(self.light.position, np.float64)
            uniforms["u_light_position"] = tuple(map(float, self.light_position))
        else:
            # An orthographic grid across the light over the scene's bounding box: every visible
            # point is a scene point, so it falls inside (up to rounding, clamped to the border).
            d = np.asarray(self.light.direction, np.float64)
            d = d / np.linalg.norm(d)
            view = tf.look_along(np.zeros(3), d)
            u_axis, v_axis = view[0, :3], view[1, :3]
            self.axes = np.stack([u_axis, v_axis, d])
            corners = _corners(np.asarray(frame.scene.bounds(), np.float64)[None])[0]
            proj = corners @ self.axes.T
            lo, hi = proj.min(axis=0), proj.max(axis=0)
            span = np.maximum(hi[:2] - lo[:2], 1e-9 * max(self.extent, 1e-9))
            self.origin = lo
            self.texels_per_unit = self.grid / span
            uniforms.update({"u_axis_u": tuple(map(float, u_axis)), "u_axis_v": tuple(map(float, v_axis)),
                             "u_axis_d": tuple(map(float, d)), "u_origin": tuple(map(float, lo)),
                             "u_texels_per_unit": tuple(map(float, self.texels_per_unit))})
        programs.set_uniforms(self.map_prog, uniforms)
        self.header_buf = self.own(ctx.buffer(reserve=4 * HEADER_WORDS))
        self.map_buf = self.own(ctx.buffer(reserve=4 * self.faces * self.grid * self.grid))

    # ------------------------------------------------------------------ per-frame work
    def render(self) -> None:
        """The receiver map (GPU, read back), the culling and clamping decisions (CPU), then the
        plain volume's passes over the kept, clamped volumes."""
        if self.needs_map:
            with self.timed_pass("receivers"):
                self._receiver_map()
        with self.timed_pass("cull", cpu=True):
            self._decide()
        super().render()

    def _receiver_map(self) -> None:
        """Build the receiver map on the GPU and read it back: ``self.map`` uint32 (faces, grid,
        grid), the largest key per texel as the shader encodes it (0 where empty), and the header."""
        ctx = self.frame.ctx
        self.header_buf.clear()
        self.map_buf.clear()
        self.header_buf.bind_to_storage_buffer(0)
        self.map_buf.bind_to_storage_buffer(1)
        self.bind_gbuffer(self.map_prog)
        span = LOCAL_SIZE * BLOCK
        self.map_prog.run(-(-self.frame.width // span), -(-self.frame.height // span))
        ctx.memory_barrier()
        header = np.frombuffer(self.header_buf.read(), np.uint32)
        # Kept as the encoded words: their unsigned order is the keys' order, so the footprints'
        # maxima are taken on them and only those are decoded (_decode).
        self.map = np.frombuffer(self.map_buf.read(), np.uint32).reshape(self.faces, self.grid, self.grid)
        self.map_filled = int(np.count_nonzero(self.map))
        self.eye_distance = float(header[HEADER_EYE_DISTANCE:HEADER_EYE_DISTANCE + 1].view(np.float32)[0])
        self.unmapped = int(header[HEADER_UNMAPPED])

    def margin(self) -> float:
        """g: how far every box grows and the clamping plane moves out (module docstring, exactness)."""
        n = float(self.frame.camera.near)
        return DEPTH_STEPS * self.eye_distance ** 2 / n * 2.0 ** -24 + FLOAT_MARGIN * self.extent

    def _decide(self) -> None:
        """Which casters are kept (``self._kept_plans``) and the clamping of each clamped one
        (``self._clamp``: plan index → (a point of its far plane, the plane's unit normal away
        from the light)), with counts of what was culled and what could not be bounded."""
        plans = self.plans
        self._counts = {"frustum": 0, "receivers": 0, "unbounded": 0}
        self._clamp = {}
        if not plans or not self.needs_map:
            self._kept_plans = list(plans)
            return
        if self.unmapped:  # a visible point at the light itself: no key bounds it
            note = (f"{self.unmapped} visible points lie at the light's position; culling and clamping are off "
                    f"for this light")
            if note not in self.notes:  # once, however many renders
                self.notes.append(note)
            self._kept_plans = list(plans)
            self._counts["unbounded"] = len(plans)
            return
        g = self.margin()
        boxes = self.boxes.copy()
        boxes[:, 0] -= g
        boxes[:, 1] += g
        keep = np.ones(len(plans), bool)
        if self.cull:
            keep = volumes_may_meet_frustum(boxes, frustum_corners(self.frame), self.light)
            self._counts["frustum"] = int(np.sum(~keep))
        deepest, nearest, farthest, inside = self._footprints(boxes, keep)
        kept = []
        for i, p in enumerate(plans):
            if not keep[i]:
                continue
            if inside[i]:  # the light inside the grown box: the volume is everywhere
                self._counts["unbounded"] += 1
                kept.append(p)
                continue
            if self.cull and not deepest[i] >= nearest[i]:
                self._counts["receivers"] += 1
                continue
            kept.append(p)
            if self.clamp:
                plane = self._clamp_plane(boxes[i], max(deepest[i] + g, farthest[i]) + g)
                if plane is None:
                    self._counts["unbounded"] += 1
                else:
                    self._clamp[p.index] = plane
        self._kept_plans = kept

    def _footprints(self, boxes: np.ndarray, wanted: np.ndarray) -> tuple:
        """Per box (K, 2, 3) — only where ``wanted`` — the deepest key in the texels its volume
        can reach (−inf if none), its nearest key, its farthest corner's key, and whether a point
        light lies inside it (then nothing bounds its volume)."""
        K = len(boxes)
        deepest = np.zeros(K, np.uint32)  # encoded, as the map's words (0: no point)
        corners = _corners(boxes)  # (K, 8, 3)
        if not self.cube:
            proj = corners @ self.axes.T  # (K, 8, 3): u, v, depth
            lo, hi = proj.min(axis=1), proj.max(axis=1)
            x0, x1 = self._texels(lo[:, 0], hi[:, 0], self.origin[0], self.texels_per_unit[0])
            y0, y1 = self._texels(lo[:, 1], hi[:, 1], self.origin[1], self.texels_per_unit[1])
            face = self.map[0]
            for i in np.flatnonzero(wanted):
                deepest[i] = face[y0[i]:y1[i] + 1, x0[i]:x1[i] + 1].max()
            return _decode(deepest), lo[:, 2] - self.origin[2], hi[:, 2] - self.origin[2], np.zeros(K, bool)
        L = self.light_position
        inside = np.all((boxes[:, 0] <= L) & (L <= boxes[:, 1]), axis=1)
        nearest = np.linalg.norm(np.clip(L, boxes[:, 0], boxes[:, 1]) - L, axis=1)
        rel = corners - L
        farthest = np.linalg.norm(rel, axis=2).max(axis=1)
        half = self.grid / 2.0
        for f in range(6):
            k, sign = f // 2, (1.0 if f % 2 == 0 else -1.0)
            z = sign * rel[:, :, k]  # (K, 8)
            reaches = wanted & ~inside & (z.max(axis=1) > 0.0)  # else behind the face's plane
            front = reaches & (z.min(axis=1) > 0.0)  # else it straddles the plane: the whole face
            others = [a for a in range(3) if a != k]
            with np.errstate(divide="ignore", invalid="ignore"):
                uv = rel[:, :, others] / z[:, :, None]
            lo, hi = uv.min(axis=1), uv.max(axis=1)
            x0, x1 = self._texels(lo[:, 0], hi[:, 0], -1.0, half)
            y0, y1 = self._texels(lo[:, 1], hi[:, 1], -1.0, half)
            off = (lo[:, 0] > 1.0) | (hi[:, 0] < -1.0) | (lo[:, 1] > 1.0) | (hi[:, 1] < -1.0)
            for i in np.flatnonzero(front & ~off):
                deepest[i] = max(deepest[i], self.map[f, y0[i]:y1[i] + 1, x0[i]:x1[i] + 1].max())
            straddle = reaches & ~front
            if straddle.any():
                deepest[straddle] = np.maximum(deepest[straddle], self.map[f].max())
        return _decode(deepest), nearest, farthest, inside

    def _texels(self, lo: np.ndarray, hi: np.ndarray, origin: float, per_unit: float) -> tuple:
        """The texel ranges [a, b] (int arrays, clamped to the grid, as the map pass clamps its
        points) that the coordinate intervals [lo, hi] overlap, with :data:`TEXEL_SLACK`."""
        with np.errstate(invalid="ignore"):
            a = np.clip(np.floor((lo - origin) * per_unit - TEXEL_SLACK), 0, self.grid - 1)
            b = np.clip(np.floor((hi - origin) * per_unit + TEXEL_SLACK), 0, self.grid - 1)
        return np.nan_to_num(a).astype(np.int64), np.nan_to_num(b, nan=self.grid - 1).astype(np.int64)

    def _clamp_plane(self, box: np.ndarray, level: float):
        """The far plane of a clamped volume as (point on it, unit normal pointing away from the
        light), at key ``level``; None where a point light's box is not wholly in front of the
        light across the axis to its centre (not clamped)."""
        if not self.cube:
            d = self.axes[2]
            return (self.origin[2] + level) * d, d
        L = self.light_position
        axis = box.mean(axis=0) - L
        axis = axis / np.linalg.norm(axis)
        if np.min((_corners(box[None])[0] - L) @ axis) <= 0.0:
            return None
        # Every point of the volume with |x − L| ≤ level has (x − L)·axis ≤ level.
        return L + level * axis, axis

    def _clamped(self, vertices: np.ndarray, plane) -> np.ndarray:
        """World float64 vertices (V, 3) pushed away from the light onto ``plane`` (each along
        its own ray from a point light, or along the direction of a light at infinity);
        elementwise arithmetic only, so a vertex's result does not depend on its neighbours."""
        point, normal = plane
        level = point[0] * normal[0] + point[1] * normal[1] + point[2] * normal[2]
        if not self.cube:
            depth = vertices[:, 0] * normal[0] + vertices[:, 1] * normal[1] + vertices[:, 2] * normal[2]
            return vertices + (level - depth)[:, None] * normal[None, :]
        L = self.light_position
        rel = vertices - L
        along = rel[:, 0] * normal[0] + rel[:, 1] * normal[1] + rel[:, 2] * normal[2]
        base = L[0] * normal[0] + L[1] * normal[1] + L[2] * normal[2]
        return L + rel * ((level - base) / along)[:, None]

    def cpu_volume_geometry(self) -> dict:
        """Per counting method of the kept casters (``zfail`` flag → arrays), as the plain
        volume's: volume vertices (sides, and the finite far caps of clamped casters, flagged
        as surface points), near-cap, flipped-cap and infinite far-cap triangle indices."""
        # Silhouettes of every kept caster, and the clamped silhouette vertices of the clamped
        # ones: each welded vertex clamped once, so shared edges stay watertight.
        shapes = []
        for p in self._kept_plans:
            t = p.table
            lit = adj.facing(t, self.light)
            sil = adj.silhouette_edges(t, lit, p.two_sided)
            faces_lit = np.flatnonzero(lit)
            faces_dark = np.flatnonzero(~lit) if p.two_sided else np.zeros(0, np.int64)
            plane = self._clamp.get(p.index)
            ends = None
            if plane is not None:
                used, where = np.unique(sil, return_inverse=True)
                ends = self._clamped(t.vertices[used], plane)[where.reshape(sil.shape)]  # (E, 2, 3)
            shapes.append((p, sil, faces_lit, faces_dark, ends))
        pays = self._clamps_pay([s for s in shapes if s[4] is not None])
        self._declined = self._fans = 0
        out = {}
        for zfail in [z for z in (False, True) if any(p.zfail == z for p in self._kept_plans)]:
            verts, caps, flipped, far = [], [], [], []
            for p, sil, faces_lit, faces_dark, ends in shapes:
                if p.zfail != zfail:
                    continue
                t = p.table
                a, b = _flagged(t.vertices[sil[:, 0]], 0.0), _flagged(t.vertices[sil[:, 1]], 0.0)
                plane = self._clamp.get(p.index)
                if plane is not None and not pays[p.index][0]:
                    # The far cap would cost more than the sides it cuts: extruded to infinity.
                    del self._clamp[p.index]
                    self._declined += 1
                    plane = None
                fan = plane is not None and pays[p.index][1]
                cap = None
                if plane is None:
                    ae, be = a.copy(), b.copy()
                    ae[:, 3] = be[:, 3] = 1.0
                elif fan:
                    ae, be = _flagged(ends[:, 0], 0.0), _flagged(ends[:, 1], 0.0)
                else:  # the cap's triangles need every vertex clamped (the same arithmetic per vertex)
                    pushed = _flagged(self._clamped(t.vertices, plane), 0.0)
                    ae, be = pushed[sil[:, 0]], pushed[sil[:, 1]]
                    # the far cap: light-facing faces turned round, the others as stored
                    cap = pushed[np.concatenate([t.faces[faces_lit][:, [0, 2, 1]], t.faces[faces_dark]]).ravel()]
                # Triangles (b, a, a') and (b, a', b'): the plain volume's order.
                verts.append(np.stack([b, a, ae, b, ae, be], axis=1).reshape(-1, 4))
                if fan:
                    # The far cap as a fan over the clamped silhouette: triangles (o, b', a'), the
                    # boundary the turned-round cap has, so the same counts off the plane.
                    apex = np.broadcast_to(_flagged(ends[:, 0].mean(axis=0)[None], 0.0), be.shape)
                    verts.append(np.stack([apex, be, ae], axis=1).reshape(-1, 4))
                    self._fans += 1
                elif cap is not None:
                    verts.append(cap)
                if zfail:
                    caps.append(faces_lit + p.first_triangle)
                    flipped.append(faces_dark + p.first_triangle)
                    if plane is None and not self.light.at_infinity:
                        far.append(_triangle_indices(faces_lit + p.first_triangle, (0, 2, 1)))
                        far.append(_triangle_indices(faces_dark + p.first_triangle))
            out[zfail] = pack_volume_geometry(verts, caps, flipped, far)
        return out

    def _clamps_pay(self, shapes: list) -> dict:
        """Plan index → (whether clamping that caster should save fill, whether its far cap
        may be the fan over its silhouette). Clamping pays where the solid angle, seen
        from the eye, of the side quads it cuts off (from the clamped vertices to infinity, both
        layers counted) exceeds that of the far cap it adds. The cap's is the signed sum over its
        boundary — the clamped silhouette edges, each with a fixed point of the cap, since the
        cap's triangles are bounded by the silhouette with its multiplicities — so it costs what
        the sides cost, not a pass over every cap triangle. An estimate (solid angles, not
        clipped to the viewport; overlapping cap layers counted once) that only chooses between
        exact geometries, never a count. The fan may replace the cap's triangles where the sum
        of its triangles' absolute solid angles is within :data:`FAN_SLACK` of the cap's."""
        if not shapes:
            return {}
        eye = np.asarray(self.frame.camera.eye, np.float64)
        owner, a, b, da, db, apex = [], [], [], [], [], []
        for n, (p, sil, _, _, ends) in enumerate(shapes):
            t = p.table
            owner.append(np.full(len(sil), n))
            a.append(ends[:, 0] - eye)
            b.append(ends[:, 1] - eye)
            if len(sil):
                apex.append(np.broadcast_to(a[-1].mean(axis=0), a[-1].shape))
            if not self.light.at_infinity:
                da.append(t.vertices[sil[:, 0]] - self.light_position)
                db.append(t.vertices[sil[:, 1]] - self.light_position)
        owner = np.concatenate(owner)
        if not len(owner):  # no silhouette edge at all: what the sums below give for one (no cut, no fold)
            return {s[0].index: (False, True) for s in shapes}
        a, b, apex = np.concatenate(a), np.concatenate(b), np.concatenate(apex)
        if self.light.at_infinity:
            da = db = np.broadcast_to(np.asarray(self.light.direction, np.float64), a.shape)
        else:
            da, db = np.concatenate(da), np.concatenate(db)
        cut = np.abs(_solid_angles(a, b, db)) + np.abs(_solid_angles(a, db, da))
        cut = np.bincount(owner, weights=cut, minlength=len(shapes))
        fan = _solid_angles(apex, a, b)
        added = np.abs(np.bincount(owner, weights=fan, minlength=len(shapes)))
        # The fan's own fill: as small as the cap's where its triangles do not fold over each
        # other (a silhouette star-shaped around the apex: convex casters).
        folded = np.bincount(owner, weights=np.abs(fan), minlength=len(shapes))
        return {s[0].index: (bool(cut[n] > added[n]), bool(folded[n] <= FAN_SLACK * added[n]))
                for n, s in enumerate(shapes)}

    # ------------------------------------------------------------------ figures
    def work(self, counted: dict, stats: dict) -> dict:
        """Stencil updates of the volume passes and the triangles of the kept casters, tested
        for facing on the CPU each render (culled casters' are not)."""
        out = {"volume": {"stencil_updates": stats["stencil_updates"]}}
        objs = self.frame.scene.objects
        cpu = sum(len(objs[p.index].faces) for p in self._kept_plans)
        if cpu:
            out["silhouette"] = {"cpu_triangles": cpu}
        return out

    def stats(self) -> dict:
        """The plain volume's figures over the kept casters (their silhouettes, methods and the
        fill left: ``volume_fragments`` = ``pixel_ops``), and what culling and clamping did."""
        everything = self.plans
        self.plans = self._kept_plans
        try:
            out = super().stats()
        finally:
            self.plans = everything
        objs = self.frame.scene.objects
        kept = {p.index for p in self._kept_plans}
        culled = [p for p in everything if p.index not in kept]
        out.update({
            "casters_culled": len(culled),
            "frustum_culled": self._counts["frustum"],
            "receiver_culled": self._counts["receivers"],
            "casters_kept": len(self._kept_plans),
            "casters_clamped": len(self._clamp),
            "clamps_declined": self._declined,
            "fan_caps": self._fans,
            "unbounded_casters": self._counts["unbounded"],
            "culled_triangles": sum(len(objs[p.index].faces) for p in culled),
            "pixel_ops": out["volume_fragments"],
            "receiver_map_bytes": 4 * (self.faces * self.grid ** 2 + HEADER_WORDS) if self.needs_map else 0,
            "receiver_map_texels": self.faces * self.grid ** 2 if self.needs_map else 0,
            "receiver_map_filled": self.map_filled,
        })
        return out


def _decode(words: np.ndarray) -> np.ndarray:
    """Keys (float64) of receiver-map words (cc_volume_receivers.glsl's ``encode``: the float32
    bits of the key, plus 1); −inf for 0, an empty texel."""
    words = np.asarray(words, np.uint32)
    keys = (words - np.uint32(1)).view(np.float32).astype(np.float64)
    keys[words == 0] = -np.inf
    return keys


def _solid_angles(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Signed solid angles (N,) of the triangles of directions a, b, c (N, 3), any lengths (Van
    Oosterom & Strackee 1983)."""
    def unit(x):
        return x / np.maximum(np.sqrt((x * x).sum(axis=1)), 1e-300)[:, None]

    a, b, c = unit(a), unit(b), unit(c)
    bc = np.stack([b[:, 1] * c[:, 2] - b[:, 2] * c[:, 1], b[:, 2] * c[:, 0] - b[:, 0] * c[:, 2],
                   b[:, 0] * c[:, 1] - b[:, 1] * c[:, 0]], axis=1)
    det = (a * bc).sum(axis=1)
    den = 1.0 + (a * b).sum(axis=1) + (b * c).sum(axis=1) + (c * a).sum(axis=1)
    return 2.0 * np.arctan2(det, den)


def _corners(boxes: np.ndarray) -> np.ndarray:
    """The 8 corners (K, 8, 3) of axis-aligned boxes (K, 2, 3)."""
    idx = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)])
    return np.stack([boxes[:, idx[:, a], a] for a in range(3)], axis=-1)


def frustum_corners(frame) -> np.ndarray:
    """The 8 corners (8, 3) of the camera's view frustum, near rectangle then far rectangle,
    grown by 1 % across (every covered pixel's point lies inside; the far plane is the
    G-buffer's, which no covered point lies beyond)."""
    eye = np.asarray(frame.camera.eye, np.float64)
    near = near_plane_quad(frame)
    centre = near.mean(axis=0)
    near = centre + 1.01 * (near - centre)
    scale = 1.01 * float(frame.camera.far) / float(frame.camera.near)
    far = eye + scale * (near - eye)
    return np.concatenate([near, far])


def volumes_may_meet_frustum(boxes: np.ndarray, frustum: np.ndarray, light) -> np.ndarray:
    """Bool (K,): for casters with axis-aligned ``boxes`` (K, 2, 3), whether the shadow volume
    may meet the view frustum with corners ``frustum`` (8, 3: near rectangle, far rectangle) —
    conservatively. The volume lies in the box swept away from the light: for a light at
    infinity the convex hull of the box and its copy moved along the light's direction past
    the frustum; for a light at a position the set {L + t (x − L): x in the box, 1 ≤ t ≤ T},
    convex, with T taking it past the frustum (True where the light is in the box). Two convex
    bodies are disjoint iff some face normal of either, or some cross product of an edge of
    each, separates them: the swept body's faces and edges are the box's and the sweep
    directions' (a light at infinity: one; a point light: the rays through the 8 corners)."""
    boxes = np.asarray(boxes, np.float64)
    K = len(boxes)
    if not K:
        return np.zeros(0, bool)
    corners = _corners(boxes)  # (K, 8, 3)
    n0, n1 = frustum[:4], frustum[4:]
    f_edges = np.array([n0[1] - n0[0], n0[3] - n0[0]] + [n1[i] - n0[i] for i in range(4)])
    f_faces = [np.cross(f_edges[0], f_edges[1])] + [np.cross(n0[(i + 1) % 4] - n0[i], n1[i] - n0[i])
                                                  for i in range(4)]
    box_axes = np.eye(3)
    if light.at_infinity:
        d = np.asarray(light.direction, np.float64)
        d = d / np.linalg.norm(d)
        low = (corners @ d).min(axis=1)
        reach = float((frustum @ d).max()) - low + 1.0
        far_corners = corners + reach[:, None, None] * d
        sweeps = np.broadcast_to(d, (K, 1, 3))
        inside = np.zeros(K, bool)
    else:
        L = np.asarray(light.position, np.float64)
        inside = np.all((boxes[:, 0] <= L) & (L <= boxes[:, 1]), axis=1)
        nearest = np.linalg.norm(np.clip(L, boxes[:, 0], boxes[:, 1]) - L, axis=1)
        reach = float(np.linalg.norm(frustum - L, axis=1).max())
        scale = np.where(inside, 1.0, reach / np.maximum(nearest, 1e-300) + 1.0)
        far_corners = L + scale[:, None, None] * (corners - L)
        sweeps = corners - L  # (K, 8, 3)
    hull = np.concatenate([corners, far_corners], axis=1)  # (K, 16, 3)
    # Axes per caster: shared (box axes, frustum faces, frustum edge × box axis) and own
    # (box axis × sweep, frustum edge × sweep).
    shared = np.concatenate([box_axes, np.array(f_faces),
                             np.cross(f_edges[:, None, :], box_axes[None, :, :]).reshape(-1, 3)])
    own = np.concatenate([np.cross(box_axes[None, :, None, :], sweeps[:, None, :, :]).reshape(K, -1, 3),
                          np.cross(f_edges[None, :, None, :], sweeps[:, None, :, :]).reshape(K, -1, 3)], axis=1)
    axes = np.concatenate([np.broadcast_to(shared, (K,) + shared.shape), own], axis=1)  # (K, A, 3)
    length = np.linalg.norm(axes, axis=2, keepdims=True)
    axes = np.where(length > 1e-12, axes / np.maximum(length, 1e-300), 0.0)
    ph = np.einsum("kvc,kac->kav", hull, axes)
    pf = np.einsum("vc,kac->kav", frustum, axes)
    separated = (ph.max(axis=2) < pf.min(axis=2)) | (ph.min(axis=2) > pf.max(axis=2))
    separated &= length[..., 0] > 1e-12
    return inside | ~separated.any(axis=1)
