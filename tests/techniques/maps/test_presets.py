"""Engine presets (shadow_map:preset=..., cascaded_map:preset=...): the documented values, the
override rule, the spec round-trip, strict names, the new bias spaces, and one behaviour:
three.js's bias of 0 shows acne where Bevy's depth + normal bias does not."""
import math

import pytest

from helpers import SMALL
from shadowlab.techniques import TechniqueError, from_spec
from shadowlab.techniques.maps import presets
from shadowlab.tuning.space import with_params


@pytest.mark.parametrize("name", list(presets.PRESETS))
def test_preset_expands_to_its_documented_directional_values(name):
    tech = from_spec(f"shadow_map:preset={name}")
    expected = presets.PRESETS[name].values("shadow_map", "directional")
    assert expected, name
    for key, value in expected.items():
        assert tech.params()[key] == value, (name, key)


def test_documented_values_of_two_engines():
    godot = presets.PRESETS["godot"].values("shadow_map", "directional")
    assert (godot["bias"], godot["bias_space"], godot["normal_offset"]) == (0.002, "units", 2.0)
    bevy_local = presets.PRESETS["bevy"].values("shadow_map", "local")
    assert (bevy_local["bias"], bevy_local["resolution"]) == (0.08, 1024)
    assert math.isclose(bevy_local["normal_offset"], 0.6 * math.sqrt(2.0), rel_tol=1e-3)
    three = presets.PRESETS["threejs"].values("shadow_map", "directional")
    assert (three["bias"], three["resolution"], three["bias_space"]) == (0.0, 512, "window")


def test_every_value_names_its_source_and_fidelity():
    rows = presets.table_rows()
    assert len(rows) > 40
    for row in rows:
        assert row["source"] and row["setting"], row
        assert row["fidelity"] in presets.FIDELITY
    # the UE5 mapping comes from documentation, never marked exact
    assert {r["fidelity"] for r in rows if r["preset"] == "ue5"} == {presets.UNCERTAIN}


def test_explicit_keys_override_the_preset():
    tech = from_spec("shadow_map:preset=godot,bias=0.005,filter=nearest")
    assert tech.bias == 0.005 and tech.filter == "nearest"
    assert tech.bias_space == "units" and tech.variant == "normal_offset"  # the rest from the preset
    assert tech.short_label() == "shadow_map:preset=godot,bias=0.005,filter=nearest"


def test_the_light_type_picks_the_values():
    class Light:
        def __init__(self, kind):
            self.type_name = kind

    tech = from_spec("shadow_map:preset=bevy")
    tech.resolve_preset(Light("point"))
    assert (tech.bias, tech.resolution, tech.projection) == (0.08, 1024, "cube")
    tech.resolve_preset(Light("directional"))
    # a key only the point light's set gives (the cube) goes back to the technique's default
    assert (tech.bias, tech.resolution, tech.projection) == (0.02, 2048, "auto")
    assert tech.short_label() == "shadow_map:preset=bevy" and from_spec(tech.spec()).projection == "auto"
    given = from_spec("shadow_map:preset=bevy,bias=0.5")
    given.resolve_preset(Light("spot"))
    assert given.bias == 0.5


@pytest.mark.parametrize("spec", ["shadow_map:preset=godot", "shadow_map:preset=unity,bias=0.8",
                                  "cascaded_map:preset=bevy", "shadow_map:preset=ue5,budget=2"])
def test_label_and_spec_round_trip(spec):
    tech = from_spec(spec)
    again = from_spec(tech.spec())
    assert again.spec() == tech.spec() and again.params() == tech.params()
    assert again.short_label() == tech.short_label()
    assert "preset=" in tech.spec()


def test_label_is_the_preset_alone():
    assert from_spec("shadow_map:preset=threejs").short_label() == "shadow_map:preset=threejs"
    assert from_spec("cascaded_map:preset=unity").short_label() == "cascaded_map:preset=unity"


def test_no_preset_leaves_the_spec_as_it_was():
    spec = from_spec("shadow_map").spec()
    assert "preset" not in spec
    assert from_spec("shadow_map:preset=none").spec() == spec
    # params() lists every declared parameter, as for any technique (metrics.csv: param_preset = none)
    assert from_spec("shadow_map").params()["preset"] == "none"


def test_tuner_keeps_the_preset_light_dependent():
    spec = with_params(from_spec("shadow_map:preset=bevy"), {"bias": 0.01})
    assert "preset=bevy" in spec and "normal_offset" not in spec and "bias=0.01" in spec


@pytest.mark.parametrize("spec, fragment", [
    ("shadow_map:preset=godt", "did you mean 'godot'"),
    ("shadow_map:preset=unreal", "preset must be one of"),
    ("cascaded_map:preset=3js", "preset"),
    ("shadow_map:bias_space=metres", "bias_space"),
    ("cascaded_map:preset=threejs", "preset=threejs has no cascaded_map defaults"),
    ("cascaded_map:preset=ue5", "cascaded_map presets: godot, bevy, unity"),
    ("shadow_map:bias=2", "bias must be <= 1.0 with bias_space=world"),
])
def test_bad_names_are_one_line_errors(spec, fragment):
    with pytest.raises(TechniqueError) as info:
        from_spec(spec)
    assert fragment in str(info.value) and "\n" not in str(info.value)


def test_threejs_zero_bias_shows_acne_where_bevy_does_not(lab):
    """sm_contact at 160x120 (directional light): three.js's bias 0 in window depth leaves the lit
    floor self-shadowed, Bevy's 0.02 m along the light plus 1.8 x sqrt(2) texels along the normal
    none; Bevy pays instead in contact gap (three.js none)."""
    rows = lab.rows("sm_contact", ["shadow_map:preset=threejs", "shadow_map:preset=bevy"], SMALL)
    three, bevy = rows.loc["shadow_map:preset=threejs"], rows.loc["shadow_map:preset=bevy"]
    assert three["false_shadow_rate"] > 0.15
    assert bevy["false_shadow_rate"] < 0.001
    assert bevy["contact_gap_px"] > three["contact_gap_px"]


def test_units_bias_is_a_world_distance(lab):
    """On sm_contact (orthographic map) bias_space=units with bias b equals window bias b / the
    map's depth range: the same visibility, bit for bit."""
    from shadowlab.measurement.pipeline import measure

    ev = lab.evaluator("sm_contact", SMALL)
    units = from_spec("shadow_map:bias_space=units,bias=0.01")
    m_units = measure(units, ev.frame, 0, repeat=1, warmup=0, release=False)
    depth_range = units.atlas.faces[0].depth_range
    units.release()
    window = from_spec(f"shadow_map:bias_space=window,bias={0.01 / depth_range!r}")
    m_window = measure(window, ev.frame, 0, repeat=1, warmup=0)
    assert (m_units.visibility == m_window.visibility).all()


def test_absolute_bias_spaces_go_past_one():
    """units and texels are absolute (an engine's 2 texels, half a metre in a city): up to 1000;
    the fractional spaces stop at 1."""
    assert from_spec("shadow_map:bias_space=texels,bias=2").bias == 2.0
    assert from_spec("shadow_map:bias_space=units,bias=40").bias == 40.0
    with pytest.raises(TechniqueError, match="bias must be <= 1.0 with bias_space=window"):
        from_spec("shadow_map:bias_space=window,bias=1.5")
