"""Stencil shadow volumes against the ground truth on the standard scenes and the SV hard cases."""
from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from shadowlab.gpu.frame import Frame
from shadowlab.evaluation.metrics import compare
from shadowlab.measurement.pipeline import measure
from shadowlab.scene import builtin_scenes, load_scene
from shadowlab.scene.lights import DirectionalLight, PointLight
from shadowlab.techniques import from_spec
from shadowlab.techniques.volumes.shadow_volume import volumes_may_reach_near_plane

from helpers import make_scene, sweep_lights

SIZE = (400, 300)
CLOSED_CASES = ["sv_camera_in_shadow", "sv_near_plane_cut", "sv_directional", "sv_light_close", "sv_many_casters"]
STANDARD = ["box_on_plane", "spot_scene", "sun_scene", "target_direct_scene"]
OPEN_CASES = ["sv_open_mesh", "sv_degenerate"]


def run(lab, scene, spec):
    """(visibility, truth, frame, stats, notes) of one configuration on the shared frame."""
    m = lab.measure(scene, spec, SIZE)
    return m.visibility, lab.truth(scene, SIZE), lab.frame(scene, SIZE), m.stats, m.notes


def far_false_shadows(vis, truth, ev, band=2):
    """False-shadow pixels inside lit surfaces (acne): farther than ``band`` pixels from the
    truth's shadow boundary and from the rim of the evaluated region (mesh silhouettes, where
    cap and side edges can tie under the rasterisation rule)."""
    shadow = (truth < 0.5) & ev
    near = ndimage.binary_dilation(shadow, iterations=band) & ~ndimage.binary_erosion(shadow, iterations=band)
    rim = ~ndimage.binary_erosion(ev, iterations=band)
    return int(np.sum((vis < 0.5) & (truth >= 0.5) & ev & ~near & ~rim))


#: The 245k-triangle sv_many_casters runs with the slow tests (the other scenes stay in the inner loop).
INNER_LOOP_CASES = [pytest.param(s, marks=pytest.mark.slow) if s == "sv_many_casters" else s
                    for s in CLOSED_CASES + STANDARD + OPEN_CASES]


@pytest.mark.parametrize("scene", INNER_LOOP_CASES)
def test_zfail_matches_ground_truth(lab, scene):
    vis, truth, frame, stats, _ = run(lab, scene, "shadow_volume:mode=zfail")
    ev = frame.evaluated(0)
    m = compare(vis, truth, ev)
    assert m["truth_shadowed_pixels"] > 300
    assert m["error_rate"] <= 0.001, m
    assert far_false_shadows(vis, truth, ev) == 0, "volumes must not self-shadow (no acne)"
    assert stats["silhouette_edges"] > 0 and stats["volume_triangles"] > 0 and stats["volume_fragments"] > 0


@pytest.mark.parametrize("scene", INNER_LOOP_CASES)
def test_cpu_and_gpu_silhouettes_give_the_same_mask(lab, scene):
    cpu, _, frame, s_cpu, _ = run(lab, scene, "shadow_volume:silhouette=cpu")
    gpu, _, _, s_gpu, notes = run(lab, scene, "shadow_volume:silhouette=gpu")
    ev = frame.evaluated(0)
    assert np.array_equal(cpu[ev], gpu[ev])  # masks.npz holds evaluated pixels only
    assert s_cpu["silhouette_edges"] == s_gpu["silhouette_edges"]


@pytest.mark.parametrize("scene", ["sv_camera_in_shadow", "sv_near_plane_cut"])
def test_zpass_fails_on_the_sv1_cases(lab, scene):
    """SV1: the camera in a volume, or the near plane through one — z-pass counts are off
    (z-fail on the same scenes: test_zfail_matches_ground_truth)."""
    vis, truth, frame, _, _ = run(lab, scene, "shadow_volume:mode=zpass")
    assert compare(vis, truth, frame.evaluated(0))["error_rate"] >= 0.05


@pytest.mark.parametrize("scene", ["sv_camera_in_shadow", "sv_near_plane_cut"])
def test_finite_far_plane_loses_zfail_caps_and_clamp_restores_them(lab, scene):
    """SV2: extruded geometry clipped by a finite far plane breaks z-fail; depth clamp fixes it —
    also where the near plane cuts the receivers (their caps must tie with the pre-pass: the
    streaks this once left, 10.6 % on sv_near_plane_cut, were caps clipped unlike their surface)."""
    vis, truth, frame, _, _ = run(lab, scene, "shadow_volume:mode=zfail,far=finite")
    assert compare(vis, truth, frame.evaluated(0))["error_rate"] > 0.05
    for spec in ("shadow_volume:mode=zfail,far=clamp", "shadow_volume:mode=zfail,far=clamp,silhouette=gpu",
                 "shadow_volume:mode=auto,far=clamp"):
        vis, truth, frame, _, _ = run(lab, scene, spec)
        assert compare(vis, truth, frame.evaluated(0))["error_rate"] <= 0.001, spec


