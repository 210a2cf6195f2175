"""Does one global setting exist? Exact answers for the bias, from per-scene exact curves.

Each scene's exact bias curve (:class:`~shadowlab.tuning.exact_bias.BiasCurve`) gives its
objective at every constant bias. The mean over a set of scenes is again a step function, on
the union of their steps, so the best *single* bias for a set of scenes is exact too. Tuned on
one set (training) and evaluated on another (held out), it answers the engine programmer's
question — is there a bias that works everywhere? — with the regret of that single bias
against each held-out scene's own optimum, and against the lab's default.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .exact_bias import Optimum, best_run


@dataclass(frozen=True)
class SceneCurve:
    """One scene's objective as a step function of the bias: ``values[k]`` on [breaks[k],
    breaks[k+1]), the last step up to ``hi`` (a rate, as metrics.py reports it)."""

    scene: str
    breaks: np.ndarray
    values: np.ndarray
    hi: float

    @classmethod
    def of(cls, scene: str, curve, objective: str) -> "SceneCurve":
        """From a :class:`~shadowlab.tuning.exact_bias.BiasCurve`."""
        return cls(scene, np.asarray(curve.breaks, np.float64), curve.values(objective), float(curve.hi))

    def at(self, biases) -> np.ndarray:
        """The objective at each bias (float32, as the shader receives it)."""
        b = np.asarray(biases, np.float32).astype(np.float64)
        k = np.clip(np.searchsorted(self.breaks, b, side="right") - 1, 0, len(self.values) - 1)
        return self.values[k]

    def optimum(self) -> Optimum:
        """This scene's own best bias (:func:`~shadowlab.tuning.exact_bias.best_run`)."""
        return best_run(self.breaks, self.values, self.hi)


def mean_curve(curves: list[SceneCurve]) -> SceneCurve:
    """The mean of several scenes' curves over the same bias range, exact (on the union of their
    steps)."""
    if not curves:
        raise ValueError("no curves to average")
    lo, hi = curves[0].breaks[0], curves[0].hi
    if any(c.breaks[0] != lo or c.hi != hi for c in curves):
        raise ValueError("curves over different bias ranges")
    breaks = np.unique(np.concatenate([c.breaks for c in curves]))
    values = np.mean([c.at(breaks) for c in curves], axis=0)
    return SceneCurve("+".join(c.scene for c in curves), breaks, values, float(hi))


@dataclass(frozen=True)
class HeldOut:
    """The best single bias of the ``train`` scenes, judged on the ``test`` scenes: per test
    scene its value there, that scene's own optimum and the regret (the difference), and the
    same for the ``default`` bias."""

    train: tuple[str, ...]
    test: tuple[str, ...]
    bias: float
    interval: tuple[float, float]
    train_mean: float
    test_values: dict
    test_optima: dict
    default: float
    default_values: dict

    @property
    def regret(self) -> dict:
        """Per test scene: value at the global bias minus the scene's own optimum."""
        return {s: self.test_values[s] - self.test_optima[s] for s in self.test}

    @property
    def default_regret(self) -> dict:
        """Per test scene: value at the default bias minus the scene's own optimum."""
        return {s: self.default_values[s] - self.test_optima[s] for s in self.test}


def held_out(curves: dict[str, SceneCurve], train: list[str], test: list[str], default: float) -> HeldOut:
    """Tune one bias on ``train`` (the optimum of their mean curve), evaluate it on ``test``."""
    unknown = [s for s in (*train, *test) if s not in curves]
    if unknown:
        raise KeyError(f"no curve for scene {unknown[0]!r}")
    opt = mean_curve([curves[s] for s in train]).optimum()
    values = {s: float(curves[s].at([opt.bias])[0]) for s in test}
    optima = {s: curves[s].optimum().value for s in test}
    defaults = {s: float(curves[s].at([default])[0]) for s in test}
    return HeldOut(tuple(train), tuple(test), opt.bias, (opt.lo, opt.hi), opt.value, values, optima, float(default),
                   defaults)


def leave_one_out(curves: dict[str, SceneCurve], default: float) -> list[HeldOut]:
    """Each scene held out in turn, the bias tuned on all the others."""
    names = list(curves)
    return [held_out(curves, [s for s in names if s != t], [t], default) for t in names]
