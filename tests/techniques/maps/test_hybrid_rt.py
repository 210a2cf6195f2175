"""Hybrid ray-traced shadows: exact (or off by the classifier's own errors only) on the hard cases,
traced pixels equal to the truth's, the classifier's error where a coarse map misses a thin
caster, rays per pixel below one and falling with resolution, ray shortening, the tile cut-off,
spread 0 as a plain shadow map, its declarations and bad parameters (hard lights: MEDIUM,
320x240). Area lights (SMALL, 160x120): error at the truth's noise level, the classifier never
wrong, rays per pixel below the samples, the truth's estimator on the uncertain pixels, the
pyramid's box minimum, the shared checks of area-light map techniques."""
from __future__ import annotations

import numpy as np
import pytest

from shadowlab.techniques import TechniqueError, from_spec

from area_map_checks import LIGHTS, assert_behind_one_sided_sees_none, assert_fully_lit
from helpers import MEDIUM, SMALL, make_scene
from shadowlab.techniques.maps import hybrid_rt
from shadowlab.truth.area import area_visibility


def run(lab, scene, spec, light=0):
    """(visibility, classifier image, stats, truth, evaluated mask) of one configuration."""
    m = lab.measure(scene, spec, MEDIUM, light)
    return (m.visibility, m.technique.component_images()["classifier"], m.stats,
            lab.truth(scene, MEDIUM, light), lab.frame(scene, MEDIUM).evaluated(light))


def errors(vis, classifier, truth, evaluated) -> tuple[int, int]:
    """(wrong evaluated pixels, pixels the classifier called sure wrongly), thresholded at 0.5."""
    shadowed = truth < 0.5
    wrong = int(np.sum(((vis < 0.5) != shadowed)[evaluated]))
    sure = evaluated & ~np.isnan(classifier)
    return wrong, int(np.sum(((classifier < 0.5) != shadowed)[sure]))


@pytest.mark.parametrize("scene,spec,expected", [
    ("box_on_plane", "hybrid_rt", 0),                    # point light, one frustum
    ("sm_thin", "hybrid_rt", 0),                         # a zero-thickness quad 1 cm above the floor
    ("sm_aliasing", "hybrid_rt", 0),                     # spot light, perspective aliasing
    # the classifier's only misses: contacts within the default bias (0.002 x the depth range) of
    # the floor, called surely lit by every tap; bias=0.0005 classifies them uncertain (0 wrong)
    ("sm_contact", "hybrid_rt", 64),
    ("sm_contact", "hybrid_rt:bias=0.0005", 0),
])
def test_exact_but_for_the_classifier(lab, scene, spec, expected):
    """With spread 1 and cutoff 0 every uncertain pixel is traced with the truth's ray, so the
    only wrong pixels are those the classifier called sure wrongly (measured: box_on_plane,
    sm_thin and sm_aliasing 0; sm_contact 64 at bias 0.002, 0 at 0.0005); the final image
    equals the truth on every pixel the classifier did not call."""
    vis, classifier, stats, truth, evaluated = run(lab, scene, spec)
    wrong, classifier_wrong = errors(vis, classifier, truth, evaluated)
    assert wrong == classifier_wrong == expected
    uncertain = evaluated & np.isnan(classifier)
    assert uncertain.sum() == stats["uncertain_pixels"] == stats["traced_pixels"] > 0
    assert np.array_equal(vis[uncertain], truth[uncertain])  # the truth's rays, bit for bit
    assert 0 < stats["rays_per_pixel"] < 0.01                # measured: 0.0003 - 0.0058
    assert (vis[evaluated] < 0.5).sum() > 100                # there is shadow, and it was found


def test_the_classifier_errs_where_a_coarse_map_misses_a_thin_caster(lab):
    """sm_wires with a 256² map: wires thinner than a texel cover no texel centre in places, every
    tap of the kernel sees the floor, and the classifier calls shadowed floor surely lit
    (measured: 85 pixels); the final error is exactly those pixels, nothing from the full-length
    rays. (At the default 2048² the classifier still misses 6 pixels of sm_wires.)"""
    vis, classifier, stats, truth, evaluated = run(lab, "sm_wires", "hybrid_rt:resolution=256,shorten=false")
    wrong, classifier_wrong = errors(vis, classifier, truth, evaluated)
    assert classifier_wrong > 40
    assert wrong == classifier_wrong  # measured 85 = 85
    bad = evaluated & ((vis < 0.5) != (truth < 0.5))
    assert np.all(classifier[bad] == 1.0)  # each one a shadowed pixel called surely lit


