"""The GL harness: context, shader includes, the depth-stencil attachment, depth formats."""
from __future__ import annotations

import numpy as np
import pytest
from OpenGL import GL

from shadowlab import gl


def test_context_and_renderer(ctx):
    assert ctx.version_code >= 330
    assert isinstance(gl.renderer(), str) and gl.renderer()


def test_include_expands_and_stages_compile(ctx):
    src = gl.shader_source("shade.glsl")
    assert "light_footprint" in src and "#include" not in src
    prog = gl.program("shade.glsl")
    assert "u_visibility" in prog
    prog.release()


def test_stencil_round_trip(ctx):
    """Write the stencil with INCR_WRAP from two overlapping quads, then test EQUAL against it."""
    w, h = 64, 32
    color = ctx.texture((w, h), 4, dtype="f4")
    target = gl.ScreenTarget.create((w, h), [color])
    target.use()
    target.clear_depth_stencil()
    prog = ctx.program(vertex_shader="#version 330\nin vec2 in_pos; uniform float u_off; uniform float u_scale;"
                                     "void main(){gl_Position=vec4(in_pos.x*u_scale+u_off,in_pos.y,0.0,1.0);}",
                       fragment_shader="#version 330\nuniform vec4 u_col; out vec4 c; void main(){c=u_col;}")
    quad = gl.fullscreen_quad(prog)
    prog["u_col"].value = (0, 0, 0, 0)
    GL.glEnable(GL.GL_STENCIL_TEST)
    GL.glStencilFunc(GL.GL_ALWAYS, 0, 0xFF)
    GL.glStencilOp(GL.GL_KEEP, GL.GL_KEEP, GL.GL_INCR_WRAP)
    # left half, then left quarter: counts 2 on the left quarter, 1 on the second quarter
    for scale, off in ((0.5, -0.5), (0.25, -0.75)):
        prog["u_scale"].value, prog["u_off"].value = scale, off
        quad.render()
    stencil = target.read_stencil()
    assert stencil[:, : w // 4].min() == 2 and stencil[:, w // 4: w // 2].max() == 1 and stencil[:, w // 2:].max() == 0
    target.use()
    GL.glStencilFunc(GL.GL_EQUAL, 2, 0xFF)
    GL.glStencilOp(GL.GL_KEEP, GL.GL_KEEP, GL.GL_KEEP)
    prog["u_scale"].value, prog["u_off"].value, prog["u_col"].value = 1.0, 0.0, (1, 0, 0, 1)
    quad.render()
    GL.glDisable(GL.GL_STENCIL_TEST)
    img = gl.read_texture(color, 4)
    assert (img[:, : w // 4, 0] == 1).all() and (img[:, w // 4:, 0] == 0).all()
    quad.release(); prog.release(); target.release(); color.release()


@pytest.mark.parametrize("bits,step", [(16, 1 / 65535), (24, 1 / 16777215), (32, 0.0)])
def test_depth_formats_quantise(ctx, bits, step):
    """A cleared depth texture stores the clear value rounded to its format (16-bit: a
    visible step; 24-bit: within a step; 32-bit float: the float32 value)."""
    tex = gl.DepthTexture.create((8, 8), bits)
    tex.use_as_target()
    value = 0.123456789
    GL.glClearDepth(value)
    GL.glClear(GL.GL_DEPTH_BUFFER_BIT)
    got = float(tex.read()[0, 0])
    if bits == 16:
        assert 1e-7 < abs(got - value) <= step / 2 + 1e-9
        assert abs(got / step - round(got / step)) < 1e-3
    elif bits == 24:
        assert abs(got - value) <= step / 2 + 1e-9
    else:
        assert got == pytest.approx(np.float32(value), abs=0)
    GL.glClearDepth(1.0)
    ctx.finish()
    tex.release()


def test_releasing_the_current_framebuffer_leaves_moderngl_usable(ctx):
    """A frame and its shading pass released while one of their framebuffers is current: the
    next moderngl framebuffer must still be created without a GL error (moderngl re-binds its
    current framebuffer, which must never be a deleted name)."""
    from shadowlab.frame import Frame
    from shadowlab.scene import load_scene
    from shadowlab.shading import ShadingPass

    frame = Frame(load_scene("box_on_plane"), 32, 24)
    shading = ShadingPass(frame)
    shading.shade([np.ones((24, 32), np.float32)])  # leaves its own framebuffer current
    shading.release()
    frame.release()
    fbo = ctx.framebuffer(color_attachments=[ctx.texture((4, 4), 4)])
    gl.check_errors("new framebuffer after releases")
    fbo.color_attachments[0].release()
    fbo.release()
    gl.park()
