"""A Frame: one scene uploaded to GL, seen by its camera, with the shared primary visibility.

Every technique and the ground truth read the same G-buffer (docs/architecture.md), so differences
between their images are differences in shadows only. Besides the GL textures, the frame
holds the exact surface point of every covered pixel: the pixel-centre camera ray intersected
in float64 with the triangle the G-buffer saw there (docs/architecture.md#evaluation-evaluator-in-shadowlabmeasurementpipelinepy). Arrays are (height, width, ...)
with row 0 at the top of the image; "compact" arrays hold only covered pixels, in the order of
``np.flatnonzero(covered)``.

What techniques may do with a frame (the stage contract, docs/architecture.md): read everything — the
G-buffer textures (the channels of :data:`GBUFFER_CHANNELS`, sampled by the techniques that
declare them in their ``READS``), the vertex buffers (through :meth:`Frame.draw`), the exact points and the
:class:`LightSlot` they render for (the light, its index, its evaluated mask) — and modify
nothing, with one declared exception: the G-buffer's depth-stencil
attachment, whose contents nobody reads after the G-buffer pass, is lent to the techniques that
list ``"depth_stencil"`` in their ``WRITES`` (:meth:`Frame.depth_stencil_for`); they
clear it before use. The frame's own caches (evaluated masks, keyed by the light object, and
the scene lights' slots) live on the frame.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import gl, glstate, heap, programs, targets
from .glstate import PassState
from ..geometry.frusta import Casters
from ..geometry.triangles import triangle_normals
from ..scene.lights import Light
from ..truth.pixel_rays import (  # noqa: F401  (the frame's camera rays and exact points)
    PIXEL_CENTRE, _pixel_ray_terms, evaluated_rule, plane_hits, plane_numerators,
)
from ..scene import Scene


#: The G-buffer's channels, in the order they take texture units when a technique binds the ones
#: it declares (``Technique.READS``, :meth:`shadowlab.techniques.base.Technique.bind_gbuffer`):
#: world position (w = 1 where covered), geometric normal, (object id, triangle id). A shader
#: samples channel ``c`` through the uniform ``u_<c>`` (``gbuffer_fetch.glsl``).
GBUFFER_CHANNELS = ("position", "normal", "ids")
#: The shared frame resources a technique may declare it overwrites (``Technique.WRITES``): the
#: G-buffer's depth-stencil attachment (:meth:`Frame.depth_stencil_for`).
FRAME_WRITABLE = frozenset({"depth_stencil"})


@dataclass(frozen=True, eq=False)
class LightSlot:
    """What a technique renders for: one light of a frame.

    ``index`` is the light's place in the scene (metrics rows, notes); ``light`` the light to
    render for — the scene's own, or a point light standing in for it while the pipeline
    averages a hard technique over points of an area light (``stands_in_for`` is then that
    area light); ``evaluated`` the compact bool (M,) mask of the pixels evaluated for ``light``
    (docs/metrics.md; :meth:`Frame.evaluated_mask`); ``scene_lights`` every light of the scene as this
    render sees them (``light`` at ``index``), for the techniques that rank lights against each
    other. Techniques get a slot and never read ``frame.scene.lights``."""

    index: int
    light: Light
    evaluated: np.ndarray = field(repr=False)
    scene_lights: tuple = field(repr=False, default=())
    stands_in_for: Light | None = None


@dataclass
class DrawRange:
    """A run of triangles in the scene's vertex buffer: first vertex and vertex count."""

    first: int
    count: int


