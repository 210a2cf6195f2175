"""Device-independent work counters of a technique's passes (docs/cost.md).

A time is the cost of one render on one device; the work a render asks of the pipeline — draws,
vertices, samples that pass the depth test, bytes cleared, compute invocations, rays — is the
same on every device, and a device's cost model turns it into time
(:mod:`shadowlab.analysis.cost`). The pipeline makes one counting render per measurement, after the timed
renders (:func:`shadowlab.measurement.pipeline.measure`): a :class:`WorkCounter` is set on the technique,
each :meth:`~shadowlab.techniques.Technique.timed_pass` of the render opens a pass in it, and
for the length of the render the counter hooks the entry points every technique draws through
(one table, :data:`HOOKS`):

- moderngl ``VertexArray.render``/``transform``: one draw each; the vertices it submits
  (``vertices`` × instances, as asked); a ``GL_SAMPLES_PASSED`` query around the draw; and the
  bytes each passing sample writes to the bound framebuffer (colour attachments with their
  write mask on, depth when the depth test and depth writes are on);
- moderngl ``ComputeShader.run``: one dispatch; groups × the program's local size invocations;
- every clear (PyOpenGL ``glClear``/``glClearBuffer*``, moderngl ``Framebuffer.clear`` and
  ``Buffer.clear``): the bytes of the attachments or buffer it clears (the scissor box where the
  scissor test is on);
- ``Buffer.write``/``Texture.write`` and ``Buffer.read``/``Texture.read``: bytes uploaded to
  and read back from the GL.

Around each pass, ``GL_PRIMITIVES_GENERATED`` (exact) and, where the driver has
``GL_ARB_pipeline_statistics_query``, shader invocations and clipper primitives (approximate,
see :data:`COUNTERS`). A technique adds what only it knows — rays traced, triangles processed
on the CPU, texture taps its shader makes per fragment, stencil updates — with
:meth:`~shadowlab.techniques.Technique.work`. Work outside any named pass is recorded under
:data:`UNNAMED`, which a test holds empty for every technique.

The columns (:func:`columns`): ``work_<counter>`` (the render's total) and
``work_<pass>_<counter>`` (per pass); zero counters are left out of the per-pass columns.
"""
from __future__ import annotations

import contextlib
import importlib
from dataclasses import dataclass
from typing import Callable

import numpy as np

from . import gl

#: The pass that work done outside every named pass is recorded under.
UNNAMED = "unnamed"


@dataclass(frozen=True)
class Counter:
    """One work counter: what it counts, whether it is exact and why, and where it comes from
    (hook, pass query or the technique). *Exact* means defined to the unit by the GL spec or by
    counting, given the rasterisation: two drivers that rasterise an edge pixel differently
    (sub-pixel precision) differ by those pixels — against an H100, a small fraction of the
    evaluated pixels and of shadow volumes' stencil updates (docs/cost.md, the rows in
    results/cost/h100/mismatches.csv).
    *Approximate* counters differ by design from driver to driver, or are models."""

    doc: str
    exact: bool
    why: str
    source: str


