"""The shadow budget applied to a measurement: which pixels of a light get its shadow, and what the
others get (docs/many-lights.md).

A spec with ``budget=K`` (:data:`shadowlab.techniques.base.BUDGET_PARAMS`) is measured on each light
like any configuration, with three differences, all here:

- the frame's :class:`BudgetPlan` — the selection policy's kept (light, face) pairs
  (:func:`shadowlab.lighting.selection.select`) and, with ``atlas``, the atlas's tiles — is made
  once per frame (per reservoir state for ``restir``) and shared by every light's measurement;
- a light kept on no evaluated pixel is not rendered at all: its time is 0 and its
  ``budget_rendered`` 0 (what the budget saves; with ``drop=imperfect`` the imperfect map's time,
  set-up and stats, ``imperfect_*``, are the light's); with ``atlas`` a kept light is rendered at the
  per-face resolution its tile gives (``atlas_resolution``), and a light the atlas could not hold
  (``atlas_overflow`` = 1, and a note) is treated as dropped everywhere — never silently;
- the visibility is the technique's where the light is kept, and elsewhere 1 (``drop=unshadowed``:
  drawn without its shadow), 0 with the light not drawn (``drop=unlit``: the measurement's
  ``weight`` image is 0 there, so the shaded image and the radiance metrics leave the light out),
  or an imperfect shadow map's (``drop=imperfect``: ``imperfect_map`` measured on the light too, its
  time added).
"""
from __future__ import annotations

import dataclasses
import weakref
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..gpu import timing
from ..lighting import selection
from ..techniques import from_spec
from ..techniques.base import ATLAS_MIN_SIZE
from .result import Measurement

#: The smallest per-face resolution the atlas gives a kept light before it reports an overflow.
ATLAS_MIN_RESOLUTION = ATLAS_MIN_SIZE
#: A light whose shadow the budget computes on less than this share of its evaluated pixels is
#: "mostly dropped": the budget's one run note counts it instead of a note per light.
MOSTLY_DROPPED = 0.5
#: The spec of the imperfect shadow maps of ``drop=imperfect``.
IMPERFECT_SPEC = "imperfect_map"

# frame → {plan key: BudgetPlan}; weak, so a released frame's plans go with it
_PLANS: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


@dataclass
class BudgetPlan:
    """One frame's budget for one configuration: the selection, the atlas plan (None without
    ``atlas``) and the lights the atlas could not hold."""

    selection: selection.Selection
    atlas: object | None = None
    overflow: frozenset = frozenset()


def reservoir_state(tech) -> selection.ReservoirState:
    """The ``restir`` reservoirs a technique carries across the frames of an animation (made on
    first use; a still frame's technique gets a fresh one per frame it is measured on)."""
    state = tech.__dict__.get("_reservoirs")
    if state is None:
        state = tech.__dict__["_reservoirs"] = selection.ReservoirState()
    return state


def forget_state(tech) -> None:
    """Drop the ``restir`` reservoirs ``tech`` carried across an animation's frames (its end)."""
    tech.__dict__.pop("_reservoirs", None)


def plan_for(tech, frame) -> BudgetPlan:
    """The :class:`BudgetPlan` of ``tech``'s budget on ``frame`` (made once per frame and
    reservoir state)."""
    b = tech.budget_settings()
    state = reservoir_state(tech) if b["select"] == "restir" else None
    key = (tech.spec(), None if state is None else state.serial)
    plans = _PLANS.setdefault(frame, {})
    if key not in plans:
        scene = frame.scene
        sel = selection.select(b["select"], b["budget"], scene.lights, scene.objects, frame, state)
        atlas, overflow = None, frozenset()
        if b["atlas"]:
            atlas, overflow = _atlas_plan(tech, sel, frame, b["atlas"], int(tech.resolution))
        plans[key] = BudgetPlan(sel, atlas, overflow)
    return plans[key]


def _atlas_plan(tech, sel: selection.Selection, frame, size: int, max_resolution: int):
    """The atlas of the selection's kept lights (:func:`shadowlab.lighting.atlas.allocate`): their
    importance is their screen-space importance (:func:`shadowlab.lighting.selection.screen_importance`),
    their faces those the technique renders for them (:func:`faces_of`)."""
    from ..lighting import atlas

    lights = frame.scene.lights
    importance = selection.screen_importance(lights, frame)
    kept = [int(i) for i in np.flatnonzero(sel.lights()) if frame.slot(int(i)).evaluated.any()]
    plan = atlas.allocate({i: float(importance[i]) for i in kept}, {i: faces_of(tech, frame, i) for i in kept},
                          size, max_resolution, ATLAS_MIN_RESOLUTION)
    return plan, frozenset(int(i) for i in plan.overflow)


def faces_of(tech, frame, index: int) -> int:
    """The faces ``tech`` renders for the scene's light ``index``: its own fit of the light's views
    (``fit_views``: a cube's six, a frustum's one, cascades) times its light samples on an area
    light; a technique without one: six for a point light, one for any other."""
    light = frame.scene.lights[index]
    samples = int(tech.params().get("light_samples", 1)) if light.type_name == "area" else 1
    fit = getattr(tech, "fit_views", None)
    if fit is None:
        return samples * (6 if light.type_name == "point" else 1)
    if light.type_name == "area" and tech.LIGHT_SAMPLED:
        return samples * 6  # each sample a point light: a cube at most
    views, _ = fit(frame, frame.slot(index))
    return len(views)


