"""Helpers every layer may use and that use no other part of the lab: strict reading of TOML
tables with one-line errors (:mod:`.validation`), compiled-kernel plumbing (:mod:`.compiled`:
numba's ``njit`` settings, splitting work over cores), text helpers (:mod:`.text`). The lowest layer
(docs/architecture.md#layers).
"""
