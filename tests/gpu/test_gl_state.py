"""GL state that a technique relies on is set by the technique (docs/architecture.md#full-pass-state-shadowlabgpuglstatepy): its output must not
depend on what earlier passes left behind, the draw checker must see what llvmpipe forgives,
and the per-pass timings name the technique's own passes."""
from __future__ import annotations

import numpy as np
import pytest
from OpenGL import GL

from shadowlab.gpu import glstate, programs, targets
from shadowlab.measurement.pipeline import measure, measure_configs
from shadowlab.techniques import REGISTRY, from_spec

from gl_pollution import clean_and_polluted, pollute, reset_to_gl_defaults  # noqa: F401
from helpers import SMALL, scene_for

SIZE = SMALL
#: Configurations that between them use every GL feature the techniques rely on.
SPECS = ["raytrace:offset_scale=1e-05", "shadow_map", "shadow_map:variant=second_depth",
         "shadow_map:variant=midpoint", "shadow_map:variant=slope,hardware_offset=true",
         "shadow_map:filter=hw2x2,projection=cube,resolution=256", "shadow_volume",
         "shadow_volume:mode=zpass,silhouette=gpu", "shadow_volume:far=clamp", "planar",
         "planar:stencil=false,clip=false,clip_light=false", "shadow_polygons",
         "filtered_map", "filtered_map:variant=esm,kernel=1", "filtered_map:projection=cube,resolution=256",
         "filtered_map:variant=evsm4", "filtered_map:variant=msm,precision=16", "projective", "blob"]


#: Every other registered technique at its defaults, so a new one is covered without an entry here.
OTHERS = [name for name in REGISTRY if not any(s.split(":")[0] == name for s in SPECS)]


#: Techniques whose default run is seconds of CPU work (exact soft shadows, ray-traced soft
#: shadows at their default sample counts): checked with the slow tests (inner-loop budget).
HEAVY = {"exact_soft", "rt_soft"}


@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow) if n in HEAVY else n for n in OTHERS])
def test_every_other_technique_ignores_inherited_state(lab, ctx, name):
    """The same check for every registered technique SPECS does not name, at its defaults, on a
    scene whose lights it renders for."""
    frame = lab.frame(scene_for(REGISTRY[name]), SIZE)
    for light in range(len(frame.scene.lights)):
        clean, polluted = clean_and_polluted(ctx, frame, name, light)
        assert np.array_equal(clean, polluted), (name, light, int(np.sum(clean != polluted)))


@pytest.mark.slow  # inner-loop budget (issue 36): among the slowest; make test runs it
@pytest.mark.parametrize("spec", SPECS)
def test_output_does_not_depend_on_inherited_state(lab, ctx, spec):
    """Each configuration renders the same visibility, bit for bit, after the GL state was left
    polluted before its setup and before each render."""
    frame = lab.frame("multi_light", SIZE)
    for light in range(len(frame.scene.lights)):
        clean, polluted = clean_and_polluted(ctx, frame, spec, light)
        assert np.array_equal(clean, polluted), (spec, light, int(np.sum(clean != polluted)))


def test_frame_and_shading_do_not_depend_on_inherited_state(lab, ctx):
    """The G-buffer pass and the shared shading pass set their own state too: a frame built, and
    an image shaded, after the state was polluted equal the clean ones bit for bit."""
    from shadowlab.gpu.frame import Frame
    from shadowlab.gpu.shading import ShadingPass

    clean = lab.frame("multi_light", SIZE)
    vis = [lab.truth("multi_light", SIZE, li) for li in range(len(clean.scene.lights))]
    reset_to_gl_defaults()
    shader = ShadingPass(clean)
    image = shader.shade(vis)
    shader.release()
    samplers = [pollute(ctx)]
    try:
        frame = Frame(clean.scene, *SIZE)
        samplers.append(pollute(ctx))
        shader = ShadingPass(clean)
        samplers.append(pollute(ctx))
        polluted_image = shader.shade(vis)
        shader.release()
        same = (np.array_equal(frame.triangle_id, clean.triangle_id)
                and np.array_equal(frame.compact_position, clean.compact_position))
        frame.release()
    finally:
        for sampler in samplers:
            reset_to_gl_defaults(sampler)
    assert same, "the G-buffer depends on inherited GL state"
    assert np.array_equal(image, polluted_image), "the shading pass depends on inherited GL state"


