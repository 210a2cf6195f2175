"""cc_volume: the plain stencil volume's masks (up to listed depth ties), with less fill; culling
is conservative, each toggle does what it says, bad parameters are refused."""
from __future__ import annotations

import numpy as np
import pytest

from helpers import MEDIUM, SMALL, make_scene
from shadowlab.geometry import adjacency as adj
from shadowlab.scene.lights import DirectionalLight, PointLight
from shadowlab.techniques import TechniqueError, from_spec
from shadowlab.techniques.volumes.cc_volume import volumes_may_meet_frustum

#: Depth-buffer steps within which a receiver and a volume side are a tie (a side quad rasterised
#: from the clamped far vertex instead of the one at infinity rounds differently by a step or two).
TIE_STEPS = 64
#: The same on pixels the metrics do not evaluate: a caster's own terminator (N·L ≈ 0), where its
#: side quads leave the surface tangentially and the camera ray meets them at a grazing angle
#: (a wider allowance than at contacts, for that grazing angle).
TERMINATOR_TIE_STEPS = 1024


def _side_ties(frame, light, pixels, steps=TIE_STEPS) -> np.ndarray:
    """Bool per pixel (row, col): whether its camera ray meets a side quad of some caster's
    volume (the plain volume's planes: a silhouette edge swept away from the light) within
    ``steps`` depth-buffer steps of its point — a tie, decided by rounding."""
    eye = np.asarray(frame.camera.eye, np.float64)
    quads = []
    for obj in frame.scene.objects:
        if not obj.casts:
            continue
        t = obj.edges
        two_sided = not t.closed
        sil = adj.silhouette_edges(t, adj.facing(t, light), two_sided)
        a, b = t.vertices[sil[:, 0]], t.vertices[sil[:, 1]]
        d = np.broadcast_to(light.direction, a.shape) if light.at_infinity else a - light.position
        quads.append((a, b, d))
    a = np.concatenate([q[0] for q in quads])
    b = np.concatenate([q[1] for q in quads])
    d = np.concatenate([q[2] for q in quads])
    e = b - a
    n = np.cross(e, d)
    out = []
    position = frame.position
    for r, c in pixels:
        p = position[r, c]
        v = p - eye
        dist = np.linalg.norm(v)
        step = dist ** 2 / frame.camera.near * 2.0 ** -24  # one 24-bit depth step along the ray
        with np.errstate(divide="ignore", invalid="ignore"):
            t_hit = np.einsum("ij,ij->i", n, a - eye) / (n @ v)
        hit = eye + t_hit[:, None] * v
        # Where on the strip a + s e + u d (0 <= s <= 1, u >= 0) the hit lies.
        rel = hit - a
        gram = np.stack([np.einsum("ij,ij->i", e, e), np.einsum("ij,ij->i", e, d), np.einsum("ij,ij->i", d, d)], 1)
        re, rd = np.einsum("ij,ij->i", rel, e), np.einsum("ij,ij->i", rel, d)
        det = gram[:, 0] * gram[:, 2] - gram[:, 1] ** 2
        with np.errstate(divide="ignore", invalid="ignore"):
            s = (re * gram[:, 2] - rd * gram[:, 1]) / det
            u = (rd * gram[:, 0] - re * gram[:, 1]) / det
        on = (s > -0.01) & (s < 1.01) & (u > -0.01)
        near = np.abs(t_hit - 1.0) * dist <= steps * step
        out.append(bool(np.any(on & near)))
    return np.array(out, bool)


def _compare(lab, scene, spec, size, light=0):
    """(the CC measurement, the plain volume's, covered pixels where they differ, the frame)."""
    mode = dict(kv.split("=") for kv in spec.partition(":")[2].split(",") if kv).get("mode", "auto")
    cc = lab.measure(scene, spec, size, light)
    plain = lab.measure(scene, f"shadow_volume:mode={mode}", size, light)
    frame = lab.frame(scene, size)
    differ = np.argwhere((cc.visibility != plain.visibility) & frame.covered)
    return cc, plain, differ, frame


