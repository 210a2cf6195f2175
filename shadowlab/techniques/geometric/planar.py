"""Projected planar shadows (Blinn 1988) and the stencil fixes for their artefacts.

Receivers are the scene's planar objects (all vertices on one plane, within a tolerance relative
to the object's size); every other object receives no shadow from this technique, and the run
notes say which. For each planar receiver, every other caster is flattened onto the receiver's
plane with the planar projection matrix

    M = (p · l) I − l pᵀ,   p = (n, d) the receiver's plane, l = (L, 1) or (−direction, 0),

and drawn through the camera as a darkening layer: the visibility target is multiplied by
1 − ``opacity`` wherever a projected triangle lands (SIGGRAPH '99 course "Advanced Graphics
Programming Techniques Using OpenGL", §projection shadows). Each classic artefact has a fix that
one boolean turns on or off, so it can be reproduced on purpose and measured:

- ``offset``: polygon offset pulls the flattened geometry in front of the receiver; without it the
  two are coplanar and the depth test z-fights (stripes; worst with a far, low camera);
- ``stencil``: each pixel is darkened once (stencil incremented on the first darkening); without
  it overlapping projected triangles multiply their darkening (double blending);
- ``clip``: the receiver's own visible pixels are marked in the stencil first and only they can be
  darkened; without it the shadow hangs off the receiver's edge onto whatever lies beyond;
- ``clip_light``: casters are clipped to the slab between the plane through the light (parallel
  to the receiver) and the receiver's plane (two clip distances, each enabled as GL 4.5 core
  requires: a written gl_ClipDistance is ignored unless GL_CLIP_DISTANCEi is on); without it geometry behind the receiver casts onto
  it (false shadows), and geometry beyond the light projects with w ≤ 0 — which GL's
  homogeneous clipper happens to remove, so on this pipeline the measurable artefact is the
  former (Blinn's anti-shadows appear where w is divided out before clipping).

The technique draws its own depth pre-pass (untimed, in ``setup``) into the G-buffer's depth-
stencil attachment with the frame's camera.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ...gpu import glstate, programs
from ...gpu.glstate import PassState, Stencil
from ..base import FIRST, SUM, Param, PlotStyle, Technique

#: Planarity tolerance: largest distance of a vertex from the fitted plane, relative to the
#: object's bounding-box diagonal.
PLANAR_TOLERANCE = 1e-7


@dataclass
class PlanarReceiver:
    """A planar receiver object: its index, plane (n, d) with n·x + d = 0 and the light on the
    positive side, and the planar projection matrix onto it (float64 4x4)."""

    index: int
    plane: np.ndarray
    projection: np.ndarray
    light_plane: np.ndarray


def fit_plane(vertices: np.ndarray) -> np.ndarray | None:
    """The plane (n, d) through ``vertices`` (V, 3) float64 if they are coplanar, else None."""
    centre = vertices.mean(axis=0)
    _, s, vt = np.linalg.svd(vertices - centre, full_matrices=False)
    extent = float(np.linalg.norm(vertices.max(0) - vertices.min(0)))
    n = vt[-1]
    if extent == 0 or np.max(np.abs((vertices - centre) @ n)) > PLANAR_TOLERANCE * extent:
        return None
    return np.append(n, -n @ centre)


def planar_projection(plane: np.ndarray, light_h: np.ndarray) -> np.ndarray:
    """Blinn's projection onto ``plane`` from ``light_h``: M = (p·l) I − l pᵀ (4x4)."""
    return float(plane @ light_h) * np.eye(4) - np.outer(light_h, plane)


