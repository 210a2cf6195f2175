"""Contact shadows (the ``contact`` parameter of every map technique, Bend Studio's march): the
contact gap a large bias opens on sm_contact is partly closed, thickness halos grow with the
surface thickness on cs_thin_fins, the technique's own visibility is untouched, the dispatch
lists (ours and Bend's) and the samples counted, on every map technique."""
from __future__ import annotations

import numpy as np
import pytest

from shadowlab.techniques import REGISTRY, TechniqueError, from_spec
from shadowlab.techniques.maps.contact import (CONTACT_PARAMS, bend_dispatch_count, quadrant_rects,
                                               samples_marched)

from shadowlab.gpu import programs, targets
from shadowlab.techniques.maps.shadow_map import ShadowMap

from helpers import SMALL


@pytest.fixture(scope="module")
def gap_rows(lab):
    """sm_contact with a bias that detaches every thin caster (0.02), without and with contact."""
    rows = lab.rows("sm_contact", ["shadow_map:bias=0.02", "shadow_map:bias=0.02,contact=true"], SMALL)
    return rows


@pytest.fixture(scope="module")
def halo_rows(lab):
    """cs_thin_fins over the thickness sweep's ends and the default."""
    specs = ["shadow_map"] + [f"shadow_map:contact=true,contact_thickness={t}" for t in (0.001, 0.005, 0.05)]
    return lab.rows("cs_thin_fins", specs, SMALL)


@pytest.mark.slow
def test_contact_closes_part_of_the_gap_a_large_bias_opens(gap_rows):
    """Measured at 160x120: contact gap 2.93 → 1.76 px, 131 truly shadowed pixels recovered, 11
    false shadows introduced, false-lit pixels 334 → 203. Bend's grouped samples give partial
    shadows (below 0.5 they count), so the gap is not closed entirely."""
    off, on = gap_rows.loc["shadow_map:bias=0.02"], gap_rows.loc["shadow_map:bias=0.02,contact=true"]
    assert off["contact_gap_px"] > 2.0
    assert on["contact_gap_closed_px"] > 0.8
    assert on["contact_recovered_pixels"] > 100
    assert on["contact_false_pixels"] < 0.2 * on["contact_recovered_pixels"]
    assert np.isnan(off["contact_recovered_pixels"])  # no contact pass, no contact columns


@pytest.mark.slow
def test_thickness_halos_grow_with_the_surface_thickness(halo_rows):
    """Measured at 160x120: false shadows introduced 0 / 3 / 20 at thickness 0.001 / 0.005 /
    0.05 (halos behind the pole's and the fins' visible edges), while 0.05 also recovers 4
    truly shadowed pixels."""
    false = [halo_rows.loc[f"shadow_map:contact=true,contact_thickness={t}", "contact_false_pixels"]
             for t in (0.001, 0.005, 0.05)]
    assert false[0] <= false[1] < false[2]
    assert false[2] >= 10
    assert halo_rows.loc["shadow_map:contact=true,contact_thickness=0.05", "seam_pixels"] > 0


def test_the_technique_s_own_visibility_is_untouched_and_multiplied(lab):
    """``base`` is the contact=false image bit for bit; the result is base × contact_shadow."""
    off = lab.measure("sm_contact", "shadow_map", SMALL).visibility
    on = lab.measure("sm_contact", "shadow_map:contact=true", SMALL)
    assert np.array_equal(on.components["base"], off)
    np.testing.assert_array_equal(on.visibility, off * on.components["contact_shadow"])
    assert on.components["contact_shadow"].min() >= 0.0 and on.components["contact_shadow"].max() <= 1.0


def test_quadrants_cover_the_screen_once():
    """Every pixel in exactly one dispatch: 4 with the light's point inside, 2 beside an edge,
    1 beyond a corner."""
    for xy, expect in (((100.3, 50.7), 4), ((-40.0, 60.0), 2), ((500.0, -3.0), 1), ((-1e6, 1e6), 1)):
        rects = quadrant_rects(xy, (320, 240))
        assert len(rects) == expect
        cover = np.zeros((240, 320), int)
        for x0, y0, w, h in rects:
            cover[y0:y0 + h, x0:x0 + w] += 1
        assert (cover == 1).all()


def test_bend_dispatch_list_matches_its_published_count():
    """Bend's comment: "one or two dispatches when the light is off-screen, 4 to 6 when on". Our
    rewrite of its list at 1920x1080 over a grid of light points: on-screen 3-7, 4-6 for most;
    off-screen 1-2 for most, up to 5 just beside the screen."""
    on, off = [], []
    for x in np.linspace(-3000, 5000, 41):
        for y in np.linspace(-3000, 4000, 36):
            (on if 0 <= x < 1920 and 0 <= y < 1080 else off).append(bend_dispatch_count((x, y), (1920, 1080)))
    on, off = np.array(on), np.array(off)
    assert on.min() >= 3 and on.max() <= 8
    assert np.mean((on >= 4) & (on <= 6)) > 0.6
    assert np.mean(off <= 2) > 0.8
    assert bend_dispatch_count((-1e6, -1e6), (1920, 1080)) <= 2  # a quadrant, cut in two by the diagonal


