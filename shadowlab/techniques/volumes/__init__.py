"""The shadow-volume family: stencil shadow volumes (z-pass / z-fail, CPU or GPU silhouettes)
and penumbra wedges built on them (soft shadow volumes). The GLSL files sit beside the modules.
"""