COUNTERS: dict[str, Counter] = {
    "draws": Counter("draw calls", True, "counted where moderngl draws", "hook"),
    "vertices": Counter("vertices submitted (vertices × instances of each draw)", True,
                        "what the application asks for, before any post-transform cache", "hook"),
    "samples_passed": Counter("samples that passed the depth and stencil tests (GL_SAMPLES_PASSED per draw)", True,
                              "defined exactly by the GL spec (§4.1.7 occlusion queries) on single-sample targets",
                              "hook"),
    "bytes_written": Counter("bytes written to render targets: samples passed × bytes per sample of the colour "
                             "attachments written and of depth when depth writes are on", False,
                             "a model: blending reads, stencil writes, compression and shader image/buffer "
                             "stores are not counted", "hook"),
    "bytes_cleared": Counter("bytes of attachments and buffers cleared (the scissor box when on, write masks "
                             "honoured)", True,
                             "from the component sizes the driver reports for each attachment (a 24-bit depth "
                             "attachment: 3 bytes, its 8-bit stencil 1)", "hook"),
    "bytes_uploaded": Counter("bytes written to buffers and textures from the CPU", True, "lengths of the data",
                              "hook"),
    "bytes_read": Counter("bytes read back from buffers and textures to the CPU", True, "lengths of the data",
                          "hook"),
    "dispatches": Counter("compute dispatches", True, "counted where moderngl dispatches", "hook"),
    "compute_invocations": Counter("compute shader invocations (groups × local size)", True,
                                   "from the dispatch's group counts and the program's declared local size", "hook"),
    "primitives_generated": Counter("primitives out of vertex processing (GL_PRIMITIVES_GENERATED), "
                                    "geometry shader output included, before clipping", True,
                                    "defined exactly by the GL spec (§13.3 primitive queries)", "pass query"),
    "vs_invocations": Counter("vertex shader invocations", False,
                              "a post-transform vertex cache may skip repeated indices: driver-dependent",
                              "pass query (ARB_pipeline_statistics_query)"),
    "gs_invocations": Counter("geometry shader invocations", False,
                              "drivers differ where no geometry shader is bound and in how they emulate the count",
                              "pass query (ARB_pipeline_statistics_query)"),
    "fs_invocations": Counter("fragment shader invocations", False,
                              "early depth tests, helper invocations in 2x2 quads and tiling differ by driver",
                              "pass query (ARB_pipeline_statistics_query)"),
    "clip_primitives": Counter("primitives out of the clipper", False,
                               "guard-band clipping differs by driver: one triangle may leave as 1 or as several",
                               "pass query (ARB_pipeline_statistics_query)"),
    "texture_taps": Counter("texture reads the technique's shader declares per fragment × samples passed", False,
                            "a model of the shader's loops (declared by the technique), not a hardware count",
                            "technique"),
    "stencil_updates": Counter("stencil values changed (shadow volumes: counted by occlusion queries)", True,
                               "from exact occlusion counts under the pass's own depth test", "technique"),
    "cpu_triangles": Counter("triangles processed on the CPU per render", True, "counted by the technique",
                             "technique"),
    "cpu_points": Counter("points tested on the CPU per render (blob shadows: evaluated points × blobs)", True,
                          "counted by the technique", "technique"),
    "rays": Counter("rays traced or tested", True, "counted by the technique", "technique"),
}

# ARB_pipeline_statistics_query targets (GL 4.6 core names) by counter; GL_PRIMITIVES_GENERATED is core.
_PIPELINE_TARGETS = {"vs_invocations": 0x82F0, "gs_invocations": 0x887F, "fs_invocations": 0x82F4,
                     "clip_primitives": 0x82F7}
_PRIMITIVES_GENERATED, _SAMPLES_PASSED = 0x8C87, 0x8914
_COMPUTE_WORK_GROUP_SIZE = 0x8267
#: Bytes per sample of each framebuffer attachment's bit sizes are summed from these queries.
_COLOR_SIZES = (0x8212, 0x8213, 0x8214, 0x8215)  # GL_FRAMEBUFFER_ATTACHMENT_{RED,GREEN,BLUE,ALPHA}_SIZE
_DEPTH_SIZE, _STENCIL_SIZE = 0x8216, 0x8217


def has_pipeline_statistics() -> bool:
    """Whether the driver counts shader invocations (GL_ARB_pipeline_statistics_query)."""
    return "GL_ARB_pipeline_statistics_query" in gl.context().extensions


class _Queries:
    """GL query objects by target, made once per process (moderngl cannot delete queries)."""

    _names: dict[int, int] = {}

    @classmethod
    def name(cls, target: int) -> int:
        from OpenGL import GL

        if target not in cls._names:
            cls._names[target] = int(np.ravel(GL.glGenQueries(1))[0])
        return cls._names[target]

    @staticmethod
    def result(name: int) -> int:
        from OpenGL import GL

        import ctypes

        out = ctypes.c_uint64(0)
        GL.glGetQueryObjectui64v(name, GL.GL_QUERY_RESULT, ctypes.byref(out))
        return int(out.value)