#: (scene, light, size): point, spot and directional lights, closed and open meshes, the camera in
#: a volume, and the colonnade (where culling and clamping have the most to do).
SAME_MASK_CASES = [("box_on_plane", 0, MEDIUM), ("sv_camera_in_shadow", 0, MEDIUM), ("sv_open_mesh", 0, MEDIUM),
                   ("sun_scene", 0, MEDIUM), ("spot_scene", 0, MEDIUM), ("multi_light", 0, SMALL),
                   ("multi_light", 1, SMALL), ("multi_light", 2, SMALL), ("sv_colonnade", 0, MEDIUM)]


#: Every case in each counting mode; the inner loop keeps the default mode (auto) on every case but
#: the colonnade, the forced modes and the colonnade go with the slow tests (inner-loop budget).
SAME_MASK_RUNS = [(*case, mode) if mode == "auto" and case[0] != "sv_colonnade"
                  else pytest.param(*case, mode, marks=pytest.mark.slow)
                  for mode in ("auto", "zpass", "zfail") for case in SAME_MASK_CASES]


@pytest.mark.parametrize("scene, light, size, mode", SAME_MASK_RUNS)
def test_same_mask_as_the_plain_volume_up_to_depth_ties(lab, scene, light, size, mode):
    """Culling drops only volumes that hold no visible point and clamping cuts volumes beyond
    every visible point they hold, so each covered pixel's count is the plain volume's — except
    where a side quad meets the receiver within a few depth steps (a contact line, a caster's own
    terminator): there the clamped side, rasterised from another far vertex, may round the other
    way. So at most a handful of pixels may differ, and every one of them must be such a tie:
    within TIE_STEPS of a side quad where the metrics evaluate it, TERMINATOR_TIE_STEPS on a
    caster's own terminator."""
    cc, plain, differ, frame = _compare(lab, scene, f"cc_volume:mode={mode}", size, light)
    assert len(differ) <= 12, differ[:20].tolist()
    evaluated = frame.evaluated(light)[differ[:, 0], differ[:, 1]] if len(differ) else np.zeros(0, bool)
    lit_light = frame.scene.lights[light]
    ties = _side_ties(frame, lit_light, differ[evaluated])
    assert ties.all(), differ[evaluated][~ties].tolist()
    ties = _side_ties(frame, lit_light, differ[~evaluated], TERMINATOR_TIE_STEPS)
    assert ties.all(), differ[~evaluated][~ties].tolist()
    assert cc.stats["casters_kept"] + cc.stats["casters_culled"] == plain.stats["zpass_casters"] + \
        plain.stats["zfail_casters"]


@pytest.mark.slow  # the soup's thousands of triangles and sv_many_casters' hundreds of thousands
@pytest.mark.parametrize("scene, most", [("sv_soup", 80), ("sv_many_casters", 12)])
def test_dense_scenes_differ_only_at_depth_ties(lab, scene, most):
    """The same on the triangle soup, where thousands of blades touch the ground (contact lines
    everywhere, so more pixels may differ, each a tie, on either side of the truth) and on
    sv_many_casters (a point light)."""
    cc, plain, differ, frame = _compare(lab, scene, "cc_volume", MEDIUM)
    assert len(differ) <= most
    assert _side_ties(frame, frame.scene.lights[0], differ, TERMINATOR_TIE_STEPS).all()
    assert cc.stats["volume_fragments"] < plain.stats["volume_fragments"]


def test_fill_on_the_colonnade(lab):
    """sv_colonnade at 320x240: culling the casters whose volumes hold no visible receiver and
    clamping the rest cut the volume fragments by at least 1.4 times against the plain volume."""
    cc, plain, _, _ = _compare(lab, "sv_colonnade", "cc_volume", MEDIUM)
    s = cc.stats
    assert plain.stats["volume_fragments"] >= 1.4 * s["volume_fragments"]
    assert s["pixel_ops"] == s["volume_fragments"]
    assert s["frustum_culled"] > 10 and s["receiver_culled"] > 10
    assert s["casters_culled"] == s["frustum_culled"] + s["receiver_culled"]
    assert s["casters_clamped"] > 50 and s["culled_triangles"] > 0
    assert s["fan_caps"] == s["casters_clamped"]  # convex columns: every far cap is a fan
    assert s["casters_kept"] + s["casters_culled"] == 145


