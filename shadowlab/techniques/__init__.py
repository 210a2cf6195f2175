"""The technique registry: name → class. Adding a technique is one module plus one line here."""
from __future__ import annotations

from .base import Param, Technique, TechniqueError, parse_spec
from .cascaded_map import CascadedShadowMap
from .filtered_map import FilteredShadowMap
from .lispsm import LiSPSM
from .blob import BlobShadow
from .projective import ProjectiveShadow
from .pcss import PCSS
from .planar import PlanarShadow
from .raytrace import RayTraced
from .shadow_map import ShadowMap
from .shadow_polygons import ShadowPolygons
from .shadow_volume import ShadowVolume

REGISTRY: dict[str, type[Technique]] = {
    RayTraced.name: RayTraced,
    ShadowMap.name: ShadowMap,
    ShadowVolume.name: ShadowVolume,
    PlanarShadow.name: PlanarShadow,
    ShadowPolygons.name: ShadowPolygons,
    PCSS.name: PCSS,
    FilteredShadowMap.name: FilteredShadowMap,
    BlobShadow.name: BlobShadow,
    ProjectiveShadow.name: ProjectiveShadow,
    CascadedShadowMap.name: CascadedShadowMap,
    LiSPSM.name: LiSPSM,
}


def from_spec(spec: str) -> Technique:
    """Build a technique from ``name`` or ``name:key=value,...`` (TechniqueError if invalid)."""
    name, values = parse_spec(spec)
    if name not in REGISTRY:
        raise TechniqueError(f"unknown technique '{name}' (known: {', '.join(REGISTRY)})")
    return REGISTRY[name](**values)


__all__ = ["REGISTRY", "from_spec", "Technique", "TechniqueError", "Param", "parse_spec"]
