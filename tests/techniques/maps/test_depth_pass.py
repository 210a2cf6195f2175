"""The map toolkit's depth pass drawn both ways — every face of an atlas in one instanced draw
(gl_ViewportIndex from the vertex shader) and a draw per face — fills the atlas with the same
depths, texel for texel; the work counters see one draw instead of one per face, and the same
vertices and primitives; the switch and the fallback behave as documented."""
from __future__ import annotations

import numpy as np
import pytest

from shadowlab.gpu import programs
from shadowlab.measurement.pipeline import count_work, measure
from shadowlab.techniques import TechniqueError, from_spec
from shadowlab.techniques.maps import toolkit

SIZE = (160, 120)

#: (scene, light, spec): a point light's cube (6 faces), the cube's two layers (depth peeling),
#: cascades (4 faces in a row), one face — every kind of atlas depth_pass fills.
ATLASES = [
    ("sm_room_lamp", 1, "shadow_map:resolution=256,projection=cube"),
    ("sm_point_cube", 0, "shadow_map:resolution=128,projection=cube,variant=dual"),
    ("sun_scene", 0, "cascaded_map:resolution=256"),
    ("box_on_plane", 0, "shadow_map:resolution=256"),
]

needs_extension = pytest.mark.skipif(
    "not __import__('shadowlab.techniques.maps.toolkit', fromlist=['x']).viewport_index_extension()",
    reason="the driver cannot write gl_ViewportIndex from a vertex shader")


def _set_up(lab, scene, light, spec):
    frame = lab.frame(scene, SIZE)
    tech = from_spec(spec)
    measure(tech, frame, light, repeat=1, warmup=0, release=False, count=False)
    return frame, tech


def _layers_both_ways(frame, tech) -> dict[bool, list[np.ndarray]]:
    """{one_pass: the depth of each layer as uint32 bit patterns} after drawing the casters into
    the technique's layers (the first layer, then — two-layer variants — the peel from it)."""
    cull_front, offset = tech.depth_state()
    out = {}
    for one in (False, True):
        layers = []
        toolkit.depth_pass(frame, tech.layers[0], tech.depth_prog, tech.atlas, cull_front, offset, one_pass=one)
        layers.append(tech.layers[0].read().view(np.uint32).copy())
        if len(tech.layers) == 3:
            tech.layers[0].texture.use(0)
            toolkit.depth_pass(frame, tech.layers[1], tech.peel_prog, tech.atlas, cull_front, offset, one_pass=one)
            layers.append(tech.layers[1].read().view(np.uint32).copy())
        out[one] = layers
    return out


@needs_extension
@pytest.mark.parametrize("scene,light,spec", ATLASES)
def test_one_pass_atlas_is_bit_identical_to_the_per_face_loop(lab, scene, light, spec):
    frame, tech = _set_up(lab, scene, light, spec)
    try:
        assert "VIEWPORT_INDEX" in tech.depth_prog.extra.defines
        both = _layers_both_ways(frame, tech)
    finally:
        tech.release()
    clear = np.float32(toolkit.CLEAR_DEPTH).view(np.uint32)
    for loop, one in zip(both[False], both[True]):
        drawn = loop != clear
        assert drawn.mean() > 0.05  # the casters really cover the faces: the comparison is not of two clears
        assert np.array_equal(loop, one), f"{int((loop != one).sum())} texels differ"
    # several faces hold casters (the faces a fit leaves empty stay clear both ways)
    h = both[True][0].shape[0]
    held = [(both[True][0][h - y - fh: h - y, x: x + w] != clear).any()  # rows read back top first
            for x, y, w, fh in tech.atlas.rects]
    assert sum(held) >= min(2, len(held))


