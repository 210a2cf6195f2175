"""Partitioned shadow volumes: the casters' shadow volumes in a ternary tree of planes (TOP tree),
built in compute each frame and queried per pixel, exact against the ray-traced truth.

Gerhards, Mora, Aveneau & Ghazanfarpour 2015 ("Partitioned Shadow Volumes", Computer Graphics
Forum 34(2), Eurographics) revisit the shadow-volume BSP trees of Chin & Feiner 1989 and Slater
1995 without their clipping: each caster triangle's shadow volume is the intersection of four
half-spaces — three *shadow planes* through the light and each edge (for a light at infinity,
through the edge along the light) and the triangle's own *capping plane* — and the volumes go
into a *Ternary Object Partitioning* tree whose nodes are planes with three children: the
negative side, the positive side and an *intersection* child for the volumes that straddle
the plane. Nothing is split, so the tree holds at most a fixed number of nodes per triangle (a
fixed pool) and any triangle soup goes in as it is. A point is located in the tree like a point
in a BSP, except that the intersection child is always visited too: reaching the end of a
triangle's chain of planes means the point lies in its volume — in shadow. Mora, Gerhards,
Aveneau & Ghazanfarpour 2016 ("Deep Partitioned Shadow Volumes Using Stackless and Hybrid
Traversals", EGSR) add depth information to the tree, for the lit points in front of the
casters, and replace the query's stack by a stackless walk over parent links, or a hybrid that
falls back on it when a small stack is full. Here each node keeps the least light depth (distance
to a point light, position along a light at infinity) of the triangles in its subtree, kept up to
date as chains are hung: a point less deep than that, by the margin δ below, cannot be shadowed
by anything in the subtree, which the query skips. The capping plane is a node of each
triangle's chain like its shadow planes, the last one: first in the chain it partitions poorly
(the volumes run to infinity behind it, so most of the volumes tested against it straddle it).

Passes (``shadowlab/techniques/volumes/psv_build.glsl``, ``psv_query.glsl``, sharing
``psv_common.glsl``; GL 4.3 compute and storage buffers):

1. ``build`` (compute): the tree from the caster triangles (float32 corners, as the truth's
   Embree scene holds them; ``order=scene`` as stored, ``order=light`` nearest the light first),
   one invocation per triangle, in rounds: each triangle walks down from where it stopped to the
   first empty child its volume goes to and asks for it (``atomicMin`` of its index); the lowest
   index asking wins and hangs its chain there, the others walk on through it in the next round.
   The papers let the first thread to arrive win (``atomicCompSwap``), a tree that depends on
   scheduling; here the tree, and every count taken from it, is the same on every run and every
   driver, for a few dispatches per level of the tree (``build`` in the pass timings). A triangle
   whose walk ends at another's leaf lies inside that one's volume and is dropped (counted in
   ``triangles_culled``, the papers' culling). The nodes come from a pool of ``pool`` nodes (0:
   five per triangle, which cannot overflow) by an atomic counter; a build that finds the pool
   full stops, and the render is repeated with a full-size pool (``on_overflow=retry``, in the
   notes and ``pool_retries``) or fails (``on_overflow=fail``) — never a tree with volumes missing.
2. ``query`` (compute): one invocation per evaluated pixel locates the truth's own shadow-ray
   origin (:func:`shadowlab.truth.tracing.offset_origins`, as the irregular z-buffer does) in the
   tree, with a stack (``query=stack``, ``stack_size`` nodes, then stackless: the hybrid) or
   without (``query=stackless``, parent links); both enter the same nodes in the same order. A
   query makes at most :data:`STEP_BUDGET` steps per dispatch and is resumed by the next one
   where it stopped (the resumes in the notes): llvmpipe ends an invocation silently after 65535
   loop iterations. The build's walk up a new chain's ancestors loops as deep as the tree: a tree
   half that deep is refused with an error (``order=light`` builds shallower trees).

Exactness (this lab's addition; the papers decide by float32 plane tests, which near a
shadow boundary or a contact disagree with an exact ray test). Every plane decision is
conservative: a node sends a query point to both sides when it lies within a margin of the
plane, and a volume goes to one side at insertion only when all of it lies beyond the margins of
both triangles. The end of a chain is then not a verdict but a candidate: the leaf runs the
watertight ray/triangle test (Woop, Benthin & Wald 2013; ``shadowlab/gpu/watertight.glsl``, the
irregular z-buffer's test) on the truth's ray, and a miss goes on with the traversal. The margins:

- absolute δ = :data:`MARGIN_SCALE` × M (M the largest coordinate magnitude of the casters, the
  ray origins and the light): it covers the float32 evaluation of a plane at a point of
  magnitude M and the absolute uncertainty of the watertight test at the crossing;
- for the shadow planes of a point light, an angle ε_T = δ / (d_T − δ) + :data:`DIRECTION_EPS`
  per triangle (d_T its distance to the light: the absolute uncertainty seen from the light,
  plus the rounding of the ray's float32 direction; rounded up to a power of two, so that the
  triangles of a mesh share it), times the query point's distance to the light.

A corner of the inserted triangle that is one of the corners a node's plane goes through (a
mesh's shared edge or vertex) lies on that plane in exact arithmetic and takes no margin: the
volume touches the plane and still goes to one side, where the margins alone would send every
neighbour of a mesh triangle to the intersection child. For a shadow plane this needs the
inserted triangle's relative margin to be no larger than the node's, whose margin then covers
the inserted triangle's uncertainty at the query.

With these, (a) a ray whose exact test hits T reaches T's leaf (at every node on T's path the
ray's origin lies within the margin of T's side; the triangle's own planes are within its own
ε_T); (b) a triangle dropped at T's leaf lies inside T's volume by the sum of both margins
(touching corners never drop a triangle), so
that any ray hitting it hits T (by the exact test too) — unless T is too close to a point light
for the truth's ray, which stops short of it (``tfar``), or lies partly behind a target-direct
light's disc: such leaves drop nothing; and (c) a ray blocked by a triangle starts deeper than
the triangle's nearest point, up to the float32 rounding that δ covers, so the depth test skips
no subtree that could block it. Planes whose orientation double precision cannot settle (the
light almost in a triangle's plane, or on an edge's line) are transparent: both sides visited,
the exact test decides. So the mask is the exact test's verdict on every ray: that of the
irregular z-buffer, which agrees with the truth but for ties it documents.

The price of the margins: a receiver on a lit face of a caster lies within δ of that face's own
capping plane (its ray starts 2^-18 of the scene's size off the surface, the truth's offset), so
its query reaches that triangle's leaf and makes one exact test that misses.

The rays and their origins are built on the CPU in ``setup`` (the truth's float64 points and
rounding), as the irregular z-buffer does. ``nodes_visited`` (= ``pixel_ops``, the papers'
measure of query work) counts the nodes each query enters, leaves included.
"""
from __future__ import annotations