class PlanarShadow(Technique):
    """Projected planar shadows onto the scene's planar receivers, with switchable fixes."""

    name = "planar"
    summary = "projected planar shadows (Blinn 1988) with stencil fixes"
    PARAMS = {
        "offset": Param(True, "polygon offset against z-fighting with the receiver"),
        "stencil": Param(True, "darken each pixel once (no double blending)"),
        "clip": Param(True, "stencil-clip the shadow to the receiver's own pixels"),
        "clip_light": Param(True, "clip casters to the slab between the light's plane and the receiver"),
        "opacity": Param(0.75, "darkening of one shadow layer (visibility 1 − opacity; above 0.5, so that one "
                                 "layer reads as shadow at the metrics' threshold)", min=0.5, min_open=True, max=1.0),
        "offset_factor": Param(-1.0, "glPolygonOffset factor of the offset fix", min=-1e3, max=0.0),
        "offset_units": Param(-4.0, "glPolygonOffset units of the offset fix", min=-1e6, max=0.0),
    }
    #: Its own depth pre-pass and the stencil of the fixes live in the G-buffer's depth-stencil.
    WRITES = frozenset({"depth_stencil"})
    PASSES = ("stencil", "darken")
    STYLE = PlotStyle("#2ca02c", "^")
    STATS = {"planar_receivers": FIRST, "polygons": SUM, "passes": SUM, "preprocess_ms": SUM}
    LIGHT_SAMPLED = True  # light_samples=N: averaged over N points of an area light (shadowlab.measurement.light_sampling)

    def setup(self, frame, slot) -> None:
        """Find planar receivers, build their projections, render the depth pre-pass."""
        t0 = time.perf_counter()
        light_h = self.light.homogeneous()
        self.receivers: list[PlanarReceiver] = []
        skipped = []
        for i, obj in enumerate(frame.scene.objects):
            if not obj.receives:
                continue
            plane = fit_plane(obj.vertices)
            if plane is None:
                skipped.append(obj.name)
                continue
            if plane @ light_h < 0:
                plane = -plane
            if plane @ light_h <= 0:  # the light lies in the receiver's plane: nothing to project
                continue
            if self.light.at_infinity:
                light_plane = np.array([0.0, 0.0, 0.0, 1.0])
            else:  # receiver-parallel plane through the light, positive towards the receiver
                light_plane = np.append(-plane[:3], plane[:3] @ self.light.position)
            self.receivers.append(PlanarReceiver(i, plane, planar_projection(plane, light_h), light_plane))
        if skipped:
            self.notes.append(f"not planar, so no shadow from planar: {', '.join(skipped)}")
        self.preprocess_ms = 1e3 * (time.perf_counter() - t0)
        defines = {"CLIP_LIGHT": 1} if self.clip_light else None
        self.prog = self.program("planar.glsl", defines=defines)
        self.prog["u_view_proj"].write(programs.mat_bytes(frame.view_projection))
        self.prog["u_keep"].value = 1.0 - float(self.opacity)
        self.depth_prog = self.program("depth_only.glsl")
        self.depth_prog["u_view_proj"].write(programs.mat_bytes(frame.view_projection))
        self.vis_tex, self.target = self.visibility_target((frame.width, frame.height),
                                                           share_depth_stencil=frame.depth_stencil_for(self))
        self.target.use()
        glstate.apply(PassState(depth_test=True, depth_func="<", depth_write=True, color_write=False))
        self.target.clear_depth_stencil()
        frame.draw(self.depth_prog, "all")

    def _draw_object(self, prog, index: int) -> None:
        rng = self.frame.object_ranges[index]
        self.frame.vertex_array(prog).render(vertices=rng.count, first=rng.first)

    def render(self) -> None:
        """Per receiver: mark its pixels (clip), then darken them with the flattened casters."""
        from OpenGL import GL

        frame = self.frame
        with self.timed_pass("darken"):  # visibility starts lit; the darken passes multiply it
            self.target.use()
            glstate.apply(PassState(depth_write=False))
            GL.glClearBufferfv(GL.GL_COLOR, 0, (1.0, 0.0, 0.0, 0.0))
        casters = [i for i, o in enumerate(frame.scene.objects) if o.casts]
        for rec in self.receivers:
            ref = 1 if self.clip else 0
            with self.timed_pass("stencil"):
                GL.glStencilMask(0xFF)
                GL.glClearStencil(0)
                GL.glClear(GL.GL_STENCIL_BUFFER_BIT)
                if self.clip:  # the receiver's visible pixels get stencil 1
                    glstate.apply(PassState(depth_test=True, depth_func="<=", depth_write=False, color_write=False,
                                            stencil=Stencil("always", 1).both(("keep", "keep", "replace"))))
                    self._draw_object(self.depth_prog, rec.index)
            with self.timed_pass("darken"):
                stencil = None
                if self.clip or self.stencil:
                    # stencil fix: the first darkening moves the pixel off ``ref``, so it is darkened once
                    stencil = Stencil("==", ref).both(("keep", "keep", "incr" if self.stencil else "keep"))
                glstate.apply(PassState(
                    depth_test=True, depth_func="<", depth_write=False,
                    blend=("zero", "src_color"),  # visibility *= 1 − opacity
                    polygon_offset=(float(self.offset_factor), float(self.offset_units)) if self.offset else None,
                    stencil=stencil,
                    clip_distances=2 if self.clip_light else 0))  # the light's and the receiver's planes
                programs.set_uniforms(self.prog, {"u_light_plane": tuple(map(float, rec.light_plane)),
                                                  "u_receiver_plane": tuple(map(float, rec.plane))})
                self.prog["u_plane_projection"].write(programs.mat_bytes(rec.projection))
                for i in casters:
                    if i != rec.index:
                        self._draw_object(self.prog, i)

    def stats(self) -> dict:
        """Receivers, flattened triangles per frame, preprocessing time."""
        objs = self.frame.scene.objects
        tris = sum(len(o.faces) for r in self.receivers for i, o in enumerate(objs) if o.casts and i != r.index)
        return {"planar_receivers": len(self.receivers), "polygons": int(tris),
                "passes": len(self.receivers) * (2 if self.clip else 1), "preprocess_ms": self.preprocess_ms}
