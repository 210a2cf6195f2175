"""Tuning: each technique at its best settings, found from the truth (docs/tuning.md).

- :mod:`shadowlab.tuning.space`: the parameters a tune searches (``--param NAME[=RANGE]``) and
  the ranges techniques declare for them;
- :mod:`shadowlab.tuning.search`: coordinate search with refinement over rendered candidates,
  on a stated budget;
- :mod:`shadowlab.tuning.exact_bias`: the shadow-map bias family optimised exactly from one
  render (every constant bias at once).
"""
