"""The shadow atlas allocator: tiles inside the atlas and disjoint, every kept light with all its
faces, resolution monotone in importance, overflow exactly when the smallest tiles of all lights
cannot fit, determinism, and the resolution rule's figures."""
from __future__ import annotations

import numpy as np
import pytest

from shadowlab.lighting.atlas import (
    AtlasPlan, Tile, allocate, draw_plan, importance_order, pack, requested_resolution,
)


def coverage(plan: AtlasPlan) -> np.ndarray:
    """Int (size, size): how many tiles cover each texel (atlases up to 4096², as uint8)."""
    grid = np.zeros((plan.size, plan.size), np.uint8)
    for t in plan.tiles:
        grid[t.y: t.y + t.size, t.x: t.x + t.size] += 1
    return grid


def check_plan(plan: AtlasPlan, importance: dict, faces: dict) -> None:
    """Every invariant of a plan."""
    for t in plan.tiles:
        assert 0 <= t.x and 0 <= t.y and t.x + t.size <= plan.size and t.y + t.size <= plan.size, t
        assert t.x % t.size == 0 and t.y % t.size == 0  # on its own grid (buddy cells)
    if plan.size <= 4096:
        assert coverage(plan).max() <= 1  # no overlap
    assert plan.texels_used == sum(t.size ** 2 for t in plan.tiles) <= plan.size ** 2
    kept = set(importance) - set(plan.overflow)
    assert set(plan.resolution) == kept and not set(plan.resolution) & set(plan.overflow)
    for light in kept:
        tiles = plan.tiles_of(light)
        assert [t.face for t in tiles] == list(range(faces[light]))
        assert {t.size for t in tiles} == {plan.resolution[light]}
        assert plan.resolution[light] <= plan.requested[light]
    ranked = importance_order(importance)  # most important first
    got = [plan.resolution.get(light, 0) for light in ranked]
    assert got == sorted(got, reverse=True), "a more important light got smaller tiles"
    # the overflow lights are the least important
    assert set(ranked[len(ranked) - len(plan.overflow):]) == set(plan.overflow)


def test_requests_follow_the_documented_rule():
    # 4 lights, shares 1/4 each: every one average -> max
    assert set(requested_resolution({0: 1, 1: 1, 2: 1, 3: 1}, 1024, 64).values()) == {1024}
    # shares 0.7, 0.2, 0.1, 0 with n = 4: 1024·√2.8 = 1713 -> 1024 (clamped), 1024·√0.8 = 916 -> 512,
    # 1024·√0.4 = 648 -> 512, 0 -> the minimum
    assert requested_resolution({0: 0.7, 1: 0.2, 2: 0.1, 3: 0.0}, 1024, 64) == {0: 1024, 1: 512, 2: 512, 3: 64}
    # no importance anywhere: every light average
    assert requested_resolution({5: 0.0, 6: 0.0}, 256, 16) == {5: 256, 6: 256}
    # texels a light asks for grow with its importance (4x importance -> 2x side, 4x texels)
    r = requested_resolution({0: 4.0, 1: 1.0, 2: 0.25}, 4096, 1)
    assert r[0] == 2 * r[1] == 4 * r[2]


def test_requests_that_fit_are_granted_and_packed_without_gaps():
    importance = {0: 0.5, 1: 0.3, 2: 0.15, 3: 0.05}
    faces = {0: 6, 1: 1, 2: 6, 3: 1}
    plan = allocate(importance, faces, 8192, 1024, 64)
    check_plan(plan, importance, faces)
    assert plan.resolution == plan.requested and not plan.overflow
    # largest first in Morton order: the tiles fill a prefix of the atlas with no gap
    assert plan.tiles[0].rect == (0, 0, plan.tiles[0].size, plan.tiles[0].size)


def test_halving_takes_the_least_important_first():
    # four average spot lights ask 1024² each: exactly a 2048² atlas
    importance = {0: 1.0, 1: 1.0, 2: 1.0, 3: 1.0}
    faces = {0: 1, 1: 1, 2: 1, 3: 1}
    plan = allocate(importance, faces, 2048, 1024, 64)
    check_plan(plan, importance, faces)
    assert plan.resolution == {0: 1024, 1: 1024, 2: 1024, 3: 1024} and plan.occupancy == 1.0
    # a fifth, less important light (asks 1024·√(5·0.5/4.5) = 763 -> 512): it is halved first
    # (256), then the last of the ties (3, to 512), which is enough; the spare room then takes
    # light 4 back to 512 (its request, and no more than light 3's)
    importance[4], faces[4] = 0.5, 1
    plan = allocate(importance, faces, 2048, 1024, 64)
    check_plan(plan, importance, faces)
    assert plan.requested == {0: 1024, 1: 1024, 2: 1024, 3: 1024, 4: 512}
    assert plan.resolution == {0: 1024, 1: 1024, 2: 1024, 3: 512, 4: 512} and not plan.overflow


@pytest.mark.parametrize("lights,fits", [(4096, True), (4097, False)])
def test_overflow_exactly_when_the_minimum_tiles_cannot_fit(lights, fits):
    """A 4096² atlas holds 4096 faces of 64²: 4096 one-face lights fit, 4097 do not (one
    overflows: the least important), whatever they asked for."""
    importance = {i: 1.0 + (i % 7) for i in range(lights)}
    faces = {i: 1 for i in range(lights)}
    plan = allocate(importance, faces, 4096, 1024, 64)
    check_plan(plan, importance, faces)
    assert (not plan.overflow) == fits
    if fits:
        assert set(plan.resolution.values()) == {64} and plan.occupancy == 1.0
    else:
        assert plan.overflow == [importance_order(importance)[-1]]


