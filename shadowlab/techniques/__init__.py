"""The technique registry: name → class, filled by the techniques themselves.

Every module of this package and of its family sub-packages (``maps``, ``volumes``, ``geometric``,
``rays``) is imported here (discovered with :mod:`pkgutil`), and every
:class:`~shadowlab.techniques.base.Technique` subclass that sets its own ``name`` registers itself
when its class is made (:data:`~shadowlab.techniques.base.REGISTRY`). Adding a technique is one
module in a family's folder with its GLSL beside it, one test file and one line in a suite: no
list to edit (docs/adding-a-technique.md). Modules that hold no technique (``base``, the map
toolkit ``maps.toolkit``, ``maps.page_cache``) register nothing. The registry's order: the
ground truth (``raytrace``) first, then by name.
"""
from __future__ import annotations

import importlib
import pkgutil

from ..util.validation import did_you_mean
from .base import REGISTRY, Param, PlotStyle, Technique, TechniqueError, TuneRange, parse_spec

for _module in sorted(m.name for m in pkgutil.walk_packages(__path__, prefix=f"{__name__}.")):
    importlib.import_module(_module)
# A stable order whatever imports what: the ground truth first, then by name.
_ordered = sorted(REGISTRY.items(), key=lambda item: (item[0] != "raytrace", item[0]))
REGISTRY.clear()
REGISTRY.update(_ordered)


def technique_class(name: str) -> type:
    """The registered technique class called ``name`` (TechniqueError, with the closest name as
    a hint, if there is none)."""
    if name not in REGISTRY:
        raise TechniqueError(f"unknown technique '{name}'{did_you_mean(name, REGISTRY)} "
                             f"(known: {', '.join(REGISTRY)})")
    return REGISTRY[name]


def from_spec(spec: str) -> Technique:
    """Build a technique from ``name`` or ``name:key=value,...`` (TechniqueError if invalid)."""
    name, values = parse_spec(spec)
    return technique_class(name)(**values)


__all__ = ["REGISTRY", "from_spec", "technique_class", "Technique", "TechniqueError", "Param", "PlotStyle",
           "TuneRange", "parse_spec"]
