"""The rank agreement (Kendall τ) between each perceptual metric (:mod:`shadowlab.evaluation.perceptual`:
mean FLIP, SSIM) and the exact metrics, per scene family of a study: when does pixel error
predict what people see (issue 28)?

Within one scene every configuration is judged on the same picture, so the question is whether
the two metrics *order* the configurations alike; across scenes their values are not
comparable (a scene with more shadow has more error of every kind). So τ is taken per scene,
over its configurations (Kendall's τ-b, which counts ties, ``scipy.stats.kendalltau``), and a
family's τ is the mean over its scenes with three or more configurations. Each metric is
oriented so that larger is worse (SSIM as 1 − SSIM): τ = 1 means the perceptual metric ranks
the configurations exactly as the exact one does, 0 that the orders are unrelated, < 0 that
they are reversed. With n configurations a τ is a statement about n(n − 1)/2 pairs, so the
table gives the pairs too, and the most discordant pair of the family (the two configurations
the exact metric orders one way and the perceptual metric the other, by the largest product of
the two differences) — the case to look at.
"""
from __future__ import annotations

import math
import warnings

import numpy as np
import pandas as pd

from ..evaluation import perceptual
from ..analysis.aggregate import normalised, per_configuration

#: The exact metrics the perceptual ones are ranked against: the thresholded rate (hard scenes'
#: judged metric), the mean visibility error (soft scenes') and the shaded image's radiance error
#: (many-light scenes').
EXACT = ("error_rate", "visibility_mae", "radiance_error")
#: Fewest configurations of a scene for its τ to count (two give one pair: ±1 by construction).
MIN_CONFIGURATIONS = 3
#: Columns of :func:`rank_agreement`.
AGREEMENT_COLUMNS = ["scene_family", "perceptual", "exact", "tau", "tau_min", "tau_max", "scenes", "pairs",
                     "discordant_scene", "discordant_pair"]
#: τ at or above AGREE: the text says the metrics "agree"; from DISAGREE up to AGREE "partly
#: agree"; between −DISAGREE and DISAGREE "do not agree"; at or below −DISAGREE "reverse".
#: Kendall's τ of 0.7 means 85 % of the pairs are ordered alike.
AGREE, DISAGREE = 0.7, 0.3


def judged_configurations(results: pd.DataFrame) -> pd.DataFrame:
    """One row per (scene, configuration) that ran, the truth left out: the exact metrics pooled
    over lights (:func:`per_configuration`) and each available perceptual metric (one value per
    configuration: one shaded picture covers every light)."""
    cfg = per_configuration(results)
    cfg = cfg[~cfg["reference"].astype(bool)] if len(cfg) else cfg
    df = normalised(results) if len(results) else results
    present = [c for c in perceptual.PACKAGES if len(df) and c in df.columns]
    if not present or not len(cfg):
        return cfg.assign(**{c: np.nan for c in present})
    ok = df[df["status"] == "ok"]
    per = ok.groupby(["scene", "label"], sort=False)[present].first().reset_index()
    return cfg.merge(per, on=["scene", "label"], how="left")


def _oriented(values: pd.Series, column: str) -> np.ndarray:
    """``values`` as floats, larger = worse (SSIM turned into 1 − SSIM)."""
    v = pd.to_numeric(values, errors="coerce").to_numpy(dtype=float)
    return 1.0 - v if perceptual.WORSE_WHEN.get(column, 1) < 0 else v


def _tau(a: np.ndarray, b: np.ndarray) -> float:
    """Kendall's τ-b of two equally long arrays (NaN when either is constant)."""
    from scipy.stats import kendalltau

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a constant input: scipy warns and returns NaN
        return float(kendalltau(a, b).statistic)


def _most_discordant(g: pd.DataFrame, a: np.ndarray, b: np.ndarray) -> tuple[float, str]:
    """The pair of configurations ordered most strongly in opposite ways by ``a`` and ``b``:
    (−(Δa·Δb) scaled by the ranges, "X vs Y"), or (0, '') when no pair is discordant."""
    ra, rb = np.ptp(a) or 1.0, np.ptp(b) or 1.0
    best, text = 0.0, ""
    labels = list(g["short_label"])
    for i in range(len(a)):
        for j in range(i + 1, len(a)):
            score = -((a[i] - a[j]) / ra) * ((b[i] - b[j]) / rb)
            if score > best:
                worse_exact, other = (i, j) if a[i] > a[j] else (j, i)
                best, text = score, f"{labels[worse_exact]} worse than {labels[other]} by pixels, better by eye"
    return best, text


def rank_agreement(results: pd.DataFrame) -> pd.DataFrame:
    """Per scene family × perceptual metric × exact metric: the mean Kendall τ over the family's
    scenes (``tau``), its range (``tau_min``, ``tau_max``), the scenes with at least
    :data:`MIN_CONFIGURATIONS` configurations (``scenes``), the pairs of configurations behind
    it (``pairs``), and the most discordant pair with its scene. Empty (with the columns) when
    the study has no perceptual column."""
    cfg = judged_configurations(results)
    present = [c for c in perceptual.PACKAGES if c in cfg.columns and cfg[c].notna().any()]
    rows = []
    for family, fam in cfg.groupby("scene_family", sort=False):
        for pc in present:
            for ex in EXACT:
                taus, pairs, worst = [], 0, (0.0, "", "")
                for scene, g in fam.groupby("scene", sort=False):
                    g = g[g[pc].notna() & g[ex].notna()]
                    if len(g) < MIN_CONFIGURATIONS:
                        continue
                    a, b = _oriented(g[ex], ex), _oriented(g[pc], pc)
                    t = _tau(a, b)
                    if math.isnan(t):
                        continue
                    taus.append(t)
                    pairs += len(g) * (len(g) - 1) // 2
                    score, text = _most_discordant(g, a, b)
                    if score > worst[0]:
                        worst = (score, scene, text)
                if taus:
                    rows.append({"scene_family": family, "perceptual": pc, "exact": ex, "tau": float(np.mean(taus)),
                                 "tau_min": float(np.min(taus)), "tau_max": float(np.max(taus)),
                                 "scenes": len(taus), "pairs": pairs, "discordant_scene": worst[1],
                                 "discordant_pair": worst[2]})
    return pd.DataFrame(rows, columns=AGREEMENT_COLUMNS)


def agreement_word(tau: float) -> str:
    """τ in words: "agree", "partly agree", "do not agree" or "reverse"."""
    if tau >= AGREE:
        return "agree"
    if tau >= DISAGREE:
        return "partly agree"
    if tau > -DISAGREE:
        return "do not agree"
    return "reverse"


def agreement_sentences(table: pd.DataFrame) -> list[str]:
    """One sentence per scene family: whether its judged pixel metric ranks configurations as
    the perceptual metrics do, with τ, and the family's most discordant pair where they differ."""
    from ..analysis.aggregate import judged_metric

    out = []
    for family, g in table.groupby("scene_family", sort=False):
        judged = judged_metric(family)
        part = g[g["exact"] == judged]
        if not len(part):
            continue
        said = "; ".join(f"{r['perceptual']} τ = {r['tau']:.2f} ({agreement_word(r['tau'])})"
                         for _, r in part.iterrows())
        low = part.sort_values("tau").iloc[0]
        tail = (f" Most discordant: {low['discordant_pair']} on {low['discordant_scene']}."
                if low["tau"] < AGREE and low["discordant_pair"] else "")
        n = int(part["scenes"].max())
        out.append(f"{family or 'general'}: {judged} against what people see — {said}, over "
                   f"{n} scene{'' if n == 1 else 's'}.{tail}")
    return out