def test_a_kernel_past_the_face_edge_is_uncertain(lab):
    """sm_thin's map is fitted to the thin quad's shadow, which therefore runs to the face's edges;
    with a 16² map the kernels at the rim reach past the edge. Called sure with taps clamped to
    the edge texel they were 330 lit pixels called shadowed; uncertain, they are traced
    (measured: 1 wrong pixel left)."""
    vis, classifier, stats, truth, evaluated = run(lab, "sm_thin", "hybrid_rt:resolution=16")
    wrong, classifier_wrong = errors(vis, classifier, truth, evaluated)
    assert wrong == classifier_wrong <= 2


def test_rays_per_pixel_is_below_one_and_falls_with_resolution(lab):
    """The truth traces one ray per evaluated pixel; the hybrid only the uncertain ones, fewer as
    the map's texels shrink (measured on sm_aliasing: 0.13, 0.021, 0.0058 at 128, 512, 2048)."""
    rates = []
    for resolution in (128, 512, 2048):
        _, _, stats, _, evaluated = run(lab, "sm_aliasing", f"hybrid_rt:resolution={resolution}")
        assert stats["rays"] == stats["traced_pixels"]
        assert stats["rays_per_pixel"] == pytest.approx(stats["rays"] / evaluated.sum())
        rates.append(stats["rays_per_pixel"])
    assert rates[0] < 1.0 and rates[0] > rates[1] > rates[2] > 0.0


@pytest.mark.slow
@pytest.mark.parametrize("scene", ["box_on_plane", "sm_thin", "sm_aliasing", "sm_contact", "sm_point_cube",
                                   "sm_wires", "sv_soup"])
def test_shortened_rays_give_the_same_visibility(lab, scene):
    """Shortening each ray to the kernel's nearest stored depth (plus the default margin of 64
    texels) changes no pixel on these scenes at the default resolution (the point light's cube
    faces, sub-texel wires and a soup of tilted triangles among them)."""
    short, _, s1, _, _ = run(lab, scene, "hybrid_rt")
    full, _, s2, _, _ = run(lab, scene, "hybrid_rt:shorten=false")
    assert s1["rays"] == s2["rays"]
    assert np.array_equal(short, full)