def _attachment_bytes_per_sample(attachment: int, sizes: tuple[int, ...]) -> int:
    """Bytes of the given component sizes of ``attachment`` of the bound draw framebuffer."""
    from OpenGL import GL

    bits = 0
    for pname in sizes:
        out = np.zeros(1, np.int32)
        GL.glGetFramebufferAttachmentParameteriv(GL.GL_DRAW_FRAMEBUFFER, attachment, pname, out)
        bits += int(out[0])
    return -(-bits // 8)


def _get_int(pname: int) -> int:
    """One integer of GL state."""
    from OpenGL import GL

    out = np.zeros(1, np.int32)
    GL.glGetIntegerv(pname, out)
    return int(out[0])


def _attachment_type(attachment: int) -> int:
    from OpenGL import GL

    out = np.zeros(1, np.int32)
    GL.glGetFramebufferAttachmentParameteriv(GL.GL_DRAW_FRAMEBUFFER, attachment,
                                             GL.GL_FRAMEBUFFER_ATTACHMENT_OBJECT_TYPE, out)
    return int(out[0])


def _draw_buffers() -> list[int]:
    """The colour attachments the bound draw framebuffer draws to, by draw-buffer index."""
    from OpenGL import GL

    fbo = _get_int(GL.GL_DRAW_FRAMEBUFFER_BINDING)
    if fbo == 0:
        return []
    out = []
    for i in range(_get_int(GL.GL_MAX_DRAW_BUFFERS)):
        buf = _get_int(GL.GL_DRAW_BUFFER0 + i)
        out.append(buf)
    return out


def _framebuffer_area() -> tuple[int, int, int]:
    """(width, height, layers) of the bound draw framebuffer's first attachment, from the
    attachment's own storage (a layered attachment: its texture's depth; the lab attaches no
    layered cube maps, whose six faces this would count as one)."""
    from OpenGL import GL

    for att in [GL.GL_COLOR_ATTACHMENT0 + i for i in range(8)] + [GL.GL_DEPTH_ATTACHMENT, GL.GL_STENCIL_ATTACHMENT]:
        kind = _attachment_type(att)
        if kind == GL.GL_NONE:
            continue
        out = np.zeros(1, np.int32)
        GL.glGetFramebufferAttachmentParameteriv(GL.GL_DRAW_FRAMEBUFFER, att,
                                                 GL.GL_FRAMEBUFFER_ATTACHMENT_OBJECT_NAME, out)
        name = int(out[0])
        if kind == GL.GL_RENDERBUFFER:
            bound = _get_int(GL.GL_RENDERBUFFER_BINDING)
            GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, name)
            w = int(GL.glGetRenderbufferParameteriv(GL.GL_RENDERBUFFER, GL.GL_RENDERBUFFER_WIDTH))
            h = int(GL.glGetRenderbufferParameteriv(GL.GL_RENDERBUFFER, GL.GL_RENDERBUFFER_HEIGHT))
            GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, bound)
            return w, h, 1
        GL.glGetFramebufferAttachmentParameteriv(GL.GL_DRAW_FRAMEBUFFER, att, GL.GL_FRAMEBUFFER_ATTACHMENT_TEXTURE_LEVEL,
                                                 out)
        level = int(out[0])
        dims = [_texture_level_size(name, level, pname) for pname in (GL.GL_TEXTURE_WIDTH, GL.GL_TEXTURE_HEIGHT)]
        GL.glGetFramebufferAttachmentParameteriv(GL.GL_DRAW_FRAMEBUFFER, att, GL.GL_FRAMEBUFFER_ATTACHMENT_LAYERED, out)
        layers = 1
        if int(out[0]):
            layers = max(1, _texture_level_size(name, level, GL.GL_TEXTURE_DEPTH))
        return dims[0], dims[1], layers
    return 0, 0, 0


def _texture_level_size(name: int, level: int, pname: int) -> int:
    """A texture level's width, height or depth (GL 4.5 direct state access)."""
    from OpenGL import GL

    v = np.zeros(1, np.int32)
    GL.glGetTextureLevelParameteriv(name, level, pname, v)
    return int(v[0])


