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


def test_contact_closes_part_of_the_gap_a_large_bias_opens(gap_rows):
    """Measured at 160x120: contact gap 2.93 → 1.76 px, 131 truly shadowed pixels recovered, 11
    false shadows introduced, false-lit pixels 334 → 203. Bend's grouped samples give partial
    shadows (below 0.5 they count), so the gap is not closed entirely."""
    off, on = gap_rows.loc["shadow_map:bias=0.02"], gap_rows.loc["shadow_map:bias=0.02,contact=true"]
    assert off["contact_gap_px"] > 2.0
    assert on["contact_gap_closed_px"] == pytest.approx(off["contact_gap_px"] - on["contact_gap_px"])
    assert on["contact_gap_closed_px"] > 0.8
    assert on["contact_recovered_pixels"] > 100
    assert on["contact_false_pixels"] < 0.2 * on["contact_recovered_pixels"]
    assert on["false_lit_pixels"] == off["false_lit_pixels"] - on["contact_recovered_pixels"]
    assert np.isnan(off["contact_recovered_pixels"])  # no contact pass, no contact columns


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