def test_samples_stop_at_the_light_and_the_screen():
    """A pixel 10 px from the light's point marches 9 samples; one at the screen's edge
    marching outwards none; a light behind the camera: away from its point."""
    light_front = np.array([100.5, 50.5, 0.5, 1.0])
    assert samples_marched(np.array([[110.5, 50.5]]), light_front, 60, (320, 240)) == 9
    assert samples_marched(np.array([[0.5, 50.5]]), np.array([200.5, 50.5, 0.5, -1.0]), 60, (320, 240)) == 0
    assert samples_marched(np.array([[300.5, 50.5]]), np.array([200.5, 50.5, 0.5, -1.0]), 60, (320, 240)) == 19


def test_every_map_technique_has_contact_shadows():
    """The mixin's parameters, last but the shared light_samples, and its pass, on every technique of the map family."""
    maps = [cls for cls in REGISTRY.values() if cls.FAMILY == "maps"]
    assert len(maps) >= 9
    for cls in maps:
        own = [k for k in cls.PARAMS if k != "light_samples"]  # the pipeline's shared parameter stays last
        assert own[-len(CONTACT_PARAMS):] == list(CONTACT_PARAMS), cls.name
        assert cls.PASSES[-1] == "contact", cls.name
        assert not cls.PARAMS["contact"].default


@pytest.mark.slow
@pytest.mark.parametrize("spec,scene", [("filtered_map", "sm_contact"), ("cascaded_map", "sm_contact"),
                                        ("virtual_map", "sm_contact"), ("irregular_zbuffer", "sm_contact"),
                                        ("pcss", "soft_contact_hardening"), ("projective", "pt_limits")])
def test_contact_on_other_map_techniques(lab, spec, scene):
    """The pass composes with techniques whose visibility comes from elsewhere (moments, pages,
    the irregular z-buffer's list, soft kernels): result = base × contact, the dispatches and
    samples reported."""
    m = lab.measure(scene, f"{spec}:contact=true", SMALL)
    np.testing.assert_allclose(m.visibility, m.components["base"] * m.components["contact_shadow"], atol=1e-6)
    assert m.stats["contact_dispatches"] >= 1 and m.stats["contact_samples"] > 0


def test_bad_contact_parameters_are_named():
    with pytest.raises(TechniqueError, match="contact_thickness"):
        from_spec("shadow_map:contact=true,contact_thickness=0")
    with pytest.raises(TechniqueError, match="contact_samples"):
        from_spec("pcss:contact_samples=0")
    spec = from_spec("lispsm:contact=true,contact_samples=16").spec()
    assert from_spec(spec).spec() == spec


@pytest.mark.slow
def test_grazing_surfaces_shadow_themselves_where_the_edge_test_point_samples(lab):
    """sm_lamp_contact's point lamp lights the side walls and the far floor at grazing angles,
    which the camera also sees at grazing angles: neighbouring depths there differ by more than
    `contact_bilinear` (2 %) of the depth left to the far plane, the pair is taken for an edge and
    point-sampled, and the half-pixel depth error falls inside the thin thickness window — false
    shadow on surfaces nothing casts onto. Measured at 160x120: 177 pixels introduced at the
    defaults, 4 with the edge test off (contact_bilinear=1: every pair interpolated, the
    conservative farther depth), 64 at thickness 0.05 (the window moves off the error)."""
    rows = lab.rows("sm_lamp_contact", ["shadow_map:contact=true", "shadow_map:contact=true,contact_bilinear=1.0",
                                        "shadow_map:contact=true,contact_thickness=0.05"], SMALL)
    default, no_edges, thick = rows["contact_false_pixels"]
    assert default > 100
    assert no_edges < 0.1 * default
    assert no_edges < thick < default


