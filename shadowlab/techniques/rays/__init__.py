"""The ray family: the ray-traced ground truth (``raytrace``, Embree) and denoised ray-traced
soft shadows (``rt_soft``) built on its rays.
"""
