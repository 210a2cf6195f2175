"""Work counters (shadowlab.gpu.work, docs/cost.md): the same numbers on every run, booked to named
passes, and equal to what the scene and the technique say they must be where that is known
exactly. Which counters are exact and which approximate is declared in ``work.COUNTERS``;
the tests below hold the exact ones to known answers."""
from __future__ import annotations

import pytest

from shadowlab.gpu import work
from shadowlab.measurement.pipeline import count_work, measure
from shadowlab.techniques import REGISTRY, from_spec
from shadowlab.techniques.maps.irregular_zbuffer import LOCAL_SIZE

SIZE = (96, 72)
#: Scenes with one light each of a point, a directional and an area light.
SCENE_BY_LIGHT = {"point": "box_on_plane", "directional": "sun_scene", "area": "soft_overlap"}


def scene_for(name: str) -> str:
    """The first of SCENE_BY_LIGHT's scenes whose light the technique renders for."""
    return next(s for light, s in SCENE_BY_LIGHT.items() if REGISTRY[name].supports_type(light))


@pytest.mark.parametrize("name", sorted(REGISTRY))
def test_counters_repeat_and_every_pass_is_named(lab, name):
    """Two measurements of one configuration count the same work, all of it inside the passes
    the technique declares (nothing under work.UNNAMED), with known counters only."""
    frame = lab.frame(scene_for(name), SIZE)
    first = measure(from_spec(name), frame, 0, repeat=1, warmup=0).work
    second = measure(from_spec(name), frame, 0, repeat=1, warmup=0).work
    assert first == second
    assert first, f"{name} reports no work"
    assert work.UNNAMED not in first
    assert set(first) <= set(REGISTRY[name].PASSES)
    for counters in first.values():
        assert set(counters) <= set(work.COUNTERS)


def test_every_counter_says_whether_it_is_exact_and_why():
    for name, counter in work.COUNTERS.items():
        assert counter.doc and counter.why and counter.source, name
        assert isinstance(counter.exact, bool)
    exact = {k for k, c in work.COUNTERS.items() if c.exact}
    # the driver-dependent ones (post-transform cache, early-z and helper invocations, guard bands)
    assert {"vs_invocations", "fs_invocations", "clip_primitives"}.isdisjoint(exact)
    assert {"draws", "vertices", "samples_passed", "primitives_generated", "compute_invocations"} <= exact


def test_every_hook_counter_has_a_hook():
    """work.HOOKS is the one table of what the counting render hooks: each entry books counters
    whose source is "hook", and every such counter is booked by some entry."""
    booked = {c for hook in work.HOOKS for c in hook.counters}
    assert booked == {k for k, c in work.COUNTERS.items() if c.source == "hook"}
    assert work.WorkCounter.hooked() == [(hook.owner(), hook.attr) for hook in work.HOOKS]
    assert len(set(work.WorkCounter.hooked())) == len(work.HOOKS)


def test_shadow_map_counts_match_the_scene(lab):
    """A 2048² single-face 24-bit map: the depth pass clears 2048²·3 bytes and draws every caster
    and receiver triangle once; the lookup draws one full-screen quad whose every pixel passes."""
    frame = lab.frame("box_on_plane", SIZE)
    tech = from_spec("shadow_map:resolution=2048,depth_bits=24,filter=pcf3")
    m = measure(tech, frame, 0, repeat=1, warmup=0)
    depth, lookup = m.work["depth"], m.work["lookup"]
    assert depth["bytes_cleared"] == 2048 * 2048 * 3
    assert depth["draws"] == 1
    triangles = sum(len(o.faces) for o in frame.scene.objects)
    assert depth["vertices"] == 3 * triangles
    assert depth["primitives_generated"] == triangles
    assert depth["samples_passed"] > 0  # overdraw: a texel passes once per nearer caster drawn after
    assert depth["bytes_written"] == 3 * depth["samples_passed"]  # a depth-only pass
    assert lookup == {**lookup, "draws": 1, "vertices": 6, "samples_passed": SIZE[0] * SIZE[1],
                      "bytes_written": 4 * SIZE[0] * SIZE[1], "texture_taps": (2 + 9) * SIZE[0] * SIZE[1]}
    cols = work.columns(m.work)
    assert cols["work_draws"] == 2 and cols["work_lookup_texture_taps"] == (2 + 9) * SIZE[0] * SIZE[1]


def test_a_pass_that_draws_nothing_counts_nothing_there(lab):
    """The counting render re-runs the passes as the timed renders did: a nearest lookup reads
    the G-buffer's position and normal and one map texel per pixel, and a one-layer map opens no
    peel or resolve pass."""
    frame = lab.frame("box_on_plane", SIZE)
    nearest = measure(from_spec("shadow_map"), frame, 0, repeat=1, warmup=0).work
    assert nearest["lookup"]["texture_taps"] == (2 + 1) * SIZE[0] * SIZE[1]  # position, normal, one texel
    assert "resolve" not in nearest and "peel" not in nearest