def test_open_and_degenerate_meshes_are_reported(lab):
    *_, notes = run(lab, "sv_open_mesh", "shadow_volume")
    assert any("open_box" in n and "boundary edges" in n and "two-sided" in n for n in notes)
    *_, notes = run(lab, "sv_degenerate", "shadow_volume:silhouette=gpu")
    assert any("degenerate_box" in n and "falls back to the CPU path" in n for n in notes)


def test_light_inside_closed_caster_shadows_everything_outside(lab):
    scene = make_scene([{"name": "floor", "mesh": "plane", "size": [10.0, 10.0]},
                        {"name": "shell", "mesh": "box", "size": [1.0, 1.0, 1.0], "translate": [0.0, 1.5, 0.0]}],
                       [{"type": "point", "position": [0.1, 1.6, 0.05]}], name="light_inside")
    vis, truth, frame, _, notes = run(lab, scene, "shadow_volume")
    ev = frame.evaluated(0)
    assert ev.sum() > 1000 and (truth[ev] < 0.5).all()  # the inside of the shell is all the light sees
    assert (vis[ev] < 0.5).all()
    assert any("light is inside" in n for n in notes)


@pytest.mark.slow  # inner-loop budget (issue 36): among the slowest; make test runs it
@pytest.mark.parametrize("mode, scene", [("zpass", "sv_many_casters"), ("zfail", "sv_many_casters"),
                                         ("auto", "sv_camera_in_shadow")])  # auto: z-pass and z-fail casters
def test_counted_stencil_updates_agree_with_the_stencil_left_behind(lab, mode, scene):
    """Each stencil update adds or removes one from one pixel's count, so the updates the
    occlusion query counts (a separate pass) must have the parity of the sum of the counts
    left in the stencil, at least their total size, and at most the volume samples rasterised."""
    tech = from_spec(f"shadow_volume:mode={mode}")
    m = measure(tech, lab.frame(scene, SIZE), 0, repeat=1, warmup=0, release=False)
    stencil = tech.target.read_stencil().astype(np.int64)
    tech.release()
    size = np.minimum(stencil, 256 - stencil)  # |count|: INCR_WRAP / DECR_WRAP counts modulo 256
    assert size.sum() > 1000
    assert m.stats["stencil_updates"] % 2 == stencil.sum() % 2
    assert size.sum() <= m.stats["stencil_updates"] <= m.stats["volume_fragments"]


def test_peak_stencil_count_is_the_number_of_volumes_around_a_point(lab):
    """Three plates stacked under a light straight above: floor points under all three lie in
    three shadow volumes, so the peak count is exactly 3 (z-fail counts volumes behind the
    surface, z-pass the ones in front: the same here, the camera being in none)."""
    plates = [{"name": f"plate_{k}", "mesh": "box", "size": [2.0 - 0.4 * k, 0.05, 2.0 - 0.4 * k],
               "translate": [0.0, 1.0 + 0.6 * k, 0.0]} for k in range(3)]
    scene = make_scene([{"name": "floor", "mesh": "plane", "size": [10.0, 10.0]}] + plates,
                       [{"type": "directional", "direction": [0.0, -1.0, 0.0]}], eye=(0.0, 7.0, 6.0),
                       name="stacked_plates")
    for mode in ("zfail", "zpass", "auto"):
        _, truth, frame, stats, _ = run(lab, scene, f"shadow_volume:mode={mode}")
        assert stats["stencil_peak_count"] == 3, mode


# ---------------------------------------------------------------------- mode=auto (issue 11)
AUTO_MODE_SCENES = ["sv_camera_in_shadow", "sv_near_plane_cut", "sv_directional", "sv_light_close", "sv_open_mesh"]


@pytest.mark.parametrize("scene", AUTO_MODE_SCENES)
@pytest.mark.parametrize("variant", ["", ",silhouette=gpu", ",far=clamp"])
def test_auto_gives_the_zfail_mask(lab, scene, variant):
    """mode=auto (z-pass for casters whose volumes cannot reach the near plane, z-fail for the
    others) leaves z-fail's mask on every pixel that shows a surface (on the background, where
    nothing is evaluated, z-pass counts volumes that run off to infinity)."""
    zfail, _, frame, s_zfail, _ = run(lab, scene, f"shadow_volume:mode=zfail{variant}")
    auto, _, _, s_auto, _ = run(lab, scene, f"shadow_volume:mode=auto{variant}")
    assert np.array_equal(zfail[frame.covered], auto[frame.covered])
    assert s_auto["zpass_casters"] + s_auto["zfail_casters"] == s_zfail["zfail_casters"] > 0
    assert s_auto["silhouette_edges"] == s_zfail["silhouette_edges"]


