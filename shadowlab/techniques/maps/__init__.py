"""The map family: techniques that render depth (or moments) from the light and look it up
per pixel — the shadow map with its bias family and filters, cascades, LiSPSM, virtual maps,
filtered (VSM/ESM/EVSM/MSM) maps, PCSS, moment soft shadows, projective shadow textures and the
irregular z-buffer (an alias-free shadow map). The family's shared toolkit (atlas, depth and
lookup passes, light-view fitting, texel mapping) is :mod:`.toolkit`; every GLSL file of the
family sits beside the modules.
"""
