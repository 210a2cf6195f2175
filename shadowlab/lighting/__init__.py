"""Many lights: which lights get shadows where, and what the shaded image of all of them is.

- :mod:`shadowlab.lighting.selection`: the selection policies of a shadow budget (``budget=K``,
  ``select=POLICY`` on any technique's spec) — per face, per object or per frame, which lights get
  their shadows computed;
- :mod:`shadowlab.lighting.atlas`: the shadow atlas's allocation — one texture shared by the
  selected lights, each light's resolution from its screen-space importance, overflow reported;
- :mod:`shadowlab.lighting.radiance`: the shaded image's per-light terms, so that the radiance of
  any combination of visibility images is a sum (the truth's, and each configuration's).

Below the techniques (a spec's ``select`` is checked against the policies here) and above the
frame (policies read the G-buffer and the scene's lights).
"""
