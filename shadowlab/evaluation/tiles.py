"""Per-tile error sums of a visibility image against the truth: what the study's significance
tests resample (docs/metrics.md#verdicts-and-significance).

Errors of neighbouring pixels are not independent — a misplaced shadow edge is wrong along its
whole length, an acne pattern covers a receiver — so a test that resamples single pixels would
call a one-edge difference certain. Tiles of :data:`TILE` × :data:`TILE` pixels are the blocks of
a block bootstrap instead (Künsch 1989; Lahiri 2003, ch. 2): errors are correlated within a tile
and, to a first approximation, not across tiles. The numerators of both judged metrics are sums
over pixels, so per-tile sums are all a paired test of two configurations on the same pixels
needs.
"""
from __future__ import annotations

import numpy as np

from .metrics import THRESHOLD

#: Tile side, pixels: a few pixels wider than the penumbra and aliasing bands a technique's error
#: comes in at the lab's usual 320×240 to 640×480, so that one artefact falls in few tiles.
TILE = 16

#: Rows of :func:`tile_sums`' result.
EVALUATED, WRONG, ABS_DIFF = 0, 1, 2


def tile_sums(vis: np.ndarray, truth: np.ndarray, evaluated: np.ndarray, tile: int = TILE) -> np.ndarray:
    """Per tile of ``tile`` × ``tile`` pixels (the last row and column of tiles may be smaller):
    the evaluated pixels, the wrong ones (V and G thresholded at 0.5, as ``error_rate`` counts
    them) and the sum of |V − G| over the evaluated ones (``visibility_mae``'s numerator).
    ``vis``, ``truth``: float (H, W); ``evaluated``: bool (H, W). Returns float32 (3, N), N the
    tiles that hold an evaluated pixel (tiles without one say nothing), in row-major order."""
    ev = evaluated.astype(bool)
    v = np.nan_to_num(np.asarray(vis, dtype=np.float64), nan=1.0)
    g = np.nan_to_num(np.asarray(truth, dtype=np.float64), nan=1.0)
    wrong = ((v < THRESHOLD) != (g < THRESHOLD)) & ev
    diff = np.where(ev, np.abs(v - g), 0.0)
    h, w = ev.shape
    ty, tx = -(-h // tile), -(-w // tile)

    def per_tile(a: np.ndarray) -> np.ndarray:
        padded = np.zeros((ty * tile, tx * tile), np.float64)
        padded[:h, :w] = a
        return padded.reshape(ty, tile, tx, tile).sum(axis=(1, 3)).ravel()

    sums = np.stack([per_tile(ev.astype(np.float64)), per_tile(wrong.astype(np.float64)), per_tile(diff)])
    return sums[:, sums[EVALUATED] > 0].astype(np.float32)
