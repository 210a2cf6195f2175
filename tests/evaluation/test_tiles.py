"""Per-tile error sums (shadowlab.evaluation.tiles) on a hand-made image, and the edge error rate
and truth boundary count of metrics.compare on a square shadow counted by hand."""
import numpy as np
import pytest

from shadowlab.evaluation import metrics
from shadowlab.evaluation.tiles import ABS_DIFF, EVALUATED, TILE, WRONG, tile_sums


def _image():
    """40 wide × 20 high: tiles of 16 → 2 rows (16, 4 pixels high) × 3 columns (16, 16, 8 wide).

    Tile (row 0, col 1) has no evaluated pixel; tile (1, 0) has a 4×4 block not evaluated. The
    truth is lit except a 4×4 shadow in tile (0, 0)."""
    h, w = 20, 40
    truth = np.ones((h, w))
    truth[2:6, 2:6] = 0.0
    vis = truth.copy()
    ev = np.ones((h, w), bool)
    ev[0:16, 16:32] = False          # tile (0, 1): nothing evaluated -> dropped
    ev[16:20, 0:4] = False           # tile (1, 0): 64 - 16 = 48 evaluated
    # tile (0, 0): NaN visibility counts as lit -> wrong where the truth is shadowed, |V-G| = 1
    vis[2, 2] = np.nan
    vis[3, 3] = 0.4                  # shadowed like the truth: right, |V-G| = 0.4
    # tile (0, 1): wrong, but not evaluated
    vis[5, 20] = 0.0
    # tile (0, 2): a false shadow (|V-G| 0.8) and a right lit pixel (0.4)
    vis[0, 35] = 0.2
    vis[1, 35] = 0.6
    # tile (1, 0): wrong, but not evaluated
    vis[17, 1] = 0.0
    # tile (1, 1): exactly at the threshold is lit: right, |V-G| = 0.5
    vis[18, 20] = 0.5
    # tile (1, 2), the last (partial) tile's last pixel: a false shadow
    vis[19, 39] = 0.0
    return vis, truth, ev


def test_tile_sums_counts_every_tile_exactly():
    vis, truth, ev = _image()
    t = tile_sums(vis, truth, ev)
    assert TILE == 16
    assert t.dtype == np.float32 and t.shape == (3, 5)   # 6 tiles, the one without an evaluated pixel dropped
    # row-major: (0,0), (0,2), (1,0), (1,1), (1,2)
    assert t[EVALUATED].tolist() == [256, 128, 48, 64, 32]
    assert t[WRONG].tolist() == [1, 1, 0, 0, 1]
    assert t[ABS_DIFF] == pytest.approx([1.4, 1.2, 0.0, 0.5, 1.0], abs=1e-6)
    # the sums are the image's: every evaluated pixel once
    assert t[EVALUATED].sum() == ev.sum()


def test_tile_sums_wrong_total_equals_the_evaluation():
    vis, truth, ev = _image()
    e = metrics.Evaluation(vis, truth, ev)
    assert e.false_shadow == 2 and e.false_lit == 1
    assert tile_sums(vis, truth, ev)[WRONG].sum() == e.false_shadow + e.false_lit
    # and with another tile size (a 7×7 grid does not divide 40×20 either)
    t7 = tile_sums(vis, truth, ev, tile=7)
    assert t7[WRONG].sum() == 3 and t7[EVALUATED].sum() == ev.sum()
    assert t7[ABS_DIFF].sum() == pytest.approx(np.abs(np.nan_to_num(vis, nan=1.0) - truth)[ev].sum(), abs=1e-5)


def test_tile_sums_of_identical_images_are_zero_errors():
    _, truth, ev = _image()
    t = tile_sums(truth, truth, ev)
    assert not t[WRONG].any() and not t[ABS_DIFF].any() and t.shape == (3, 5)
    assert tile_sums(truth, truth, np.zeros_like(ev)).shape == (3, 0)


def _square():
    """10×10, all evaluated; the truth shadows the 4×4 square rows 3-6, cols 3-6. Its boundary by
    hand: the square's 12 rim pixels plus the 4 × 4 lit pixels 4-adjacent to its sides = 28."""
    truth = np.ones((10, 10))
    truth[3:7, 3:7] = 0.0
    return truth, np.ones((10, 10), bool)


def test_edge_error_rate_on_a_square_shadow():
    truth, ev = _square()
    vis = truth.copy()
    vis[3:7, 7] = 0.0                  # the shadow one column too wide: 4 false shadow pixels
    m = metrics.compare(vis, truth, ev)
    assert m["truth_boundary_pixels"] == 28
    assert m["edge_error_rate"] == pytest.approx(4 / 28)
    assert m["error_rate"] == pytest.approx(4 / 100)
    exact = metrics.compare(truth, truth, ev)
    assert exact["truth_boundary_pixels"] == 28 and exact["edge_error_rate"] == 0.0


def test_edge_error_rate_counts_only_evaluated_boundary_and_is_zero_without_one():
    truth, ev = _square()
    ev = ev.copy()
    ev[:, 8:] = False                  # columns 8-9 not evaluated: the boundary is unchanged (col 7 is)
    ev[0:5, :] = False                 # rows 0-4 not evaluated: the square's top rows and the pixels above go
    # left: square rows 5-6 (cols 3-6). Rim: row 6 all 4, row 5 cols 3 and 6 -> 6 (row 5 cols 4,5 have
    # evaluated neighbours only inside the square); lit: cols 2 and 7 on rows 5-6 (4) and row 7 cols 3-6 (4)
    m = metrics.compare(truth, truth, ev)
    assert m["truth_boundary_pixels"] == 14
    lit = np.ones((10, 10))
    m = metrics.compare(lit * 0.0, lit, np.ones((10, 10), bool))   # the truth has no shadow: no boundary
    assert m["truth_boundary_pixels"] == 0 and m["edge_error_rate"] == 0.0 and m["error_rate"] == 1.0