def _cleared_pixels() -> int:
    """Pixels a clear of the bound draw framebuffer touches: its area (times layers), or the
    scissor box inside it when the scissor test is on."""
    from OpenGL import GL

    w, h, layers = _framebuffer_area()
    if GL.glIsEnabled(GL.GL_SCISSOR_TEST):
        box = np.zeros(4, np.int32)
        GL.glGetIntegerv(GL.GL_SCISSOR_BOX, box)
        x0, y0 = max(0, int(box[0])), max(0, int(box[1]))
        w, h = max(0, min(w, int(box[0] + box[2])) - x0), max(0, min(h, int(box[1] + box[3])) - y0)
    return w * h * layers


def _clear_bytes(color_buffers: list[int] | None, depth: bool, stencil: bool) -> int:
    """Bytes a clear writes: ``color_buffers`` (draw-buffer indices; None = every draw buffer),
    and depth and stencil when asked and attached."""
    from OpenGL import GL

    per_pixel = 0
    buffers = _draw_buffers()
    for i in (range(len(buffers)) if color_buffers is None else color_buffers):
        if i < len(buffers) and buffers[i] != GL.GL_NONE and _attachment_type(buffers[i]) != GL.GL_NONE \
                and _color_mask_on(i):
            per_pixel += _attachment_bytes_per_sample(buffers[i], _COLOR_SIZES)
    if (depth or stencil) and _get_int(GL.GL_DRAW_FRAMEBUFFER_BINDING):
        if depth and _attachment_type(GL.GL_DEPTH_ATTACHMENT) != GL.GL_NONE and _depth_mask_on():
            per_pixel += _attachment_bytes_per_sample(GL.GL_DEPTH_ATTACHMENT, (_DEPTH_SIZE,))
        if stencil and _attachment_type(GL.GL_STENCIL_ATTACHMENT) != GL.GL_NONE and _get_int(GL.GL_STENCIL_WRITEMASK):
            per_pixel += _attachment_bytes_per_sample(GL.GL_STENCIL_ATTACHMENT, (_STENCIL_SIZE,))
    return per_pixel * _cleared_pixels() if per_pixel else 0


def _color_mask_on(draw_buffer: int) -> bool:
    """Whether any channel of draw buffer ``draw_buffer`` is written (glColorMaski)."""
    from OpenGL import GL

    mask = np.zeros(4, np.uint8)
    GL.glGetBooleani_v(GL.GL_COLOR_WRITEMASK, draw_buffer, mask)
    return bool(mask.any())


def _depth_mask_on() -> bool:
    """Whether depth writes are on (glDepthMask)."""
    from OpenGL import GL

    mask = np.zeros(1, np.uint8)
    GL.glGetBooleanv(GL.GL_DEPTH_WRITEMASK, mask)
    return bool(mask[0])


def _written_bytes_per_sample() -> int:
    """Bytes one passing sample writes to the bound draw framebuffer: the colour attachments
    whose write mask is on, and depth when the depth test and depth writes are on."""
    from OpenGL import GL

    if GL.glIsEnabled(GL.GL_RASTERIZER_DISCARD):
        return 0
    out = 0
    for i, buf in enumerate(_draw_buffers()):
        if buf == GL.GL_NONE or _attachment_type(buf) == GL.GL_NONE:
            continue
        if _color_mask_on(i):
            out += _attachment_bytes_per_sample(buf, _COLOR_SIZES)
    if GL.glIsEnabled(GL.GL_DEPTH_TEST) and _depth_mask_on():
        if _get_int(GL.GL_DRAW_FRAMEBUFFER_BINDING) and _attachment_type(GL.GL_DEPTH_ATTACHMENT):
            out += _attachment_bytes_per_sample(GL.GL_DEPTH_ATTACHMENT, (_DEPTH_SIZE,))
    return out


def _local_size(compute_shader) -> int:
    """Invocations per work group of a moderngl ComputeShader (its declared local size; asked
    each time: a released program's name may be reused by another)."""
    from OpenGL import GL

    out = np.zeros(3, np.int32)
    GL.glGetProgramiv(int(compute_shader.glo), _COMPUTE_WORK_GROUP_SIZE, out)
    return int(np.prod(out))


