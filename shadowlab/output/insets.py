"""Zoom insets at the same places for every configuration of a scene (docs/architecture.md#pages-shadowlaboutput): the regions
where the configurations are wrong most, over all of them together, so that a reader compares
techniques on the same pixels instead of each one's own worst corner.

A region is a square window (clipped to the image) chosen greedily on the pooled wrong-pixel
count of every configuration (:func:`common_insets`), then centred on the wrong pixels inside
it. The page draws each region's box on the full images and shows the region magnified with
nearest-neighbour sampling (CSS ``image-rendering: pixelated`` on the full image, so flipping an
image flips its insets too and no crop files are needed).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..evaluation import metrics

#: Insets per scene.
INSET_COUNT = 2
#: An inset's side: this fraction of the image's smaller side, at least MIN_INSET pixels.
INSET_FRACTION, MIN_INSET = 1 / 8, 16


@dataclass(frozen=True)
class Inset:
    """One zoom region: ``box`` = (x0, y0, x1, y1) in pixels (x1, y1 exclusive; row 0 = top) of
    an image ``size`` = (width, height); ``wrong`` = wrong pixels inside it, summed over every
    configuration; ``number`` = its label on the page (1, 2, ...)."""

    box: tuple[int, int, int, int]
    size: tuple[int, int]
    wrong: int
    number: int

    def box_style(self) -> str:
        """CSS placing the region's outline over the full image (percentages of its size)."""
        (x0, y0, x1, y1), (w, h) = self.box, self.size
        return (f"left:{100 * x0 / w:.3f}%;top:{100 * y0 / h:.3f}%;"
                f"width:{100 * (x1 - x0) / w:.3f}%;height:{100 * (y1 - y0) / h:.3f}%")

    def zoom_style(self, src: str) -> str:
        """CSS showing the region of image ``src`` magnified to fill its box: the background is
        scaled by image / region and positioned so the region's corner meets the box's corner
        (a background position of p % puts the image's p % point on the box's p % point)."""
        (x0, y0, x1, y1), (w, h) = self.box, self.size
        bw, bh = x1 - x0, y1 - y0
        px = 100 * x0 / (w - bw) if w > bw else 0.0
        py = 100 * y0 / (h - bh) if h > bh else 0.0
        return (f"background-image:url('{src}');background-size:{100 * w / bw:.3f}% {100 * h / bh:.3f}%;"
                f"background-position:{px:.3f}% {py:.3f}%;aspect-ratio:{bw}/{bh}")


def worst_region(weight: np.ndarray, window: int) -> tuple[tuple[int, int, int, int], float]:
    """The ``window`` x ``window`` box (clipped to the image) holding the most of ``weight``
    (H, W; a bool mask counts pixels), row 0 = top: ((x0, y0, x1, y1) with x1, y1 exclusive,
    its sum). Where several boxes tie, the first in row-major order."""
    h, w = weight.shape
    wy, wx = min(window, h), min(window, w)
    # window sums from the summed-area table
    sat = np.zeros((h + 1, w + 1), np.float64)
    sat[1:, 1:] = np.cumsum(np.cumsum(weight.astype(np.float64), 0), 1)
    sums = sat[wy:, wx:] - sat[:-wy, wx:] - sat[wy:, :-wx] + sat[:-wy, :-wx]
    y0, x0 = np.unravel_index(int(np.argmax(sums)), sums.shape)
    return (int(x0), int(y0), int(x0 + wx), int(y0 + wy)), float(sums[y0, x0])


def inset_window(width: int, height: int) -> int:
    """The side of an inset window for a ``width`` × ``height`` image."""
    return max(MIN_INSET, int(round(min(width, height) * INSET_FRACTION)))


def wrong_pixels(mask: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """Bool (H, W): pixels where a configuration's visibility ``mask`` and the truth's (float
    (H, W), NaN off the evaluated pixels, as in masks.npz) disagree after thresholding
    (:func:`shadowlab.evaluation.metrics.error_classes`: false shadow or false lit)."""
    evaluated = ~np.isnan(truth)
    classes = metrics.error_classes(np.nan_to_num(mask, nan=1.0), np.nan_to_num(truth, nan=1.0), evaluated)
    return (classes == 3) | (classes == 4)


def _centred(box, weight: np.ndarray) -> tuple[int, int, int, int]:
    """``box`` moved (same size, inside the image) so its centre is the ``weight``-weighted
    centroid of the pixels it holds."""
    x0, y0, x1, y1 = box
    part = weight[y0:y1, x0:x1]
    total = float(part.sum())
    if total <= 0:
        return box
    h, w = weight.shape
    bw, bh = x1 - x0, y1 - y0
    ys, xs = np.mgrid[0:bh, 0:bw]
    cx = x0 + float((xs * part).sum()) / total + 0.5
    cy = y0 + float((ys * part).sum()) / total + 0.5
    nx0 = int(np.clip(round(cx - bw / 2), 0, w - bw))
    ny0 = int(np.clip(round(cy - bh / 2), 0, h - bh))
    return nx0, ny0, nx0 + bw, ny0 + bh


def common_insets(truth: np.ndarray, masks: list[np.ndarray], count: int = INSET_COUNT) -> list[Inset]:
    """Up to ``count`` regions where the configurations' ``masks`` (float (H, W), NaN off the
    evaluated pixels) are wrong against ``truth``, for as many of them as possible: the window
    (:func:`inset_window`) holding the largest summed *share* of each configuration's wrong
    pixels, centred on them; its pixels are then removed and the next window chosen. No region
    where nothing is wrong (an empty list when every configuration is right everywhere).

    Why shares, not counts: one configuration that is wrong over a large area (a blob shadow, a
    planar shadow that misses a receiver) would otherwise pull every window onto its own error,
    where the others are right; weighting each configuration's wrong pixels by 1 / its total
    makes each configuration count the same, so the windows land where several go wrong."""
    h, w = truth.shape
    pooled = np.zeros((h, w), np.int64)
    share = np.zeros((h, w), np.float64)
    for m in masks:
        wrong = wrong_pixels(m, truth)
        pooled += wrong
        if wrong.any():
            share += wrong / float(wrong.sum())
    window = inset_window(w, h)
    out: list[Inset] = []
    left = share
    for k in range(count):
        box, score = worst_region(left, window)
        if score <= 0:
            break
        box = _centred(box, left)
        x0, y0, x1, y1 = box
        out.append(Inset(box, (w, h), int(pooled[y0:y1, x0:x1].sum()), k + 1))
        left[y0:y1, x0:x1] = 0
    return out