def march(ctx, depth: np.ndarray, light, thickness: float, samples: int = 60, hard: int = 4, fade: int = 8,
          bilinear: float = 0.02) -> np.ndarray:
    """contact_march.glsl on a hand-made depth buffer (rows bottom-up, as GL stores them) with the
    light's projected point ``light`` (x, y, window depth, ±1): the contact visibility, same rows."""
    h, w = depth.shape
    tex = ctx.texture((w, h), 1, depth.astype("f4").tobytes(), dtype="f4")
    tex.filter = (ctx.NEAREST, ctx.NEAREST)
    out = ctx.texture((w, h), 1, dtype="f4")
    prog = programs.program("contact_march.glsl")
    try:
        programs.set_uniforms(prog, {"u_depth": 0, "u_contact": 0, "u_size": (w, h), "u_light": tuple(map(float, light)),
                                     "u_samples": samples, "u_hard": hard, "u_fade": fade, "u_thickness": thickness,
                                     "u_bilinear": bilinear, "u_contrast": 4.0})
        tex.use(0)
        out.bind_to_image(0, read=False, write=True)
        for x0, y0, rw, rh in quadrant_rects(light[:2], (w, h)):
            prog["u_origin"].value, prog["u_extent"].value = (x0, y0), (rw, rh)
            prog.run(-(-rw // 8), -(-rh // 8))
        ctx.memory_barrier()
        return np.frombuffer(out.read(), np.float32).reshape(h, w)
    finally:
        tex.release()
        out.release()


@pytest.mark.parametrize("gap", [2e-4, 1e-3, 3e-3, 1e-2])
def test_the_march_follows_bend_s_window(ctx, gap):
    """A flat background at window depth 0.9 with the light's point at its own depth on the right
    (every ray runs at depth 0.9), and a 4-pixel caster `gap` in front of it. The pixel 30 pixels
    left of the caster (s0 = 53 from the light's point) meets it at samples k = 30..33, one in
    each of the four groups; each sees u = gap · (s0 / s) · m / (1 − d0), s = s0 − k, m =
    min(s0 − 1, 1 / thickness) = 20, and shadows by clamp(4 |u − 1| − 3, 0, 1): the result is the
    mean over the four. 1e-3 and 3e-3 fall inside the window (shadow), 2e-4 on its soft edge (a
    surface almost on the ray), 1e-2 beyond it (a gap deeper than the thickness: a leak)."""
    depth = np.full((8, 64), 0.9)
    depth[:, 40:44] = 0.9 - gap
    vis = march(ctx, depth, (63.5, 4.5, 0.9, 1.0), thickness=0.05)
    s = 53.0 - np.arange(30, 34)
    u = gap * (53.0 / s) * 20.0 / 0.1
    expected = float(np.clip(4.0 * np.abs(u - 1.0) - 3.0, 0.0, 1.0).mean())
    assert vis[4, 10] == pytest.approx(expected, abs=2e-3)
    assert (expected < 0.05) == (gap in (1e-3, 3e-3))
    assert vis[4, 50] == 1.0  # right of the caster: nothing between it and the light


def test_the_march_stops_at_its_length(ctx):
    """The same caster 1e-3 in front: shadowed from 30 pixels with 60 samples, not with 16."""
    depth = np.full((8, 64), 0.9)
    depth[:, 40:44] = 0.9 - 1e-3
    assert march(ctx, depth, (63.5, 4.5, 0.9, 1.0), thickness=0.05)[4, 10] < 0.05
    assert march(ctx, depth, (63.5, 4.5, 0.9, 1.0), thickness=0.05, samples=16)[4, 10] == 1.0


def test_a_subclass_calling_super_gets_the_contact_part_once(lab):
    """A subclass overriding render and visibility with super() is wrapped again; the flag makes
    only the outermost wrapper act: visibility = base × contact, not base × contact²."""
    from shadowlab.measurement.pipeline import measure

    class Override(ShadowMap):
        def render(self):
            super().render()

        def visibility(self):
            return super().visibility()

    frame = lab.frame("sm_contact", SMALL)
    m = measure(Override(contact=True), frame, 0, repeat=1, warmup=0, count=False)
    off = lab.measure("sm_contact", "shadow_map", SMALL).visibility
    assert np.array_equal(m.components["base"], off)
    np.testing.assert_array_equal(m.visibility, off * m.components["contact_shadow"])


@pytest.mark.slow
def test_light_sampled_base_is_the_technique_without_contact(lab):
    """On an area light averaged over 4 samples, ``base`` is averaged as a visibility (horizon
    and facing included): it equals shadow_map:light_samples=4 without contact."""
    off = lab.measure("soft_overlap", "shadow_map:light_samples=4", SMALL).visibility
    on = lab.measure("soft_overlap", "shadow_map:light_samples=4,contact=true", SMALL)
    np.testing.assert_allclose(on.components["base"], off, atol=1e-6)


def test_contact_parameters_are_checked_together():
    with pytest.raises(TechniqueError, match=r"contact_fade \(12\) must not exceed contact_samples \(8\)"):
        from_spec("shadow_map:contact=true,contact_samples=8,contact_fade=12")
    from_spec("shadow_map:contact=true,contact_samples=8")  # 4 hard + 8 fading overlap: allowed
    assert any("contact=false" in n for n in from_spec("pcss:contact_thickness=0.01").notes)
