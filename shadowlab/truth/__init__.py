"""Exact CPU ray queries, the ground truth's machinery: Embree scenes and shadow rays
(:mod:`.tracing`), the compiled per-pixel kernels (:mod:`.compiled`; each with a numpy reference
the tests hold it to), the camera's pixel rays and their exact float64 surface points
(:mod:`.pixel_rays`), and sub-pixel samples (:mod:`.subpixel`). No GL: the frame (gpu/) and the
ray-traced techniques build on it.
"""
