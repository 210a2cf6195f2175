"""The map toolkit: what every technique that renders the scene from the light into a texture
shares — shadow_map, lispsm, cascaded_map, pcss, moment_soft, filtered_map and projective are
built on it, not on each other.

- **Fitting** (docs/architecture.md): :func:`fit_light_views` fits a map's views (1, or 6 for a point
  light's cube) to the receivers the camera sees — those that can be shadowed at all
  (:func:`shadowable`, ``fit=shadowable``) or every evaluated receiver (``fit=receivers``); each
  light type fits its own projection (:meth:`shadowlab.scene.lights.Light.shadow_views`).
- **The atlas** (:class:`Atlas`): the faces of one map side by side in one texture — a cube's six
  in a 3x2 grid, cascades in a row — with its size checked against ``GL_MAX_TEXTURE_SIZE``
  (:func:`check_texture_size`), and the per-face light matrices and rects padded to
  :data:`MAX_FACES`, the one array size every atlas-reading shader is compiled with
  (:data:`ATLAS_DEFINES`).
- **Passes**: :func:`depth_pass` (the casters' depth into every face of a depth layer: one
  instanced draw for all faces where the driver lets the vertex shader choose the viewport, else
  a draw per face; :data:`ONE_PASS`, :func:`depth_defines`) and :func:`lookup_pass` (one
  full-screen pass over the G-buffer reading the atlas).
- **The texel mapping** (:class:`TexelMapping`): which face a world point looks up and where its
  texels lie, for the texel-footprint metric (:mod:`shadowlab.evaluation.texel_footprint`).
- **Soft shadows' parallel planes** (pcss, moment_soft): heights above an area light's plane
  (:func:`height_axis`), its extents (:func:`light_extents`) and size (:func:`light_size`), the
  blocker search's slice (:func:`search_height`), a perspective map's planes (:func:`near_far`).
- **Depth-map techniques** (:class:`DepthMapTechnique`): the depth atlas, its optional second
  layer (two-layer comparisons), the comparison lookup with the bias family and PCF, and their
  cost figures; a subclass supplies only its views (:meth:`DepthMapTechnique.fit_views`) and its
  comparison's uniforms.
"""
from __future__ import annotations

import numpy as np

from ...gpu import gl, glstate, programs, targets
from ...geometry.bounds import segments_hit_boxes
from ...geometry.frusta import LightView
from ...geometry.transforms import BIAS
from ...gpu.glstate import PassState
from ...scene.area_lights import AreaLight, DiscLight, RectLight, SphereLight, basis
from ..base import FIRST, MAX, SUM, Technique, TechniqueError

#: Most faces one map atlas holds (a cube's 6; cascades up to 8): the size of every per-face
#: uniform array in the shaders that read an atlas, passed to them as ``MAX_FACES``.
MAX_FACES = 8
#: The defines every atlas-reading program is compiled with.
ATLAS_DEFINES = {"MAX_FACES": MAX_FACES}
#: The shadowable test starts each segment this far off its surface (× the scene's extent), so
#: that a flat receiver's own bounding box does not count as a caster in its way.
SHADOWABLE_OFFSET = 1e-5
#: The window depth :func:`depth_pass` clears the map to: a texel still holding it saw no caster
#: between the light and the far plane (PCSS tells such empty texels from blockers by it).
CLEAR_DEPTH = 1.0
#: G-buffer texels a lookup reads per fragment (position and normal), for its texture taps.
GBUFFER_TAPS = 2
#: PCF kernel radius (texels) of each lookup filter; None: hardware bilinear comparison.
FILTERS = {"nearest": 0, "pcf3": 1, "pcf5": 2, "hw2x2": None}
#: How :func:`depth_pass` draws an atlas's faces, for the whole process (tests and timings set
#: it; a call's ``one_pass`` argument overrides it): None — in one instanced draw where the
#: driver has a vertex-shader viewport index (:func:`viewport_index_extension`), else a draw per
#: face; True — always in one draw (a TechniqueError where the driver cannot); False — always a
#: draw per face. Both ways fill the atlas with the same depths, texel for texel.
ONE_PASS: bool | None = None
#: The extensions that let a vertex shader write ``gl_ViewportIndex``, in order of preference,
#: with the value of the ``VIEWPORT_INDEX`` define that picks each in light_vertex.glsl.
VIEWPORT_INDEX_EXTENSIONS = {"GL_ARB_shader_viewport_layer_array": 1, "GL_AMD_vertex_shader_viewport_index": 2}


# --------------------------------------------------------------------------- fitting

def shadowable(points: np.ndarray, normals: np.ndarray, light, bounds: np.ndarray, eps: float) -> np.ndarray:
    """Bool (M,): receiver points whose segment to the light crosses some caster's bounding box.

    Conservative (a superset of the points that can be in shadow): a point whose segment
    misses every caster box is certainly lit, so the shadow map need not cover it. The
    segment starts ``eps`` off the surface, so a receiver's own flat box does not count.
    """
    origin = points + eps * normals
    dirs, dist = light.to_light(origin)
    return segments_hit_boxes(origin, dirs, np.minimum(dist, 1e30), bounds)