def test_auto_picks_zpass_outside_the_volumes_and_zfail_where_the_camera_is_in_one(lab):
    """box_on_plane: the camera sees the scene from outside every volume, so every caster is
    counted by z-pass (no caps at all); sv_camera_in_shadow: the camera stands in the building's
    volume, which is counted by z-fail, while the ground and the post, whose volumes it is not
    in, stay z-pass; sv_near_plane_cut: the near plane cuts the building's volume."""
    *_, stats, notes = run(lab, "box_on_plane", "shadow_volume:mode=auto")
    assert stats["zfail_casters"] == 0 and stats["zpass_casters"] == 2
    assert stats["zfail_caster_triangles"] == 0 and stats["zpass_caster_triangles"] > 0
    assert not any("mode=auto" in n for n in notes)
    *_, stats, notes = run(lab, "sv_camera_in_shadow", "shadow_volume:mode=auto")
    assert stats["zfail_casters"] == 1 and stats["zpass_casters"] == 2
    assert any("mode=auto" in n and "'building'" in n and "'post'" not in n for n in notes)
    *_, stats, notes = run(lab, "sv_near_plane_cut", "shadow_volume:mode=auto")
    assert any("mode=auto" in n and "'building'" in n for n in notes)
    _, _, _, stats, _ = run(lab, "sv_camera_in_shadow", "shadow_volume:mode=zpass")
    assert stats["zfail_casters"] == 0
    _, _, _, stats, _ = run(lab, "box_on_plane", "shadow_volume:mode=zfail")
    assert stats["zpass_casters"] == 0


def test_auto_is_the_default_mode():
    assert from_spec("shadow_volume").mode == "auto"


def test_occlusion_pyramid_test():
    """The conservative near-plane test on boxes around a unit near-plane square at z = 0: a box
    between a point light and the square, or one holding the light, may put the square in its
    volume (z-fail); a box beside the pyramid, or behind the square (away from the light), may
    not. For a light at infinity the square is swept towards the light, however far."""
    quad = np.array([[-0.5, -0.5, 0.0], [0.5, -0.5, 0.0], [0.5, 0.5, 0.0], [-0.5, 0.5, 0.0]])
    # The pyramid from (0, 0, 5): half-width 0.5 (1 - z / 5), 0.25 at z = 2.5.
    boxes = np.array([
        [[-0.1, -0.1, 2.0], [0.1, 0.1, 2.2]],     # on the way from the light to the square
        [[3.0, 3.0, 2.0], [4.0, 4.0, 3.0]],       # well beside the pyramid
        [[-0.1, -0.1, -2.0], [0.1, 0.1, -1.0]],   # behind the square
        [[-1.0, -1.0, 4.0], [1.0, 1.0, 6.0]],     # holds the light
        [[0.2, -0.1, 2.5], [0.3, 0.1, 2.6]],      # reaches into a slanted side
        [[0.3, -0.1, 2.5], [0.4, 0.1, 2.6]],      # just outside it
    ])
    point = PointLight(position=np.array([0.0, 0.0, 5.0]))
    assert volumes_may_reach_near_plane(boxes, quad, point, 10.0).tolist() == [True, False, False, True, True, False]
    down = DirectionalLight(direction=np.array([0.0, 0.0, -1.0]))  # the light is up at z = +inf
    boxes = np.array([[[-0.1, -0.1, 100.0], [0.1, 0.1, 101.0]], [[-0.1, -0.1, -2.0], [0.1, 0.1, -1.0]],
                      [[0.6, -0.1, 100.0], [0.7, 0.1, 101.0]]])
    assert volumes_may_reach_near_plane(boxes, quad, down, 10.0).tolist() == [True, False, False]
    slanted = DirectionalLight(direction=np.array([-1.0, 0.0, -1.0]) / np.sqrt(2.0))  # from (+x, +z)
    boxes = np.array([[[9.9, -0.1, 9.9], [10.1, 0.1, 10.1]], [[-10.1, -0.1, 9.9], [-9.9, 0.1, 10.1]]])
    assert volumes_may_reach_near_plane(boxes, quad, slanted, 10.0).tolist() == [True, False]