def test_irregular_zbuffer_counts_its_rays_and_groups(lab):
    """One ray per evaluated pixel, inserted by ceil(rays / local size) groups of the local size."""
    frame = lab.frame("box_on_plane", SIZE)
    m = measure(from_spec("irregular_zbuffer"), frame, 0, repeat=1, warmup=0)
    rays = int(frame.evaluated_image(frame.slot(0)).sum())
    assert m.work["insert"]["rays"] == rays
    assert m.work["insert"]["compute_invocations"] == -(-rays // LOCAL_SIZE) * LOCAL_SIZE
    assert m.work["insert"]["dispatches"] == 1
    assert m.stats["izb_pairs"] > 0 and m.work["raster"]["draws"] >= 1


def test_cpu_techniques_declare_their_work_without_another_render(lab):
    frame = lab.frame("box_on_plane", SIZE)
    tech = from_spec("raytrace")
    m = measure(tech, frame, 0, repeat=1, warmup=0)
    assert m.work == {"trace": {"rays": m.stats["rays"]}}
    assert count_work(tech) == {}  # a CPU technique is not rendered for counting


def test_shadow_volume_stencil_updates_are_the_samples_that_count(lab):
    """z-pass updates the stencil exactly where a volume sample passes the depth test: the
    technique's declared updates (its own occlusion counts, under an untimed replay) equal the
    samples the counting render's hooks saw pass in the volume pass. The CPU silhouette path
    tests every caster triangle each render; the GPU path none."""
    frame = lab.frame("sv_camera_in_shadow", SIZE)
    m = measure(from_spec("shadow_volume:mode=zpass"), frame, 0, repeat=1, warmup=0)
    assert m.work["volume"]["stencil_updates"] == m.work["volume"]["samples_passed"] > 0
    triangles = m.stats["zpass_caster_triangles"] + m.stats["zfail_caster_triangles"]
    assert m.work["silhouette"]["cpu_triangles"] == triangles > 0
    gpu = measure(from_spec("shadow_volume:mode=zpass,silhouette=gpu"), frame, 0, repeat=1, warmup=0)
    assert "cpu_triangles" not in gpu.work.get("silhouette", {})
    assert gpu.work["volume"]["gs_invocations"] > 0


def test_light_samples_add_their_work(lab):
    """A light-sampled technique renders once per point of the area light: its work is N renders'."""
    frame = lab.frame("soft_overlap", SIZE)
    one = measure(from_spec("shadow_map:light_samples=1"), frame, 0, repeat=1, warmup=0).work
    four = measure(from_spec("shadow_map:light_samples=4"), frame, 0, repeat=1, warmup=0).work
    assert four["depth"]["draws"] == 4 * one["depth"]["draws"]
    assert four["depth"]["bytes_cleared"] == 4 * one["depth"]["bytes_cleared"]
    assert four["lookup"]["samples_passed"] == 4 * one["lookup"]["samples_passed"]


def test_columns_and_their_parsing():
    per_pass = {"depth": {"draws": 2, "samples_passed": 10}, "lookup": {"draws": 1, "texture_taps": 0}}
    cols = work.columns(per_pass)
    assert cols == {"work_draws": 3, "work_samples_passed": 10, "work_texture_taps": 0,
                    "work_depth_draws": 2, "work_depth_samples_passed": 10, "work_lookup_draws": 1}
    assert work.counter_of("work_draws") == (None, "draws")
    assert work.counter_of("work_depth_samples_passed") == ("depth", "samples_passed")
    assert work.counter_of("time_ms_median") is None
    with pytest.raises(KeyError, match="unknown work counter"):
        work.merge({}, {"depth": {"drawz": 1}})


def test_counting_restores_every_hook(lab):
    """After a counting render — also one whose hooked call raised — every hooked entry point of
    moderngl and PyOpenGL is the original again."""
    hooked = work.WorkCounter.hooked()
    before = [getattr(owner, attr) for owner, attr in hooked]
    frame = lab.frame("box_on_plane", SIZE)
    tech = from_spec("irregular_zbuffer")
    tech.prepare(frame, 0)
    try:
        counter = work.WorkCounter()
        with pytest.raises(Exception):
            with counter.counting():
                assert [getattr(o, a) for o, a in hooked] != before  # hooked inside
                tech.buffers["heads"].write(b"\0" * (tech.buffers["heads"].size + 4))  # raises inside the hook
        assert [getattr(o, a) for o, a in hooked] == before
        assert count_work(tech)
    finally:
        tech.release()
    assert [getattr(o, a) for o, a in hooked] == before