def shadowable_mask(frame, slot) -> np.ndarray:
    """Bool (M,) over the slot's evaluated receiver points: those that can be in shadow
    (:func:`shadowable`). A mask, not the points, for fits that also need the others (cascaded_map's
    focused SDSM falls back to every evaluated point of a slice that holds no shadowable one)."""
    return shadowable(frame.compact_position[slot.evaluated], frame.compact_normal[slot.evaluated], slot.light,
                      frame.caster_bounds(), eps=SHADOWABLE_OFFSET * frame.scene.extent())


def shadowable_receivers(frame, slot) -> np.ndarray:
    """The slot's evaluated receiver points (M, 3) that can be in shadow (:func:`shadowable`)."""
    return frame.compact_position[slot.evaluated][shadowable_mask(frame, slot)]


def fit_light_views(frame, slot, resolution: int, projection: str = "auto", near_override: float = 0.0,
                    fit: str = "shadowable") -> tuple[list[LightView], list[str]]:
    """The map's views (1, or 6 for a cube) fitted to the frame, and notes for the run.

    ``fit='shadowable'`` covers the evaluated receiver points that can be in shadow at all;
    ``fit='receivers'`` covers every evaluated receiver point (the classic fit to what the
    camera sees: coarser texels, and acne wherever the receivers are). The slot's light decides
    the projection (:meth:`shadowlab.scene.lights.Light.shadow_views`)."""
    if fit == "shadowable":
        receivers = shadowable_receivers(frame, slot)
    else:
        receivers = frame.compact_position[slot.evaluated]
    if len(receivers) == 0:
        receivers = frame.scene.bounds()  # nothing to answer: any valid frustum will do
    return slot.light.shadow_views(receivers, frame.casters(), resolution, projection=projection,
                                   near=near_override)


# --------------------------------------------------------------------------- the atlas

def check_texture_size(size: tuple[int, int], owner: str, what: str = "map",
                       remedy: str = "lower the resolution") -> None:
    """TechniqueError naming ``owner`` (and ``remedy``) when a texture of ``size`` (width,
    height) exceeds the context's ``GL_MAX_TEXTURE_SIZE``."""
    max_size = int(gl.context().info["GL_MAX_TEXTURE_SIZE"])
    if max(size) > max_size:
        raise TechniqueError(f"{owner}: a {size[0]}x{size[1]} {what} exceeds GL_MAX_TEXTURE_SIZE {max_size}; "
                             f"{remedy}")


