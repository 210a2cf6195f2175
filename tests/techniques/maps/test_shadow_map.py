"""The shadow map measured against the ground truth on the standard scenes (stated tolerances),
and what it reports of its cost checked against the GL objects and draws it really makes."""
from __future__ import annotations

import pytest
from OpenGL import GL

from shadowlab.measurement.pipeline import measure
from shadowlab.techniques import from_spec


def metrics(lab, scene, spec, size=(640, 480)):
    return lab.rows(scene, [spec], size).iloc[0]


@pytest.mark.slow  # inner-loop budget (issue 36): among the slowest; make test runs it
def test_box_on_plane_2048_sensible_bias_under_1_percent(lab):
    m = metrics(lab, "box_on_plane", "shadow_map:resolution=2048,bias=0.002", size=(800, 600))
    assert m["evaluated_pixels"] > 100_000 and m["truth_shadowed_pixels"] > 2_000
    assert m["error_rate"] < 0.01


@pytest.mark.slow  # inner-loop budget (issue 36): among the slowest; make test runs it
def test_zero_bias_on_sloped_receiver_shows_acne(lab):
    """sun_scene has a ramp (a receiver sloped to the light): without bias, self-shadowing acne."""
    m = metrics(lab, "sun_scene", "shadow_map:resolution=2048,bias=0")
    assert m["false_shadow_rate"] > 0.05
    fixed = metrics(lab, "sun_scene", "shadow_map:resolution=2048,bias=0.002")
    assert fixed["false_shadow_rate"] < 0.01


@pytest.mark.slow  # inner-loop budget (issue 36): among the slowest; make test runs it
@pytest.mark.parametrize("scene", ["spot_scene", "sun_scene", "target_direct_scene"])
def test_standard_scenes_within_tolerance(lab, scene):
    """Every light type on its standard scene: error rate under 1 % at 2048² with the default bias."""
    m = metrics(lab, scene, "shadow_map")
    assert m["truth_shadowed_pixels"] > 1_000
    assert m["error_rate"] < 0.01


@pytest.mark.slow  # inner-loop budget (issue 36): among the slowest; make test runs it
def test_lower_resolution_is_worse_on_boundary(lab):
    hi = metrics(lab, "box_on_plane", "shadow_map:resolution=2048")
    lo = metrics(lab, "box_on_plane", "shadow_map:resolution=128")
    assert lo["false_lit_rate"] + lo["false_shadow_rate"] > hi["false_lit_rate"] + hi["false_shadow_rate"]


def _texture_size(glo: int) -> tuple[int, int, int]:
    """(width, height, depth bits) of a depth texture, as GL allocated it."""
    GL.glBindTexture(GL.GL_TEXTURE_2D, glo)
    out = tuple(int(GL.glGetTexLevelParameteriv(GL.GL_TEXTURE_2D, 0, p))
                for p in (GL.GL_TEXTURE_WIDTH, GL.GL_TEXTURE_HEIGHT, GL.GL_TEXTURE_DEPTH_SIZE))
    GL.glBindTexture(GL.GL_TEXTURE_2D, 0)
    return out


@pytest.mark.parametrize("spec,depth_passes,screen_passes", [
    ("shadow_map:resolution=512,depth_bits=16", 1, 1),
    ("shadow_map:resolution=256,depth_bits=32,variant=midpoint", 2, 2),
    ("shadow_map:resolution=128,projection=cube", 6, 1),
    ("shadow_map:resolution=128,projection=cube,variant=dual", 12, 2),
])
def test_reported_cost_is_what_gl_holds_and_draws(lab, ctx, spec, depth_passes, screen_passes):
    """memory_bytes is the size of the depth textures GL really allocated (24-bit depth stored in
    4 bytes), and ``passes`` the passes really drawn: the primitives one render generates are
    the casters once per depth pass plus two triangles per full-screen pass."""
    frame = lab.frame("sm_point_cube" if "cube" in spec else "box_on_plane", (160, 120))
    tech = from_spec(spec)
    m = measure(tech, frame, 0, repeat=1, warmup=0, release=False)
    sizes = [_texture_size(layer.glo) for layer in tech.layers]
    with ctx.query(primitives=True) as q:
        tech.render()
    tech.release()
    held = sum(w * h * (2 if bits == 16 else 4) for w, h, bits in sizes)
    requested = int(spec.split("depth_bits=")[1].split(",")[0]) if "depth_bits" in spec else 24
    assert all(bits == requested for _, _, bits in sizes)
    assert m.stats["memory_bytes"] == held
    caster_triangles = sum(len(o.faces) for o in frame.scene.objects if o.casts)
    assert q.primitives == depth_passes * caster_triangles + 2 * screen_passes
    assert m.stats["passes"] == depth_passes + screen_passes and m.stats["faces"] in (1, 6)
