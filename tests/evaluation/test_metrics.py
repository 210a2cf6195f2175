"""Metrics of docs/metrics.md on hand-made masks."""
from __future__ import annotations

import numpy as np
import pytest

from shadowlab.evaluation.metrics import compare, error_classes, shadow_boundary


def masks(h=20, w=30):
    truth = np.ones((h, w), np.float32)
    truth[5:15, 10:20] = 0.0  # a 10x10 shadow
    return truth, np.ones((h, w), bool)


def test_identical_is_perfect():
    truth, ev = masks()
    m = compare(truth, truth, ev)
    assert m["error_rate"] == 0 and m["false_shadow_rate"] == 0 and m["false_lit_rate"] == 0
    assert m["boundary_error_px"] == 0 and m["evaluated_pixels"] == 600
    assert m["truth_shadowed_pixels"] == 100 and m["truth_lit_pixels"] == 500


def test_rates_by_hand():
    truth, ev = masks()
    vis = truth.copy()
    vis[5:15, 10:12] = 1.0      # 20 false lit
    vis[0:2, 0:5] = 0.0         # 10 false shadow
    m = compare(vis, truth, ev)
    assert m["false_lit_pixels"] == 20 and m["false_shadow_pixels"] == 10
    assert m["false_lit_rate"] == pytest.approx(20 / 100)
    assert m["false_shadow_rate"] == pytest.approx(10 / 500)
    assert m["error_rate"] == pytest.approx(30 / 600)


def brute_force_boundary(shadowed):
    """Boundary pixels by docs/metrics.md's words, with plain loops: a pixel with a 4-neighbour on the
    other side (every pixel evaluated)."""
    h, w = shadowed.shape
    out = set()
    for r in range(h):
        for c in range(w):
            for dr, dc in ((0, 1), (1, 0), (0, -1), (-1, 0)):
                rr, cc = r + dr, c + dc
                if 0 <= rr < h and 0 <= cc < w and shadowed[rr, cc] != shadowed[r, c]:
                    out.add((r, c))
    return out


def nearest(p, pixels):
    return min(np.hypot(p[0] - q[0], p[1] - q[1]) for q in pixels)


def test_shifted_boundary_distance_equals_brute_force():
    truth, ev = masks()
    vis = np.ones_like(truth)
    vis[5:15, 13:23] = 0.0  # the same square moved 3 px right
    m = compare(vis, truth, ev)
    vb, gb = brute_force_boundary(vis < 0.5), brute_force_boundary(truth < 0.5)
    d_vg = [nearest(p, gb) for p in vb]
    both = d_vg + [nearest(p, vb) for p in gb]
    assert m["boundary_pixels"] == len(vb)
    assert m["boundary_error_px"] == pytest.approx(np.mean(d_vg), rel=1e-12)
    assert m["boundary_hausdorff_px"] == pytest.approx(max(both), rel=1e-12) == 3.0
    assert m["boundary_p95_px"] == pytest.approx(np.percentile(both, 95), rel=1e-12)


def test_not_evaluated_pixels_do_not_count():
    truth, ev = masks()
    vis = np.zeros_like(truth)
    ev[:] = False
    ev[5:15, 10:20] = True  # only the true shadow is evaluated
    m = compare(vis, truth, ev)
    assert m["evaluated_pixels"] == 100 and m["error_rate"] == 0
    assert m["false_shadow_rate"] == 0 and m["truth_lit_pixels"] == 0  # empty denominator -> 0


def test_empty_and_all_shadow():
    ev = np.ones((10, 10), bool)
    lit, dark = np.ones((10, 10), np.float32), np.zeros((10, 10), np.float32)
    m = compare(dark, dark, ev)
    assert m["error_rate"] == 0 and m["false_lit_rate"] == 0 and m["boundary_error_px"] == 0
    m = compare(dark, lit, ev)
    assert m["error_rate"] == 1.0 and m["false_shadow_rate"] == 1.0 and m["false_lit_rate"] == 0.0
    m = compare(lit, lit, np.zeros((10, 10), bool))
    assert m["evaluated_pixels"] == 0 and m["error_rate"] == 0
    # one side has a boundary, the other none: worst case, the image diagonal
    half = lit.copy(); half[:, :5] = 0
    assert compare(half, lit, ev)["boundary_error_px"] == pytest.approx(np.hypot(10, 10))


def test_fractional_visibility_mae():
    truth, ev = masks()
    vis = np.clip(truth + 0.25, 0, 1)
    m = compare(vis, truth, ev)
    assert m["error_rate"] == 0
    assert m["visibility_mae"] == pytest.approx(0.25 * 100 / 600)


def test_boundary_and_classes():
    truth, ev = masks()
    b = shadow_boundary(truth < 0.5, ev)
    assert b[5, 10] and b[5, 9] and not b[10, 15] and not b[0, 0]
    vis = truth.copy(); vis[0, 0] = 0; vis[10, 15] = 1
    cls = error_classes(vis, truth, ev)
    assert cls[0, 0] == 3 and cls[10, 15] == 4 and cls[1, 1] == 1 and cls[6, 11] == 2


def test_contact_pixels_need_touching_neighbours():
    from shadowlab.evaluation.metrics import contact_pixels

    obj = np.zeros((6, 6), np.int32)
    obj[:, 3:] = 1
    pos = np.zeros((6, 6, 3))
    pos[..., 0] = np.arange(6)[None, :] * 0.01
    foot = np.full((6, 6), 0.01)
    receivers = obj == 0
    touching = contact_pixels(obj, pos, foot, receivers)
    assert touching[:, 2].all() and touching.sum() == 6
    pos[:, 3:, 2] = 5.0  # object 1 is far behind: it hides nothing, touches nothing
    assert not contact_pixels(obj, pos, foot, receivers).any()


def test_contact_gap_is_band_width_in_pixels():
    from shadowlab.evaluation.metrics import contact_gap

    truth = np.ones((20, 20), np.float32)
    truth[:, 5:15] = 0.0                    # shadow beside a contact line at column 5
    contact = np.zeros((20, 20), bool)
    contact[:, 5] = True
    ev = np.ones((20, 20), bool)
    vis = truth.copy()
    assert contact_gap(vis, truth, ev, contact) == 0.0
    vis[:, 5:8] = 1.0                       # a 3-pixel lit gap along the whole contact
    assert contact_gap(vis, truth, ev, contact) == pytest.approx(3.0)
    assert contact_gap(vis, truth, ev, np.zeros_like(contact)) == 0.0
