"""Helpers every layer may use and that use no other part of the lab: strict TOML reading,
compiled-kernel plumbing, text helpers, atomic files, number formats, default image sizes.

Strict reading of TOML tables with one-line errors (:mod:`.validation`), compiled-kernel plumbing
(:mod:`.compiled`: numba's ``njit`` settings, splitting work over cores), text helpers
(:mod:`.text`), files written whole or not at all (:mod:`.files`), number formats
(:mod:`.format`) and the default image sizes (:mod:`.sizes`). The lowest layer
(docs/architecture.md#layers).
"""
