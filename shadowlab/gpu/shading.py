"""Shared shading: the extended Blinn model of docs/architecture.md#the-shading-pass-shadowlabgpushadingpy over the G-buffer.

Every technique's image comes from this one pass with its own visibility images, so the
pictures differ only where the shadows differ.
"""
from __future__ import annotations

import numpy as np

from . import gl, glstate, programs, targets
from .glstate import PassState


class ShadingPass:
    """Shades a frame given one visibility image per light (built once per frame)."""

    def __init__(self, frame):
        self.frame = frame
        ctx = frame.ctx
        self.prog = programs.program("shade.glsl")
        self.quad = targets.fullscreen_quad(self.prog)
        objs = frame.scene.objects
        mats = np.zeros((3, len(objs), 4), np.float32)  # rows: diffuse+receives, specular+shininess, ambient
        for i, o in enumerate(objs):
            m = o.material
            mats[0, i] = (*m.diffuse, 1.0 if o.receives else 0.0)
            mats[1, i] = (*m.specular, m.shininess)
            mats[2, i, :3] = m.ambient_color()
        self.materials = ctx.texture((len(objs), 3), 4, mats.tobytes(), dtype="f4")
        self.materials.filter = (ctx.NEAREST, ctx.NEAREST)
        self.vis_tex = ctx.texture((frame.width, frame.height), 1, dtype="f4")
        self.vis_tex.filter = (ctx.NEAREST, ctx.NEAREST)
        self.weight_tex = ctx.texture((frame.width, frame.height), 1, dtype="f4")
        self.weight_tex.filter = (ctx.NEAREST, ctx.NEAREST)
        self.out_tex = ctx.texture((frame.width, frame.height), 4, dtype="f4")
        self.out_fbo = targets.framebuffer([self.out_tex])
        sh = frame.scene.shading
        # Set again by every shade(): the program is programs.program's shared one, and another ShadingPass
        # made since (another frame) may have set its own values.
        self.uniforms = {
            "u_position": 0, "u_normal": 1, "u_ids": 2, "u_materials": 3, "u_visibility": 4, "u_weight": 5,
            "u_eye": tuple(map(float, frame.camera.eye)), "u_density": float(sh.density),
            "u_shadow_color": tuple(map(float, sh.shadow_color)),
        }

    def shade(self, visibilities: list[np.ndarray], weights: list | None = None) -> np.ndarray:
        """Linear RGB float32 (height, width, 3), row 0 = top, from one visibility image
        (float32 (height, width), row 0 = top) per light; uncovered pixels are 0. ``weights``:
        per light None or an image (height, width) that multiplies the light's whole contribution
        (0 where a shadow budget leaves the light out, ``drop=unlit``)."""
        frame, ctx = self.frame, self.frame.ctx
        if len(visibilities) != len(frame.scene.lights):
            raise ValueError(f"need {len(frame.scene.lights)} visibility images, got {len(visibilities)}")
        weights = list(weights) if weights is not None else [None] * len(visibilities)
        from OpenGL import GL

        self.out_fbo.use()
        ctx.viewport = (0, 0, frame.width, frame.height)
        glstate.apply(PassState(blend=("one", "one")))  # the lights add up
        GL.glClearBufferfv(GL.GL_COLOR, 0, (0.0, 0.0, 0.0, 0.0))
        for tex, unit in ((frame.tex_position, 0), (frame.tex_normal, 1), (frame.tex_ids, 2),
                          (self.materials, 3), (self.vis_tex, 4), (self.weight_tex, 5)):
            tex.use(unit)
        programs.set_uniforms(self.prog, self.uniforms)
        for light, vis, weight in zip(frame.scene.lights, visibilities, weights):
            self.vis_tex.write(np.ascontiguousarray(vis[::-1], dtype=np.float32).tobytes())
            if weight is not None:
                self.weight_tex.write(np.ascontiguousarray(weight[::-1], dtype=np.float32).tobytes())
            self.prog["u_weighted"].value = weight is not None
            programs.set_uniforms(self.prog, light.uniforms())
            self.quad.render()
        gl.check_errors("shading pass")
        return targets.read_texture(self.out_tex, 4)[..., :3]

    def release(self) -> None:
        """Free GL objects (programs.program's cache keeps the program)."""
        targets.park()
        for obj in (self.quad, self.materials, self.vis_tex, self.weight_tex, self.out_fbo, self.out_tex):
            obj.release()