@pytest.mark.slow  # a sweep: every shipped scene and light, twice per variant (the hard cases: test_auto_gives_the_zfail_mask)
@pytest.mark.parametrize("variant", ["", ",far=clamp", ",silhouette=gpu", ",silhouette=gpu,far=clamp"])
def test_auto_gives_the_zfail_mask_on_every_shipped_scene_and_light(variant):
    """The issue's demand, on every shipped scene (real meshes included) and every light (eight
    spread over a many-light scene's, :func:`helpers.sweep_lights`): mode=auto
    leaves z-fail's mask on every covered pixel (small frames of their own, released at once)."""
    chose_zfail, infinite_zfail_broken = set(), set()
    for name in builtin_scenes():
        frame = Frame(load_scene(name), 320, 240)
        try:
            for li in sweep_lights(frame.scene):  # a many-light scene: eight of its lights
                want = measure(from_spec(f"shadow_volume:mode=zfail{variant}"), frame, li, repeat=1, warmup=0)
                got = measure(from_spec(f"shadow_volume:mode=auto{variant}"), frame, li, repeat=1, warmup=0)
                cov = frame.covered
                if not np.array_equal(want.visibility[cov], got.visibility[cov]) and "far=clamp" not in variant:
                    # z-fail with the infinite far plane breaks for some lights of the many-light
                    # scenes (issue 40: 29 of ml_city_256's lights, street lamps under their posts'
                    # arms and window lights half a metre from a facade: nearly every evaluated pixel
                    # shadowed); there auto must give depth-clamped z-fail's mask, which is right
                    clamped = measure(from_spec(f"shadow_volume:mode=zfail,far=clamp{variant}"), frame, li,
                                      repeat=1, warmup=0)
                    ev = frame.evaluated(li)  # on the light's evaluated pixels (off them z-fail's sides differ)
                    assert np.array_equal(clamped.visibility[ev] < 0.5, got.visibility[ev] < 0.5), (name, li)
                    infinite_zfail_broken.add((name, li))
                    continue
                assert np.array_equal(want.visibility[cov], got.visibility[cov]), (name, li)
                if got.stats["zfail_casters"]:
                    chose_zfail.add(name)
        finally:
            frame.release()
    # the scenes where the near plane lies in a volume (z-pass would be wrong there) took z-fail
    assert {"sv_camera_in_shadow", "sv_near_plane_cut"} <= chose_zfail
    assert all(name.startswith("ml_") for name, _ in infinite_zfail_broken), infinite_zfail_broken


def test_auto_sweeps_far_enough_past_a_box_lit_from_an_oblique_direction(lab):
    """A light at infinity: the near-plane rectangle, swept towards the light, must pass every
    caster's box; a box's lowest point along the direction is the corner picked per axis by the
    direction's signs, not its min or max corner (taking the lower of those two once cut the sweep
    short of a wide slab and chose z-pass with the camera in the slab's volume: every pixel wrong)."""
    d = np.array([0.5, -0.6, -0.6]) / np.linalg.norm([0.5, -0.6, -0.6])
    quad = np.array([[-0.5, -0.5, 0.0], [0.5, -0.5, 0.0], [0.5, 0.5, 0.0], [-0.5, 0.5, 0.0]])
    p = -10.0 * d  # on the sweep, at the slab's (low x, high y, high z) corner
    slab = np.array([[p[0] - 0.05, p[1] - 0.1, p[2] - 30.0], [p[0] + 30.0, p[1] + 0.1, p[2] + 0.05]])
    assert volumes_may_reach_near_plane(slab[None], quad, DirectionalLight(direction=d), 50.0).tolist() == [True]
    scene = make_scene([{"name": "ground", "mesh": "plane", "size": [60.0, 60.0]},
                        {"name": "slab", "mesh": "box", "size": [10.0, 0.2, 10.0], "translate": [0.0, 4.0, 0.0]}],
                       [{"type": "directional", "direction": d.tolist()}], eye=(-3.0, 2.0, 2.7),
                       target=(2.0, 0.0, -2.0), name="oblique_slab")  # the eye under the slab's corner, in its volume
    zfail, _, frame, _, _ = run(lab, scene, "shadow_volume:mode=zfail")
    zpass, *_ = run(lab, scene, "shadow_volume:mode=zpass")
    auto, _, _, stats, _ = run(lab, scene, "shadow_volume:mode=auto")
    cov = frame.covered
    assert np.sum(zpass[cov] != zfail[cov]) > 0.5 * cov.sum()  # the camera is in the volume: SV1
    assert np.sum(zfail[cov] < 0.5) > 1000
    assert stats["zfail_casters"] == 1 and np.array_equal(auto[cov], zfail[cov])
