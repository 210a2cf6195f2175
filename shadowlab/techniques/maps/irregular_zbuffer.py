"""The irregular z-buffer: exact hard shadows inside the rasteriser (alias-free shadow maps).

Johnson, Lee, Mark & Hunt 2005 ("The irregular z-buffer: hardware acceleration for irregular data
structures", ACM TOG 24(4)) and Aila & Laine 2004 ("Alias-free shadow maps", EGSR): instead of
sampling the light's view on a regular grid (a shadow map, which aliases), store the points the
camera actually sees in the light's grid and test every caster against exactly those points.
Wyman, Hoetzlein & Lefohn 2015 ("Frustum-traced raster shadows", I3D) made it practical on GPUs.

Passes (``shadowlab/techniques/maps/izb_insert.glsl``, ``izb_raster.glsl``, ``izb_test.glsl``; GL 4.3 compute
and storage buffers):

1. ``insert`` (compute): every sample's shadow ray — the truth's own ray, from the same float32
   offset origin (:func:`shadowlab.truth.tracing.offset_origins`: the exact surface point moved along
   its normal by 2^-18 of max(|P|∞, scene extent)), with the same direction and ``tfar``
   (:meth:`shadowlab.scene.lights.Light.shadow_rays`) — goes into the list of the light-space
   texel its origin projects to (head pointers by atomic exchange, nodes from a pool);
2. ``raster``: the casters are rasterised in light space with conservative coverage (a geometry
   shader emits each triangle's bounding box grown by :data:`COVERAGE_MARGIN` texels: llvmpipe
   has no conservative rasterisation extension; with ``coverage=polygon`` the fragment stage
   keeps only the texels whose square, grown by :data:`EDGE_PAD`, overlaps the triangle's
   projection: Hasselgren et al. 2005); each fragment whose texel holds rays appends the pair
   (triangle, texel) to a work list. ``coverage=box`` is the default: on llvmpipe the
   per-fragment test costs more than it saves except on long thin triangles (slower on dense
   meshes such as sv_many_casters, where it drops few pairs; faster on sm_wires, where it drops
   most: docs/irregular-zbuffer.md);
3. ``test`` (compute): each pair's triangle against every ray listed in its texel, with the
   watertight ray/triangle test (Woop et al. 2013), setting the sample's bit in a per-pixel
   mask. One invocation walks at most :data:`WALK_BUDGET` nodes of the list per dispatch, saves
   the node where it stopped (a continuation per pair) and is dispatched again, for the pairs
   still pending, until every walk has reached the end of its list (``izb_resumes``, in the
   notes): llvmpipe ends an invocation silently after 65535 loop iterations, which would leave
   the rest of a longer list (a coarse grid) lit.

The list walk is a compute pass, not the fragment stage as in Johnson et al.: on llvmpipe a
fragment shader that walks a list costs orders of magnitude more per step than a compute
shader (docs/irregular-zbuffer.md), so the fragments only append work.

The grid is the shadow map's atlas (:class:`shadowlab.techniques.maps.toolkit.Atlas`): one face, or a
point light's six cube faces, fitted as the shadow map fits its faces
(:meth:`shadowlab.scene.lights.Light.shadow_views`) to every ray's surface point (every ray's
origin must land in a face; one that does not is counted and the run fails loudly). With
``samples=N`` each pixel has N sub-pixel samples (:mod:`shadowlab.truth.subpixel`), one bit each, and
the visibility is the lit fraction of the pixel's evaluated samples: anti-aliased hard shadows,
judged against ``raytrace:pixel_samples=N``.

The node pool holds one node per ray (it cannot overflow; it is checked anyway). The work list
of (triangle, texel) pairs holds ``capacity`` pairs (0: :data:`PAIRS_PER_RAY` per ray to start
with); the raster pass counts every pair it asks for, so a full list is known exactly: the
render is repeated with a list large enough (``on_overflow=retry``, reported in the notes and
``izb_retries``) or fails (``on_overflow=fail``) — never a silently lit sample.

The rays are built on the CPU in :meth:`IrregularZBuffer.setup` (the truth's float64 points and
rounding, so the two agree bit for bit on every ray; untimed, like the G-buffer): a real engine
would form them from its G-buffer in a shader, which this lab cannot do without giving up
exactness against the truth.
"""
from __future__ import annotations