class Frame:
    """Uploads ``scene`` once and renders its G-buffer at ``width`` x ``height``."""

    def __init__(self, scene: Scene, width: int, height: int):
        self.scene = scene
        self._casters = None
        self.width, self.height = int(width), int(height)
        self.camera = scene.fitted_camera()
        self.view = self.camera.view()
        self.projection = self.camera.projection(self.width / self.height)
        self.view_projection = self.projection @ self.view
        heap.keep_freed_memory()  # per-pixel arrays reuse freed memory (shadowlab.gpu.heap)
        self.ctx = gl.context()
        self._upload()
        self._render_gbuffer()
        self.compute_exact_points()
        #: id(light) → (light, compact mask): keyed by the light object (kept alive here, so the
        #: id is not reused), never by its position in a list.
        self._evaluated: dict[int, tuple[Light, np.ndarray]] = {}
        self._slots: dict[int, LightSlot] = {}

    # ------------------------------------------------------------------ upload
    def _upload(self) -> None:
        objs = self.scene.objects
        tris = [o.triangles for o in objs]
        self.triangles = np.concatenate(tris)  # (T, 3, 3) float64 world
        self.triangle_object = np.concatenate([np.full(len(t), i, np.int32) for i, t in enumerate(tris)])
        starts = np.cumsum([0] + [len(t) for t in tris])
        self.object_ranges = [DrawRange(int(3 * a), int(3 * (b - a))) for a, b in zip(starts[:-1], starts[1:])]
        self.triangle_normals, twice_area = triangle_normals(self.triangles)  # (T, 3) unit, zero if degenerate
        self.degenerate_triangles = int(np.sum(twice_area == 0))
        verts = self.triangles.reshape(-1, 3).astype("f4")
        nrm = np.repeat(self.triangle_normals, 3, axis=0).astype("f4")
        obj = np.repeat(self.triangle_object, 3).astype("i4")
        ctx = self.ctx
        self.vbo_position = ctx.buffer(verts.tobytes())
        self.vbo_normal = ctx.buffer(nrm.tobytes())
        self.vbo_object = ctx.buffer(obj.tobytes())
        self._vaos: dict[int, object] = {}

    def vertex_array(self, prog):
        """A VertexArray binding the scene's buffers to whichever of ``in_pos``, ``in_normal``,
        ``in_object`` the program uses (cached per program, released with the frame: programs are
        shared for the life of the process)."""
        key = id(prog)
        if key not in self._vaos:
            content = [(buf, fmt, name) for buf, fmt, name in
                       ((self.vbo_position, "3f", "in_pos"), (self.vbo_normal, "3f", "in_normal"),
                        (self.vbo_object, "1i", "in_object")) if name in prog]
            self._vaos[key] = (prog, self.ctx.vertex_array(prog, content))
        return self._vaos[key][1]

    def ranges(self, which: str = "all") -> list[DrawRange]:
        """Draw ranges of ``which`` objects ('all', 'casters', 'receivers'), adjacent runs merged."""
        keep = {"all": lambda o: True, "casters": lambda o: o.casts, "receivers": lambda o: o.receives}[which]
        out: list[DrawRange] = []
        for obj, rng in zip(self.scene.objects, self.object_ranges):
            if not keep(obj):
                continue
            if out and out[-1].first + out[-1].count == rng.first:
                out[-1] = DrawRange(out[-1].first, out[-1].count + rng.count)
            else:
                out.append(DrawRange(rng.first, rng.count))
        return out

    def draw(self, prog, which: str = "all", instances: int = 1) -> None:
        """Draw the ``which`` objects of the scene with ``prog`` into the bound framebuffer,
        ``instances`` times in each draw (``gl_InstanceID`` 0 … instances − 1: the map
        toolkit's one-pass depth pass draws every face of an atlas this way)."""
        vao = self.vertex_array(prog)
        for rng in self.ranges(which):
            if instances == 1:
                vao.render(vertices=rng.count, first=rng.first)
            else:
                vao.render(vertices=rng.count, first=rng.first, instances=instances)

    def caster_bounds(self) -> np.ndarray:
        """Per caster object, its axis-aligned bounds (K, 2, 3)."""
        return np.stack([o.bounds() for o in self.scene.objects if o.casts]) if self.has_casters \
            else np.zeros((0, 2, 3))

    def casters(self) -> Casters:
        """What casts, as the light-view fits take it (:class:`shadowlab.geometry.frusta.Casters`):
        per caster object its bounds, and every caster triangle (world, float64)."""
        if self._casters is None:
            casting = np.array([o.casts for o in self.scene.objects], bool)
            tris = self.triangles[casting[self.triangle_object]] if len(casting) else self.triangles[:0]
            self._casters = Casters(self.caster_bounds(), tris)
        return self._casters

    @property
    def has_casters(self) -> bool:
        """True when at least one object casts shadows."""
        return any(o.casts for o in self.scene.objects)

    # ------------------------------------------------------------------ G-buffer
    def _render_gbuffer(self) -> None:
        from OpenGL import GL

        ctx, size = self.ctx, (self.width, self.height)
        self.tex_position = ctx.texture(size, 4, dtype="f4")
        self.tex_normal = ctx.texture(size, 4, dtype="f4")
        self.tex_ids = ctx.texture(size, 2, dtype="i4")
        for tex in (self.tex_position, self.tex_normal, self.tex_ids):
            tex.filter = (ctx.NEAREST, ctx.NEAREST)
        self.target = targets.ScreenTarget.create(size, [self.tex_position, self.tex_normal, self.tex_ids])
        self.gbuffer_program = programs.program("gbuffer.glsl")
        self.gbuffer_program["u_view_proj"].write(programs.mat_bytes(self.view_projection))
        self.target.use()
        glstate.apply(PassState(depth_test=True, depth_func="<", depth_write=True))  # before the clears
        GL.glClearBufferfv(GL.GL_COLOR, 0, (0.0, 0.0, 0.0, 0.0))
        GL.glClearBufferfv(GL.GL_COLOR, 1, (0.0, 0.0, 0.0, 0.0))
        GL.glClearBufferiv(GL.GL_COLOR, 2, (-1, -1, 0, 0))
        self.target.clear_depth_stencil()
        self.draw(self.gbuffer_program, "all")
        ctx.finish()
        gl.check_errors("G-buffer pass")
        ids = targets.read_texture(self.tex_ids, 2, "i4")
        self.object_id = ids[..., 0].copy()
        self.triangle_id = ids[..., 1].copy()
        self.covered = self.triangle_id >= 0

    def compute_exact_points(self) -> None:
        """(Re)compute the float64 hit points of the pixel-centre rays with the triangles the
        G-buffer saw (``compact_position``, ``compact_normal`` turned to the camera,
        ``compact_valid``: False where a degenerate triangle or a grazing ray gives no point).

        Bit for bit the straightforward computation — ``ray_plane_hits(eye, pixel_rays[covered],
        v0[tri], n[tri])`` (:func:`shadowlab.geometry.rays.ray_plane_hits`, pinned by
        tests/truth/test_ground_truth.py) — but only on covered pixels and with every arithmetic result
        formed by the same operation on the same operands: the rays from per-column and per-row
        tables (the same two terms :meth:`Camera.pixel_rays` adds), the plane's numerator
        (v0 − eye)·n once per triangle and gathered, N·d summed in ``einsum``'s order. The
        per-pixel work is one compiled pass (:func:`shadowlab.truth.compiled.exact_points`,
        issue 27; :func:`plane_hits` is the same arithmetic in numpy), which also forms the
        truth's shadow-ray origins at the default offset (:func:`shadowlab.truth.tracing.offset_origins`,
        bit for bit :func:`shadowlab.truth.tracing.offset_points`): every CPU ray tracer of the lab
        starts from them, and forming them while the point is in registers saves a second pass
        over 48 bytes per pixel."""
        from ..truth import compiled as compiled_truth, tracing

        compiled_truth.warm()  # load every compiled pass with the first frame, not in a timed render
        w, h = self.width, self.height
        col_term, row_term = _pixel_ray_terms(self.camera, w, h)
        eye = np.asarray(self.camera.eye, np.float64)
        unit = np.ascontiguousarray(self.triangle_normals, np.float64)
        numerator = plane_numerators(self.triangles, unit, eye)
        tri_valid = np.any(unit != 0, axis=1)  # negation keeps zero-ness
        extent, scale = float(self.scene.extent()), tracing.DEFAULT_OFFSET_SCALE
        first = np.empty(h + 1, np.int64)  # covered pixels above each row, then their total
        compiled_truth.covered_above_rows(self.covered, first)
        m = int(first[-1])
        # outputs allocated by numpy, in memory earlier frames freed (shadowlab.gpu.heap)
        idx, objects = np.empty(m, np.int64), np.empty(m, self.object_id.dtype)
        points, normals, valid = np.empty((m, 3)), np.empty((m, 3)), np.empty(m, bool)
        origins = np.empty((m, 3), np.float32)
        bad = compiled_truth.in_parts(
            lambda r0, r1: compiled_truth.exact_points(self.covered, self.triangle_id, self.object_id, col_term,
                                                       row_term, unit, numerator, tri_valid, eye, extent, scale,
                                                       r0, r1, int(first[r0]), idx, objects, points, normals,
                                                       valid, origins),
            compiled_truth.split(h, m))
        self.pixel_index = idx  # row-major covered pixels, as np.flatnonzero(covered)
        self.compact_position = points  # (M, 3) float64
        self.compact_normal = normals  # (M, 3) float64, unit, facing the camera (two-sided surfaces, docs/metrics.md)
        self.compact_object = objects
        self.compact_valid = valid
        # The truth's default ray origins came out of the same pass (a NaN among them: the numpy
        # formula decides all of them, tracing.offset_points); any others are formed on demand.
        if sum(bad):
            origins = tracing.offset_points_reference(points, normals, extent, scale)
        tracing.set_frame_origins(self, {scale: origins})

    def to_image(self, compact: np.ndarray, fill=np.nan, dtype=np.float32) -> np.ndarray:
        """Scatter a compact per-pixel array (M,) or (M, C) into a (height, width[, C]) image."""
        shape = (self.height * self.width,) + compact.shape[1:]
        out = np.full(shape, fill, dtype=dtype)
        out[self.pixel_index] = compact
        return out.reshape((self.height, self.width) + compact.shape[1:])

    @property
    def position(self) -> np.ndarray:
        """Exact world positions, float64 (height, width, 3), NaN where nothing is visible."""
        return self.to_image(self.compact_position, dtype=np.float64)

    def pixel_footprint(self) -> np.ndarray:
        """World size of one pixel at each visible point (distance × pixel angle), float64
        (height, width), NaN where nothing is visible."""
        dist = np.linalg.norm(self.compact_position - self.camera.eye, axis=1)
        per_unit = 2.0 * np.tan(np.radians(self.camera.fov_y) / 2.0) / self.height
        return self.to_image(dist * per_unit, dtype=np.float64)

    def gbuffer_texture(self, channel: str):
        """The G-buffer texture of ``channel`` (one of :data:`GBUFFER_CHANNELS`; KeyError with the
        known names otherwise). What :meth:`shadowlab.techniques.base.Technique.bind_gbuffer`
        binds: techniques name channels, not the frame's attributes."""
        if channel not in GBUFFER_CHANNELS:
            raise KeyError(f"no G-buffer channel {channel!r} (the channels: {', '.join(GBUFFER_CHANNELS)})")
        return getattr(self, f"tex_{channel}")

    def depth_stencil_for(self, technique) -> targets.ScreenTarget:
        """The G-buffer's depth-stencil attachment, lent to ``technique`` (to share with its own
        colour targets: ``targets.ScreenTarget.create(..., share_depth_stencil=...)``). Only techniques
        that declare ``"depth_stencil"`` in ``WRITES`` may have it: its contents are
        theirs to clear and overwrite, and nothing after the G-buffer pass reads them."""
        if "depth_stencil" not in technique.WRITES:
            raise RuntimeError(f"{type(technique).__name__} uses the frame's depth-stencil without declaring "
                               f"'depth_stencil' in WRITES")
        return self.target

    # ------------------------------------------------------------------ light slots
    def evaluated_mask(self, light: Light) -> np.ndarray:
        """Compact bool (M,): receiving surface, facing ``light`` (N·L > 0) and lit by its
        footprint (λ > 0) — the evaluated pixels of docs/metrics.md — computed once per light object."""
        key = id(light)
        if key not in self._evaluated:
            self._evaluated[key] = (light, self._mask_for(light))
        return self._evaluated[key][1]

    def _mask_for(self, light: Light) -> np.ndarray:
        """:meth:`evaluated_mask`, computed."""
        receives = np.array([o.receives for o in self.scene.objects])[self.compact_object]
        return evaluated_rule(light, self.compact_position, self.compact_normal, self.compact_valid, receives)

    def slot(self, light_index: int) -> LightSlot:
        """The :class:`LightSlot` of the scene's light ``light_index`` (made once)."""
        lights = self.scene.lights
        if not 0 <= light_index < len(lights):
            raise IndexError(f"light {light_index} of a scene with {len(lights)} lights")
        if light_index not in self._slots:
            light = lights[light_index]
            self._slots[light_index] = LightSlot(light_index, light, self.evaluated_mask(light), tuple(lights))
        return self._slots[light_index]

    def as_slot(self, light: "LightSlot | int") -> LightSlot:
        """``light`` if it is a slot, else the slot of the scene's light with that index."""
        return light if isinstance(light, LightSlot) else self.slot(int(light))

    def stand_in(self, slot: LightSlot, light: Light) -> LightSlot:
        """A slot for ``light`` standing in for ``slot``'s light under its index (light sampling):
        its own evaluated mask, and the scene's lights with ``light`` in the slot's place. The
        shared scene is not touched, and the mask is not cached (one per sample point)."""
        mask = self._mask_for(light)
        lights = list(slot.scene_lights)
        lights[slot.index] = light
        return LightSlot(slot.index, light, mask, tuple(lights), stands_in_for=slot.light)

    def compact_evaluated(self, light_index: int) -> np.ndarray:
        """Compact bool (M,): the evaluated pixels of the scene's light ``light_index``."""
        return self.slot(light_index).evaluated

    def evaluated(self, light_index: int) -> np.ndarray:
        """Bool (height, width): the evaluated pixels of the scene's light ``light_index``."""
        return self.to_image(self.compact_evaluated(light_index), fill=False, dtype=bool)

    def evaluated_image(self, slot: LightSlot) -> np.ndarray:
        """Bool (height, width): the evaluated pixels of ``slot``."""
        return self.to_image(slot.evaluated, fill=False, dtype=bool)

    def release(self) -> None:
        """Free the frame's GL objects."""
        targets.park()
        for _, vao in self._vaos.values():
            vao.release()
        self.target.release()
        for obj in (self.tex_position, self.tex_normal, self.tex_ids, self.vbo_position, self.vbo_normal,
                    self.vbo_object):  # gbuffer_program: programs.program's cache keeps it
            obj.release()
