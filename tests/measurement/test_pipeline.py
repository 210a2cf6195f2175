"""The stage contract (docs/architecture.md–3): techniques read the frame and change nothing of it but what
they declare; the metric table is the docs/contracts.md#run-directory contract; the one loop's rows are consistent."""
from __future__ import annotations

import numpy as np
import pytest

from shadowlab.gpu import gl, targets
from shadowlab.evaluation.metrics import COLUMNS, CONTRACT_COLUMNS, compare
from shadowlab.measurement.pipeline import compare_frame, measure
from shadowlab.techniques import REGISTRY, from_spec

from helpers import SMALL, scene_for

SIZE = SMALL


def gbuffer_bytes(frame):
    return [t.read() for t in (frame.tex_position, frame.tex_normal, frame.tex_ids)]


@pytest.mark.slow  # inner-loop budget (issue 36): among the slowest; make test runs it
@pytest.mark.parametrize("name", list(REGISTRY))
def test_techniques_leave_the_gbuffer_untouched(lab, name):
    """Every registered technique, run on a frame, leaves its G-buffer textures, exact points
    and evaluated masks bit for bit as they were (the next technique reads them); techniques
    that need an area light run on an area-light scene, those that need a directional light on
    a sun scene."""
    cls = REGISTRY[name]
    scene = scene_for(cls)
    frame = lab.frame(scene, SIZE)
    last = len(frame.scene.lights) - 1
    before = gbuffer_bytes(frame), frame.compact_position.copy(), frame.evaluated(last).copy()
    for light in range(len(frame.scene.lights)):
        measure(from_spec(name), frame, light, repeat=1, warmup=0)
    after = gbuffer_bytes(frame), frame.compact_position, frame.evaluated(last)
    assert before[0] == after[0]
    assert np.array_equal(before[1], after[1]) and np.array_equal(before[2], after[2])


def test_only_declared_techniques_get_the_depth_stencil(lab):
    frame = lab.frame("box_on_plane", SIZE)
    for name, cls in REGISTRY.items():
        if "depth_stencil" in cls.WRITES:
            assert frame.depth_stencil_for(cls()) is frame.target
        else:
            with pytest.raises(RuntimeError, match="WRITES"):
                frame.depth_stencil_for(cls())


def test_metric_table_holds_the_design_contract():
    assert CONTRACT_COLUMNS == ["scene", "light", "technique", "params", "width", "height", "evaluated_pixels",
                                "error_rate", "false_shadow_rate", "false_lit_rate", "boundary_error_px",
                                "time_ms_median", "time_ms_iqr"]
    names = [c.name for c in COLUMNS]
    assert len(names) == len(set(names))
    metric_names = {c.name for c in COLUMNS if c.compute is not None}
    ones = np.ones((4, 4), np.float32)
    parts = {"base": ones, "contact_shadow": ones, "classifier": ones}  # every component a metric judges
    assert set(compare(ones, ones, ones > 0, contact=ones < 0, overlap=ones < 0, components=parts)) == metric_names
    # without the components, the metrics that judge them are left out
    assert not {"seam_pixels", "classifier_error_pixels"} & set(compare(ones, ones, ones > 0, ones < 0, ones < 0))


def test_comparison_rows_follow_the_table_and_judge_against_the_truth(lab):
    frame = lab.frame("multi_light", SIZE)
    result = compare_frame(frame, [from_spec("shadow_map:resolution=256")], repeat=1, warmup=0)
    df = result.rows
    assert list(df.columns[: len(CONTRACT_COLUMNS)]) == CONTRACT_COLUMNS
    assert len(df) == 2 * len(frame.scene.lights) and df["reference"].sum() == len(frame.scene.lights)
    for li, m in enumerate(result.results[0]):
        row = df[(df["light"] == li) & ~df["reference"]].iloc[0]
        assert row["evaluated_pixels"] == frame.evaluated(li).sum()  # each light judged on its own pixels
        truth = result.truth[li].visibility
        assert row["error_rate"] == compare(m.visibility, truth, frame.evaluated(li))["error_rate"]
    assert (df.loc[df["reference"], "error_rate"] == 0).all()
    gl.check_errors()


def test_a_setup_that_fails_half_way_is_released(lab, registry_snapshot):
    """GL objects a technique registered before its setup failed are freed by the pipeline (the
    textures deleted, the framebuffers gone), and the technique can be set up again."""
    from OpenGL import GL

    from shadowlab.techniques.maps.shadow_map import ShadowMap

    made = []

    class Failing(ShadowMap):
        name = "failing_shadow_map_test"

        def setup(self, frame, slot):
            super().setup(frame, slot)
            made.extend(self._owned)
            raise RuntimeError("boom after the atlas was made")

    frame = lab.frame("box_on_plane", SMALL)
    tech = from_spec("failing_shadow_map_test")
    with pytest.raises(RuntimeError, match="boom"):
        measure(tech, frame, 0, repeat=1, warmup=0)
    depth = [o for o in made if isinstance(o, targets.DepthTexture)]
    assert depth and not any(GL.glIsTexture(o.glo) for o in depth)
    assert tech._owned == [] and len(made) >= 4
    m = measure(from_spec("shadow_map"), frame, 0, repeat=1, warmup=0)
    assert m.stats["faces"] == 1


def test_a_program_held_by_a_live_technique_is_not_shared(lab):
    """Programs are compiled once and shared; a second technique set up on the same program
    while the first still holds it is an error, not a render with the first one's uniforms."""
    from shadowlab.techniques.maps.toolkit import ATLAS_DEFINES

    frame = lab.frame("box_on_plane", SMALL)
    alone = measure(from_spec("shadow_map"), frame, 0, repeat=1, warmup=0).visibility
    first, second = from_spec("shadow_map"), from_spec("shadow_map:bias=0.01")
    first.prepare(frame, 0)
    try:
        with pytest.raises(RuntimeError, match="held by shadow_map"):
            second.prepare(frame, 0)
        second.release()
        with pytest.raises(RuntimeError, match="held by shadow_map"):  # the lookup, whose uniforms matter
            second.program("shadow_lookup.glsl", defines=ATLAS_DEFINES)
        first.render()  # the refused attempts left the first one's uniforms alone
        assert np.array_equal(first.visibility(), alone)
    finally:
        first.release()
    second.prepare(frame, 0)  # free again once the first is released
    second.release()


def test_the_footprint_is_left_out_when_not_asked_for(lab):
    """``measure(footprint=False)`` (the viewer, outside its footprint view): no texel-footprint
    image or columns, and the same visibility as with them."""
    from shadowlab.evaluation import texel_footprint

    frame = lab.frame("box_on_plane", SMALL)
    with_fp = measure(from_spec("shadow_map"), frame, 0, repeat=1, warmup=0, count=False)
    without = measure(from_spec("shadow_map"), frame, 0, repeat=1, warmup=0, count=False, footprint=False)
    assert with_fp.footprint is not None and set(texel_footprint.COLUMNS) <= set(with_fp.stats)
    assert without.footprint is None and not set(texel_footprint.COLUMNS) & set(without.stats)
    assert np.array_equal(with_fp.visibility, without.visibility)
