"""Per-triangle shadow volumes in compute: each caster triangle's own volume tested against a
hierarchy over the view samples, exact on triangle soups.

Sintorn, Olsson & Assarsson 2011 ("An Efficient Alias-free Shadow Algorithm for Opaque and
Transparent Objects using per-triangle Shadow Volumes", ACM TOG 30(6), SIGGRAPH Asia) and Sintorn,
Kämpe, Olsson & Assarsson 2014 ("Per-Triangle Shadow Volumes Using a View-Sample Cluster
Hierarchy", I3D). The stencil volume (:mod:`shadowlab.techniques.volumes.shadow_volume`) extrudes
silhouettes, which needs consistent, closed meshes (or a multiplicity scheme that breaks on soups
and intersecting triangles), and rasterises the volumes at pixel resolution: its fill grows with
the volumes' screen area. Here every caster triangle is its own volume — the region bounded by
its three *edge planes* through the light and its own plane — and a view sample is in shadow when
it lies inside some triangle's volume: no silhouettes, no adjacency, no counting, so soups,
open, non-manifold and intersecting geometry are exact. The volumes are not rasterised: each is
tested against a hierarchy of bounding boxes of the view samples, top down (as in 2011: a tile
wholly outside one plane is rejected, a tile wholly inside all four is accepted at once, the
others descend), so the per-sample work concentrates along the volumes' boundaries.

The view samples are the truth's own shadow rays, as the irregular z-buffer uses them
(:mod:`shadowlab.techniques.maps.irregular_zbuffer`): origin = the exact surface point offset along
its normal (:func:`shadowlab.truth.tracing.offset_origins`), direction and ``tfar`` from
:meth:`shadowlab.scene.lights.Light.shadow_rays` (a point light: to :data:`shadowlab.scene.lights.T_LIGHT`
of the way to its float32 position). A segment from an origin towards the light lies wholly on
one side of every plane through the light, so "the origin inside the three edge planes and
beyond the triangle's plane" is the segment-meets-triangle test; at the leaves the segment test
itself decides, the watertight float32 test of Woop et al. 2013 (``shadowlab/gpu/watertight.glsl``,
shared with the irregular z-buffer), which is how this technique is exact against the truth.

Passes (GL 4.3 compute, ``per_triangle_volume_*.glsl``):

1. ``bounds`` (per frame): one work group per leaf tile (``tile`` × ``tile`` pixels) splits its
   samples into ``depth_clusters`` logarithmic slices of the tile's own depth range — after the
   view-sample clusters of 2014, which keep a tile that spans a depth discontinuity (a
   column in front of the far ground) from having one box that every volume straddles — and
   writes each cluster's box of ray origins (a level of its own under the tiles); then passes
   unite the clusters into their tile and 4 × 4 tiles into the tiles above, ``levels`` levels of
   tiles (8, 32, 128 pixels by default). 2011 tests the volumes against a hierarchical depth
   map (screen tiles with their depth ranges); 2014 builds a full 3D hierarchy (a BVH) over
   clusters of view samples. Here the hierarchy is the 2011 tile pyramid, with boxes of the
   samples' world positions instead of depth ranges and 2014's depth clusters as its lowest
   level: a fixed 4 × 4 fan-out, simple to build and to bound.
2. ``triangles``: one invocation per caster triangle builds its four planes (in double, kept in
   float32) and tests every node of the top level.
3. ``tiles``: per level, one invocation per (triangle, node) pair that descended tests the
   node's children (16 tiles, or a leaf tile's clusters).
4. ``samples``: one invocation per (triangle, leaf node) pair tests the leaf's samples exactly,
   setting each hit sample's bit (``atomicOr``: the per-pixel merge of all triangles).
5. ``resolve``: a sample is in shadow when its bit is set or a node above it was accepted.

2011 traverses with one warp per triangle and a per-warp stack; here the descent is breadth-first
through global lists of (triangle, node) pairs, one per level (one invocation per pair): simpler
to bound. Each list holds ``capacity`` pairs (0: sized to start from the triangles and nodes);
every append is counted even past the end, the counts are read back after each level, and a
full list is retried larger (``on_overflow=retry``, in the notes and ``list_retries``) or fails
(``on_overflow=fail``): never a silently lit sample. The counts are 32-bit atomics, so before each
level (and the samples pass) an upper bound on what it may count is formed (the pairs in × the
children of a node, the triangles × the top level's nodes, the leaf pairs × a tile's samples) and a
pass that could reach 2^32 is refused with an error rather than let a count wrap.

**Culling (``cull=closed``).** Soups need every triangle, but on a closed, consistently oriented
mesh the triangles facing away from the light may be skipped: a segment whose ends are both
outside such a mesh crosses it as often inwards as outwards, and one that starts inside (a
receiver piercing the caster) leaves it once more than it enters; either way a blocked segment
crosses a triangle facing the light. The watertight test keeps this count exact in float32: on
an edge two triangles share, both compute the same edge function with opposite signs, so a
segment's crossings of the mesh in the test's projection are counted without gaps or doubles.
The triangles of such meshes facing away by more than a small cosine (2^-10; nearly edge-on ones
are kept) are culled in the ``triangles`` pass, when every ray ends outside the mesh: a
directional light, or a point light outside the mesh's bounding box grown by BAND · D (rays stop
short of the light); never for target-direct lights, whose rays end on a plane that may cut the
mesh. Meshes are judged by their edge table (:attr:`shadowlab.geometry.adjacency.EdgeTable.closed`)
and oriented by the sign of their volume. Soups, open and non-manifold meshes keep every triangle.

**Exactness of accept and reject.** The leaf test is the truth's; a tile's verdict must give the
answer that test would give for every sample below, including float32 rounding. Each triangle's
planes are built in double from its float32 corners (kept in float32 for the tile tests), and a
tile decides only beyond a margin of at least θ · D, θ = :data:`THETA` (2^-14, some 500 float32
ulps) and D (``u_scale``) an upper bound on every distance in the scene (4 × its largest
coordinate): far above the float32 error of the tile test itself and of the leaf test's edge
functions, which err by a few ulps of the coordinates. Rejected when outside an edge plane: the
segment runs on the outer side of a plane through the light, at a distance from it that grows in
proportion to the distance from the light; for point lights the margin grows with the box's
distance from the light over r_min (the triangle's distance from the light, in double), so the
segment passes the triangle's edges at least θ · D away. Rejected when on the light's side of the
triangle's plane: both ends of the segment are (the plane is used only when the light is at least
:data:`BAND` · D from it, so the segment's end, T_LIGHT of the way and rounded, stays on that
side; lights at infinity: only when the rays are at least at cosine BAND to the plane). Accepted
when inside all three edge planes and beyond the plane, all by the margin: the segment crosses
the plane at least θ · D inside the triangle, at a fraction 1 − d_L/(d_o + d_L) < 1 − BAND/2 of the
way (d_L, d_o: the light's and the origin's distances from the plane), well before T_LIGHT
(target-direct lights: the triangle must also lie in front of the light's plane, where the rays
end). Degenerate planes (an edge seen end-on from the light, a zero-area triangle, a light in or
near the triangle's plane, a triangle touching the light) are not used: the tiles descend and the
leaves decide. So the masks with and without tile-level accepts are equal (a test says so), and
both equal the truth's except where the segment test itself ties (the tests require equality on the
scenes they render).

Counters: ``triangles_culled``; ``tile_tests`` (node–volume tests; empty nodes are skipped) = ``tiles_accepted`` +
``tiles_rejected`` + ``tiles_descended``; ``sample_tests`` (leaf segment tests: every sample of a
descended leaf), ``sample_sets`` (hits), ``pixel_ops`` = sample tests + tile-level sets (the
per-pixel test-and-set operations the papers compare with a stencil volume's fill);
``volume_fragments`` = 0 (no volume geometry is rasterised).

Like the irregular z-buffer, the rays are built on the CPU in :meth:`PerTriangleVolume.setup` (the
truth's float64 points and rounding; untimed, like the G-buffer): a real engine would form them
from its G-buffer in a shader. One sample per pixel.
"""
from __future__ import annotations

