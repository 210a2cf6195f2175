"""The one measurement loop (:mod:`.pipeline`: setup → timed renders → visibility → stats →
metrics row, with the ground truth's :class:`~.pipeline.Evaluator`) and the light-sampling loop that
stands N point lights in for an area light (:mod:`.light_sampling`).
"""