def test_overflow_with_cubes_drops_the_least_important_lights_whole():
    # 256² atlas, min 64: 16 faces. Three cubes (18 faces) cannot all fit: the least important cube
    # goes whole; the two kept cubes (12 faces of 64²) cannot grow into the 4 faces left
    importance = {0: 3.0, 1: 2.0, 2: 1.0}
    faces = {0: 6, 1: 6, 2: 6}
    plan = allocate(importance, faces, 256, 128, 64)
    check_plan(plan, importance, faces)
    assert plan.overflow == [2] and plan.resolution == {0: 64, 1: 64}
    assert len(plan.tiles) == 12
    # two cubes and four spots: 16 faces of 64², exactly the atlas: all fit
    importance, faces = {0: 1.0, 1: 5.0, 2: 1, 3: 1, 4: 1, 5: 1}, {0: 6, 1: 6, 2: 1, 3: 1, 4: 1, 5: 1}
    plan = allocate(importance, faces, 256, 64, 64)
    check_plan(plan, importance, faces)
    assert not plan.overflow and plan.occupancy == 1.0


def test_spare_room_goes_back_to_the_most_important():
    # 1024² atlas; light 0 asks 1024² (1 M texels), lights 1..4 ask 512² (1 M together). A round
    # of halvings from the least important (4, 3, 2, 1 to 256, then 0 to 512) frees more than
    # needed (0.5 M used); the room goes back most important first: 1 and 2 to 512 (0.875 M);
    # 3 would not fit, and 4 may not pass 3
    importance = {0: 4.0, 1: 1.0, 2: 1.0, 3: 1.0, 4: 1.0}
    faces = {i: 1 for i in importance}
    plan = allocate(importance, faces, 1024, 1024, 32)
    check_plan(plan, importance, faces)
    assert plan.requested == {0: 1024, 1: 512, 2: 512, 3: 512, 4: 512}
    assert plan.resolution == {0: 512, 1: 512, 2: 512, 3: 256, 4: 256}
    assert plan.occupancy == 0.875


def test_determinism_and_ties():
    rng = np.random.default_rng(7)
    importance = {int(i): float(v) for i, v in enumerate(rng.choice([0.0, 0.1, 0.5, 1.0, 3.0], 60))}
    faces = {i: int(rng.choice([1, 6])) for i in importance}
    a = allocate(importance, faces, 4096, 1024, 32)
    b = allocate(dict(reversed(list(importance.items()))), dict(reversed(list(faces.items()))), 4096, 1024, 32)
    assert a == b
    check_plan(a, importance, faces)


@pytest.mark.parametrize("seed", range(30))
def test_random_plans_hold_every_invariant(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 120))
    importance = {int(i): float(v) for i, v in enumerate(rng.exponential(1.0, n) * (rng.random(n) > 0.1))}
    faces = {i: int(rng.choice([1, 1, 6, 4])) for i in importance}
    size = int(2 ** rng.integers(8, 13))
    top = int(2 ** rng.integers(6, int(np.log2(size)) + 1))
    low = int(2 ** rng.integers(0, int(np.log2(top)) + 1))
    plan = allocate(importance, faces, size, top, low)
    check_plan(plan, importance, faces)
    minimum = sum(faces.values()) * low * low
    assert bool(plan.overflow) == (minimum > size * size)


def test_pack_is_gapless_and_refuses_too_much():
    sizes = [(0, 0, 2), (1, 0, 8), (2, 0, 4), (3, 0, 4), (4, 0, 2), (5, 0, 2), (6, 0, 2)]
    tiles = pack(sizes, 16)
    assert tiles[0] == Tile(1, 0, 0, 0, 8) and tiles[1] == Tile(2, 0, 8, 0, 4) and tiles[2] == Tile(3, 0, 12, 0, 4)  # Z order inside the 8² cell at (8, 0)
    with pytest.raises(ValueError, match="exceed"):
        pack([(0, 0, 16), (1, 0, 1)], 16)


@pytest.mark.parametrize("kwargs,names", [
    (dict(atlas_size=1000), "atlas_size"), (dict(min_resolution=0), "min_resolution"),
    (dict(max_resolution=4096), "max_resolution"), (dict(min_resolution=512), "max_resolution"),
    (dict(importance={0: -1.0}), "importance"), (dict(importance={0: float("nan")}), "importance"),
    (dict(faces={0: 0}), "faces"), (dict(faces={1: 1}), "faces"),
])
def test_bad_input_is_named(kwargs, names):
    args = dict(importance={0: 1.0}, faces={0: 1}, atlas_size=1024, max_resolution=256, min_resolution=16)
    args.update(kwargs)
    with pytest.raises(ValueError, match=names):
        allocate(**args)


def test_no_lights_is_an_empty_plan():
    plan = allocate({}, {}, 1024, 256, 16)
    assert plan.tiles == [] and plan.overflow == [] and plan.texels_used == 0


def test_draw_plan_pictures_every_tile():
    importance = {0: 3.0, 1: 1.0, 2: 0.2}
    faces = {0: 6, 1: 1, 2: 1}
    plan = allocate(importance, faces, 4096, 1024, 64)
    img = draw_plan(plan, 256)
    assert img.shape == (256, 256, 3) and img.dtype == np.uint8
    covered = (img.sum(axis=2) > 0).mean()
    assert covered == pytest.approx(plan.occupancy, abs=0.01)
