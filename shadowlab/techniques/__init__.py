"""The technique registry: name → class, filled by the techniques themselves.

Every module of this package is imported here (discovered with :mod:`pkgutil`), and every :class:`~shadowlab.techniques.base.Technique` subclass that sets its own ``name``
registers itself when its class is made (:data:`~shadowlab.techniques.base.REGISTRY`). Adding a
technique is one module here, one shader and one test file: no list to edit. Modules that hold
no technique (``base``, the map toolkit ``maps``) register nothing. The registry's order: the
ground truth (``raytrace``) first, then by name.
"""
from __future__ import annotations

import importlib
import pkgutil

from .base import REGISTRY, Param, PlotStyle, Technique, TechniqueError, parse_spec

for _module in sorted(m.name for m in pkgutil.iter_modules(__path__)):
    importlib.import_module(f"{__name__}.{_module}")
# A stable order whatever imports what: the ground truth first, then by name.
_ordered = sorted(REGISTRY.items(), key=lambda item: (item[0] != "raytrace", item[0]))
REGISTRY.clear()
REGISTRY.update(_ordered)


def from_spec(spec: str) -> Technique:
    """Build a technique from ``name`` or ``name:key=value,...`` (TechniqueError if invalid)."""
    import difflib

    name, values = parse_spec(spec)
    if name not in REGISTRY:
        close = difflib.get_close_matches(name, list(REGISTRY), n=1)
        hint = f"; did you mean '{close[0]}'?" if close else ""
        raise TechniqueError(f"unknown technique '{name}'{hint} (known: {', '.join(REGISTRY)})")
    return REGISTRY[name](**values)


__all__ = ["REGISTRY", "from_spec", "Technique", "TechniqueError", "Param", "PlotStyle", "parse_spec"]
