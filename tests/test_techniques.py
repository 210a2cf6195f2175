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
    assert t.spec().startswith("shadow_map:resolution=1024,bias=0.002,depth_bits=16,variant=slope,")
    assert t.short_label() == "shadow_map:resolution=1024,depth_bits=16,variant=slope,hardware_offset=true"


@pytest.mark.parametrize("spec,match", [
    ("no_such", "unknown technique 'no_such'"),
    ("shadow_map:resolutoin=1024", "unknown parameter 'resolutoin'"),
    ("shadow_map:resolution=big", "resolution must be int"),
    ("shadow_map:resolution=1.5", "resolution must be int"),
    ("shadow_map:depth_bits=12", "depth_bits must be one of 16, 24, 32"),
    ("shadow_map:variant=bogus", "variant must be one of none, constant, slope"),
    ("shadow_map:filter=pcf7", "filter must be one of"),
    ("shadow_map:bias=-1", "bias must be >= 0"),
    ("shadow_map:bias=nan", "bias must be float"),
    ("shadow_map:bias", "expected key=value"),
    ("shadow_map:bias=1,bias=2", "given twice"),
    ("planar:opacity=0.5", "opacity must be > 0.5"),  # one layer at 0.5 would read as lit
])
def test_bad_specs(spec, match):
    with pytest.raises(TechniqueError, match=match):
        from_spec(spec)
