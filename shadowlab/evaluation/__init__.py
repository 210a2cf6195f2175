"""The judges: per-pixel, boundary and artefact metrics against the truth (:mod:`.metrics`),
occluder layers and receiver heights (:mod:`.occluder_layers`), the texel footprint of map-based
techniques (:mod:`.texel_footprint`), perceptual metrics (:mod:`.perceptual`) and temporal
metrics of animations (:mod:`.temporal`). They read visibility images and frames; they never
render.
"""
