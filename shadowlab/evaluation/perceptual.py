"""Perceptual metrics beside the exact ones: mean FLIP and SSIM of a configuration's shaded
image against the truth's (issue 28), from optional packages (``pip install
'shadowlab[perceptual]'``).

The exact metrics (:mod:`shadowlab.evaluation.metrics`) count wrong visibility; people look at shaded
pictures, where an error's visibility depends on its contrast, size and surroundings. Two
standard image metrics judge the same pair of pictures the run directory writes — the shaded
image of every light's visibility (:class:`shadowlab.gpu.shading.ShadingPass`), sRGB-encoded for
display (:func:`shadowlab.output.pictures.to_display`), the truth's against the configuration's:

- ``flip_mean``: the mean of the LDR FLIP error map (Andersson, Nilsson, Akenine-Möller,
  Oskarsson, Åström & Fairchild, "FLIP: A Difference Evaluator for Alternating Images", HPG
  2020; package ``flip-evaluator``, NVIDIA's, which recommends the mean over the median), at the
  package's default 67 pixels per degree; 0 = identical, larger = worse;
- ``ssim``: the mean SSIM (Wang, Bovik, Sheikh & Simoncelli, IEEE TIP 2004; scikit-image's
  ``structural_similarity``) with the paper's settings — Gaussian window σ = 1.5, population
  covariances, data range 1, the three channels averaged (Nilsson & Akenine-Möller,
  "Understanding SSIM", 2020, on why the settings must be stated); 1 = identical, smaller =
  worse.

Both maps are averaged over the covered pixels only (the background is the same flat colour
in both pictures and would dilute the mean by the share of sky). Where a package is missing
its column is absent and :func:`missing_note` says so; nothing else changes.
"""
from __future__ import annotations

import importlib.util

import numpy as np

#: The perceptual columns, each with the package that computes it.
PACKAGES = {"flip_mean": "flip_evaluator", "ssim": "skimage"}
#: The pip extra that installs them.
EXTRA = "shadowlab[perceptual]"
#: SSIM's Gaussian window (Wang et al. 2004, §III-C).
SSIM_SIGMA = 1.5
#: Direction of each column: +1 when larger is worse (an error), −1 when larger is better.
WORSE_WHEN = {"flip_mean": 1, "ssim": -1}


def available() -> list[str]:
    """The perceptual columns whose package is installed, in :data:`PACKAGES` order."""
    return [col for col, mod in PACKAGES.items() if importlib.util.find_spec(mod) is not None]


def missing_note() -> str | None:
    """One line for a run's or study's notes when a perceptual column cannot be computed
    (None when every one can)."""
    missing = [col for col in PACKAGES if col not in available()]
    if not missing:
        return None
    return (f"perceptual metrics {', '.join(missing)} not computed: their packages are not installed "
            f"(pip install '{EXTRA}')")


def compare_pictures(test: np.ndarray, reference: np.ndarray, covered: np.ndarray) -> dict[str, float]:
    """``{column: value}`` for every available perceptual column: ``test`` against ``reference``,
    both sRGB-encoded RGB float (H, W, 3) in [0, 1] (the pictures of
    :func:`shadowlab.output.pictures.to_display`), averaged over ``covered`` (H, W) bool."""
    if test.shape != reference.shape or test.shape[:2] != covered.shape:
        raise ValueError(f"pictures of shapes {test.shape} and {reference.shape} with a mask of {covered.shape}")
    if not covered.any():
        return {col: float("nan") for col in available()}
    a = np.ascontiguousarray(np.clip(reference, 0.0, 1.0), np.float32)
    b = np.ascontiguousarray(np.clip(test, 0.0, 1.0), np.float32)
    out = {}
    for col in available():
        error_map = _flip_map(a, b) if col == "flip_mean" else _ssim_map(a, b)
        out[col] = float(np.mean(error_map[covered], dtype=np.float64))
    return out


def _flip_map(reference: np.ndarray, test: np.ndarray) -> np.ndarray:
    """The LDR FLIP error map (H, W) of sRGB pictures in [0, 1]."""
    import flip_evaluator

    error_map, _, _ = flip_evaluator.evaluate(reference, test, "LDR", inputsRGB=True, applyMagma=False,
                                              computeMeanError=False)
    return np.asarray(error_map, np.float64).reshape(reference.shape[:2])


def _ssim_map(reference: np.ndarray, test: np.ndarray) -> np.ndarray:
    """The SSIM map (H, W) of two RGB pictures in [0, 1], the channels averaged."""
    from skimage.metrics import structural_similarity

    _, full = structural_similarity(reference, test, channel_axis=2, data_range=1.0, full=True,
                                    gaussian_weights=True, sigma=SSIM_SIGMA, use_sample_covariance=False)
    return np.asarray(full, np.float64).mean(axis=2)