import numpy as np

from ...gpu import programs
from ...truth.tracing import caster_corners, offset_origins
from ..base import FIRST, MAX, SUM, Param, PlotStyle, Technique, TechniqueError

#: Storage-buffer bindings (``per_triangle_volume_common.glsl``).
BINDING = {"origins": 0, "directions": 1, "clusters": 2, "blocked": 3, "counters": 4, "triangles": 5,
           "nodes": 6, "flags": 7, "list_in": 8, "list_out": 9, "result": 10, "volumes": 11, "order": 12,
           "cullable": 13}
#: Levels the shaders take at most (MAX_LEVELS: four of tiles, one of depth clusters), and child
#: tiles per tile and axis (FANOUT).
MAX_LEVELS, FANOUT = 5, 4
#: Counter slots: per level (tests, accepted, rejected, descended), then sample tests, hits and
#: triangles culled.
PER_LEVEL = ("tests", "accepted", "rejected", "descended")
COUNTER_SLOTS = 4 * MAX_LEVELS + 3
SAMPLE_TESTS, SAMPLE_HITS, CULLED = 4 * MAX_LEVELS, 4 * MAX_LEVELS + 1, 4 * MAX_LEVELS + 2
#: Counts a 32-bit counter holds exactly: a dispatch that could add this many is refused
#: (:meth:`PerTriangleVolume._check_count`) rather than let a counter wrap.
COUNTER_RANGE = 2 ** 32
#: ``ray_origin[s].w`` of a slot without a ray (NO_RAY).
NO_RAY = -1.0
#: Compute invocations per work group of the passes over triangles, pairs and slots.
LOCAL_SIZE = 64
#: The margin of tile verdicts, a fraction of the scene's size bound D (module docstring).
THETA = 2.0 ** -14
#: Planes closer than BAND · D to a point light (or within cosine BAND of parallel to a light at
#: infinity) are not used to decide tiles.
BAND = 2.0 ** -12
#: Light kinds of the traversal shader (LIGHT_AT_POINT, LIGHT_AT_INFINITY, LIGHT_TARGET_DIRECT).
LIGHT_KIND = {"point": 0, "spot": 0, "directional": 1, "target_direct": 2}
#: Retries of an overflowing pair list before the run fails (each sizes it to what was asked).
MAX_RETRIES = 3
#: Bytes of one sample slot (origin+tfar vec4, direction vec4, cluster, hit bits, result, its
#: place in its tile's order), one node (two vec4 and a flag), one triangle's volume (five vec4:
#: four planes, margins and flags) and one (triangle, node) pair.
SLOT_BYTES, NODE_BYTES, VOLUME_BYTES, PAIR_BYTES = 48, 36, 80, 8
#: Lights the technique renders for (area lights through light sampling, as point lights).
LIGHTS = frozenset({"point", "directional", "spot", "target_direct", "area"})