class Atlas:
    """The faces of one map in one texture: ``faces`` (LightViews), ``rects`` (x0, y0, width,
    height per face, texels) and ``size`` (width, height). :meth:`grid` lays out 1 face or a
    cube's 6 (3x2), :meth:`row` any number side by side (cascades)."""

    def __init__(self, faces: list[LightView], rects: list[tuple[int, int, int, int]], size: tuple[int, int],
                 owner: str):
        if len(faces) > MAX_FACES:
            raise TechniqueError(f"{owner}: {len(faces)} faces exceed the atlas's {MAX_FACES}")
        check_texture_size(size, owner)
        self.faces, self.rects, self.size = list(faces), list(rects), (int(size[0]), int(size[1]))

    @classmethod
    def grid(cls, faces: list[LightView], resolution: int, owner: str) -> "Atlas":
        """One face (1x1) or a cube's six (3 columns, 2 rows), each ``resolution``² texels."""
        cols, rows = (3, 2) if len(faces) == 6 else (1, 1)
        rects = [((i % cols) * resolution, (i // cols) * resolution, resolution, resolution)
                 for i in range(len(faces))]
        return cls(faces, rects, (cols * resolution, rows * resolution), owner)

    @classmethod
    def row(cls, faces: list[LightView], resolution: int, owner: str) -> "Atlas":
        """Every face side by side (face i at x = i · resolution), each ``resolution``² texels."""
        rects = [(i * resolution, 0, resolution, resolution) for i in range(len(faces))]
        return cls(faces, rects, (len(faces) * resolution, resolution), owner)

    @property
    def texels(self) -> int:
        """Texels of the whole atlas."""
        return self.size[0] * self.size[1]

    def _padded(self, matrices: list[np.ndarray]) -> bytes:
        """``matrices`` (4x4 each) then identities up to :data:`MAX_FACES`, as GLSL mat4[] bytes."""
        mats = list(matrices) + [np.eye(4)] * (MAX_FACES - len(matrices))
        return b"".join(programs.mat_bytes(m) for m in mats)

    def view_proj_matrices(self) -> bytes:
        """Per face projection · view (world → clip), padded: the ``u_face_view_proj[MAX_FACES]``
        uniform of a :func:`depth_pass` program."""
        return self._padded([f.view_proj for f in self.faces])

    def light_matrices(self) -> bytes:
        """Per face BIAS · projection · view (world → map uv and window depth), padded: the
        ``u_light_matrix[MAX_FACES]`` uniform."""
        return self._padded([BIAS @ f.view_proj for f in self.faces])

    def inverse_light_matrices(self) -> np.ndarray:
        """Float32 (MAX_FACES, 16): per face the inverse of BIAS · projection · view (map uv and
        window depth → world, inverted in float64), column-major as GLSL's mat4, padded with
        identities: the ``u_light_matrix_inverse[MAX_FACES]`` uniform."""
        mats = [np.linalg.inv(BIAS @ f.view_proj) for f in self.faces]
        mats += [np.eye(4)] * (MAX_FACES - len(mats))
        return np.stack([np.asarray(m, np.float64).T.ravel() for m in mats]).astype(np.float32)

    def view_matrices(self) -> bytes:
        """Per face the world → view matrix, padded: the ``u_light_view[MAX_FACES]`` uniform."""
        return self._padded([f.view for f in self.faces])

    def rect_array(self) -> np.ndarray:
        """Float32 (MAX_FACES, 4): each face's rect, zero-padded: the ``u_face_rect`` uniform."""
        return self.padded(self.rects, np.float32)

    def padded(self, values, dtype=np.float64) -> np.ndarray:
        """One value (or row) per face, padded with zeros to :data:`MAX_FACES` rows."""
        values = np.asarray(values, dtype)
        out = np.zeros((MAX_FACES,) + values.shape[1:], dtype)
        out[:len(values)] = values
        return out

    def write_uniforms(self, prog) -> None:
        """Set the atlas uniforms of a lookup program: ``u_light_matrix``, ``u_faces``,
        ``u_face_rect`` and ``u_atlas_size``."""
        prog["u_light_matrix"].write(self.light_matrices())
        programs.set_uniforms(prog, {"u_faces": len(self.faces), "u_face_rect": self.rect_array(),
                                     "u_atlas_size": tuple(map(float, self.size))})


def centre_map_atlas(frame, slot, resolution: int, owner: str) -> tuple["Atlas", list[str]]:
    """The one-face map from an area light's centre that pcss, smrt and hybrid_rt (under an area
    light) look up, as a one-face atlas, and notes for the run: a perspective frustum over every
    evaluated receiver (``fit=receivers``) — the shadowable fit tests segments to the centre only
    and would leave the outer penumbra off the map."""
    faces, notes = fit_light_views(frame, slot, resolution, "frustum", 0.0, "receivers")
    return Atlas.grid(faces[:1], resolution, owner), notes  # the one face fills the map


# --------------------------------------------------------------------------- passes

_VIEWPORT_INDEX: list[str | None] = []  # the context's answer, asked once per process


def viewport_index_extension() -> str | None:
    """The first of :data:`VIEWPORT_INDEX_EXTENSIONS` the context has (asked once per process:
    there is one context), or None. With it a vertex shader writes ``gl_ViewportIndex``, so one
    instanced draw can put each instance in its own face of an atlas (viewport arrays are core
    since GL 4.1; writing the index outside a geometry shader is the extension's)."""
    if not _VIEWPORT_INDEX:
        have = gl.context().extensions
        _VIEWPORT_INDEX.append(next((e for e in VIEWPORT_INDEX_EXTENSIONS if e in have), None))
    return _VIEWPORT_INDEX[0]


def depth_defines(peel: bool = False) -> dict:
    """The defines of a :func:`depth_pass` program (``shadow_depth.glsl``, or any program that
    includes ``light_vertex.glsl`` first): the per-face matrix array (``FACE_ARRAY``,
    ``MAX_FACES``) and, where the driver has it, the vertex shader's viewport index
    (``VIEWPORT_INDEX``, :func:`viewport_index_extension`); with ``peel``, depth peeling's
    ``PEEL``."""
    defines = {"FACE_ARRAY": 1, **ATLAS_DEFINES}
    extension = viewport_index_extension()
    if extension is not None:
        defines["VIEWPORT_INDEX"] = VIEWPORT_INDEX_EXTENSIONS[extension]
    if peel:
        defines["PEEL"] = 1
    return defines


def draws_in_one_pass(prog, one_pass: bool | None = None) -> bool:
    """Whether :func:`depth_pass` draws every face with ``prog`` in one instanced draw:
    ``one_pass`` (None: the module's :data:`ONE_PASS`; None there too: wherever ``prog`` was
    compiled with a viewport index, i.e. the driver has one). True asked of a program without
    one is a TechniqueError."""
    choice = ONE_PASS if one_pass is None else one_pass
    able = "VIEWPORT_INDEX" in prog.extra.defines
    if choice and not able:
        raise TechniqueError(f"one_pass: the depth pass cannot draw every face at once: the driver has none of "
                             f"{', '.join(VIEWPORT_INDEX_EXTENSIONS)} (or the program lacks depth_defines())")
    return able if choice is None else bool(choice)


def depth_pass(frame, layer: targets.DepthTexture, prog, atlas: Atlas, cull_front: bool = False,
               polygon_offset: tuple[float, float] | None = None, one_pass: bool | None = None) -> None:
    """Clear ``layer`` and render the frame's casters into it through each face of ``atlas``, in
    its rect. ``prog`` is a ``shadow_depth.glsl`` program compiled with :func:`depth_defines`;
    ``polygon_offset`` = (factor, units) for glPolygonOffset, or None.

    The faces are drawn in one instanced draw (instance i = face i; viewport i = face i's rect,
    glViewportArrayv; the vertex shader picks the face's matrix from ``u_face_view_proj`` and
    writes ``gl_ViewportIndex``) or, as a fallback, one draw per face (that face's rect as the
    viewport, ``u_face_base`` = the face): :func:`draws_in_one_pass` decides, from ``one_pass``,
    :data:`ONE_PASS` and the driver. Either way every vertex goes through the same product with
    the same matrix and each triangle is clipped to its own face's rect, so the depths are the
    same texel for texel (``tests/techniques/maps/test_depth_pass.py``); the draws counted fall
    from faces × caster ranges to the ranges, the vertices and primitives stay faces × the
    casters'. Why not a pass-through geometry shader where the extension is missing: it is one
    more stage per triangle (slow on llvmpipe, and on many GPUs slower than the loop it
    replaces), and its output would change the primitives counted; the per-face loop is the
    portable fallback."""
    from OpenGL import GL

    if "u_face_view_proj" not in prog.extra.uniforms:
        raise TechniqueError(f"depth_pass: program {prog.extra.label()} lacks u_face_view_proj; compile it "
                             f"with depth_defines()")
    one = draws_in_one_pass(prog, one_pass)
    layer.use_as_target()
    glstate.apply(PassState(depth_test=True, depth_func="<", depth_write=True, color_write=False,
                            cull="front" if cull_front else None, polygon_offset=polygon_offset))
    GL.glClearBufferfv(GL.GL_DEPTH, 0, (CLEAR_DEPTH,))
    prog["u_face_view_proj"].write(atlas.view_proj_matrices())
    if one:
        n = len(atlas.faces)
        glstate.set_viewports(atlas.rects)
        prog["u_face_base"].value = 0
        frame.draw(prog, "casters", instances=n)
        # glViewport sets every viewport: back to one, and to what moderngl believes is set
        frame.ctx.viewport = (0, 0) + tuple(atlas.size)
    else:
        for i, rect in enumerate(atlas.rects):
            frame.ctx.viewport = rect  # every viewport: the one the shader's index picks too
            prog["u_face_base"].value = i
            frame.draw(prog, "casters")


def lookup_pass(technique, target, quad, map_texture) -> None:
    """One full-screen lookup over ``technique``'s frame's G-buffer into ``target`` (a
    framebuffer): the channels the technique declares (``READS``: world position and normal, on
    units 0 and 1, :meth:`~shadowlab.techniques.base.Technique.bind_gbuffer`), ``map_texture``
    (the depth atlas) on 2 — the layout of ``shadow_lookup.glsl`` and ``pcss.glsl``."""
    target.use()
    glstate.apply(PassState())
    technique.bind_gbuffer(quad.program)
    map_texture.use(2)
    quad.render()


# --------------------------------------------------------------------------- texel mapping

def cube_face_index(points: np.ndarray, light_position, faces: int) -> np.ndarray:
    """Int (M,): the face of a map's atlas a lookup of each world point (M, 3) uses — for a cube
    (``faces`` = 6) the face of the major axis of the light-to-point vector, in
    :data:`shadowlab.geometry.frusta.CUBE_FACES` order (+x, −x, +y, −y, +z, −z), with the ties
    broken as ``face_of`` in shadowlab/techniques/maps/cube_face.glsl breaks them; else 0 (a single face; maps
    with several faces of another kind, cascades, choose their own)."""
    points = np.asarray(points, np.float64)
    if faces != 6:
        return np.zeros(len(points), int)
    d = points - np.asarray(light_position, np.float64)
    a = np.abs(d)
    x = (a[:, 0] >= a[:, 1]) & (a[:, 0] >= a[:, 2])
    y = ~x & (a[:, 1] >= a[:, 2])
    axis = np.where(x, 0, np.where(y, 1, 2))
    positive = np.take_along_axis(d, axis[:, None], axis=1)[:, 0] > 0
    return 2 * axis + np.where(positive, 0, 1)


def map_texel_coordinates(faces: list[LightView], rects, face_of_point, points: np.ndarray,
                          reference: np.ndarray) -> np.ndarray:
    """Float64 (M, 2): texel coordinates of world ``points`` (M, 3) in the map face each matching
    ``reference`` point (M, 3) looks up (``face_of_point(reference)`` → int (M,) indices into
    ``faces`` / ``rects``). Texels of that face, from its lower-left corner, x right and y up as
    in the map: (u, v) = (BIAS · proj · view · p).xy / w × the face's (width, height) — the
    coordinates the lookup passes floor to a texel. NaN behind the face's centre of projection
    (w <= 0)."""
    points = np.asarray(points, np.float64)
    face = np.asarray(face_of_point(np.asarray(reference, np.float64)), int)
    out = np.full((len(points), 2), np.nan)
    homogeneous = np.concatenate([points, np.ones((len(points), 1))], axis=1)
    for i, (view, rect) in enumerate(zip(faces, rects)):
        sel = face == i
        if not sel.any():
            continue
        s = homogeneous[sel] @ (BIAS @ view.view_proj).T
        with np.errstate(divide="ignore", invalid="ignore"):
            uv = s[:, :2] / s[:, 3:4] * np.asarray(rect[2:4], np.float64)
        uv[s[:, 3] <= 0] = np.nan
        out[sel] = uv
    return out


class TexelMapping:
    """Mixin of the techniques that render a map per face (``self.atlas``: an :class:`Atlas`,
    ``self.light``): which face a world point looks up and where its texels lie — what the
    texel-footprint metric (:mod:`shadowlab.evaluation.texel_footprint`) measures. Valid between ``setup``
    and ``release``. Subclasses with another choice of face (cascades) override
    :meth:`face_index` only."""

    def face_index(self, points: np.ndarray) -> np.ndarray:
        """Int (M,): the face of the atlas the lookup of each world point (M, 3) uses."""
        return cube_face_index(points, getattr(self.light, "position", None), len(self.atlas.faces))

    def texel_coordinates(self, points: np.ndarray, reference: np.ndarray) -> np.ndarray:
        """Float64 (M, 2): texel coordinates (x right, y up, in texels of the face) of world
        ``points`` (M, 3), each projected through the face the matching ``reference`` point
        (M, 3) looks up (:func:`map_texel_coordinates`)."""
        return map_texel_coordinates(self.atlas.faces, self.atlas.rects, self.face_index, points, reference)


# --------------------------------------------------------------------------- the bias in world units

def window_to_world(light_matrix: np.ndarray, points: np.ndarray, to_light: np.ndarray,
                    window: np.ndarray) -> np.ndarray:
    """Float64 (N,): the distance each world point of ``points`` (N, 3) moves towards the light
    (unit ``to_light`` (N, 3)) to lower its window depth in the map of ``light_matrix`` (BIAS ·
    projection · view, (4, 4), or (N, 4, 4) per point) by ``window`` (N,) — the world size of a
    window-depth bias at each receiver. Exact for any projective map: with s = M X and m = M δ̂,
    moving t along δ̂ changes window depth by Δ = t (m.z s.w − s.z m.w) / (s.w (s.w + t m.w)),
    solved for t at Δ = −window. ``shadowlab/techniques/maps/world_bias.glsl``'s ``window_change`` is the forward
    form. +inf where no distance does (the depth cannot fall that far)."""
    M = np.asarray(light_matrix, np.float64)
    X = np.c_[np.asarray(points, np.float64), np.ones(len(points))]
    D = np.c_[np.asarray(to_light, np.float64), np.zeros(len(points))]
    if M.ndim == 2:
        s, m = X @ M.T, D @ M.T
    else:
        s, m = np.einsum("nij,nj->ni", M, X), np.einsum("nij,nj->ni", M, D)
    delta = -np.asarray(window, np.float64)
    den = m[:, 2] * s[:, 3] - s[:, 2] * m[:, 3] - delta * s[:, 3] * m[:, 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = delta * s[:, 3] ** 2 / den
    return np.where(t >= 0, t, np.inf)


# --------------------------------------------------------------------------- depth-map techniques

#: One step of each depth format: what "the same surface" means when peeling the second layer.
#: Fixed point: 1 / (2^bits − 1). Float: depths of perspective maps crowd into [0.5, 1), where a
#: float32 ulp is 2^-24; the rasteriser's interpolated depth of the same surface varies by a few
#: ulps between passes, so a layer must lie 4 ulps behind the first to count as a new surface.
DEPTH_STEP = {16: 1.0 / 65535, 24: 1.0 / 16777215, 32: 2.0 ** -22}
#: The cost figures of a depth-map technique and how they combine over light samples.
DEPTH_MAP_STATS = {"memory_bytes": MAX, "faces": FIRST, "passes": SUM, "depth_range": FIRST, "texel_world": FIRST,
                   "near_plane": FIRST, "far_plane": FIRST, "bias_world_median": FIRST, "bias_world_max": MAX}
#: Receivers sampled (evenly, in pixel order) for the world size of the bias at the receivers.
BIAS_WORLD_SAMPLES = 20000


class DepthMapTechnique(TexelMapping, Technique):
    """A depth atlas rendered from the light and compared in one lookup over the G-buffer
    (``shadowlab/techniques/maps/shadow_lookup.glsl``): Williams 1978's shadow map and the techniques that only
    place its faces differently (LiSPSM's warp, cascades). No ``name``: not a technique itself.

    A subclass supplies :meth:`fit_views` (the faces and notes) and, where it differs from the
    defaults, :attr:`ATLAS_LAYOUT`, :meth:`two_layer`, :meth:`lookup_defines`,
    :meth:`comparison_uniforms` and :meth:`depth_state`; it has the parameters ``resolution``,
    ``depth_bits`` and ``filter``. Passes: ``depth`` (and ``peel``, ``resolve`` for two-layer
    comparisons), ``lookup``."""

    PASSES = ("depth", "peel", "resolve", "lookup")
    STATS = DEPTH_MAP_STATS
    READS = frozenset({"position", "normal"})
    PROVIDES = frozenset({"texel_mapping"})
    #: How the faces are laid out in the atlas: "grid" (1 face, or a cube's 3x2) or "row".
    ATLAS_LAYOUT = "grid"

    # -- what a subclass supplies -------------------------------------------------
    def fit_views(self, frame, slot) -> tuple[list[LightView], list[str]]:
        """The map's faces for ``slot`` and notes for the run."""
        raise NotImplementedError

    def two_layer(self) -> bool:
        """True when the comparison needs the second depth layer (depth peeling) and a resolve."""
        return False

    def resolve_uniforms(self) -> dict:
        """Uniforms of the resolve program (two-layer comparisons)."""
        return {}

    def lookup_defines(self) -> dict:
        """Compile-time switches of the lookup program (besides :data:`ATLAS_DEFINES`)."""
        return {}

    def comparison_uniforms(self) -> dict:
        """The lookup's depth-comparison uniforms: ``u_bias``, ``u_slope_scale``,
        ``u_normal_offset``, ``u_texel_world``, ``u_texel_angle``, ``u_kernel_radius``, and
        optionally ``u_depth_comparison`` (0: the point's own depth, the default) with what the
        per-tap comparisons need (``u_light_matrix_inverse``, ``u_adaptive_epsilon``,
        ``u_scene_extent``)..."""
        raise NotImplementedError

    def depth_state(self) -> tuple[bool, tuple[float, float] | None]:
        """(cull front faces, glPolygonOffset (factor, units) or None) of the depth pass."""
        return False, None

    # -- the shared machinery ------------------------------------------------------
    def setup(self, frame, slot) -> None:
        """Fit the faces, lay out the atlas, allocate its layers and set up the programs."""
        faces, notes = self.fit_views(frame, slot)
        self.notes.extend(notes)
        layout = Atlas.grid if self.ATLAS_LAYOUT == "grid" else Atlas.row
        self.atlas = layout(faces, self.resolution, self.name)
        two = self.two_layer()
        self.layers = [self.own(targets.DepthTexture.create(self.atlas.size, self.depth_bits))
                       for _ in range(3 if two else 1)]
        self.map = self.layers[-1]  # the layer the lookup compares with
        self.depth_prog = self.program("shadow_depth.glsl", defines=depth_defines())
        if two:
            self.peel_prog = self.program("shadow_depth.glsl", defines=depth_defines(peel=True))
            self.resolve_prog = self.program("shadow_resolve.glsl")
            self.resolve_quad = self.fullscreen_quad(self.resolve_prog)
            programs.set_uniforms(self.peel_prog, {"u_first_layer": 0, "u_peel_epsilon": DEPTH_STEP[self.depth_bits]})
            programs.set_uniforms(self.resolve_prog, {"u_first_layer": 0, "u_second_layer": 1,
                                                      **self.resolve_uniforms()})
        hw = FILTERS[self.filter] is None
        defines = {**ATLAS_DEFINES, **self.lookup_defines(), **({"FILTER_HW": 1} if hw else {})}
        self.lookup_prog = self.program("shadow_lookup.glsl", defines=defines)
        self.sampler = None
        if hw:
            ctx = frame.ctx
            self.sampler = self.own(ctx.sampler(texture=self.map.texture, filter=(ctx.LINEAR, ctx.LINEAR),
                                                compare_func="<=", repeat_x=False, repeat_y=False))
        programs.set_uniforms(self.lookup_prog, self.light.uniforms())
        self.atlas.write_uniforms(self.lookup_prog)
        programs.set_uniforms(self.lookup_prog, {"u_map": 2, **self.comparison_uniforms()})
        self.quad = self.fullscreen_quad(self.lookup_prog)
        self.vis_tex, self.vis_fbo = self.visibility_target((frame.width, frame.height))

    def _depth_pass(self, layer: targets.DepthTexture, prog, name: str) -> None:
        """Render the casters into every face of ``layer`` (pass ``name``: depth or peel)."""
        with self.timed_pass(name):
            cull_front, offset = self.depth_state()
            depth_pass(self.frame, layer, prog, self.atlas, cull_front, offset)

    def render(self) -> None:
        """Depth pass(es) from the light, the resolve (two-layer comparisons), the lookup."""
        if len(self.layers) == 3:
            first, second, comparison = self.layers
            self._depth_pass(first, self.depth_prog, "depth")
            first.texture.use(0)
            self._depth_pass(second, self.peel_prog, "peel")
            with self.timed_pass("resolve"):
                comparison.use_as_target()
                # every texel gets the resolved depth (written by the shader, test always passes)
                glstate.apply(PassState(depth_test=True, depth_func="always", depth_write=True, color_write=False))
                first.texture.use(0)
                second.texture.use(1)
                self.resolve_quad.render()
        else:
            self._depth_pass(self.map, self.depth_prog, "depth")
        with self.timed_pass("lookup"):
            self.vis_fbo.use()
            glstate.apply(PassState(samplers=(2,) if self.sampler is not None else ()))
            self.bind_gbuffer(self.lookup_prog)
            if self.sampler is not None:
                self.sampler.use(2)
            else:
                self.map.texture.use(2)
            self.quad.render()
            if self.sampler is not None:
                self.sampler.clear(2)

    def comparison_terms(self, taps: list[tuple[int, int]], uniforms: dict | None = None) -> np.ndarray:
        """Float32 (len(taps), height, width, 4): per pixel the terms of the lookup's depth
        comparison ``receiver − (u_bias + extra) <= stored`` for each tap offset (dx, dy) of
        ``taps``, as the lookup computes them (``shadow_lookup.glsl`` with ``THRESHOLDS``):
        (receiver depth, stored depth at the tap, extra bias, 1) — the tap's own receiver depth
        (receiver-plane comparison) or extra bias (adaptive) where the comparison is per tap — or
        w = 0 where the point is lit whatever the bias. ``uniforms`` override the comparison's
        (another ``u_slope_scale``, ``u_normal_offset`` or ``u_adaptive_epsilon``). Valid after :meth:`render` (the map holds the casters' depth); for
        the exact bias optimiser (:mod:`shadowlab.tuning.exact_bias`). No hardware filter, no
        cascades: their comparison is not one depth test per tap."""
        if FILTERS[self.filter] is None or self.lookup_defines().get("CASCADES"):
            raise TechniqueError(f"{self.name}: the {self.filter} lookup has no per-tap comparison terms")
        ctx = self.frame.ctx
        prog = self.program("shadow_lookup.glsl", defines={**ATLAS_DEFINES, **self.lookup_defines(), "THRESHOLDS": 1})
        programs.set_uniforms(prog, self.light.uniforms())
        self.atlas.write_uniforms(prog)
        programs.set_uniforms(prog, {"u_map": 2, **self.comparison_uniforms(), **(uniforms or {})})
        quad = self.fullscreen_quad(prog)
        size = (self.frame.width, self.frame.height)
        tex = self.own(ctx.texture(size, 4, dtype="f4"))
        fbo = self.own(ctx.framebuffer(color_attachments=[tex]))
        out = np.empty((len(taps), size[1], size[0], 4), np.float32)
        for k, tap in enumerate(taps):
            prog["u_tap"].value = tuple(int(v) for v in tap)
            fbo.use()
            glstate.apply(PassState())
            self.bind_gbuffer(prog)
            self.map.texture.use(2)
            quad.render()
            out[k] = targets.read_texture(tex, 4)
        return out

    def work(self, counted: dict, stats: dict) -> dict:
        """Texture taps: the lookup reads the G-buffer's position and normal, then (2r+1)² map
        texels per fragment for ``pcfN`` (r = the kernel radius), one for ``nearest``, four for
        the hardware 2x2 comparison; the two-layer resolve reads one texel of each layer."""
        radius = FILTERS[self.filter]
        per = 4 if radius is None else (2 * radius + 1) ** 2
        return self.taps_work(counted, {"lookup": GBUFFER_TAPS + per, "resolve": 2})

    def bias_window_world(self) -> tuple[float, float]:
        """(window, world): the constant bias the lookup applies, as window depth and as a world
        distance towards the light (0 for what it does not use); (0, 0) without a constant bias.
        The subclasses with a bias override it."""
        return 0.0, 0.0

    def bias_at_receivers(self) -> tuple[float, float] | tuple[None, None]:
        """(median, max) world distance the constant bias amounts to at the evaluated receivers
        (up to :data:`BIAS_WORLD_SAMPLES` of them): what a window-depth bias means in metres once
        the near plane has compressed the depth; (None, None) without receivers or bias."""
        window, world = self.bias_window_world()
        pts = self.frame.compact_position[self.slot.evaluated]
        if not len(pts) or (window <= 0 and world <= 0):
            return None, None
        pts = pts[:: max(1, len(pts) // BIAS_WORLD_SAMPLES)]
        dist = np.full(len(pts), float(world))
        if window > 0:
            to_light, _ = self.light.to_light(pts)
            face = self.face_index(pts)
            mats = np.stack([BIAS @ f.view_proj for f in self.atlas.faces])[face]
            dist = dist + window_to_world(mats, pts, to_light, np.full(len(pts), window))
        finite = dist[np.isfinite(dist)]
        return (float(np.median(finite)), float(finite.max())) if len(finite) else (float("inf"), float("inf"))

    def stats(self) -> dict:
        """Map memory (every layer), faces, passes per frame, the first face's depth range,
        near and far planes (perspective maps; world, along its axis) and world texel size, and
        the world size of the constant bias at the receivers (median and max)."""
        two_layer = len(self.layers) == 3
        depth_passes = len(self.atlas.faces) * (2 if two_layer else 1)
        face = self.atlas.faces[0]
        near, far = face.near_far() if list(face.proj[3]) == [0.0, 0.0, -1.0, 0.0] else (None, None)
        median, largest = self.bias_at_receivers()
        return {"memory_bytes": sum(layer.nbytes for layer in self.layers), "faces": len(self.atlas.faces),
                "passes": depth_passes + (1 if two_layer else 0) + 1,  # depth (and peel), resolve, lookup
                "depth_range": face.depth_range, "near_plane": near, "far_plane": far,
                "texel_world": float(face.texel_world) or None,
                "bias_world_median": median, "bias_world_max": largest}

    def degenerate_causes(self, stats: dict) -> list[str]:
        """Why a depth map lost its shadows (:meth:`Technique.degenerate_causes`), from the
        measurement's figures: a near plane so close that perspective window depth crowds into
        the top of [0, 1] (``near_plane`` / ``far_plane`` < 1e-3); a bias that amounts, at the
        receivers, to more than the casters' height above their shadows (``bias_world_median``
        against ``occluder_height_median``) or to a large share (≥ 10 %) of the map's
        ``depth_range`` — or, without the world figure, a window-depth ``bias`` of half the
        window range or more (at 1, every receiver passes the comparison); else depth precision.
        Keys are read with ``stats.get`` (older runs lack the plane and bias figures)."""
        def g(key):
            try:
                v = float(stats.get(key))
            except (TypeError, ValueError):
                return None
            return v if np.isfinite(v) else None

        near, far, depth_range = g("near_plane"), g("far_plane"), g("depth_range")
        bias_world, bias_max, height = g("bias_world_median"), g("bias_world_max"), g("occluder_height_median")
        bias = self.params().get("bias")
        causes = []
        if near is not None and far and near > 0 and near / far < 1e-3:
            causes.append(f"the near plane at {near:.3g}, far/near = {far / near:.3g}: window depth crowds into the top "
                          f"{near / (far + near):.2g} of [0, 1] over the far half of the depth range, where the bias "
                          f"and the depth format's steps swallow the gap between caster and receiver")
        converts = getattr(self, "converts_world_bias", None)
        unit = "x the scene's extent, bias_space=world" if converts is not None and converts() else "in window depth"
        named = f"the bias ({bias:g} {unit})" if bias is not None else "the bias"
        if bias_world is not None:
            at = (f"amounts to {bias_world:.3g} world units at the receivers (median"
                  + (f"; max {bias_max:.3g})" if bias_max is not None else ")"))
            if height is not None and bias_world > height:
                causes.append(f"{named} {at}, more than the casters' median height {height:.3g} above their shadows")
            elif depth_range and bias_world >= 0.1 * depth_range:
                causes.append(f"{named} {at}, {bias_world / depth_range:.0%} of the map's depth range {depth_range:.3g}")
        elif bias is not None and float(bias) >= 0.5:
            causes.append(f"{named} spans the whole window-depth range [0, 1]: every receiver passes the depth comparison"
                          if float(bias) >= 1.0 else
                          f"{named} spans {float(bias):.0%} of the window-depth range [0, 1]: most receivers pass the "
                          f"depth comparison")
        if not causes:
            bits = self.params().get("depth_bits")
            causes.append(f"depth precision: {f'{bits}-bit depth' if bits else 'the depth format'} over a depth range of "
                          + (f"{depth_range:.3g}" if depth_range else "unknown size")
                          + (f" against a bias of {bias:g} {unit}" if bias is not None else ""))
        return causes


# --------------------------------------------------------------------------- soft shadows: parallel planes

# Shared by the soft-shadow map techniques (pcss, moment_soft): Fernando 2005's parallel planes,
# taken parallel to the area light — heights above the light's plane along :func:`height_axis`,
# the light's extents (:func:`light_extents`), the blocker search's slice (:func:`search_height`),
# the scalar light size of the penumbra formula (:func:`light_size`), the planes of a perspective
# map (:func:`near_far`) and the receiver's tangent basis for its plane's slope.

#: The receiver's tangent basis for its plane's depth slope (``u_basis_*`` in the shader), the
#: choice of :func:`shadowlab.scene.area_lights.basis`: t1 = N × helper a while |N.x| < the switch
#: (a is then far from parallel to N), else N × helper b.
BASIS_SWITCH = 0.9
BASIS_HELPERS = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0))


def near_far(proj: np.ndarray) -> tuple[float, float]:
    """The near and far planes (linear depth along the axis) of a GL perspective matrix (4, 4),
    row-major: proj[2, 2] = −(f + n) / (f − n), proj[2, 3] = −2 f n / (f − n)."""
    return float(proj[2, 3] / (proj[2, 2] - 1.0)), float(proj[2, 3] / (proj[2, 2] + 1.0))


def light_extents(light: AreaLight, view: np.ndarray, owner: str = "pcss") -> np.ndarray:
    """The light's two extents (3, 2), world vectors as columns: rect — the full edges u, v;
    disc — two orthogonal diameters in its plane; sphere — diameters along the rows 0 and 1 of
    the world → view matrix ``view`` (4, 4) (the map's x and y axes). Another shape: a
    TechniqueError naming ``owner``."""
    if isinstance(light, RectLight):
        cols = (light.u, light.v)
    elif isinstance(light, DiscLight):
        t1, t2 = basis(light.normal)
        cols = (2 * light.radius * t1, 2 * light.radius * t2)
    elif isinstance(light, SphereLight):
        cols = (2 * light.radius * view[0, :3], 2 * light.radius * view[1, :3])
    else:
        raise TechniqueError(f"{owner}: no extent for area light shape {light.shape!r}")
    return np.stack([np.asarray(c, np.float64) for c in cols], axis=1)


def height_axis(light: AreaLight, view: np.ndarray) -> np.ndarray:
    """The unit axis (3,) heights above the light are measured along (PCSS's planes parallel to
    the light are the planes of constant height): a one-sided light's normal; a sphere's, the
    map's axis (−row 2 of the world → view matrix ``view`` (4, 4): the map looks down −z), to
    which its extents are perpendicular."""
    if light.one_sided:
        return np.asarray(light.normal, np.float64)
    return -np.asarray(view[2, :3], np.float64)


def search_height(axis: np.ndarray, centre: np.ndarray, caster_bounds: np.ndarray, near: float,
                  map_axis: np.ndarray, owner: str = "pcss") -> float:
    """The blocker search's slice height (world, > 0): the lowest height above the light (along
    ``axis`` (3,) from ``centre`` (3,)) of any corner of the casters' bounding boxes
    ``caster_bounds`` (K, 2, 3) — the slice nearest the light holds every lower one's region —
    but no lower than the height of the map's near plane on its axis, ``near`` · axis·``map_axis``
    (casters reaching the light's plane). A clear error (naming ``owner``) when that is not
    positive."""
    bounds = np.asarray(caster_bounds, np.float64).reshape(-1, 2, 3)
    corners = np.stack(np.meshgrid([0, 1], [0, 1], [0, 1], indexing="ij"), -1).reshape(-1, 3)
    pts = bounds[:, corners, [0, 1, 2]].reshape(-1, 3)  # (K·8, 3)
    floor = near * float(np.dot(axis, map_axis))
    lowest = float(((pts - centre) @ axis).min()) if len(pts) else floor
    height = max(lowest, floor)
    if not height > 0.0:
        raise TechniqueError(f"{owner}: the map's axis is perpendicular to or behind the light's height "
                             f"axis (axis·normal = {np.dot(axis, map_axis):.3g}); no blocker search plane")
    return height


def light_size(light: AreaLight) -> float:
    """The scalar light size of Fernando's formula (world units): a rect's longer edge, a disc's
    or a sphere's diameter (reported in stats; the kernel uses the full shape)."""
    if isinstance(light, RectLight):
        return float(max(np.linalg.norm(light.u), np.linalg.norm(light.v)))
    return float(2.0 * light.radius)