class WorkCounter:
    """The work of one render, per named pass (see the module docstring). Made by the pipeline
    for its counting render; :meth:`counting` hooks the draw, dispatch, clear and transfer
    entry points for the render's length, :meth:`measure` (what ``timed_pass`` opens) names the
    pass they are booked to, and :meth:`passes` hands back {pass: {counter: value}}."""

    def __init__(self):
        self.statistics = has_pipeline_statistics()
        self._passes: dict[str, dict[str, int]] = {}
        self._current = UNNAMED

    def add(self, counter: str, value: float, pass_name: str | None = None) -> None:
        """Book ``value`` of ``counter`` to ``pass_name`` (default: the pass open now)."""
        if counter not in COUNTERS:
            raise KeyError(f"unknown work counter {counter!r}; known: {', '.join(COUNTERS)}")
        book = self._passes.setdefault(pass_name or self._current, {})
        book[counter] = book.get(counter, 0) + value

    def measure(self, name: str, cpu: bool = False):
        """Context manager booking what runs inside to pass ``name``, with the pass-level
        queries (primitives generated; pipeline statistics where the driver has them) around
        GPU passes."""
        from OpenGL import GL

        @contextlib.contextmanager
        def booked():
            outer, self._current = self._current, name
            self._passes.setdefault(name, {})
            targets = {} if cpu else {"primitives_generated": _PRIMITIVES_GENERATED,
                                      **(_PIPELINE_TARGETS if self.statistics else {})}
            begun = []
            try:
                for counter, target in targets.items():
                    GL.glBeginQuery(target, _Queries.name(target))
                    begun.append((counter, target))
                yield
            finally:
                for _, target in begun:
                    GL.glEndQuery(target)
                for counter, target in begun:
                    self.add(counter, _Queries.result(_Queries.name(target)), name)
                self._current = outer

        return booked()

    @contextlib.contextmanager
    def counting(self):
        """Hook moderngl's and PyOpenGL's draw, dispatch, clear and transfer entry points for
        the length of the block (restored after, whatever happens): every entry of
        :data:`HOOKS`, in its order."""
        patches = []
        try:
            for hook in HOOKS:
                owner = hook.owner()
                original = getattr(owner, hook.attr)
                patches.append((owner, hook.attr, original))
                setattr(owner, hook.attr, hook.wrap(self, original))
            yield self
        finally:
            for owner, attr, original in reversed(patches):
                setattr(owner, attr, original)

    @staticmethod
    def hooked() -> list[tuple[object, str]]:
        """The (owner, attribute) pairs :meth:`counting` replaces for its block (:data:`HOOKS`)."""
        return [(hook.owner(), hook.attr) for hook in HOOKS]

    def passes(self) -> dict[str, dict[str, int]]:
        """{pass: {counter: value}} of what was counted (passes in the order first opened)."""
        return {p: dict(c) for p, c in self._passes.items()}


# --------------------------------------------------------------------------- the hooks
# Each wrapper takes the WorkCounter and the original entry point and returns the replacement
# that books the call's work (module docstring) and then makes the call.

def _draw(counter: "WorkCounter", original):
    """``VertexArray.render``: a draw, its vertices × instances, the samples it passes (a
    GL_SAMPLES_PASSED query around it) and the bytes they write."""
    from OpenGL import GL

    def wrapped(vao, mode=None, vertices=-1, *args, **kwargs):
        instances = kwargs.get("instances", args[1] if len(args) > 1 else -1)  # args: first, instances
        n = vao.vertices if vertices is None or vertices < 0 else vertices
        per_sample = _written_bytes_per_sample()
        q = _Queries.name(_SAMPLES_PASSED)
        GL.glBeginQuery(_SAMPLES_PASSED, q)
        try:
            return original(vao, mode, vertices, *args, **kwargs)
        finally:
            GL.glEndQuery(_SAMPLES_PASSED)
            samples = _Queries.result(q)
            counter.add("draws", 1)
            counter.add("vertices", int(n) * max(1, int(instances)))
            counter.add("samples_passed", samples)
            counter.add("bytes_written", samples * per_sample)
    return wrapped


