"""GL state pollution for the tests that check a pass sets every state it relies on: turn every
fixed-function setting a pass could inherit to an unhelpful value (:func:`pollute`), undo it with
raw GL calls (:func:`reset_to_gl_defaults`), and measure a configuration both ways
(:func:`clean_and_polluted`). Shared by tests/gpu/test_gl_state.py and the techniques' tests."""
from __future__ import annotations

import numpy as np
from OpenGL import GL

from shadowlab.gpu import glstate
from shadowlab.measurement.pipeline import measure
from shadowlab.techniques import from_spec


#: Capabilities off in a new context, which :func:`pollute` turns on.
CAPABILITIES = [GL.GL_CULL_FACE, GL.GL_BLEND, GL.GL_POLYGON_OFFSET_FILL, GL.GL_DEPTH_CLAMP, GL.GL_STENCIL_TEST,
                GL.GL_SCISSOR_TEST, GL.GL_DEPTH_TEST, GL.GL_RASTERIZER_DISCARD] + [GL.GL_CLIP_DISTANCE0 + i for i in range(glstate.MAX_CLIP_DISTANCES)]


#: (setter, an unhelpful value, GL's initial value — GL 4.5 core state tables) for every other
#: fixed-function setting a pass relies on.
SETTINGS = [
    (GL.glCullFace, (GL.GL_FRONT_AND_BACK,), (GL.GL_BACK,)),
    (GL.glBlendFunc, (GL.GL_ZERO, GL.GL_ZERO), (GL.GL_ONE, GL.GL_ZERO)),
    (GL.glPolygonOffset, (50.0, 5000.0), (0.0, 0.0)),
    (GL.glStencilFunc, (GL.GL_NEVER, 7, 0x0F), (GL.GL_ALWAYS, 0, 0xFF)),
    (GL.glStencilOp, (GL.GL_INVERT, GL.GL_INVERT, GL.GL_INVERT), (GL.GL_KEEP, GL.GL_KEEP, GL.GL_KEEP)),
    (GL.glStencilMask, (0x00,), (0xFF,)),
    (GL.glScissor, (0, 0, 3, 3), None),
    (GL.glDepthFunc, (GL.GL_GREATER,), (GL.GL_LESS,)),
    (GL.glDepthMask, (GL.GL_FALSE,), (GL.GL_TRUE,)),
    (GL.glColorMask, (False, True, False, True), (True, True, True, True)),
    (GL.glProvokingVertex, (GL.GL_FIRST_VERTEX_CONVENTION,), (GL.GL_LAST_VERTEX_CONVENTION,)),
    (GL.glFrontFace, (GL.GL_CW,), (GL.GL_CCW,)),
    (GL.glPolygonMode, (GL.GL_FRONT_AND_BACK, GL.GL_LINE), (GL.GL_FRONT_AND_BACK, GL.GL_FILL)),
    (GL.glBlendEquation, (GL.GL_MAX,), (GL.GL_FUNC_ADD,)),
    (GL.glDepthRange, (0.5, 1.0), (0.0, 1.0)),
] + ([(GL.glClipControl, (GL.GL_UPPER_LEFT, GL.GL_ZERO_TO_ONE), (GL.GL_LOWER_LEFT, GL.GL_NEGATIVE_ONE_TO_ONE))]
     if bool(GL.glClipControl) else [])


def pollute(ctx):
    """Leave every fixed-function state a pass could inherit at an unhelpful value, and a
    comparison sampler on every texture unit (returned: deleting it unbinds it)."""
    for cap in CAPABILITIES:
        GL.glEnable(cap)
    for setter, bad, _ in SETTINGS:
        setter(*bad)
    sampler = ctx.sampler(compare_func=">=")
    for unit in range(glstate.TEXTURE_UNITS):
        sampler.use(unit)
    return sampler


def reset_to_gl_defaults(sampler=None):
    """Undo :func:`pollute` with GL's initial values, set with raw GL calls rather than the code
    under test, so that a clean reference run is really clean."""
    if sampler is not None:
        sampler.release()  # deleting a sampler object unbinds it from every unit
    for cap in CAPABILITIES:
        GL.glDisable(cap)
    for setter, _, initial in SETTINGS:
        if initial is not None:
            setter(*initial)


def clean_and_polluted(ctx, frame, spec: str, light: int) -> tuple[np.ndarray, np.ndarray]:
    """The visibility of ``spec`` on one light of ``frame`` measured from GL defaults, and again
    with the GL state polluted before its setup and before its render (float32 (H, W) each)."""
    reset_to_gl_defaults()
    clean = measure(from_spec(spec), frame, light, repeat=1, warmup=0).visibility
    tech = from_spec(spec)
    samplers = [pollute(ctx)]
    try:
        tech.prepare(frame, light)
        samplers.append(pollute(ctx))  # kept alive: deleting a sampler object unbinds it
        tech.render()
        polluted = tech.visibility()
    finally:
        tech.release()
        for sampler in samplers:
            reset_to_gl_defaults(sampler)
    return clean, polluted
