"""The shaded image as a sum of per-light terms, so that any combination of visibility images has
a radiance without shading the frame again.

The shading model (docs/architecture.md#the-shading-pass-shadowlabgpushadingpy, ``shade.glsl``)
is, per light, I = λ · (A + (1 − sh)·D + sh·sc + (1 − shade)·S) with sh = density·(1 − v) and
shade = 1 − v. It is affine in the visibility v:

    I(v) = a + b·v,   a = λ·(A + (1 − density)·D + density·sc),   b = λ·(density·(D − sc) + S)

(an object that does not receive shadows is shaded with v = 1: its a is a + b and its b is 0).
So with a weight w per light and pixel (1 where the light is drawn, 0 where a shadow budget drops
it altogether) the image is L = Σ w·(a + b·v), and the truth's is Σ (a + b·g). :class:`RadianceTerms`
computes a and b per light on the frame's covered pixels — the numpy twin of ``shade.glsl``
(``tests/lighting/test_radiance.py`` holds the two together) from the frame's exact points — once
per light, as luminance (Rec. 709) or as linear RGB.
"""
from __future__ import annotations

import numpy as np

from .selection import LUMA

#: Bytes the luminance terms of one frame may hold in memory before they are recomputed on demand
#: instead of kept (two float32 per covered pixel and light).
CACHE_BYTES = 1 << 30


class RadianceTerms:
    """Per light, the terms a and b of the shaded image I(v) = a + b·v on the frame's covered
    pixels (compact arrays (M,) or (M, 3), in the order of ``frame.pixel_index``)."""

    def __init__(self, frame):
        self.frame = frame
        scene = frame.scene
        objs = scene.objects
        obj = frame.compact_object
        self.kd = np.array([o.material.diffuse for o in objs], np.float64)[obj]
        self.ks = np.array([o.material.specular for o in objs], np.float64)[obj]
        self.shininess = np.array([o.material.shininess for o in objs], np.float64)[obj]
        self.ka = np.array([o.material.ambient_color() for o in objs], np.float64)[obj]
        self.receives = np.array([o.receives for o in objs], bool)[obj]
        self.density = float(scene.shading.density)
        self.shadow_color = np.asarray(scene.shading.shadow_color, np.float64)
        self.points = frame.compact_position
        self.normals = frame.compact_normal
        view = np.asarray(frame.camera.eye, np.float64) - self.points
        self.view = view / np.linalg.norm(view, axis=1, keepdims=True)
        self._cache: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        m = len(self.points)
        self._cacheable = 8 * m * max(1, len(scene.lights)) <= CACHE_BYTES

    def rgb(self, light) -> tuple[np.ndarray, np.ndarray]:
        """(a, b), each float64 (M, 3) linear RGB, for ``light`` (any scene light)."""
        dirs, _ = light.to_light(self.points)
        ndl = np.einsum("ij,ij->i", self.normals, dirs)
        color = np.asarray(light.color, np.float64)
        diffuse = self.kd * color * np.maximum(ndl, 0.0)[:, None]
        half = dirs + self.view
        half /= np.maximum(np.linalg.norm(half, axis=1, keepdims=True), 1e-300)
        nh = np.maximum(np.einsum("ij,ij->i", self.normals, half), 0.0)
        spec = np.where((ndl > 0.0)[:, None], self.ks * color * (nh ** self.shininess)[:, None], 0.0)
        ambient = self.ka * float(light.ambient)
        lam = light.footprint(self.points)[:, None]
        d, sc = self.density, self.shadow_color
        a = lam * (ambient + (1.0 - d) * diffuse + d * sc)
        b = lam * (d * (diffuse - sc) + spec)
        fixed = ~self.receives  # not a receiver: shaded with v = 1
        a[fixed] += b[fixed]
        b[fixed] = 0.0
        return a, b

    def luminance(self, index: int) -> tuple[np.ndarray, np.ndarray]:
        """(a, b), each float32 (M,), the luminance of :meth:`rgb` for the scene's light ``index``
        (kept per light while the frame's terms fit :data:`CACHE_BYTES`)."""
        if index in self._cache:
            return self._cache[index]
        a, b = self.rgb(self.frame.scene.lights[index])
        out = ((a @ LUMA).astype(np.float32), (b @ LUMA).astype(np.float32))
        if self._cacheable:
            self._cache[index] = out
        return out

    def compact(self, image: np.ndarray) -> np.ndarray:
        """An image (height, width) as a compact array (M,) over the covered pixels."""
        return np.asarray(image).reshape(-1)[self.frame.pixel_index]

    def light_radiance(self, index: int, visibility: np.ndarray, weight: np.ndarray | None = None) -> np.ndarray:
        """Float64 (M,): the luminance light ``index`` adds with ``visibility`` (image (H, W) or
        compact (M,)); ``weight`` (same forms, or None for 1): where it is 0 the light is not drawn."""
        a, b = self.luminance(index)
        v = visibility if visibility.ndim == 1 else self.compact(visibility)
        v = np.nan_to_num(v.astype(np.float64), nan=1.0)
        out = a + b * v
        if weight is not None:
            out = out * (weight if weight.ndim == 1 else self.compact(weight))
        return out
