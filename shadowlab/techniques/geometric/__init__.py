"""The geometric (object-space) family: shadows computed from the geometry itself rather than
from a depth image — planar projected shadows, exact shadow polygons clipped on the receivers,
exact soft shadows (the light's visible part per pixel) and blob shadows.
"""