def test_draw_checker_sees_what_llvmpipe_forgives(ctx):
    """A program that writes clip distances drawn without the enables, and enables without a
    writer, are both reported; a depth texture read through a plain sampler with a compare
    mode is reported."""
    prog = programs.program("planar.glsl", defines={"CLIP_LIGHT": 1})
    written = programs.program_info(prog).clip_distances
    assert written == {0, 1}
    targets.park()
    glstate.apply(glstate.PassState(clip_distances=0))
    assert len(glstate.draw_problems(written, {})) == 2
    glstate.apply(glstate.PassState(clip_distances=3))
    assert any("GL_CLIP_DISTANCE2 is enabled" in p for p in glstate.draw_problems(written, {}))
    glstate.apply(glstate.PassState(clip_distances=2))
    assert glstate.draw_problems(written, {}) == []
    depth = targets.DepthTexture.create((8, 8), 24)
    sampler = ctx.sampler(texture=depth.texture, compare_func="<=")
    targets.park()
    glstate.apply(glstate.PassState(samplers=(3,)))
    sampler.use(3)
    depth.texture.use(3)
    assert any("unit 3: sampler2D reads a depth texture with a compare mode" in p
               for p in glstate.draw_problems(frozenset(), {3: False}))
    assert glstate.draw_problems(frozenset(), {3: True}) == []
    sampler.clear(3)
    assert any("unit 3: sampler2DShadow without" in p for p in glstate.draw_problems(frozenset(), {3: True}))
    glstate.apply(glstate.PassState())
    sampler.release()
    depth.release()


def test_the_preprocessor_follows_ifdefs():
    src = "#define A 1\n#ifdef A\nx\n#ifndef B\ny\n#else\nz\n#endif\n#endif\n#ifdef B\nw\n#endif"
    assert glstate.active_source(src).split() == ["x", "y"]


@pytest.mark.parametrize("spec,expected", [
    ("raytrace:offset_scale=1e-05", {"trace"}),
    ("shadow_map", {"depth", "lookup"}),
    ("shadow_map:variant=dual", {"depth", "peel", "resolve", "lookup"}),
    ("shadow_volume", {"silhouette", "volume", "count"}),  # auto: box_on_plane needs no z-fail, so no caps
    ("shadow_volume:mode=zfail", {"silhouette", "volume", "caps", "count"}),
    ("shadow_volume:mode=zfail,silhouette=gpu", {"silhouette", "volume", "caps", "count"}),
    ("planar", {"stencil", "darken"}),
    ("shadow_polygons", {"draw"}),
    ("filtered_map", {"moments", "blur", "lookup"}),
    ("filtered_map:variant=esm,kernel=1", {"moments", "lookup"}),  # a 1-texel kernel skips the blur
    ("filtered_map:variant=msm", {"moments", "blur", "lookup"}),
    ("projective", {"mask", "lookup"}),
    ("blob", {"blob"}),
])
@pytest.mark.slow  # inner-loop budget (issue 36): among the slowest; make test runs it
def test_pass_timings_name_the_techniques_passes(lab, spec, expected):
    """With pass timing asked for, a configuration reports a time for exactly the passes it runs
    (declared in its PASSES); without, no pass columns."""
    df = measure_configs(None, [spec], evaluator=lab.evaluator("box_on_plane", SIZE), pass_timing=True, repeat=2)
    row = df[~df["reference"]].iloc[0]
    passes = {c[len("pass_"):-len("_ms")] for c in df.columns if c.startswith("pass_") and np.isfinite(row[c])}
    assert passes == expected and passes <= set(REGISTRY[spec.split(":")[0]].PASSES), passes
    assert all(row[f"pass_{p}_ms"] >= 0 for p in passes)
    plain = measure_configs(None, ["shadow_map"], evaluator=lab.evaluator("box_on_plane", SIZE))
    assert not any(c.startswith("pass_") for c in plain.columns)
