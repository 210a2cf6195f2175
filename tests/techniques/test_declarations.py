"""Declared, not guessed (issue 36): what every registered technique declares it reads (READS: the
G-buffer channels), writes (WRITES: the frame's depth-stencil) and provides (PROVIDES: the
capabilities other layers ask for) is what it does — checked on every technique at its defaults,
on a scene whose lights it renders for, by watching the frame while it is set up and renders."""
from __future__ import annotations

import types
from pathlib import Path

import moderngl
import pytest

import shadowlab.techniques as techniques_package
from shadowlab.gpu import targets
from shadowlab.gpu.frame import GBUFFER_CHANNELS, Frame
from shadowlab.techniques import REGISTRY, Technique
from shadowlab.techniques.base import CAPABILITIES

from helpers import SMALL, scene_for

#: The family folders of shadowlab/techniques/ (sub-packages).
FAMILY_FOLDERS = {p.parent.name for p in Path(techniques_package.__file__).parent.glob("*/__init__.py")}


def _members(cls) -> set[str]:
    """What a technique class offers a capability: its attributes and methods, and its parameters."""
    return {m for m in set(dir(cls)) | set(cls.PARAMS)}


@pytest.mark.parametrize("name", list(REGISTRY))
def test_declared_capabilities_are_backed_by_what_they_promise(name):
    """A capability in PROVIDES has every member CAPABILITIES promises (texel_mapping ⇒
    face_index and texel_coordinates, ...); and a class that has all of a capability's members
    declares it, so that a new map technique cannot drop out of the texel-footprint metric or the
    exact bias optimiser by forgetting its declaration."""
    cls = REGISTRY[name]
    have = _members(cls)
    for capability in cls.PROVIDES:
        missing = [m for m in CAPABILITIES[capability] if m not in have]
        assert not missing, f"{name} provides {capability} but has no {missing}"
    for capability, members in CAPABILITIES.items():
        if all(m in have for m in members):
            assert capability in cls.PROVIDES, f"{name} has every member of {capability} but does not declare it"


def test_the_layers_ask_the_declaration():
    """The texel-footprint metric and the exact bias optimiser take a technique's capabilities
    from PROVIDES: which techniques qualify is read off the declarations."""
    from shadowlab.evaluation.texel_footprint import has_texel_mapping
    from shadowlab.tuning.exact_bias import ExactBiasError, check_spec

    mapped = {n for n, cls in REGISTRY.items() if has_texel_mapping(cls())}
    assert mapped == {n for n, cls in REGISTRY.items() if "texel_mapping" in cls.PROVIDES}
    assert {"shadow_map", "cascaded_map", "filtered_map", "pcss", "virtual_map"} <= mapped
    for n, cls in REGISTRY.items():
        if "depth_bias" in cls.PROVIDES:
            check_spec(cls())
        else:
            with pytest.raises(ExactBiasError, match="handles the techniques that provide depth_bias .*lispsm.*shadow_map"):
                check_spec(cls())


@pytest.mark.parametrize("name", list(REGISTRY))
def test_family_is_the_module_folder(name):
    """FAMILY is derived from the folder the technique's module lives in (techniques/<family>/)."""
    cls = REGISTRY[name]
    assert cls.FAMILY in FAMILY_FOLDERS, (name, cls.FAMILY)
    assert cls.__module__.split(".")[2] == cls.FAMILY


def test_declarations_are_checked_when_the_class_is_made():
    """An unknown channel, resource or capability, a non-frozenset, or a FAMILY written by hand is
    a TypeError when the class is made; a class outside a family folder has no family."""
    for attr, value in (("READS", frozenset({"depth"})), ("WRITES", frozenset({"position"})),
                        ("PROVIDES", frozenset({"texel_maping"})), ("READS", {"position"}),
                        ("FAMILY", "maps")):
        with pytest.raises(TypeError, match=attr):
            type("Bad", (Technique,), {attr: value})
    assert type("Outside", (Technique,), {}).FAMILY is None