class PerTriangleVolume(Technique):
    """Per-triangle shadow volumes against a view-sample hierarchy, in compute (module docstring):
    exact on soups, open, non-manifold and intersecting geometry."""

    name = "per_triangle_volume"
    summary = ("per-triangle shadow volumes (Sintorn et al. 2011, 2014): each triangle's four planes against a "
               "hierarchy of view-sample tiles in compute, exact segment tests at the leaves")
    STYLE = PlotStyle("#ad494a", "8")  # a darker red than the stencil volume's
    LIGHTS = LIGHTS
    LIGHT_SAMPLED = True
    PASSES = ("bounds", "triangles", "tiles", "samples", "resolve")
    PARAMS = {
        "tile": Param(8, "leaf tile side in pixels (a work group per leaf tile builds its boxes)", choices=(4, 8, 16)),
        "levels": Param(3, f"levels of the tile hierarchy, each {FANOUT}x{FANOUT} tiles of the one below "
                           f"(3 with tile=8: 8, 32, 128 pixels)", min=1, max=MAX_LEVELS - 1),
        "depth_clusters": Param(4, "depth clusters per leaf tile (logarithmic slices of its depth range, "
                                   "Sintorn et al. 2014); 0 = off (one box per tile)", min=0, max=8),
        "accept": Param(True, "accept tiles wholly inside a volume at once (one tile-level set); false: every "
                              "tile not rejected descends to the leaves' sample tests"),
        "cull": Param("closed", "skip the triangles facing away from the light on closed, consistently oriented "
                                "meshes with the light outside their bounding box (exact: module docstring), or "
                                "none",
                      choices=("closed", "none")),
        "capacity": Param(0, "(triangle, node) pairs each level's list holds (0: sized from the triangles and "
                             "nodes to start, grown as needed)", min=0),
        "on_overflow": Param("retry", "a full pair list: retry with a list large enough, or fail",
                             choices=("retry", "fail")),
    }
    STATS = {"triangles": FIRST, "triangles_culled": SUM, "tile_tests": SUM, "tiles_accepted": SUM,
             "tiles_rejected": SUM, "tiles_descended": SUM, "sample_tests": SUM, "sample_sets": SUM, "pixel_ops": SUM,
             "volume_fragments": SUM, "list_retries": SUM, "nodes": FIRST, "memory_bytes": MAX}

    # -- setup ---------------------------------------------------------------------
    def setup(self, frame, slot) -> None:
        """The rays in tile order, the node layout, the buffers and the programs."""
        ctx = frame.ctx
        light = slot.light
        if light.type_name not in LIGHT_KIND:
            raise TechniqueError(f"{self.name}: no {light.type_name} lights (area lights are light-sampled)")
        tile, clusters = self.tile, max(1, self.depth_clusters)
        self.clusters = clusters
        tiles = (-(-frame.width // tile), -(-frame.height // tile))
        # levels from the leaves up: (tiles across and down, nodes per tile, child tiles per axis)
        sizes, per_tile, fanout = [tiles], [clusters], [1]
        if clusters > 1:  # the depth clusters under the leaf tiles: a level of their own
            sizes, per_tile, fanout = sizes + [tiles], per_tile + [1], fanout + [1]
        for _ in range(1, self.levels):
            w, h = sizes[-1]
            sizes.append((-(-w // FANOUT), -(-h // FANOUT)))
            per_tile.append(1)
            fanout.append(FANOUT)
        self.level_count = len(sizes)
        counts = [w * h * k for (w, h), k in zip(sizes, per_tile)]
        # The top pass loops over every top-level node in one invocation per triangle; llvmpipe
        # would end that loop silently past its iteration limit, so such a layout is refused.
        top_iterations = sizes[-1][0] * sizes[-1][1] * (per_tile[-1] + 1)
        if top_iterations > programs.LLVMPIPE_LOOP_LIMIT // 2:
            raise TechniqueError(
                f"{self.name}: {counts[-1]:,} top-level nodes at {frame.width}x{frame.height} (tile={tile}, "
                f"levels={self.levels}) are more than one invocation may loop over on llvmpipe (it stops "
                f"after {programs.LLVMPIPE_LOOP_LIMIT:,} iterations); use more levels or a larger tile")
        self.level_sizes, self.level_counts = sizes, counts
        # children a node of level l + 1 has at level l (a tile's child tiles times their nodes each)
        self.level_children = [fanout[l + 1] ** 2 * per_tile[l] for l in range(len(sizes) - 1)]
        self.level_offsets = [int(x) for x in np.cumsum([0] + counts[:-1])]
        self.node_count = int(sum(counts))
        self.slot_count = tiles[0] * tiles[1] * tile * tile

        # the rays of the evaluated pixels, each in its tile's slot
        idx = np.flatnonzero(slot.evaluated)
        origins = offset_origins(frame)[idx]
        directions, tfar = light.shadow_rays(origins, frame.compact_position[idx])
        pix = frame.pixel_index[idx]
        x, y = pix % frame.width, pix // frame.width
        slots = ((y // tile) * tiles[0] + x // tile) * tile * tile + (y % tile) * tile + x % tile
        self.ray_slots, self.evaluated = slots, slot.evaluated
        origin_w = np.zeros((self.slot_count, 4), np.float32)
        origin_w[:, 3] = NO_RAY
        origin_w[slots, :3], origin_w[slots, 3] = origins, tfar
        dir_w = np.zeros((self.slot_count, 4), np.float32)
        dir_w[slots, :3] = directions
        corners = caster_corners(frame)
        self.triangle_count = int(sum(len(o.faces) for o in frame.scene.objects if o.casts))
        # D: every distance between two points of the scene (origins, casters, the light) is below it
        extent = [np.abs(origins).max() if len(origins) else 0.0, np.abs(corners[:, :3]).max()]
        light_pos = getattr(light, "position", None)
        if light_pos is not None:
            extent.append(np.abs(np.asarray(light_pos, np.float32)).max())
        scale = 4.0 * max(1.0, float(max(extent)))

        self.buffers = {
            "origins": self.own(ctx.buffer(origin_w.tobytes())),
            "directions": self.own(ctx.buffer(dir_w.tobytes())),
            "clusters": self.own(ctx.buffer(reserve=4 * self.slot_count)),
            "blocked": self.own(ctx.buffer(reserve=4 * self.slot_count)),
            "result": self.own(ctx.buffer(reserve=4 * self.slot_count)),
            "counters": self.own(ctx.buffer(reserve=4 * COUNTER_SLOTS)),
            "triangles": self.own(ctx.buffer(corners.tobytes())),
            "nodes": self.own(ctx.buffer(reserve=32 * self.node_count)),
            "flags": self.own(ctx.buffer(reserve=4 * self.node_count)),
            "volumes": self.own(ctx.buffer(reserve=VOLUME_BYTES * max(1, self.triangle_count))),
            "order": self.own(ctx.buffer(reserve=4 * self.slot_count)),
            "cullable": self.own(ctx.buffer(self._cullable(frame, light, scale).tobytes())),
        }
        # one pair list per level (level l: the pairs that descended at level l)
        self.capacities = [self.capacity if self.capacity > 0 else 2 * max(self.triangle_count, 1) + 4 * n
                           for n in counts]
        self.lists = [self.own(ctx.buffer(reserve=PAIR_BYTES * c)) for c in self.capacities]

        defines = {"TILE": tile, "TILE_SLOTS": tile * tile, "CLUSTERS": clusters, "LOCAL_SIZE": LOCAL_SIZE}
        self.leaves_prog = self.program("per_triangle_volume_bounds.glsl", defines={**defines, "LEAVES": 1})
        self.union_prog = self.program("per_triangle_volume_bounds.glsl", defines=defines)
        self.top_prog = self.program("per_triangle_volume_traverse.glsl", defines={**defines, "TOP": 1})
        self.descend_prog = self.program("per_triangle_volume_traverse.glsl", defines=defines)
        self.samples_prog = self.program("per_triangle_volume_samples.glsl", defines=defines)
        self.resolve_prog = self.program("per_triangle_volume_resolve.glsl", defines=defines)
        layout = {"u_level_offset": self.level_offsets, "u_level_size": sizes, "u_level_per_tile": per_tile,
                  "u_level_fanout": fanout}
        for prog in (self.leaves_prog, self.union_prog, self.top_prog, self.descend_prog, self.samples_prog,
                     self.resolve_prog):
            programs.set_uniforms(prog, {"u_tiles": tiles, "u_levels": self.level_count})
            for key, val in layout.items():
                if key in prog:  # the compiler trims an array to the elements a program reads
                    n = prog[key].array_length
                    padded = np.zeros((MAX_LEVELS,) + np.shape(val)[1:], np.int32)
                    padded[:len(val)] = val
                    programs.set_uniforms(prog, {key: padded[:n]})
        programs.set_uniforms(self.leaves_prog, {"u_eye": tuple(map(float, frame.camera.eye))})
        kind = LIGHT_KIND[light.type_name]
        if kind == 0:
            towards = (0.0, 0.0, 0.0)
        else:  # the rays' own float32 direction (towards the light)
            towards = tuple(map(float, (-np.asarray(light.direction)).astype(np.float32)))
        geometry = {"u_light_kind": kind, "u_light": tuple(map(float, np.asarray(
                        light_pos if light_pos is not None else (0, 0, 0)).astype(np.float32))),
                    "u_light_dir": towards, "u_scale": scale, "u_theta": THETA,
                    "u_band": BAND, "u_accept": int(self.accept), "u_triangles": self.triangle_count}
        for prog in (self.top_prog, self.descend_prog):
            programs.set_uniforms(prog, geometry)
        self.notes.append(f"{self.triangle_count} caster triangles, {self.levels} levels of {tile}-pixel leaf tiles "
                          f"x{FANOUT} ({clusters} depth cluster{'s' if clusters > 1 else ''} per leaf tile)")
        if self.cullable_objects:
            self.notes.append(f"{self.cullable_objects} closed caster object(s) with the light outside: their "
                              f"triangles facing away from the light are culled")
        self.retries = 0
        self.counts = np.zeros(COUNTER_SLOTS, np.int64)

    def _cullable(self, frame, light, scale: float) -> np.ndarray:
        """Int32 (max(T, 1),): per caster triangle 0, or the orientation of its mesh (+1: outward,
        −1: inward, from the sign of its volume) where the mesh is closed and consistently
        oriented (:attr:`shadowlab.geometry.adjacency.EdgeTable.closed`) and every ray's end is
        outside it (``cull=closed``): a directional light, or a point light outside the mesh's
        bounding box grown by :data:`BAND` · ``scale`` (rays stop short of the light, and this
        keeps their ends on the light's side of every face; a target-direct light's rays end on
        its plane, which may cut the mesh: never). The traversal skips such triangles when they
        face away from the light."""
        out = []
        for obj in frame.scene.objects:
            if not obj.casts:
                continue
            flag = 0
            if self.cull == "closed" and obj.edges.closed and light.type_name != "target_direct":
                vertices = np.asarray(obj.vertices, np.float64)
                outside = light.at_infinity
                if not outside:
                    grow = BAND * scale
                    pos = np.asarray(light.position, np.float64)
                    outside = bool(np.any(pos < vertices.min(axis=0) - grow)
                                   or np.any(pos > vertices.max(axis=0) + grow))
                if outside:
                    v = vertices[np.asarray(obj.faces)]
                    volume = float(np.einsum("ij,ij->i", v[:, 0], np.cross(v[:, 1], v[:, 2])).sum())
                    flag = 1 if volume > 0 else -1 if volume < 0 else 0
            out.append(np.full(len(obj.faces), flag, np.int32))
        flags = np.concatenate(out) if out else np.zeros(0, np.int32)
        self.cullable_objects = int(sum(1 for f in out if len(f) and f[0] != 0))
        return flags if len(flags) else np.zeros(1, np.int32)

    # -- rendering -----------------------------------------------------------------
    def render(self) -> None:
        """Build the hierarchy, traverse it with every triangle's volume level by level, test the
        leaves' samples, merge; a pair list that overflows is retried larger or fails."""
        ctx = self.frame.ctx
        b = self.buffers
        for name, buf in b.items():
            buf.bind_to_storage_buffer(BINDING[name])
        top = self.level_count - 1
        with self.timed_pass("bounds"):
            b["counters"].clear()
            w, h = self.level_sizes[0]
            tiles = w * h
            rows = -(-tiles // programs.MAX_GROUPS_X)
            self.leaves_prog.run(-(-tiles // rows), rows)  # one work group per leaf tile
            ctx.memory_barrier()
            for level in range(1, self.level_count):
                self.union_prog["u_level"].value = level
                programs.dispatch(self.union_prog, self.level_counts[level], LOCAL_SIZE)
                ctx.memory_barrier()
        with self.timed_pass("triangles"):
            pairs = self._level(top, self.top_prog, self.triangle_count, None)
        with self.timed_pass("tiles"):
            for level in range(top - 1, -1, -1):
                pairs = self._level(level, self.descend_prog, pairs, self.lists[level + 1])
        with self.timed_pass("samples"):
            if pairs:
                self._check_count("sample_tests", pairs * self.tile * self.tile,
                                  f"{pairs:,} leaf pairs x up to {self.tile * self.tile} samples each")
                self.lists[0].bind_to_storage_buffer(BINDING["list_in"])
                self.samples_prog["u_pairs"].value = pairs
                programs.dispatch(self.samples_prog, pairs, LOCAL_SIZE)
                ctx.memory_barrier()
        with self.timed_pass("resolve"):
            self.resolve_prog["u_slots"].value = self.slot_count
            programs.dispatch(self.resolve_prog, self.slot_count, LOCAL_SIZE)
            ctx.memory_barrier()
            self.counts = np.frombuffer(b["counters"].read(), np.uint32).astype(np.int64)

    def _level(self, level: int, prog, invocations: int, list_in) -> int:
        """Test the nodes of ``level``: ``invocations`` triangles (the top level) or pairs of
        ``list_in`` (below); the pairs that descended go to the level's list. Its count is read
        back: a list too small is made as large as asked and the level run again (its counters
        zeroed first; the flags it set are set again, idempotently), or the run fails. Returns
        the pairs that descended."""
        ctx = self.frame.ctx
        counters = self.buffers["counters"]
        descended = 4 * level + PER_LEVEL.index("descended")
        # every node test may append a pair: the level's tests and appends are at most this
        if list_in is None:
            bound, why = invocations * self.level_counts[level], (
                f"{invocations:,} triangles x {self.level_counts[level]:,} top-level nodes")
        else:
            bound, why = invocations * self.level_children[level], (
                f"{invocations:,} pairs x {self.level_children[level]} children each")
        self._check_count(f"level-{level} tile tests and appends", bound, why)
        for attempt in range(MAX_RETRIES + 1):
            if invocations == 0:
                return 0
            if list_in is not None:
                list_in.bind_to_storage_buffer(BINDING["list_in"])
                prog["u_pairs"].value = invocations
            self.lists[level].bind_to_storage_buffer(BINDING["list_out"])
            programs.set_uniforms(prog, {"u_level": level, "u_capacity": self.capacities[level]})
            programs.dispatch(prog, invocations, LOCAL_SIZE)
            ctx.memory_barrier()
            asked = int(np.frombuffer(counters.read(4, offset=4 * descended), np.uint32)[0])
            if asked <= self.capacities[level]:
                return asked
            if self.on_overflow == "fail" or attempt == MAX_RETRIES:
                raise TechniqueError(f"{self.name}: the level-{level} list of {self.capacities[level]} "
                                     f"(triangle, node) pairs overflowed ({asked} asked for); set capacity=0 or "
                                     f"larger, or on_overflow=retry")
            self.notes.append(f"level-{level} list of {self.capacities[level]} pairs overflowed ({asked} asked "
                              f"for): retried with {asked}")
            self.retries += 1
            self.free(self.lists[level])
            self.capacities[level] = asked
            self.lists[level] = self.own(ctx.buffer(reserve=PAIR_BYTES * asked))
            counters.write(np.zeros(4, np.uint32).tobytes(), offset=16 * level)
            if list_in is None:  # the top pass counts the culled triangles again
                counters.write(np.zeros(1, np.uint32).tobytes(), offset=4 * CULLED)
        raise AssertionError("unreachable")

    def _check_count(self, what: str, bound: int, why: str) -> None:
        """Refuse a dispatch whose counter (a 32-bit atomic) could wrap: ``bound`` is an upper
        bound on what it may add. A wrapped append count would make a full list look as if it fit
        (samples left lit), and a wrapped work count would be a wrong statistic; neither can be
        counted exactly past 2^32, so the run fails instead."""
        if bound >= COUNTER_RANGE:
            raise TechniqueError(
                f"{self.name}: the {what} may reach {bound:,} ({why}), more than a 32-bit counter "
                f"holds exactly; use fewer triangles, a smaller frame, or more levels")

    # -- results -------------------------------------------------------------------
    def sample_blocked(self) -> np.ndarray:
        """Bool (M,): per covered pixel (the frame's compact order), whether its ray is blocked
        (False for pixels the light does not evaluate)."""
        result = np.frombuffer(self.buffers["result"].read(), np.uint32)
        out = np.zeros(len(self.frame.pixel_index), bool)
        out[np.flatnonzero(self.evaluated)] = result[self.ray_slots] != 0
        return out

    def visibility(self) -> np.ndarray:
        """Float32 (H, W): 0 where the sample's ray is blocked, 1 elsewhere."""
        vis = np.where(self.sample_blocked(), 0.0, 1.0).astype(np.float32)
        return self.frame.to_image(vis, fill=1.0)

    def level_counts_of(self) -> list[dict]:
        """Per level (0 = the leaves) the counters of the last render: node tests, accepted,
        rejected, descended."""
        return [dict(zip(PER_LEVEL, map(int, self.counts[4 * level:4 * level + 4])))
                for level in range(self.level_count)]

    def work(self, counted: dict, stats: dict) -> dict:
        """The leaves' segment tests, as rays tested (the per-sample work)."""
        return {"samples": {"rays": stats["sample_tests"]}}

    def stats(self) -> dict:
        """The counters of the last render (module docstring), the nodes of the hierarchy, the
        lists' retries and the storage-buffer memory."""
        per = self.level_counts_of()
        accepted = sum(p["accepted"] for p in per)
        sample_tests = int(self.counts[SAMPLE_TESTS])
        memory = (self.slot_count * SLOT_BYTES + self.node_count * NODE_BYTES + self.buffers["triangles"].size
                  + VOLUME_BYTES * self.triangle_count + 4 * COUNTER_SLOTS + PAIR_BYTES * sum(self.capacities))
        return {"triangles": self.triangle_count, "triangles_culled": int(self.counts[CULLED]),
                "tile_tests": sum(p["tests"] for p in per),
                "tiles_accepted": accepted, "tiles_rejected": sum(p["rejected"] for p in per),
                "tiles_descended": sum(p["descended"] for p in per), "sample_tests": sample_tests,
                "sample_sets": int(self.counts[SAMPLE_HITS]), "pixel_ops": sample_tests + accepted,
                "volume_fragments": 0, "list_retries": int(self.retries), "nodes": self.node_count,
                "memory_bytes": int(memory)}