def _transform(counter: "WorkCounter", original):
    """``VertexArray.transform``: a draw and its vertices × instances."""
    def wrapped(vao, buffer, mode=None, vertices=-1, *args, **kwargs):
        instances = kwargs.get("instances", args[1] if len(args) > 1 else -1)
        n = vao.vertices if vertices is None or vertices < 0 else vertices
        counter.add("draws", 1)
        counter.add("vertices", int(n) * max(1, int(instances)))
        return original(vao, buffer, mode, vertices, *args, **kwargs)
    return wrapped


def _dispatch(counter: "WorkCounter", original):
    """``ComputeShader.run``: a dispatch and its groups × local size invocations."""
    def wrapped(cs, group_x=1, group_y=1, group_z=1):
        counter.add("dispatches", 1)
        counter.add("compute_invocations", int(group_x) * int(group_y) * int(group_z) * _local_size(cs))
        return original(cs, group_x, group_y, group_z)
    return wrapped


def _gl_clear(counter: "WorkCounter", original):
    """PyOpenGL ``glClear``: the bytes of the buffers its mask names."""
    from OpenGL import GL

    def wrapped(mask):
        if not GL.glIsEnabled(GL.GL_RASTERIZER_DISCARD):
            counter.add("bytes_cleared", _clear_bytes(None if mask & GL.GL_COLOR_BUFFER_BIT else [],
                                                      bool(mask & GL.GL_DEPTH_BUFFER_BIT),
                                                      bool(mask & GL.GL_STENCIL_BUFFER_BIT)))
        return original(mask)
    return wrapped


def _gl_clear_buffer(counter: "WorkCounter", original):
    """PyOpenGL ``glClearBuffer*``: the bytes of the one buffer it clears."""
    from OpenGL import GL

    def wrapped(buffer, drawbuffer, *args):
        if GL.glIsEnabled(GL.GL_RASTERIZER_DISCARD):
            pass  # clears are ignored under rasterizer discard
        elif buffer == GL.GL_COLOR:
            counter.add("bytes_cleared", _clear_bytes([int(drawbuffer)], False, False))
        else:
            counter.add("bytes_cleared", _clear_bytes([], buffer in (GL.GL_DEPTH, GL.GL_DEPTH_STENCIL),
                                                      buffer in (GL.GL_STENCIL, GL.GL_DEPTH_STENCIL)))
        return original(buffer, drawbuffer, *args)
    return wrapped


def _fbo_clear(counter: "WorkCounter", original):
    """moderngl ``Framebuffer.clear``: the whole framebuffer, by the same rule as glClear."""
    def wrapped(fbo, *args, **kwargs):
        result = original(fbo, *args, **kwargs)  # binds fbo (moderngl clears through it)
        # the whole framebuffer, by the same rule as glClear (a ``viewport`` argument's
        # smaller box is not seen: the lab's techniques clear whole targets)
        counter.add("bytes_cleared", _clear_bytes(None, True, False))
        return result
    return wrapped


def _context_clear(counter: "WorkCounter", original):
    """moderngl ``Context.clear``: the bound framebuffer, by the same rule as glClear."""
    def wrapped(ctx, *args, **kwargs):
        result = original(ctx, *args, **kwargs)
        counter.add("bytes_cleared", _clear_bytes(None, True, False))
        return result
    return wrapped


def _buffer_clear(counter: "WorkCounter", original):
    """moderngl ``Buffer.clear``: the bytes it clears."""
    def wrapped(buf, size=-1, *args, **kwargs):
        counter.add("bytes_cleared", buf.size if size is None or size < 0 else int(size))
        return original(buf, size, *args, **kwargs)
    return wrapped


def _upload(counter: "WorkCounter", original):
    """``Buffer.write`` / ``Texture.write``: the bytes uploaded from the CPU."""
    def wrapped(obj, data, *args, **kwargs):
        try:
            n = len(memoryview(data).cast("B"))
        except TypeError:  # Texture.write from a moderngl Buffer: a GPU-side copy, no upload
            n = 0
        counter.add("bytes_uploaded", n)
        return original(obj, data, *args, **kwargs)
    return wrapped


def _download(counter: "WorkCounter", original):
    """``Buffer.read`` / ``Texture.read``: the bytes read back to the CPU."""
    def wrapped(obj, *args, **kwargs):
        data = original(obj, *args, **kwargs)
        counter.add("bytes_read", len(data))
        return data
    return wrapped