import numpy as np

from ...gpu import glstate, programs
from ...gpu.glstate import PassState
from ...scene.lights import T_LIGHT
from ...truth.tracing import caster_corners, offset_origins
from ..base import FIRST, MAX, SUM, Param, PlotStyle, Technique, TechniqueError, TuneRange
from .toolkit import ATLAS_DEFINES, Atlas
from .contact import ContactShadows

#: Storage-buffer bindings (``shadowlab/techniques/maps/izb_common.glsl``).
BINDING = {"origins": 0, "directions": 1, "samples": 2, "heads": 3, "nodes": 4, "blocked": 5, "counters": 6,
           "texels": 7, "triangles": 8, "pairs": 9, "continuation": 10}
#: Counter slots (``shadowlab/techniques/maps/izb_common.glsl``: COUNTER_*).
COUNTERS = ("nodes", "node_overflow", "outside", "pairs", "tests", "hits", "pending")
#: The work list's first size per ray when ``capacity=0`` (grown to what a render needs).
PAIRS_PER_RAY = 4
#: The list terminator and the ``w`` of a ray not to trace (izb_common.glsl: NO_NODE, NO_RAY).
NO_NODE = -1
NO_RAY = -1.0
#: Compute invocations per work group of the insert and test passes.
LOCAL_SIZE = 64
#: List nodes one invocation of the test pass walks per dispatch; a longer list is walked on
#: where it stopped by another dispatch. llvmpipe ends a shader invocation silently after 65535
#: loop iterations (Mesa's LP_MAX_TGSI_LOOP_ITERATIONS), leaving the rays past that point lit; a
#: quarter of it keeps well clear while making a resume rare (only coarse grids list more rays
#: in one texel).
WALK_BUDGET = 16384
#: Texels each triangle's light-space bounding box is grown by: half a texel makes the box cover
#: every texel centre the triangle's texels could hold; one more absorbs float32 rounding of the
#: projection, so no covered texel is missed (extra texels only cost tests).
COVERAGE_MARGIN = 1.5
#: Texels around each texel's square in the fragment stage's polygon overlap test: float32
#: edge functions of window coordinates err far below a texel, so one texel is ample.
EDGE_PAD = 1.0
#: Polygons with a corner further than this (texels) from the atlas origin skip the overlap test
#: (their edge functions lose the precision the pad covers) and keep their whole box.
EDGE_TEST_LIMIT = 2.0 ** 20
#: Perspective faces are clipped at w = this × the smallest w of any ray's end (rays stop at
#: T_LIGHT of the way to the light, so their ends have w >= (1 - T_LIGHT) × their origin's w).
W_MIN_FRACTION = 0.5 * (1.0 - T_LIGHT)
#: Retries of an overflowing work list before the run fails (each sizes it to what was asked).
MAX_RETRIES = 2
#: Bytes of one ray (origin+tfar vec4, direction vec4, sample int), one node (ivec2), one ray's
#: texel (int), one work pair (ivec2) and its walk's continuation (int): the storage-buffer
#: memory the stats report.
RAY_BYTES, NODE_BYTES, TEXEL_BYTES, PAIR_BYTES, CONTINUATION_BYTES = 36, 8, 4, 8, 4
#: The most sub-pixel samples: one bit each in a 32-bit word per pixel.
MAX_SAMPLES = 32


