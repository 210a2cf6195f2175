"""hierarchical_volume: the plain stencil volume's mask on every pixel that shows a surface, with
per-pixel stencil work only in boundary tiles; its tile classes and counters."""
from __future__ import annotations

import numpy as np
import pytest

from shadowlab.measurement.pipeline import measure
from shadowlab.techniques import TechniqueError, from_spec

from helpers import MEDIUM, SMALL

#: The hard cases of the plain volume: z-fail casters (camera in shadow, near plane cut), flipped
#: caps (open mesh), a light at infinity, a spot light, and the many-column fill case.
SCENES = ["box_on_plane", "sv_colonnade", "sv_camera_in_shadow", "sv_near_plane_cut", "sv_open_mesh",
          "sv_directional", "spot_scene"]


def _plain_spec(spec: str) -> str:
    """The plain volume with the same counting options (``tile`` dropped)."""
    name, _, rest = spec.partition(":")
    options = [kv for kv in rest.split(",") if kv and not kv.startswith("tile=")]
    return "shadow_volume" + (":" + ",".join(options) if options else "")


def _differences(lab, scene, spec, size) -> tuple[int, object, object]:
    """(pixels showing a surface where ``spec`` and the plain volume disagree, the measurement,
    the plain volume's measurement)."""
    plain = lab.measure(scene, _plain_spec(spec), size)
    m = lab.measure(scene, spec, size)
    covered = lab.frame(scene, size).covered
    return int(np.sum((m.visibility[covered] < 0.5) != (plain.visibility[covered] < 0.5))), m, plain


#: Every scene but the colonnade (144 casters) at 160x120 in the inner loop; at 320x240 the two whose frames other tests share,
#: the others with the slow tests (inner-loop budget).
INNER_MEDIUM = {"box_on_plane", "sv_camera_in_shadow"}
MASK_CASES = [(scene, SMALL) if scene != "sv_colonnade" else pytest.param(scene, SMALL, marks=pytest.mark.slow)
              for scene in SCENES] + [
    (scene, MEDIUM) if scene in INNER_MEDIUM else pytest.param(scene, MEDIUM, marks=pytest.mark.slow)
    for scene in SCENES]


@pytest.mark.parametrize("scene, size", MASK_CASES, ids=lambda v: "x".join(map(str, v)) if isinstance(v, tuple) else v)
def test_the_plain_volumes_mask(lab, scene, size):
    wrong, m, plain = _differences(lab, scene, "hierarchical_volume", size)
    assert wrong == 0, f"{wrong} pixels differ from shadow_volume"
    assert (m.visibility[lab.frame(scene, size).covered] < 0.5).sum() > 100  # it has shadow to get right
    s = m.stats
    # per-pixel work only in boundary tiles: never more than the plain volume's, whose figure the
    # unmasked passes reproduce exactly
    assert s["all_volume_fragments"] == plain.stats["volume_fragments"]
    assert 0 < s["volume_fragments"] <= s["all_volume_fragments"]
    assert s["pixel_ops"] == s["volume_fragments"]
    assert s["uncertain_triangles"] == 0


@pytest.mark.parametrize("tile", [4, 16, 32])
@pytest.mark.parametrize("scene", [pytest.param("sv_colonnade", marks=pytest.mark.slow), "sv_camera_in_shadow",
                                   "sv_open_mesh", "sv_directional", "spot_scene"])
def test_every_tile_size(lab, scene, tile):
    wrong, m, _ = _differences(lab, scene, f"hierarchical_volume:tile={tile}", SMALL)
    assert wrong == 0, f"{wrong} pixels differ from shadow_volume"


@pytest.mark.parametrize("spec", ["hierarchical_volume:mode=zfail", "hierarchical_volume:mode=zpass",
                                  "hierarchical_volume:far=clamp", "hierarchical_volume:mode=zfail,far=clamp"])
@pytest.mark.parametrize("scene", ["sv_camera_in_shadow", "sv_near_plane_cut", "sv_open_mesh"])
def test_every_counting_mode_and_far_plane(lab, scene, spec):
    """Each counting method and far plane against the plain volume with the same options: z-pass
    is wrong on these scenes (hard case SV1), and identically so."""
    wrong, _, _ = _differences(lab, scene, spec, SMALL)
    assert wrong == 0, f"{wrong} pixels differ from {_plain_spec(spec)}"