@dataclass(frozen=True)
class Hook:
    """One entry point :meth:`WorkCounter.counting` replaces for its block: the module and
    (optionally) the class that own it, the attribute, the counters it books and ``wrap``,
    which makes the replacement from the WorkCounter and the original."""

    module: str
    cls: str | None
    attr: str
    counters: tuple[str, ...]
    wrap: Callable

    def owner(self):
        """The object whose attribute is replaced: the module, or its class ``cls``."""
        module = importlib.import_module(self.module)
        return module if self.cls is None else getattr(module, self.cls)


#: Every hooked entry point, in the order :meth:`WorkCounter.counting` replaces them (restored
#: in the reverse order): the one list of what the counting render hooks.
HOOKS: tuple[Hook, ...] = (
    Hook("moderngl", "VertexArray", "render", ("draws", "vertices", "samples_passed", "bytes_written"), _draw),
    Hook("moderngl", "VertexArray", "transform", ("draws", "vertices"), _transform),
    Hook("moderngl", "ComputeShader", "run", ("dispatches", "compute_invocations"), _dispatch),
    Hook("OpenGL.GL", None, "glClear", ("bytes_cleared",), _gl_clear),
    *(Hook("OpenGL.GL", None, name, ("bytes_cleared",), _gl_clear_buffer)
      for name in ("glClearBufferfv", "glClearBufferiv", "glClearBufferuiv", "glClearBufferfi")),
    Hook("moderngl", "Framebuffer", "clear", ("bytes_cleared",), _fbo_clear),
    Hook("moderngl", "Context", "clear", ("bytes_cleared",), _context_clear),
    Hook("moderngl", "Buffer", "clear", ("bytes_cleared",), _buffer_clear),
    *(hook for cls in ("Buffer", "Texture")
      for hook in (Hook("moderngl", cls, "write", ("bytes_uploaded",), _upload),
                   Hook("moderngl", cls, "read", ("bytes_read",), _download))),
)


def merge(into: dict[str, dict], more: dict[str, dict]) -> dict[str, dict]:
    """Add the per-pass counters ``more`` to ``into`` (returns a new dict; light samples and a
    technique's declared work combine this way)."""
    out = {p: dict(c) for p, c in into.items()}
    for p, counters in more.items():
        book = out.setdefault(p, {})
        for k, v in counters.items():
            if k not in COUNTERS:
                raise KeyError(f"unknown work counter {k!r} in pass {p!r}; known: {', '.join(COUNTERS)}")
            book[k] = book.get(k, 0) + v
    return out


def columns(per_pass: dict[str, dict]) -> dict[str, float]:
    """The metrics columns of one render's work: ``work_<counter>`` summed over passes (every
    counter any pass has), then ``work_<pass>_<counter>`` for each non-zero per-pass count."""
    totals: dict[str, float] = {}
    for counters in per_pass.values():
        for k, v in counters.items():
            totals[k] = totals.get(k, 0) + v
    out = {f"work_{k}": _number(v) for k, v in sorted(totals.items(), key=lambda kv: list(COUNTERS).index(kv[0]))}
    for p, counters in per_pass.items():
        for k in COUNTERS:
            if counters.get(k):
                out[f"work_{p}_{k}"] = _number(counters[k])
    return out


def _number(v):
    return int(v) if float(v).is_integer() else float(v)


def is_work_column(name: str) -> bool:
    """Whether a metrics column is a work counter (``work_...``)."""
    return name.startswith("work_")


def counter_of(column: str, passes: tuple[str, ...] = ()) -> tuple[str | None, str] | None:
    """(pass or None for a total, counter) of a ``work_`` column; ``passes`` resolves pass names
    that contain underscores. None for a column that is not a work counter."""
    if not is_work_column(column):
        return None
    rest = column[len("work_"):]
    if rest in COUNTERS:
        return None, rest
    for counter in sorted(COUNTERS, key=len, reverse=True):
        if rest.endswith("_" + counter):
            return rest[: -len(counter) - 1], counter
    return None