class IrregularZBuffer(ContactShadows, Technique):
    """Exact hard shadows by rasterising the casters against the visible samples themselves
    (module docstring): every light type the shadow map supports, 1 to 32 samples per pixel."""

    name = "irregular_zbuffer"
    summary = ("irregular z-buffer / alias-free shadow map (Johnson et al. 2005; Aila & Laine 2004): the visible "
               "samples in light-space lists, casters rasterised conservatively and tested exactly")
    STYLE = PlotStyle("#17becf", "D")
    LIGHT_SAMPLED = True  # area lights: averaged over light samples like the other hard techniques
    PASSES = ("insert", "raster", "test")
    PARAMS = {
        "resolution": Param(1024, "light-space grid width and height in texels (per cube face)", min=1, max=16384,
                            # coarse grids mean long lists, fine ones many fragments per triangle
                            tune=TuneRange(64, 4096, log=True)),
        "samples": Param(1, f"sub-pixel samples per pixel (1 to {MAX_SAMPLES}; > 1: coverage visibility)",
                         min=1, max=MAX_SAMPLES),
        "capacity": Param(0, f"(triangle, texel) work-list size (0: {PAIRS_PER_RAY} per ray to start, grown as "
                             f"needed)", min=0),
        "on_overflow": Param("retry", "a full work list: retry with a list large enough, or fail",
                             choices=("retry", "fail")),
        "projection": Param("auto", "point lights: cube (six faces), frustum (one), auto",
                            choices=("auto", "cube", "frustum")),
        "coverage": Param("box", "conservative coverage: each triangle's grown bounding box, or only the texels "
                                 "of the box that overlap the triangle (polygon: fewer pairs, a test per fragment)",
                          choices=("box", "polygon")),
    }
    STATS = {"izb_rays": SUM, "izb_pairs": SUM, "izb_tests": SUM, "izb_hits": SUM, "izb_retries": SUM,
             "izb_resumes": SUM, "izb_list_mean": FIRST, "izb_list_p99": FIRST, "izb_list_max": MAX,
             "izb_texels_used": FIRST,
             "memory_bytes": MAX, "faces": FIRST, "passes": FIRST, "samples": FIRST}

    def setup(self, frame, slot) -> None:
        """The grid (the atlas of the fitted faces), the rays, the buffers and the programs."""
        ctx = frame.ctx
        origins, directions, tfar, sample, points = self._rays(frame, slot)
        # the grid covers every ray's surface point (the shadow map's classic fit to the receivers,
        # here to the samples themselves: sub-pixel samples reach past the pixel centres)
        covered = points if len(points) else frame.scene.bounds()
        faces, notes = slot.light.shadow_views(covered, frame.casters(), self.resolution,
                                               projection=self.projection, near=0.0)
        self.notes.extend(notes)
        self.notes.append("conservative coverage: geometry-shader bounding box grown by "
                          f"{COVERAGE_MARGIN:g} texels" + (", then a polygon overlap test per fragment"
                                                           if self.coverage == "polygon" else "")
                          + " (no conservative-rasterisation extension used)")
        self.atlas = Atlas.grid(faces, self.resolution, self.name)
        self.ray_count = len(origins)
        self.evaluated = slot.evaluated
        words = len(frame.pixel_index)
        origin_w = np.empty((max(1, self.ray_count), 4), np.float32)
        origin_w[:, 3] = NO_RAY
        origin_w[:self.ray_count, :3], origin_w[:self.ray_count, 3] = origins, tfar
        dir_w = np.zeros((max(1, self.ray_count), 4), np.float32)
        dir_w[:self.ray_count, :3] = directions
        sample_w = np.zeros(max(1, self.ray_count), np.int32)
        sample_w[:self.ray_count] = sample
        self.buffers = {
            "origins": self.own(ctx.buffer(origin_w.tobytes())),
            "directions": self.own(ctx.buffer(dir_w.tobytes())),
            "samples": self.own(ctx.buffer(sample_w.tobytes())),
            "heads": self.own(ctx.buffer(reserve=4 * self.atlas.texels)),
            "blocked": self.own(ctx.buffer(reserve=4 * max(1, words))),
            "counters": self.own(ctx.buffer(reserve=4 * len(COUNTERS))),
            "texels": self.own(ctx.buffer(reserve=4 * max(1, self.ray_count))),
        }
        corners = caster_corners(frame)
        self.buffers["triangles"] = self.own(ctx.buffer(corners.tobytes()))
        self.pool = max(1, self.ray_count)  # one node per ray
        self.buffers["nodes"] = self.own(ctx.buffer(reserve=NODE_BYTES * self.pool))
        self.pair_capacity = self.capacity if self.capacity > 0 else PAIRS_PER_RAY * max(1, self.ray_count)
        self._allocate_pairs()
        self.insert_prog = self.program("izb_insert.glsl", defines={**ATLAS_DEFINES, "LOCAL_SIZE": LOCAL_SIZE})
        programs.set_uniforms(self.insert_prog, self.light.uniforms())
        self.atlas.write_uniforms(self.insert_prog)
        programs.set_uniforms(self.insert_prog, {"u_rays": self.ray_count, "u_samples_per_pixel": self.samples,
                                                 "u_node_capacity": self.pool})
        self.raster_prog = self.program("izb_raster.glsl",
                                        defines={"COVERAGE_POLYGON": 1} if self.coverage == "polygon" else None)
        self.test_prog = self.program("izb_test.glsl", defines={"LOCAL_SIZE": LOCAL_SIZE, "WALK_BUDGET": WALK_BUDGET})
        for prog in (self.raster_prog, self.test_prog):
            programs.set_uniforms(prog, {"u_samples_per_pixel": self.samples,
                                         "u_atlas_size": tuple(map(float, self.atlas.size))})
        programs.set_uniforms(self.raster_prog, {"u_edge_pad": EDGE_PAD, "u_edge_test_limit": EDGE_TEST_LIMIT})
        tri_vbo = self.own(ctx.buffer(np.ascontiguousarray(corners[:, :3]).tobytes()))
        self.caster_vao = self.own(ctx.vertex_array(self.raster_prog, [(tri_vbo, "3f", "in_position")]))
        self.target = self.own(ctx.framebuffer(color_attachments=[self.own(ctx.renderbuffer(self.atlas.size, 1,
                                                                                          dtype="f1"))]))
        self.w_min = self._w_min(origins)
        self.empty_heads = np.full(self.atlas.texels, NO_NODE, np.int32).tobytes()
        self.retries = 0
        self.resumes = 0
        self.counts = dict.fromkeys(COUNTERS, 0)

    def _allocate_pairs(self) -> None:
        """The work list of :attr:`pair_capacity` (triangle, texel) pairs and its walks' continuations."""
        ctx = self.frame.ctx
        for name in ("pairs", "continuation"):
            if name in self.buffers:
                self.free(self.buffers[name])
        self.buffers["pairs"] = self.own(ctx.buffer(reserve=PAIR_BYTES * self.pair_capacity))
        self.buffers["continuation"] = self.own(ctx.buffer(reserve=CONTINUATION_BYTES * self.pair_capacity))

    # -- the rays ------------------------------------------------------------------
    def _rays(self, frame, slot):
        """The shadow rays of the evaluated samples, as the truth traces them: origins (K, 3),
        directions (K, 3), tfar (K,) float32, each ray's sample index (K,) int32 (pixel ``i`` of
        the frame's compact order, sample ``k``: ``i · samples + k``) and its exact surface point
        (K, 3) float64."""
        if self.samples == 1:
            idx = np.flatnonzero(slot.evaluated)
            origins = offset_origins(frame)[idx]
            points = frame.compact_position[idx]
            directions, tfar = slot.light.shadow_rays(origins, points)
            return origins, directions, tfar, idx.astype(np.int32), points
        from ...truth.subpixel import subpixel_samples

        sub = subpixel_samples(frame, self.samples)
        origins, directions, tfar, index = sub.rays(slot.light)
        # only the samples of pixels the frame evaluates: the others keep visibility 1
        keep = slot.evaluated[index // self.samples]
        self.subpixel = sub
        points = sub.points.reshape(-1, 3)[index[keep]]
        return origins[keep], directions[keep], tfar[keep], index[keep].astype(np.int32), points

    def _w_min(self, origins: np.ndarray) -> list[float]:
        """Per face the clip plane w of the raster pass (:data:`W_MIN_FRACTION` × the smallest w
        of the rays' origins in front of the face); 0 for an orthographic face, whose w is 1
        everywhere (nothing is clipped)."""
        out = []
        for face in self.atlas.faces:
            if len(origins) == 0 or face.proj[3, 3] == 1.0:  # orthographic
                out.append(0.0)
                continue
            w = (np.asarray(origins, np.float64) @ face.view_proj[3, :3]) + face.view_proj[3, 3]
            positive = w[w > 0]
            out.append(float(positive.min()) * W_MIN_FRACTION if len(positive) else 0.0)
        return out

    # -- rendering -----------------------------------------------------------------
    def render(self) -> None:
        """Insert the rays into the grid's lists, rasterise the casters into (triangle, texel)
        pairs, test the pairs; an overflowing work list is retried larger or fails
        (``on_overflow``)."""
        for attempt in range(MAX_RETRIES + 1):
            self._render_once()
            asked = int(self.counts["pairs"])
            if asked <= self.pair_capacity:
                break
            if self.on_overflow == "fail" or attempt == MAX_RETRIES:
                raise TechniqueError(f"{self.name}: the work list of {self.pair_capacity} (triangle, texel) pairs "
                                     f"overflowed ({asked} asked for); set capacity=0 or larger, or on_overflow=retry")
            self.notes.append(f"work list of {self.pair_capacity} pairs overflowed ({asked} asked for): retried "
                              f"with {asked}")
            self.retries += 1
            self.pair_capacity = asked
            self._allocate_pairs()
        problems = [f"{self.counts['outside']} rays start outside the light's grid (the fit missed them)"
                    if self.counts["outside"] else "",
                    f"{self.counts['node_overflow']} rays found the node pool full" if self.counts["node_overflow"]
                    else ""]
        if any(problems):
            raise TechniqueError(f"{self.name}: {'; '.join(p for p in problems if p)}: their samples would be lit "
                                 f"wrongly")

    def _render_once(self) -> None:
        """One insert, raster and test pass; the counters read back (the pairs asked for decide
        the test pass's size, so the raster pass's count is read between the two)."""
        ctx = self.frame.ctx
        b = self.buffers
        for name, buf in b.items():
            buf.bind_to_storage_buffer(BINDING[name])
        with self.timed_pass("insert"):
            b["heads"].write(self.empty_heads)
            b["blocked"].clear()
            b["counters"].clear()
            programs.dispatch(self.insert_prog, self.ray_count, LOCAL_SIZE)
            ctx.memory_barrier()
        with self.timed_pass("raster"):
            self.target.use()
            glstate.apply(PassState(color_write=False, depth_write=False))
            self.raster_prog["u_pair_capacity"].value = self.pair_capacity
            for face, rect, w_min in zip(self.atlas.faces, self.atlas.rects, self.w_min):
                ctx.viewport = rect
                self.raster_prog["u_face_view_proj"].write(programs.mat_bytes(face.view_proj))
                margin = 2.0 * COVERAGE_MARGIN / np.array(rect[2:], np.float64)
                programs.set_uniforms(self.raster_prog, {"u_w_min": w_min, "u_margin_ndc": tuple(map(float, margin)),
                                                         "u_viewport": tuple(map(float, rect))})
                self.caster_vao.render(ctx.TRIANGLES)
            ctx.memory_barrier()
            asked = int(np.frombuffer(b["counters"].read(4, offset=4 * COUNTERS.index("pairs")), np.uint32)[0])
        with self.timed_pass("test"):
            pairs = min(asked, self.pair_capacity)
            self.resumes = 0
            if asked <= self.pair_capacity and pairs:  # an overflowing list is rendered again first
                self.test_prog["u_pairs"].value = pairs
                self.test_prog["u_resume"].value = 0
                programs.dispatch(self.test_prog, pairs, LOCAL_SIZE)
                ctx.memory_barrier()
                # walks cut at WALK_BUDGET nodes go on where they stopped; each dispatch takes
                # every pending walk WALK_BUDGET nodes further, so no list needs more than this
                limit = self.ray_count // WALK_BUDGET + 1
                pending_at = 4 * COUNTERS.index("pending")
                while pending := int(np.frombuffer(b["counters"].read(4, offset=pending_at), np.uint32)[0]):
                    if self.resumes == limit:
                        raise TechniqueError(f"{self.name}: {pending} list walks still pending after {limit} "
                                             f"resumed dispatches")
                    note = (f"{pending} list walks longer than {WALK_BUDGET} nodes (llvmpipe ends a loop "
                            f"after 65535 iterations): resumed by further test dispatches (izb_resumes)")
                    if self.resumes == 0 and note not in self.notes:
                        self.notes.append(note)
                    b["counters"].write(np.zeros(1, np.uint32).tobytes(), offset=pending_at)
                    self.test_prog["u_resume"].value = 1
                    programs.dispatch(self.test_prog, pairs, LOCAL_SIZE)
                    ctx.memory_barrier()
                    self.resumes += 1
            self.counts = dict(zip(COUNTERS, np.frombuffer(b["counters"].read(), np.uint32).tolist()))

    # -- results -------------------------------------------------------------------
    def sample_blocked(self) -> np.ndarray:
        """Bool (M, samples): per covered pixel (the frame's compact order) and sample, whether
        its ray was blocked (False for samples without a ray)."""
        words = np.frombuffer(self.buffers["blocked"].read(), np.uint32)[:len(self.frame.pixel_index)]
        bits = (words[:, None] >> np.arange(self.samples, dtype=np.uint32)[None, :]) & 1
        return bits.astype(bool)

    def visibility(self) -> np.ndarray:
        """Float32 (H, W): 1 − blocked (samples=1), or the lit fraction of the pixel's evaluated
        samples; 1 where the frame does not evaluate the pixel."""
        blocked = self.sample_blocked()
        if self.samples == 1:
            vis = np.where(blocked[:, 0], 0.0, 1.0)
        else:
            evaluated = self.subpixel.evaluated(self.light)
            vis = self.subpixel.coverage(evaluated & ~blocked, evaluated)
        vis = np.where(self.evaluated, vis, 1.0).astype(np.float32)
        return self.frame.to_image(vis, fill=1.0)

    def work(self, counted: dict, stats: dict) -> dict:
        """Rays inserted into the light-space lists (one per evaluated sample)."""
        return {"insert": {"rays": stats["izb_rays"]}}

    def stats(self) -> dict:
        """Work counters (rays, (triangle, texel) pairs, triangle–segment tests, hits,
        retries, resumed test dispatches; ``izb_tests`` and ``izb_hits`` are approximate: a ray
        another triangle has already blocked is skipped, and which triangle gets there first depends on scheduling —
        the visibility does not), the list-length distribution over non-empty texels (mean, p99, max), the
        storage-buffer memory, faces, passes, samples per pixel."""
        texels = np.frombuffer(self.buffers["texels"].read(), np.int32)[:self.ray_count]
        lengths = np.bincount(texels[texels >= 0], minlength=1)
        used = lengths[lengths > 0]
        memory = (self.ray_count * (RAY_BYTES + TEXEL_BYTES) + self.pool * NODE_BYTES + 4 * self.atlas.texels
                  + 4 * len(self.frame.pixel_index) + self.buffers["triangles"].size
                  + (PAIR_BYTES + CONTINUATION_BYTES) * self.pair_capacity)
        return {"izb_rays": int(self.ray_count), "izb_pairs": int(self.counts["pairs"]),
                "izb_tests": int(self.counts["tests"]), "izb_hits": int(self.counts["hits"]),
                "izb_retries": int(self.retries), "izb_resumes": int(self.resumes),
                "izb_list_mean": float(used.mean()) if len(used) else 0.0,
                "izb_list_p99": float(np.percentile(used, 99)) if len(used) else 0.0,
                "izb_list_max": int(used.max()) if len(used) else 0, "izb_texels_used": int(len(used)),
                "memory_bytes": int(memory), "faces": len(self.atlas.faces),
                "passes": 2 + len(self.atlas.faces), "samples": int(self.samples)}