class _FakeUniform:
    value = None


def test_bind_gbuffer_binds_declared_channels_on_their_units_and_refuses_others():
    """bind_gbuffer gives the declared channels units in the frame's channel order (the G-buffer
    first, compactly), sets the program's sampler uniforms to them, binds the frame's textures
    there, and refuses a program that samples an undeclared channel. No GL: stand-ins."""
    bound = []
    frame = types.SimpleNamespace(gbuffer_texture=lambda c: types.SimpleNamespace(
        use=lambda unit: bound.append((c, unit))))
    Demo = type("Demo", (Technique,), {"READS": frozenset({"ids", "position"})})
    tech = Demo()
    tech.frame = frame
    program = {"u_position": _FakeUniform(), "u_ids": _FakeUniform()}
    tech.bind_gbuffer(program)
    assert bound == [("position", 0), ("ids", 1)]
    assert (program["u_position"].value, program["u_ids"].value) == (0, 1)
    assert Demo.gbuffer_unit("ids") == 1
    with pytest.raises(RuntimeError, match="normal"):
        tech.bind_gbuffer({"u_normal": _FakeUniform()})


class _Watch:
    """Records, while active, the G-buffer channels bound (``.use`` of the frame's textures), the
    G-buffer samplers of every program the technique takes, and whether the frame's
    depth-stencil was lent (through ``depth_stencil_for`` or shared into a target)."""

    def __init__(self, monkeypatch, frame: Frame):
        self.bound: set[str] = set()
        self.sampled: set[str] = set()
        self.lent = False
        channels = {id(frame.gbuffer_texture(c)): c for c in GBUFFER_CHANNELS}
        use, lend, create, program = (moderngl.Texture.use, Frame.depth_stencil_for, targets.ScreenTarget.create.__func__,
                                      Technique.program)
        watch = self

        def texture_use(tex, *args, **kwargs):
            if id(tex) in channels:
                watch.bound.add(channels[id(tex)])
            return use(tex, *args, **kwargs)

        def depth_stencil_for(fr, technique):
            watch.lent = True
            return lend(fr, technique)

        def target_create(cls, size, colors, share_depth_stencil=None):
            if share_depth_stencil is frame.target:
                watch.lent = True
            return create(cls, size, colors, share_depth_stencil)

        def take_program(tech, *args, **kwargs):
            prog = program(tech, *args, **kwargs)
            watch.sampled |= {c for c in GBUFFER_CHANNELS if f"u_{c}" in prog}
            return prog

        monkeypatch.setattr(moderngl.Texture, "use", texture_use)
        monkeypatch.setattr(Frame, "depth_stencil_for", depth_stencil_for)
        monkeypatch.setattr(targets.ScreenTarget, "create", classmethod(target_create))
        monkeypatch.setattr(Technique, "program", take_program)


@pytest.mark.parametrize("name", list(REGISTRY))
def test_a_technique_reads_and_writes_only_what_it_declares(lab, monkeypatch, name):
    """Every registered technique at its defaults, on a scene whose lights it renders for, set
    up and rendered for each light: the G-buffer channels it binds and the ones its programs
    sample are exactly its READS, and it borrows the frame's depth-stencil exactly when WRITES
    says so."""
    cls = REGISTRY[name]
    frame = lab.frame(scene_for(cls), SMALL)
    watch = _Watch(monkeypatch, frame)
    for light in range(len(frame.scene.lights)):
        tech = cls()
        try:
            tech.prepare(frame, light)
            tech.render()
            tech.visibility()
        finally:
            tech.release()
    assert watch.sampled <= cls.READS, f"{name}'s programs sample {sorted(watch.sampled - cls.READS)} undeclared"
    assert watch.bound == cls.READS, f"{name} binds {sorted(watch.bound)}, declares {sorted(cls.READS)}"
    assert watch.lent == ("depth_stencil" in cls.WRITES), f"{name}: depth-stencil lent {watch.lent}, WRITES {cls.WRITES}"