def test_toggles_off_give_the_plain_volume(lab):
    """With culling and clamping off the volumes are the plain volume's, fragment for fragment
    and pixel for pixel (sun_scene: every caster clamped when both are on)."""
    frame = lab.frame("sun_scene", MEDIUM)
    on = lab.measure("sun_scene", "cc_volume", MEDIUM).stats
    off = lab.measure("sun_scene", "cc_volume:cull=false,clamp=false", MEDIUM)
    plain = lab.measure("sun_scene", "shadow_volume", MEDIUM)
    assert on["casters_clamped"] == 6 and on["volume_fragments"] < plain.stats["volume_fragments"]
    assert off.stats["casters_clamped"] == off.stats["casters_culled"] == off.stats["receiver_map_texels"] == 0
    assert off.stats["volume_fragments"] == plain.stats["volume_fragments"]
    assert np.array_equal(off.visibility[frame.covered], plain.visibility[frame.covered])


@pytest.mark.slow  # five configurations on the colonnade
def test_toggles(lab):
    """cull=false keeps every caster; clamp=false clamps none; with both off the volumes are the
    plain volume's, fragment for fragment and pixel for pixel."""
    frame = lab.frame("sv_colonnade", MEDIUM)
    both = lab.measure("sv_colonnade", "cc_volume", MEDIUM).stats
    no_cull = lab.measure("sv_colonnade", "cc_volume:cull=false", MEDIUM).stats
    no_clamp = lab.measure("sv_colonnade", "cc_volume:clamp=false", MEDIUM).stats
    neither = lab.measure("sv_colonnade", "cc_volume:cull=false,clamp=false", MEDIUM)
    plain = lab.measure("sv_colonnade", "shadow_volume", MEDIUM)
    assert no_cull["casters_culled"] == 0 and no_cull["casters_kept"] == 145 and no_cull["casters_clamped"] > 50
    assert no_clamp["casters_clamped"] == 0 and no_clamp["casters_culled"] == both["casters_culled"] > 0
    assert neither.stats["casters_culled"] == neither.stats["casters_clamped"] == 0
    assert neither.stats["receiver_map_texels"] == 0
    assert neither.stats["volume_fragments"] == plain.stats["volume_fragments"]
    assert np.array_equal(neither.visibility[frame.covered], plain.visibility[frame.covered])
    # each part saves fill on its own, and together they save the most
    full = plain.stats["volume_fragments"]
    assert both["volume_fragments"] < no_cull["volume_fragments"] < full
    assert both["volume_fragments"] < no_clamp["volume_fragments"] < full


def _pole_scene():
    """A floor, a thin pole whose shadow is a short streak on the visible floor, and a box in view
    but hidden under the floor, whose volume runs down, away from everything visible."""
    objects = [{"name": "floor", "mesh": "plane", "size": [10.0, 10.0]},
               {"name": "pole", "mesh": "box", "size": [0.15, 1.0, 0.15], "translate": [1.0, 1.5, 0.0]},
               {"name": "buried", "mesh": "box", "size": [1.0, 1.0, 1.0], "translate": [-1.0, -2.0, -1.0]}]
    lights = [{"type": "directional", "direction": [-0.6, -0.7, 0.2]}]
    return make_scene(objects, lights, eye=(3.0, 5.0, 8.0), target=(0.0, 0.0, -1.0), name="cc_pole")


