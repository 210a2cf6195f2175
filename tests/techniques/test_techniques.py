"""Technique specs: parameters round-trip, unknown or ill-typed parameters are errors."""
from __future__ import annotations

import pytest

from shadowlab.techniques import REGISTRY, TechniqueError, from_spec


@pytest.mark.parametrize("name", list(REGISTRY))
def test_defaults_round_trip(name):
    t = from_spec(name)
    again = from_spec(t.spec())
    assert again.params() == t.params() and again.spec() == t.spec()


def test_spec_values_are_typed():
    t = from_spec("shadow_map:resolution=1024,bias=0.002,depth_bits=16,variant=slope,hardware_offset=on")
    p = t.params()
    assert (p["resolution"], p["bias"], p["depth_bits"], p["variant"], p["hardware_offset"]) == (1024, 0.002, 16, "slope", True)
    assert t.spec().startswith("shadow_map:resolution=1024,bias=0.002,bias_space=world,depth_bits=16,variant=slope,")
    assert t.short_label() == "shadow_map:resolution=1024,depth_bits=16,variant=slope,hardware_offset=true"


@pytest.mark.parametrize("spec,match", [
    ("no_such", "unknown technique 'no_such'"),
    ("shadow_map:resolutoin=1024", "unknown parameter 'resolutoin'"),
    ("shadow_map:resolution=big", "resolution must be int"),
    ("shadow_map:resolution=1.5", "resolution must be int"),
    ("shadow_map:depth_bits=12", "depth_bits must be one of 16, 24, 32"),
    ("shadow_map:bias", "expected key=value"),
    ("shadow_map:bias=1,bias=2", "given twice"),
])
def test_bad_specs(spec, match):
    with pytest.raises(TechniqueError, match=match):
        from_spec(spec)


def test_every_technique_declares_what_the_core_needs():
    """Each registered technique declares a summary, its passes, the lights it renders for,
    how each stat combines over light samples, and a plot style of its own (no two alike)."""
    from shadowlab.techniques.base import ALL_LIGHTS, COMBINE_RULES, PlotStyle

    styles = set()
    for name, cls in REGISTRY.items():
        assert cls.name == name and cls.summary and cls.PASSES, name
        assert cls.LIGHTS and cls.LIGHTS <= ALL_LIGHTS, name
        assert cls.STATS and set(cls.STATS.values()) <= set(COMBINE_RULES), name
        assert isinstance(cls.STYLE, PlotStyle), name
        styles.add((cls.STYLE.color, cls.STYLE.marker))
    assert len(styles) == len(REGISTRY)
    assert REGISTRY["pcss"].LIGHTS == {"area"}
    assert REGISTRY["cascaded_map"].LIGHTS == REGISTRY["lispsm"].LIGHTS == {"directional"}


def test_unknown_technique_suggests_a_close_name():
    with pytest.raises(TechniqueError, match="did you mean 'shadow_map'"):
        from_spec("shadow_mop")


def test_a_technique_registers_itself(registry_snapshot):
    """Subclassing Technique with a name is all it takes to be known to from_spec; a name that
    is already taken by another class is refused."""
    from shadowlab.techniques import Technique

    class Demo(Technique):
        name = "demo_registered"
        summary = "a test technique"
        PASSES = ("nothing",)

    assert from_spec("demo_registered").name == "demo_registered"
    with pytest.raises(TypeError, match="taken"):
        class Clash(Technique):
            name = "shadow_map"


def test_planning_refuses_a_light_a_technique_does_not_render_for(tmp_path):
    """compare, study and animate check every technique against every light before rendering:
    cascades on a point light and PCSS on a hard light are errors naming both."""
    from shadowlab.commands.animate import animate
    from shadowlab.commands.compare import compare
    from shadowlab.study.suite import SuiteError, load_suite

    with pytest.raises(TechniqueError, match=r"cascaded_map does not render for light 0 of scene box_on_plane "
                                             r"\(point\); it needs a directional light"):
        compare("box_on_plane", ["cascaded_map"], size=(64, 48), out=tmp_path / "run")
    with pytest.raises(TechniqueError, match=r"pcss .*\(directional\); it needs an area light"):
        animate("sun_scene", ["pcss"], frames=2, size=(64, 48), out=tmp_path / "anim")
    suite = tmp_path / "s.toml"
    suite.write_text('name = "s"\nscenes = ["box_on_plane"]\ntechniques = ["lispsm"]\n')
    with pytest.raises(SuiteError, match=r"lispsm does not render for light 0 of scene box_on_plane"):
        load_suite(suite)
    assert not (tmp_path / "run").exists() and not (tmp_path / "anim").exists()


def test_owned_bytes_counts_every_gl_object(lab):
    """owned_bytes: a 512² 24-bit shadow map owns at least its depth texture (4 bytes a texel)."""
    from helpers import SMALL
    from shadowlab.techniques import from_spec

    tech = from_spec("shadow_map:resolution=512")
    tech.prepare(lab.frame("box_on_plane", SMALL), 0)
    try:
        assert tech.owned_bytes() >= 512 * 512 * 4
    finally:
        tech.release()
    assert tech.owned_bytes() == 0


def test_kept_objects_last_across_frames_only_when_asked(lab):
    """Technique.keep: freed by release() in a compare or study; kept across release() while
    keep_across_frames (animate), until forget()."""
    import moderngl

    from helpers import SMALL
    from shadowlab.techniques import from_spec

    ctx = lab.frame("box_on_plane", SMALL).ctx
    tech = from_spec("shadow_map:resolution=64")
    buf = tech.keep("cache", lambda: ctx.buffer(reserve=16))
    assert tech.keep("cache", lambda: ctx.buffer(reserve=16)) is buf  # made once
    tech.release()
    assert isinstance(buf.mglo, moderngl.InvalidObject) and tech.kept("cache") is None
    tech.keep_across_frames = True
    buf = tech.keep("cache", lambda: ctx.buffer(reserve=16))
    tech.release()
    assert tech.kept("cache") is buf and not isinstance(buf.mglo, moderngl.InvalidObject)
    tech.forget()
    assert isinstance(buf.mglo, moderngl.InvalidObject) and tech.kept("cache") is None