import numpy as np

from ...gpu import programs
from ...truth.tracing import caster_corners, offset_origins
from ..base import FIRST, MAX, SUM, Param, PlotStyle, Technique, TechniqueError

#: Storage-buffer bindings (``psv_common.glsl``).
BINDING = {"origins": 0, "directions": 1, "triangles": 2, "nodes": 3, "counters": 4, "blocked": 5, "visits": 6,
           "staged": 7, "walks": 8, "claims": 9, "query_states": 10}
#: Counter slots (``psv_common.glsl``: COUNTER_*).
COUNTERS = ("nodes", "overflow", "culled", "skipped", "depth", "leaf_tests", "stack_overflows", "inserted", "root",
            "wanting", "pending")
#: u_stage values of ``psv_build.glsl`` (STAGE_*).
STAGE_PREPARE, STAGE_WALK, STAGE_HANG = 0, 1, 2
#: RAY_PENDING of ``psv_common.glsl``: a ray whose query ran out of steps in one dispatch.
RAY_PENDING = 2
#: Nodes per inserted triangle: three shadow planes, the capping plane, the leaf.
NODES_PER_TRIANGLE = 5
#: Bytes of one node (``psv_common.glsl``: Node, std430) with its three child slots' claims, one
#: ray (origin+tfar, direction, the result, the visit count, the saved walk) and one triangle (three
#: vec4 corners, five staged vec4, the walk's ivec4).
NODE_BYTES, RAY_BYTES, TRIANGLE_BYTES = 48 + 12, 48, 48 + 80 + 16
#: The absolute margin δ, × M (module docstring): 2^-17, about 128 float32 ulps of M — above
#: the float32 error of a plane evaluated at a point of size M (a few ulps) plus the watertight
#: test's own uncertainty (a few ulps), with room to spare; it only makes more points take both
#: sides of a plane near it, never a wrong answer.
MARGIN_SCALE = 2.0 ** -17
#: The angle (radians) covering a float32 ray direction's rounding (light − origin: 2^-24 per
#: component) and the float32 distance to the light that scales the margins.
DIRECTION_EPS = 2.0 ** -20
#: A triangle nearer a point light than this × the farthest ray's length drops nothing: the
#: truth's rays stop at T_LIGHT = 1 − 2^-20 of the way, so one that far from the light could be
#: passed by a ray that a volume inside its own still stops (8× margin).
NEAR_SCALE = 2.0 ** -17
#: Nodes of the query's stack (``query=stack``); a query that needs more goes on stackless.
STACK_SIZE = 32
#: Steps (nodes entered or returned to) one query makes per dispatch; a query that needs more is
#: resumed by another dispatch where it stopped. llvmpipe ends a shader invocation silently after
#: 65535 loop iterations (Mesa's LP_MAX_TGSI_LOOP_ITERATIONS), so no walk may loop longer.
STEP_BUDGET = 16384
#: Dispatches of a query over the pending rays before the run fails (each makes STEP_BUDGET steps).
MAX_RESUMES = 10000
#: Compute invocations per work group of the build and the query; larger dispatches are split over y.
LOCAL_SIZE = 64