@pytest.mark.slow
@pytest.mark.parametrize("scene,spec,expected", [
    # tilted sub-texel triangles just in front of the stored depth: a 4-texel margin misses them
    ("sv_soup", "hybrid_rt:margin=4", 18),
    # a coarse map: a higher wire that covers no texel centre, far in front of a lower one the
    # kernel saw; no texel margin covers the gap between their heights
    ("sm_wires", "hybrid_rt:resolution=256", 72),
])
def test_shortening_can_miss_a_caster_the_map_never_saw(lab, scene, spec, expected):
    """Shortening is not exact: a caster that covers no texel centre of the kernel is not in the
    map, so the stored depths do not bound it. Measured: the pixels where the shortened rays
    differ from the full segments (every one of them a pixel the full ray gets right)."""
    short, _, _, truth, evaluated = run(lab, scene, spec)
    full, _, _, _, _ = run(lab, scene, spec + ",shorten=false")
    differ = evaluated & (short != full)
    # measured on llvmpipe; rasteriser ties move a pixel or two (sv_soup: 17 on an NVIDIA H200)
    assert abs(int(differ.sum()) - expected) <= max(2, expected // 10)
    assert np.array_equal(full[differ], truth[differ])


def test_spread_zero_is_the_shadow_map_it_classifies_with(lab):
    """spread=0: one tap, never uncertain, no rays: shadow_map's nearest comparison with the same
    bias, bit for bit (so the classifier's spread is what makes the hybrid exact)."""
    vis, classifier, stats, truth, evaluated = run(lab, "sm_aliasing", "hybrid_rt:spread=0")
    assert stats["rays"] == stats["uncertain_pixels"] == 0
    assert not np.isnan(classifier[evaluated]).any()
    sm = lab.measure("sm_aliasing", "shadow_map", MEDIUM).visibility
    assert np.array_equal(vis[evaluated], sm[evaluated])  # (shadow_map also draws the unevaluated pixels)
    wrong, classifier_wrong = errors(vis, classifier, truth, evaluated)
    assert wrong == classifier_wrong > 0  # measured: 29 (the map's aliasing)


@pytest.mark.slow
def test_the_tile_cutoff_drops_sparse_tiles_to_the_nearest_tap(lab):
    """cutoff=8 leaves tiles with fewer than 8 uncertain pixels to the nearest tap: fewer rays,
    the dropped pixels counted, and wrong pixels only where they were dropped; cutoff=65 (more
    than a tile holds) traces nothing and is spread=0's nearest-tap image."""
    full, _, s0, truth, evaluated = run(lab, "box_on_plane", "hybrid_rt")
    cut, classifier, s8, _, _ = run(lab, "box_on_plane", "hybrid_rt:cutoff=8")
    assert s8["dropped_pixels"] > 0 and s8["rays"] == s0["rays"] - s8["dropped_pixels"]
    assert s8["uncertain_pixels"] == s0["uncertain_pixels"]
    changed = evaluated & (cut != full)
    assert np.all(np.isnan(classifier[changed]))
    wrong, _ = errors(cut, classifier, truth, evaluated)
    assert wrong == 2  # measured: 2 dropped pixels wrong
    none, _, s65, _, _ = run(lab, "box_on_plane", "hybrid_rt:cutoff=65")
    assert s65["rays"] == 0 and s65["dropped_pixels"] == s0["uncertain_pixels"]
    nearest, _, _, _, _ = run(lab, "box_on_plane", "hybrid_rt:spread=0")
    assert np.array_equal(none, nearest)


def test_classifier_image_and_stats(lab):
    """The classifier image is NaN off the evaluated pixels and on the uncertain ones, 0 or 1
    elsewhere; memory is the 24-bit atlas (4 bytes a texel) and the RGBA32F class image; passes
    are one depth pass per face, the classification and the trace."""
    vis, classifier, stats, _, evaluated = run(lab, "box_on_plane", "hybrid_rt:resolution=512")
    assert classifier.shape == vis.shape == (MEDIUM[1], MEDIUM[0]) and classifier.dtype == np.float32
    assert np.isnan(classifier[~evaluated]).all()
    called = classifier[evaluated & ~np.isnan(classifier)]
    assert set(np.unique(called)) == {0.0, 1.0}
    assert np.all(vis[~evaluated] == 1.0)
    assert stats["memory_bytes"] == 512 * 512 * 4 + MEDIUM[0] * MEDIUM[1] * 16
    assert stats["passes"] == 3  # one face


def test_spec_round_trips():
    t = from_spec("hybrid_rt:resolution=512,spread=2,cutoff=8,shorten=false,bias=0.001,depth_bits=32")
    assert from_spec(t.spec()).params() == t.params()
    assert t.short_label() == "hybrid_rt:resolution=512,spread=2,cutoff=8,shorten=false,bias=0.001,depth_bits=32"


@pytest.mark.parametrize("spec,match", [
    ("hybrid_rt:spread=-1", "spread"),
    ("hybrid_rt:spread=9", "spread"),
    ("hybrid_rt:cutoff=66", "cutoff"),
    ("hybrid_rt:resolution=8", "resolution"),
    ("hybrid_rt:bias=-0.1", "bias"),
    ("hybrid_rt:depth_bits=12", "depth_bits"),
    ("hybrid_rt:shorten=maybe", "shorten"),
])
def test_bad_parameters_are_refused(spec, match):
    with pytest.raises(TechniqueError, match=match):
        from_spec(spec)


def run_area(lab, scene, spec):
    """(measurement, classifier image, truth, evaluated mask) of one configuration at SMALL."""
    m = lab.measure(scene, spec, SMALL)
    return (m, m.technique.component_images()["classifier"], lab.truth(scene, SMALL),
            lab.frame(scene, SMALL).evaluated(0))


@pytest.mark.slow
@pytest.mark.parametrize("scene,max_rate", [
    # measured: mae 0.0061, 38.2 rays per pixel of 64; 6587 of the 9081 lit pixels called lit
    ("soft_overlap", 0.65),
    # measured: mae 0.0055, 45.2 rays per pixel; 3262 of 4615 lit pixels called lit (and a wide
    # umbra, 2168 pixels, traced: there is no surely-shadowed class)
    ("soft_two_heights", 0.75),
])
def test_area_lights_at_the_truths_noise_level(lab, scene, max_rate):
    """An area light: the surely-lit pixels are lit in the truth (the classifier is never wrong
    on these scenes), the rest carry 64 stratified samples, so the mean error is below the
    truth's own per-pixel bound (0.5/sqrt(samples) of its truth: 0.031 at 256, 0.016 at 1024),
    with fewer rays than 64 per pixel."""
    m, classifier, truth, evaluated = run_area(lab, scene, "hybrid_rt")
    sure = evaluated & ~np.isnan(classifier)
    assert sure.sum() > 1000                                  # the classifier calls something
    assert set(np.unique(classifier[sure])) == {1.0}          # surely lit only: no shadowed class
    assert np.all(truth[sure] == 1.0)                         # and never wrongly
    assert np.all(m.visibility[sure] == 1.0)
    truth_stderr = lab.evaluator(scene, SMALL).truth(0).stats["truth_stderr_max"]
    mae = float(np.abs(m.visibility - truth)[evaluated].mean())
    assert mae < 0.5 * truth_stderr
    rate = m.stats["rays_per_pixel"]
    assert rate == pytest.approx(m.stats["rays"] / evaluated.sum())
    assert 0.3 * 64 < rate < max_rate * 64
    assert m.stats["uncertain_pixels"] == m.stats["traced_pixels"] == evaluated.sum() - sure.sum()
    assert m.stats["dropped_pixels"] == 0 and m.stats["passes"] == 3


@pytest.mark.slow
def test_area_uncertain_pixels_carry_the_truths_estimator(lab):
    """The uncertain pixels get exactly area_visibility's answer (the truth's stratified
    estimator, seed 0) over those pixels, bit for bit; the sure ones 1 and no rays."""
    m, classifier, truth, evaluated = run_area(lab, "soft_overlap", "hybrid_rt:samples=16")
    tech = m.technique
    frame = lab.frame("soft_overlap", SMALL)
    uncertain = np.flatnonzero(tech.cls == hybrid_rt.CLASS_UNCERTAIN)
    from shadowlab.truth.tracing import caster_scene, offset_origins
    pixels = tech.eval_index[uncertain]
    expected, rays = area_visibility(caster_scene(frame), tech.light, frame.compact_position[pixels],
                                     frame.compact_normal[pixels], offset_origins(frame)[pixels], 16)
    vis = m.visibility.ravel()[frame.pixel_index[pixels]]
    assert np.array_equal(vis, expected.astype(np.float32))
    assert m.stats["rays"] == rays > 0


@pytest.mark.slow
def test_area_a_coarser_map_costs_rays(lab):
    """A coarser map calls fewer pixels lit (its texels, and so its boxes, overreach the regions
    more): more rays, the classifier still never wrong. Measured on soft_overlap at 160x120:
    38.2 rays per pixel at 2048², 40.8 at 128² (5924 pixels called lit, against 6587)."""
    fine, cf, truth, evaluated = run_area(lab, "soft_overlap", "hybrid_rt")
    coarse, cc, _, _ = run_area(lab, "soft_overlap", "hybrid_rt:resolution=128")
    assert coarse.stats["rays"] > fine.stats["rays"]
    sure = evaluated & ~np.isnan(cc)
    assert sure.sum() > 500 and np.all(truth[sure] == 1.0)


#: A floor and a tilted box under each area shape of area_map_checks.LIGHTS (the regions' check).
BOX_SCENES = {shape: make_scene([{"mesh": "plane", "size": [8.0, 8.0]},
                                 {"mesh": "box", "size": [1.0, 0.3, 0.8], "translate": [0.2, 1.5, -0.3],
                                  "rotate": [10.0, 30.0, 0.0]}], [LIGHTS[shape]], eye=(3.0, 5.0, 6.0))
              for shape in ("rect", "disc", "sphere")}


@pytest.mark.slow
@pytest.mark.parametrize("shape", ["rect", "disc", "sphere"])
def test_area_search_boxes_hold_every_segment_to_the_light(lab, shape):
    """The geometry the classifier rests on: every point of a segment from a receiver to a point
    of the light (the truth's own samples) at a height in band j projects into a texel of band
    j's box. 12 samples and 9 points on each segment, for every pixel the boxes decide."""
    scene = BOX_SCENES[shape]
    tech = lab.measure(scene, "hybrid_rt", SMALL).technique
    possible, free, limits, boxes = tech.search_boxes()
    decided = np.flatnonzero(possible & ~free)
    assert len(decided) > 1000
    points = tech.eval_points[decided]
    samples, _ = tech.light.sample_for(points, 12, np.random.default_rng(2))       # (M, 12, 3)
    t = np.linspace(0.0, 1.0, 9)[None, None, :, None]
    seg = points[:, None, None, :] + t * (samples[:, :, None, :] - points[:, None, None, :])  # (M, 12, 9, 3)
    h = (seg - tech.centre) @ tech.axis
    lo, hi = limits[decided, :1, None], limits[decided, -1:, None]
    band = np.floor((h - lo) / (hi - lo) * hybrid_rt.BANDS).astype(int)
    inside = (band >= 0) & (band < hybrid_rt.BANDS)                                 # in a band: a caster could be
    clip = seg @ tech.view_proj[:3, :3].T + tech.view_proj[:3, 3]
    w = seg @ tech.view_proj[3, :3] + tech.view_proj[3, 3]
    texel = np.floor((clip[..., :2] / w[..., None] + 1.0) * 0.5 * tech.resolution).astype(int)
    box = np.take_along_axis(boxes[decided][:, None, None, :, :],
                             np.clip(band, 0, hybrid_rt.BANDS - 1)[..., None, None], axis=3)[..., 0, :]
    held = ((texel[..., 0] >= box[..., 0]) & (texel[..., 0] <= box[..., 1]) &
            (texel[..., 1] >= box[..., 2]) & (texel[..., 1] <= box[..., 3]))
    assert inside.sum() > 10000
    assert np.all(held[inside])


def test_box_minimum_bounds_the_true_minimum():
    """The min pyramid's answer is at most the box's true minimum and at least the minimum over
    the box widened by one covering texel of its level (random heights, random boxes)."""
    rng = np.random.default_rng(4)
    heights = rng.random((100, 100)).astype(np.float32)
    flat, layout = hybrid_rt.min_pyramid(heights)
    assert layout[0] == (0, 128) and layout[-1][1] == 1
    x0, y0 = rng.integers(0, 100, 500), rng.integers(0, 100, 500)
    x1, y1 = np.minimum(99, x0 + rng.integers(0, 60, 500)), np.minimum(99, y0 + rng.integers(0, 60, 500))
    got = hybrid_rt.box_minimum(flat, layout, x0, x1, y0, y1)
    exact = np.array([heights[b:d + 1, a:c + 1].min() for a, c, b, d in zip(x0, x1, y0, y1)])
    assert np.all(got <= exact)
    assert np.sum(got < exact) > 0                     # conservative: the level's texels overreach
    small = (x1 - x0 < hybrid_rt.BOX_TAPS) & (y1 - y0 < hybrid_rt.BOX_TAPS)
    assert small.sum() > 0 and np.array_equal(got[small], exact[small])  # level 0: exact


@pytest.mark.slow
@pytest.mark.parametrize("shape", ["rect", "disc", "sphere"])
def test_area_a_lone_floor_is_fully_lit(lab, shape):
    """The shared check of area-light map techniques: V = 1 on a floor alone under each shape."""
    assert_fully_lit(lab, shape, "hybrid_rt")


@pytest.mark.slow
def test_area_behind_a_one_sided_light_sees_none(lab):
    """Points behind a one-sided light are uncertain and get the estimator's 0 (no live sample)."""
    assert_behind_one_sided_sees_none(lab, "hybrid_rt")


def test_area_lights_are_declared():
    assert "area" in from_spec("hybrid_rt").LIGHTS
    assert from_spec("hybrid_rt").samples == 64


@pytest.mark.parametrize("spec", ["hybrid_rt:samples=0", "hybrid_rt:samples=70000", "hybrid_rt:samples=many"])
def test_bad_samples_are_refused(spec):
    with pytest.raises(TechniqueError, match="samples"):
        from_spec(spec)
