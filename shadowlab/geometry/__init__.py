"""Geometry with no GL: transforms, triangle normals, ray hits, bounds, light frusta, edge
adjacency and convex polygon clipping. Everything here is numpy (float64 unless stated) and can
be tested without a GL context."""