def test_the_tile_classes_cover_the_screen(lab):
    frame = lab.frame("sv_camera_in_shadow", MEDIUM)
    for tile in (4, 8, 32):
        s = lab.measure("sv_camera_in_shadow", f"hierarchical_volume:tile={tile}", MEDIUM).stats
        tiles = -(-frame.width // tile) * -(-frame.height // tile)
        assert s["tiles_inside"] + s["tiles_outside"] + s["tiles_boundary"] == tiles
        assert s["tiles_boundary"] > 0 and s["tiles_outside"] > 0
        assert s["tile_tests"] >= s["tiles_boundary"]


def test_tiles_settled_in_shadow(lab):
    """sv_camera_in_shadow: whole tiles inside the building's shadow are settled at tile level."""
    s = lab.measure("sv_camera_in_shadow", "hierarchical_volume", MEDIUM).stats
    assert s["tiles_inside"] > 200


@pytest.mark.parametrize("scene, size, factor", [
    ("box_on_plane", MEDIUM, 6.0),                                        # one caster: few boundary tiles
    ("sv_camera_in_shadow", MEDIUM, 3.5),
    ("sv_colonnade", SMALL, 1.25),                                        # many thin shadows: most tiles boundary
    pytest.param("sv_colonnade", MEDIUM, 1.5, marks=pytest.mark.slow),    # the share falls as the image grows
])
def test_fewer_volume_fragments_than_the_plain_volume(lab, scene, size, factor):
    """The point of the technique: per-pixel stencil work only in boundary tiles. On
    sv_colonnade the many thin column shadows and column outlines leave most tiles boundary at
    small sizes; the share falls as the image grows."""
    s = lab.measure(scene, "hierarchical_volume", size).stats
    assert s["all_volume_fragments"] > factor * s["volume_fragments"]


def test_the_masked_passes_skip_fragments_outside_boundary_tiles(lab):
    """The per-pixel passes' occlusion counts: boundary tiles only, so their stencil updates are at
    most those of the plain volume, and the stencil holds nothing outside boundary tiles."""
    tech = from_spec("hierarchical_volume")
    frame = lab.frame("box_on_plane", SMALL)
    m = measure(tech, frame, 0, repeat=1, warmup=0, count=False, release=False)
    try:
        stencil = tech.target.read_stencil()[::-1]  # bottom row first, as the tiles are numbered
        classes = tech.tile_classes()
        n = tech.tile_grid[0] * tech.tile_grid[1]
        boundary = np.frombuffer(tech.buffers["tile_boundary"].read(), np.uint32)[:n] != 0
        mask = np.kron(boundary.reshape(tech.tile_grid[1], tech.tile_grid[0]), np.ones((tech.tile, tech.tile), bool))
        mask = mask[:frame.height, :frame.width]
        assert not stencil[~mask].any()
        assert classes["boundary"] == m.stats["tiles_boundary"] == int(boundary.sum())
    finally:
        tech.release()
    plain = lab.measure("box_on_plane", "shadow_volume", SMALL).stats
    assert m.stats["stencil_updates"] <= plain["stencil_updates"]


def test_tile_sizes_are_declared_choices():
    assert from_spec("hierarchical_volume").tile == 8
    with pytest.raises(TechniqueError):
        from_spec("hierarchical_volume:tile=12")
    with pytest.raises(TechniqueError):
        from_spec("hierarchical_volume:silhouette=gpu")  # forced CPU silhouettes: not a parameter


def test_a_full_span_list_is_grown_to_the_same_answer(lab, monkeypatch):
    import shadowlab.techniques.volumes.hierarchical_volume as hv

    full = lab.measure("spot_scene", "hierarchical_volume", SMALL)
    monkeypatch.setattr(hv, "SPANS_PER_TRIANGLE", 0)  # the first list holds hv's minimum only
    monkeypatch.setattr(hv, "MIN_SPANS", 1)
    small = lab.measure("spot_scene", "hierarchical_volume", SMALL)
    assert small.stats["span_retries"] == 1 and any("overflowed" in n for n in small.notes)
    np.testing.assert_array_equal(small.visibility, full.visibility)
    assert small.stats["volume_fragments"] == full.stats["volume_fragments"]