@needs_extension
def test_one_pass_needs_its_viewports(lab):
    """Without the per-face viewports, the instanced draw puts every face over the whole atlas:
    the identity above is the viewports' doing, and the test can fail."""
    frame, tech = _set_up(lab, "sm_room_lamp", 1, "shadow_map:resolution=128,projection=cube")
    try:
        original = toolkit.glstate.set_viewports
        toolkit.glstate.set_viewports = lambda rects: None
        try:
            toolkit.depth_pass(frame, tech.map, tech.depth_prog, tech.atlas, one_pass=True)
        finally:
            toolkit.glstate.set_viewports = original
        wrong = tech.map.read()
        toolkit.depth_pass(frame, tech.map, tech.depth_prog, tech.atlas, one_pass=True)
        right = tech.map.read()
    finally:
        tech.release()
    assert (wrong != right).mean() > 0.05


@needs_extension
@pytest.mark.parametrize("spec,faces", [("shadow_map:resolution=128,projection=cube", 6),
                                        ("cascaded_map:resolution=128,cascades=3", 3)])
def test_work_counts_one_draw_per_range_and_every_face_of_vertices(lab, monkeypatch, spec, faces):
    """The counting render: one draw per caster range instead of one per face and range; the
    vertices submitted (× instances), the primitives generated and the samples passed are
    the same both ways."""
    scene = "sm_room_lamp" if "cube" in spec else "sun_scene"
    frame, tech = _set_up(lab, scene, 1 if "cube" in spec else 0, spec)
    try:
        counted = {}
        for one in (False, True):
            monkeypatch.setattr(toolkit, "ONE_PASS", one)
            counted[one] = count_work(tech)["depth"]
    finally:
        tech.release()
    ranges = len(frame.ranges("casters"))
    caster_vertices = sum(r.count for r in frame.ranges("casters"))
    assert counted[False]["draws"] == faces * ranges and counted[True]["draws"] == ranges
    for key in ("vertices", "primitives_generated", "samples_passed", "bytes_written", "bytes_cleared"):
        assert counted[True][key] == counted[False][key], key
    assert counted[True]["vertices"] == faces * caster_vertices
    assert counted[True]["primitives_generated"] == faces * caster_vertices // 3


def test_the_switch_and_the_fallback(lab, monkeypatch):
    """ONE_PASS = False draws per face whatever the driver; a driver without a vertex-shader
    viewport index gets programs without one and the loop (the same visibility), and forcing
    one pass there is a clear error."""
    spec, scene = "shadow_map:resolution=128,projection=cube", "sm_room_lamp"
    frame = lab.frame(scene, SIZE)
    reference = lab.measure(scene, spec, SIZE, light=1).visibility
    monkeypatch.setattr(toolkit, "_VIEWPORT_INDEX", [None])  # as if the driver had no extension
    assert "VIEWPORT_INDEX" not in toolkit.depth_defines()
    tech = from_spec(spec)
    m = measure(tech, frame, 1, repeat=1, warmup=0, release=False, count=False)
    try:
        assert "VIEWPORT_INDEX" not in tech.depth_prog.extra.defines
        assert not toolkit.draws_in_one_pass(tech.depth_prog)
        assert len(count_work(tech)["depth"]) and count_work(tech)["depth"]["draws"] == 6 * len(frame.ranges("casters"))
        with pytest.raises(TechniqueError, match="one_pass"):
            toolkit.depth_pass(frame, tech.map, tech.depth_prog, tech.atlas, one_pass=True)
        monkeypatch.setattr(toolkit, "ONE_PASS", True)
        with pytest.raises(TechniqueError, match="one_pass"):
            tech.render()
    finally:
        tech.release()
    assert np.array_equal(m.visibility, reference)


def test_a_program_without_the_face_array_is_refused(lab):
    frame, tech = _set_up(lab, "box_on_plane", 0, "shadow_map:resolution=64")
    try:
        plain = programs.program("shadow_depth.glsl")
        with pytest.raises(TechniqueError, match="depth_defines"):
            toolkit.depth_pass(frame, tech.map, plain, tech.atlas)
    finally:
        tech.release()