def measure_budgeted(tech, frame, slot, alone: Callable[[object], Measurement], repeat: int) -> Measurement:
    """``tech`` (with a budget) measured on ``slot``: ``alone(t)`` is the pipeline's measurement of
    a technique ``t`` on the slot without any budget, called for ``tech`` only when the light is
    kept somewhere (at the atlas's resolution when there is one) and for the imperfect shadow
    map of ``drop=imperfect``. Returns the measurement with the budget applied (module
    docstring), its ``weight`` set for ``drop=unlit`` and the budget's stats added; ``repeat``:
    the timed runs, for the zero timing of a light that is not rendered."""
    b = tech.budget_settings()
    plan = plan_for(tech, frame)
    covered_kept = plan.selection.compact_mask(frame, slot.index)
    overflow = slot.index in plan.overflow
    if overflow:
        covered_kept = np.zeros_like(covered_kept)
    evaluated = slot.evaluated
    kept_eval = covered_kept & evaluated
    rendered = bool(kept_eval.any())
    stats = {"budget_rendered": int(rendered),
             # NaN for a light that reaches no pixel: nothing of it is kept or dropped
             "budget_kept_share": float(kept_eval.sum() / evaluated.sum()) if evaluated.any() else float("nan"),
             "budget_lights": int(plan.selection.lights().sum())}
    notes = []
    if plan.atlas is not None:
        stats["atlas_resolution"] = int(plan.atlas.resolution.get(slot.index, 0))
        stats["atlas_overflow"] = int(overflow)
        stats["atlas_texels_used"] = int(plan.atlas.texels_used)
        if overflow:
            notes.append(f"light {slot.index}: the {b['atlas']}² shadow atlas could not hold its map even at "
                         f"{ATLAS_MIN_RESOLUTION}² per face; the light is dropped ({b['drop']}) everywhere")
    if rendered:
        if plan.atlas is not None:
            saved = tech._params["resolution"]
            tech._params["resolution"] = stats["atlas_resolution"]
            try:
                m = alone(tech)
            finally:
                tech._params["resolution"] = saved
        else:
            m = alone(tech)
    else:
        h, w = frame.height, frame.width
        m = Measurement(tech, slot.index, np.ones((h, w), np.float32),
                        timing.Timing(0.0, 0.0, [0.0] * max(1, repeat), 0.0, 0.0, 0.0), {}, setup_ms=0.0)
    kept_image = frame.to_image(covered_kept, fill=False, dtype=bool)
    vis = m.visibility.astype(np.float32)
    weight = None
    if b["drop"] == "unshadowed":
        dropped = np.float32(1.0)
    elif b["drop"] == "unlit":
        dropped = np.float32(0.0)
        weight = (kept_image | ~frame.covered).astype(np.float32)
    else:
        ism = from_spec(IMPERFECT_SPEC)
        dropped_any = bool((~covered_kept & evaluated).any())
        if dropped_any:
            im = alone(ism)
            dropped = im.visibility.astype(np.float32)
            m = dataclasses.replace(m, timing=_summed(m.timing, im.timing), setup_ms=m.setup_ms + im.setup_ms,
                                    notes=list(m.notes) + [f"{IMPERFECT_SPEC}: {n}" for n in im.notes])
            stats["imperfect_rendered"] = 1
            stats.update({f"imperfect_{k}": v for k, v in im.stats.items()})
        else:
            dropped = np.float32(1.0)
            stats["imperfect_rendered"] = 0
    vis = np.where(kept_image | ~frame.covered, vis, dropped).astype(np.float32)  # nothing to drop where nothing is seen
    return dataclasses.replace(m, visibility=vis, stats={**m.stats, **stats}, notes=list(m.notes) + notes,
                               weight=weight, budget_kept=kept_image & frame.evaluated_image(slot))


def _summed(a: timing.Timing, b: timing.Timing) -> timing.Timing:
    """Two renders of one frame as one timing (:func:`shadowlab.measurement.light_sampling.combined_timing`)."""
    from .light_sampling import combined_timing

    return combined_timing([a, b])


def budget_note(tech, ms) -> list[str]:
    """One run note for a configuration with a budget, from its measurements ``ms`` (one per
    light): how many lights got their shadows somewhere, and what the others got — so that the
    lights a budget drops are said once, not as one "draws almost no shadow" per light. [] without
    a budget."""
    b = tech.budget_settings()
    if not b or not ms:
        return []
    rendered = sum(int(m.stats.get("budget_rendered", 0)) for m in ms)
    dropped = [m.light for m in ms if m.stats.get("budget_kept_share", 1.0) == 0.0]  # NaN (reaches no pixel): neither
    mostly = [m.light for m in ms if 0.0 < m.stats.get("budget_kept_share", 1.0) < MOSTLY_DROPPED]
    what = {"unshadowed": "lit without their shadows", "unlit": "not drawn",
            "imperfect": "shadowed by imperfect shadow maps"}[b["drop"]]

    def listed(lights):
        return ", ".join(map(str, lights[:12])) + (", …" if len(lights) > 12 else "")

    text = (f"{tech.short_label()}: shadows computed for {rendered} of {len(ms)} lights; "
            f"{len(dropped)} lights kept on none of their evaluated pixels are {what} there"
            + (f" (lights {listed(dropped)})" if dropped else ""))
    if mostly:
        text += (f"; {len(mostly)} more are kept on under {MOSTLY_DROPPED:.0%} of theirs (lights {listed(mostly)}) "
                 f"and {what} elsewhere")
    overflow = [m.light for m in ms if m.stats.get("atlas_overflow")]
    if overflow:
        text += f"; the {b['atlas']}² atlas could not hold {len(overflow)} lights' maps"
    return [text]