class PartitionedVolume(Technique):
    """Partitioned shadow volumes (module docstring): a TOP tree of the casters' shadow planes
    built in compute, each evaluated pixel's shadow-ray origin located in it, exact leaves."""

    name = "partitioned_volume"
    summary = ("partitioned shadow volumes (Gerhards et al. 2015; Mora et al. 2016): the casters' shadow planes in "
               "a ternary tree built in compute, each pixel located in it; exact leaf tests")
    STYLE = PlotStyle("#393b79", "*")
    LIGHT_SAMPLED = True  # area lights: averaged over point lights, like the other hard techniques
    LIGHTS = frozenset({"point", "spot", "directional", "target_direct", "area"})
    PASSES = ("build", "query")
    PARAMS = {
        "query": Param("stack", f"tree traversal: stack (a {STACK_SIZE}-node stack, stackless past it: the hybrid "
                                f"of Mora et al. 2016) or stackless (parent links); the same nodes either way",
                       choices=("stack", "stackless")),
        "stack_size": Param(STACK_SIZE, "nodes of the query's stack (query=stack); a query needing more is counted "
                                        "and goes on stackless", min=1, max=256),
        "order": Param("scene", "insertion order: scene (as stored) or light (nearest the light first, sorted on "
                                "the CPU in setup; deeper trees and no more culling on the shipped scenes)", choices=("scene", "light")),
        "pool": Param(0, f"tree nodes in the pool (0: {NODES_PER_TRIANGLE} per caster triangle, which cannot "
                         f"overflow)", min=0),
        "on_overflow": Param("retry", "a full pool: build again with a full-size pool, or fail",
                             choices=("retry", "fail")),
    }
    STATS = {"triangles": FIRST, "tree_nodes": SUM, "triangles_culled": SUM, "triangles_skipped": SUM,
             "tree_depth": MAX, "nodes_visited": SUM, "nodes_visited_mean": FIRST, "nodes_visited_max": MAX,
             "pixel_ops": SUM, "leaf_tests": SUM, "stack_overflows": SUM, "pool_retries": SUM,
             "memory_bytes": MAX}

    def setup(self, frame, slot) -> None:
        """The rays (the truth's), the caster triangles, the margins, the buffers and programs."""
        ctx = frame.ctx
        light = slot.light
        idx = np.flatnonzero(slot.evaluated)
        origins = offset_origins(frame)[idx]
        directions, tfar = light.shadow_rays(origins, frame.compact_position[idx])
        self.ray_index = idx
        self.ray_count = len(idx)
        corners = caster_corners(frame)
        if self.order == "light" and len(corners) > 3:
            corners = self._nearest_first(corners, light)
        self.triangle_count = len(corners) // 3 if frame.has_casters else 0
        rays = max(1, self.ray_count)
        origin_w = np.zeros((rays, 4), np.float32)
        origin_w[:self.ray_count, :3], origin_w[:self.ray_count, 3] = origins, tfar
        dir_w = np.zeros((rays, 4), np.float32)
        dir_w[:self.ray_count, :3] = directions
        # M: the largest coordinate magnitude the planes are evaluated at (casters, origins, light)
        point = not light.at_infinity
        position = np.asarray(getattr(light, "position", np.zeros(3)), np.float64)
        magnitude = max(float(np.abs(corners).max()) if len(corners) else 0.0,
                        float(np.abs(origins).max()) if len(origins) else 0.0,
                        float(np.abs(position).max()), float(frame.scene.extent()), 1e-30)
        far = float(np.linalg.norm(origins.astype(np.float64) - position, axis=1).max()) if point and len(origins) \
            else 0.0
        self.delta = MARGIN_SCALE * magnitude
        self.buffers = {
            "origins": self.own(ctx.buffer(origin_w.tobytes())),
            "directions": self.own(ctx.buffer(dir_w.tobytes())),
            "triangles": self.own(ctx.buffer(corners.tobytes())),
            "counters": self.own(ctx.buffer(reserve=4 * len(COUNTERS))),
            "blocked": self.own(ctx.buffer(reserve=4 * rays)),
            "visits": self.own(ctx.buffer(reserve=4 * rays)),
            "query_states": self.own(ctx.buffer(reserve=8 * rays)),
            "staged": self.own(ctx.buffer(reserve=80 * max(1, self.triangle_count))),
            "walks": self.own(ctx.buffer(reserve=16 * max(1, self.triangle_count))),
        }
        self.full_pool = NODES_PER_TRIANGLE * max(1, self.triangle_count)
        self._make_pool(self.pool if self.pool > 0 else self.full_pool)
        common = {"u_point": int(point), "u_light_position": tuple(map(float, position.astype(np.float32))),
                  "u_light_direction": tuple(map(float, np.asarray(getattr(light, "direction", (0.0, -1.0, 0.0)),
                                                                   np.float32))),
                  "u_delta": float(self.delta)}
        self.build_prog = self.program("psv_build.glsl", defines={"LOCAL_SIZE": LOCAL_SIZE})
        programs.set_uniforms(self.build_prog, {**common, "u_triangles": self.triangle_count,
                                                "u_target": int(light.type_name == "target_direct"),
                                                "u_near": float(NEAR_SCALE * far), "u_direction_eps": DIRECTION_EPS})
        defines = {"LOCAL_SIZE": LOCAL_SIZE, "STEP_BUDGET": STEP_BUDGET}
        if self.query == "stack":
            defines.update(QUERY_STACK=1, STACK_SIZE=self.stack_size)
        self.query_prog = self.program("psv_query.glsl", defines=defines)
        programs.set_uniforms(self.query_prog, {**common, "u_rays": self.ray_count})
        self.retries = 0
        self.counts = dict.fromkeys(COUNTERS, 0)

    def _make_pool(self, nodes: int) -> None:
        """A node pool of ``nodes`` nodes (replacing the last one)."""
        for key in ("nodes", "claims"):
            if key in self.buffers:
                self.free(self.buffers[key])
        self.pool_nodes = nodes
        self.buffers["nodes"] = self.own(self.frame.ctx.buffer(reserve=48 * nodes))
        self.buffers["claims"] = self.own(self.frame.ctx.buffer(reserve=4 * (1 + 3 * nodes)))

    @staticmethod
    def _nearest_first(corners: np.ndarray, light) -> np.ndarray:
        """``corners`` (3T, 4) reordered triangle by triangle, nearest the light first (each
        triangle's nearest corner: its distance to a point light, or its depth along a light at
        infinity), ties in scene order."""
        pts = corners[:, :3].astype(np.float64).reshape(-1, 3, 3)
        if light.at_infinity:
            key = (pts @ np.asarray(light.direction, np.float64)).min(axis=1)
        else:
            key = np.linalg.norm(pts - np.asarray(light.position, np.float64), axis=2).min(axis=1)
        order = np.argsort(key, kind="stable")
        return np.ascontiguousarray(corners.reshape(-1, 3, 4)[order].reshape(-1, 4))

    # -- rendering -----------------------------------------------------------------
    def render(self) -> None:
        """Build the tree, then query it per ray; a full pool is retried with a full-size pool or
        fails (``on_overflow``)."""
        for attempt in range(2):
            if self._render_once():
                return
            left = self.counts["overflow"]
            if self.on_overflow == "fail" or self.pool_nodes >= self.full_pool:
                raise TechniqueError(f"{self.name}: the pool of {self.pool_nodes} tree nodes overflowed ({left} "
                                     f"triangles not inserted); set pool=0 or larger, or on_overflow=retry")
            self.notes.append(f"pool of {self.pool_nodes} tree nodes overflowed ({left} triangles not inserted): "
                              f"retried with {self.full_pool}")
            self.retries += 1
            self._make_pool(self.full_pool)

    def _counters(self) -> dict:
        """The counter slots, read back."""
        return dict(zip(COUNTERS, np.frombuffer(self.buffers["counters"].read(), np.uint32).tolist()))

    def _render_once(self) -> bool:
        """One build and (when the tree is complete) one query; False when the pool overflowed.
        The build's rounds run until no triangle asks for a child (at least one triangle is
        inserted or dropped per round); the query's dispatches until no ray is pending. The
        counters are read between them: a query never runs on an incomplete tree."""
        ctx = self.frame.ctx
        b = self.buffers
        for name, buf in b.items():
            buf.bind_to_storage_buffer(BINDING[name])
        zero = np.zeros(1, np.uint32).tobytes()
        with self.timed_pass("build"):
            b["counters"].clear()
            b["claims"].clear(chunk=b"\xff\xff\xff\xff")
            self.build_prog["u_pool"].value = self.pool_nodes
            self.build_prog["u_stage"].value = STAGE_PREPARE
            programs.dispatch(self.build_prog, self.triangle_count, LOCAL_SIZE)
            ctx.memory_barrier()
            self.rounds = 0
            while self.triangle_count:
                b["counters"].write(zero, offset=4 * COUNTERS.index("wanting"))
                self.build_prog["u_stage"].value = STAGE_WALK
                programs.dispatch(self.build_prog, self.triangle_count, LOCAL_SIZE)
                ctx.memory_barrier()
                counts = self._counters()
                if counts["wanting"] == 0 or counts["overflow"]:
                    break
                self.build_prog["u_stage"].value = STAGE_HANG
                programs.dispatch(self.build_prog, self.triangle_count, LOCAL_SIZE)
                ctx.memory_barrier()
                self.rounds += 1
            self.counts = self._counters()
        # hang() walks up the new chain's ancestors in one loop, as many steps as the tree is deep:
        # llvmpipe would end it silently past its loop limit (ancestors left with stale depths)
        depth = self.counts["depth"]
        if depth >= programs.LLVMPIPE_LOOP_LIMIT // 2:
            raise TechniqueError(
                f"{self.name}: the tree is {depth:,} nodes deep, more than one invocation may walk up "
                f"(llvmpipe stops a loop after {programs.LLVMPIPE_LOOP_LIMIT:,} iterations, so the ancestors' "
                f"depths could be left wrong); use order=light (a shallower tree) or fewer triangles")
        if self.counts["overflow"]:
            return False
        with self.timed_pass("query"):
            self.resumes = 0
            if self.ray_count:
                self.query_prog["u_resume"].value = 0
                programs.dispatch(self.query_prog, self.ray_count, LOCAL_SIZE)
                ctx.memory_barrier()
                while self._counters()["pending"]:
                    if self.resumes == MAX_RESUMES:
                        raise TechniqueError(f"{self.name}: queries still pending after {MAX_RESUMES} dispatches")
                    b["counters"].write(zero, offset=4 * COUNTERS.index("pending"))
                    self.query_prog["u_resume"].value = 1
                    programs.dispatch(self.query_prog, self.ray_count, LOCAL_SIZE)
                    ctx.memory_barrier()
                    self.resumes += 1
            if self.resumes:
                self.notes.append(f"queries resumed {self.resumes} time(s) ({STEP_BUDGET} steps per dispatch)")
            self.counts = self._counters()
        return True

    # -- results -------------------------------------------------------------------
    def ray_blocked(self) -> np.ndarray:
        """Bool (K,): per evaluated pixel (in the frame's compact order), whether its ray is blocked."""
        return np.frombuffer(self.buffers["blocked"].read(), np.uint32)[:self.ray_count] == 1

    def visibility(self) -> np.ndarray:
        """Float32 (H, W): 0 where the pixel's shadow ray is blocked, 1 elsewhere (and where the
        frame does not evaluate the pixel)."""
        vis = np.ones(len(self.frame.pixel_index), np.float32)
        vis[self.ray_index[self.ray_blocked()]] = 0.0
        return self.frame.to_image(vis, fill=1.0)

    def work(self, counted: dict, stats: dict) -> dict:
        """The rays the query locates in the tree (one per evaluated pixel)."""
        return {"query": {"rays": int(self.ray_count)}}

    def stats(self) -> dict:
        """The tree (triangles, nodes, culled and skipped triangles, depth), the queries' nodes
        entered (total = ``pixel_ops``, mean and max per ray), their exact leaf tests and stack
        overflows, pool retries and the storage-buffer memory."""
        visits = np.frombuffer(self.buffers["visits"].read(), np.uint32)[:self.ray_count].astype(np.int64)
        c = self.counts
        total = int(visits.sum())
        memory = (NODE_BYTES * self.pool_nodes + 4 + RAY_BYTES * self.ray_count
                  + TRIANGLE_BYTES * self.triangle_count + 4 * len(COUNTERS))
        return {"triangles": int(self.triangle_count), "tree_nodes": int(c["nodes"]),
                "triangles_culled": int(c["culled"]), "triangles_skipped": int(c["skipped"]),
                "tree_depth": int(c["depth"]), "nodes_visited": total,
                "nodes_visited_mean": total / self.ray_count if self.ray_count else 0.0,
                "nodes_visited_max": int(visits.max()) if self.ray_count else 0,
                "pixel_ops": total, "leaf_tests": int(c["leaf_tests"]),
                "stack_overflows": int(c["stack_overflows"]), "pool_retries": int(self.retries),
                "memory_bytes": int(memory)}
