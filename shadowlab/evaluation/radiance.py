"""The error people see in the shaded image: radiance metrics over every light at once.

The per-light columns judge each light's visibility on its own; a shadow budget's cost, though, is
in the picture — a dropped shadow brightens it, a dropped light darkens it — and a light's error
matters as much as its light does. These columns compare the shaded image of a configuration
(every light, each with the configuration's visibility, and its budget's ``weight``: 0 where a
light is not drawn) with the truth's (every light, every shadow exact), in luminance (Rec. 709 of
linear RGB), over covered pixels, through the per-light terms of :mod:`shadowlab.lighting.radiance`.

With L and L* a pixel's luminance and the truth's, the error is relative to max(L*, τ), where the
floor τ = :data:`DARK_FLOOR` × the truth image's mean luminance keeps the nearly black pixels of a
night scene from dominating (a relative error of a pixel with no light is undefined):

- ``radiance_error``: the mean of |L − L*| / max(L*, τ);
- ``radiance_error_p95``: its 95th percentile;
- ``radiance_bias``: the mean of (L − L*) / max(L*, τ) — positive where dropped shadows brighten,
  negative where dropped lights darken;
- per light, ``radiance_error_light``: the mean of |L_i − L*_i| / max(L*, τ) — the light's own
  error weighted by its contribution (they sum to at least ``radiance_error``), and
  ``light_share``: the light's share of the truth image's luminance.

Off a light's evaluated pixels (facing away, outside its footprint) its visibility does not
matter and counts as 1 for both images.
"""
from __future__ import annotations

import numpy as np

from ..lighting.radiance import RadianceTerms

#: The dark floor τ of the relative error, as a share of the truth image's mean luminance.
DARK_FLOOR = 0.05
#: The configuration-wide radiance columns (every row of the configuration carries them).
IMAGE_COLUMNS = ("radiance_error", "radiance_error_p95", "radiance_bias")
#: The per-light radiance columns.
LIGHT_COLUMNS = ("radiance_error_light", "light_share")


def _visibility(frame, terms: RadianceTerms, index: int, image: np.ndarray) -> np.ndarray:
    """A light's visibility as a compact array, 1 off its evaluated pixels."""
    return np.where(frame.slot(index).evaluated, terms.compact(image), 1.0)


def radiance_columns(frame, visibilities, truth, weights=None, terms: RadianceTerms | None = None
                     ) -> tuple[dict, list[dict]]:
    """The radiance columns of a configuration on ``frame``: ``visibilities`` and ``truth`` one
    image (height, width) per scene light, ``weights`` one image or None per light (None: 1).
    Returns (the image-wide columns, one dict of per-light columns per light). ``terms``: the
    frame's :class:`RadianceTerms`, to share them between configurations."""
    terms = terms or RadianceTerms(frame)
    n = len(frame.scene.lights)
    if len(visibilities) != n or len(truth) != n:
        raise ValueError(f"need one visibility image per light ({n}), got {len(visibilities)} and {len(truth)}")
    weights = list(weights) if weights is not None else [None] * n
    per_truth, per_conf = [], []
    for i in range(n):
        per_truth.append(terms.light_radiance(i, _visibility(frame, terms, i, truth[i])))
        w = weights[i]
        per_conf.append(terms.light_radiance(i, _visibility(frame, terms, i, visibilities[i]),
                                             None if w is None else terms.compact(w)))
    if not len(frame.pixel_index):
        return {c: 0.0 for c in IMAGE_COLUMNS}, [{c: 0.0 for c in LIGHT_COLUMNS} for _ in range(n)]
    total_truth = np.sum(per_truth, axis=0)
    total = np.sum(per_conf, axis=0)
    floor = DARK_FLOOR * max(float(total_truth.mean()), 1e-12)
    denom = np.maximum(total_truth, floor)
    rel = (total - total_truth) / denom
    image = {"radiance_error": float(np.abs(rel).mean()), "radiance_error_p95": float(np.percentile(np.abs(rel), 95)),
             "radiance_bias": float(rel.mean())}
    all_light = float(total_truth.sum())
    lights = [{"radiance_error_light": float((np.abs(c - t) / denom).mean()),
               "light_share": float(t.sum() / all_light) if all_light > 0 else 0.0}
              for c, t in zip(per_conf, per_truth)]
    return image, lights


def luminance_image(frame, visibilities, weights=None, terms: RadianceTerms | None = None) -> np.ndarray:
    """The shaded image's luminance, float32 (height, width), NaN where nothing is seen: what the
    radiance metrics compare (for pictures of a configuration's radiance error)."""
    terms = terms or RadianceTerms(frame)
    n = len(frame.scene.lights)
    weights = list(weights) if weights is not None else [None] * n
    total = np.zeros(len(frame.pixel_index))
    for i in range(n):
        w = weights[i]
        total += terms.light_radiance(i, _visibility(frame, terms, i, visibilities[i]),
                                      None if w is None else terms.compact(w))
    return frame.to_image(total.astype(np.float32))