@pytest.mark.parametrize("grid", [1, 32, 256])
def test_a_volume_that_holds_a_visible_point_is_never_culled(lab, grid):
    """The pole's shadow covers a few dozen floor pixels: its volume holds visible points, so it
    is kept on any grid and its shadow is the plain volume's; the buried box's volume holds no
    visible point, so the receiver map culls it — but not the view frustum, which it lies in —
    except on a 1-texel grid, whose one texel holds the deepest visible point of all (deeper than
    the box's nearest point: kept)."""
    scene = _pole_scene()
    frame = lab.frame(scene, SMALL)
    cc = lab.measure(scene, f"cc_volume:grid={grid}", SMALL)
    plain = lab.measure(scene, "shadow_volume", SMALL)
    names = [o.name for o in scene.objects]
    assert np.array_equal(cc.visibility[frame.covered], plain.visibility[frame.covered])
    tech = from_spec(f"cc_volume:grid={grid}")
    tech.prepare(frame, 0)
    try:
        tech.render()
        kept = {names[p.index] for p in tech._kept_plans}
    finally:
        tech.release()
    assert "pole" in kept and "floor" in kept
    assert cc.stats["frustum_culled"] == 0
    assert ("buried" in kept) == (grid == 1) and cc.stats["receiver_culled"] == (grid > 1)
    shadow = (plain.visibility < 0.5) & frame.evaluated(0)
    pole_shadow = shadow & (frame.object_id == names.index("floor"))
    assert 10 < pole_shadow.sum() < 400  # a small shadow, found all the same


def test_frustum_test_on_boxes():
    """The view-frustum test on boxes around a frustum looking down −z from the origin (near 1,
    far 10, a 2 x 2 near rectangle): a box inside or one whose volume sweeps into the frustum may
    meet it; a box beside it whose volume runs away from it, or one behind the camera under a
    light in front, may not; a point light inside a box: always."""
    near = np.array([[-1.0, -1.0, -1.0], [1.0, -1.0, -1.0], [1.0, 1.0, -1.0], [-1.0, 1.0, -1.0]])
    frustum = np.concatenate([near, 10.0 * near])
    boxes = np.array([
        [[-0.5, -0.5, -5.0], [0.5, 0.5, -4.0]],      # inside
        [[20.0, -0.5, -5.0], [21.0, 0.5, -4.0]],     # beside (+x), the light sweeps it to +x
        [[-21.0, -0.5, -5.0], [-20.0, 0.5, -4.0]],   # beside (−x): swept along +x, through the frustum
        [[-0.5, -0.5, 3.0], [0.5, 0.5, 4.0]],        # behind the camera
    ])
    sun = DirectionalLight(direction=np.array([1.0, 0.0, 0.0]))
    assert volumes_may_meet_frustum(boxes, frustum, sun).tolist() == [True, False, True, False]
    lamp = PointLight(position=np.array([0.0, 0.0, 8.0]))  # behind the camera: volumes run towards −z
    boxes = np.array([[[-0.5, -0.5, 3.0], [0.5, 0.5, 4.0]],      # between the lamp and the frustum
                      [[-0.5, -0.5, 12.0], [0.5, 0.5, 13.0]],    # behind the lamp: swept away from it
                      [[-1.0, -1.0, 7.0], [1.0, 1.0, 9.0]]])     # holds the lamp
    assert volumes_may_meet_frustum(boxes, frustum, lamp).tolist() == [True, False, True]


def test_rejects_the_gpu_silhouette_path_and_bad_grids():
    with pytest.raises(TechniqueError, match="silhouette"):
        from_spec("cc_volume:silhouette=gpu")
    with pytest.raises(TechniqueError):
        from_spec("cc_volume:grid=0")
    assert from_spec("cc_volume").cull and from_spec("cc_volume").clamp


def test_casters_without_silhouette_edges_get_both_answers():
    """The clamp's cost estimate for casters none of which has a silhouette edge (the light
    inside a closed caster, say) answers per caster (whether clamping pays, whether the fan may
    stand for the cap) like every other case: a pair, what the sums give for no edges (nothing
    cut: clamping does not pay), not a bare flag the caller cannot index."""
    from types import SimpleNamespace
    from shadowlab.techniques.volumes.cc_volume import CCVolume
    t = object.__new__(CCVolume)
    t.frame = SimpleNamespace(camera=SimpleNamespace(eye=(0.0, 1.0, 5.0)))
    t.light = SimpleNamespace(at_infinity=False)
    t.light_position = np.zeros(3)
    no_edges, ends = np.zeros((0, 2), np.int64), np.zeros((0, 2, 3))
    shapes = [(SimpleNamespace(index=i, table=SimpleNamespace(vertices=np.zeros((4, 3)))), no_edges, None, None, ends)
              for i in (3, 7)]
    assert t._clamps_pay(shapes) == {3: (False, True), 7: (False, True)}
