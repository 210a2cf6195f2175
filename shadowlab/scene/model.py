"""The scene model (docs/contracts.md#scene-files): camera, materials, objects in world space, scene-wide shading.

Plain data, no GL and no file reading (that is :mod:`shadowlab.scene.reading`). The dataclasses
here are the single source of every default a scene file may leave out: the reader takes its
defaults from their fields (:func:`default_of`).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np

from ..geometry import transforms as tf
from .lights import Light

#: The family of a scene that is a plain set-up rather than one hard case.
GENERAL_FAMILY = "general"
#: The one family whose scenes are judged on fractional visibility (``visibility_mae``) instead
#: of the thresholded ``error_rate``: soft shadows, where the visibility between 0 and 1 is the
#: answer and a threshold at 0.5 would hide it (:func:`shadowlab.analysis.aggregate.judged_metric`
#: is the one rule that reads it).
SOFT_FAMILY = "soft shadows"
#: The family judged on the shaded image (``radiance_error``: every light at once) instead of the
#: per-light rates: scenes with tens to hundreds of lights, where a shadow budget drops the shadows
#: of lights that barely matter and the per-light error rate would weigh them like the rest
#: (docs/many-lights.md; :func:`shadowlab.analysis.aggregate.judged_metric` reads it).
MANY_LIGHTS_FAMILY = "many lights"
#: Every hard-case family a scene file may declare in its ``family`` key (docs/hard-cases.md), in
#: the catalogue's order: what a study groups its scenes by (the ``scene_family`` column) and,
#: through :data:`SOFT_FAMILY` and :data:`MANY_LIGHTS_FAMILY`, which metric it judges them on.
SCENE_FAMILIES = (GENERAL_FAMILY, "shadow volumes", "planar shadows", "shadow maps", "perspective aliasing",
                  "projective textures", "temporal stability", "real meshes", "ground truth", SOFT_FAMILY,
                  "city scale", "contact shadows", MANY_LIGHTS_FAMILY)
#: Scene-name prefixes → family: only the fallback for a scene file without a ``family`` key
#: (the study notes each such scene, :func:`family_from_name`), as families were named before
#: scene files declared them; a file's own ``family`` always wins over its name.
FAMILY_PREFIXES = {"sv_": "shadow volumes", "pp_": "planar shadows", "sm_": "shadow maps",
                   "pa_": "perspective aliasing", "pt_": "projective textures", "tm_": "temporal stability",
                   "rm_": "real meshes", "rt_": "ground truth", "soft_": SOFT_FAMILY, "city_": "city scale",
                   "cs_": "contact shadows", "ml_": MANY_LIGHTS_FAMILY}


def family_from_name(scene_name: str) -> str:
    """The family a scene's name suggests (:data:`FAMILY_PREFIXES`; :data:`GENERAL_FAMILY` for
    any other name): the fallback for a scene file that declares none. A guess, hence only a
    fallback: a soft scene named like a hard one declares its family instead."""
    for prefix, family in FAMILY_PREFIXES.items():
        if scene_name.startswith(prefix):
            return family
    return GENERAL_FAMILY


def default_of(cls, name: str):
    """The default of field ``name`` of dataclass ``cls`` (its default or a fresh
    ``default_factory()`` value): what a scene file that leaves the key out gets."""
    for f in dataclasses.fields(cls):
        if f.name == name:
            if f.default is not dataclasses.MISSING:
                return f.default
            if f.default_factory is not dataclasses.MISSING:  # type: ignore[misc]
                return f.default_factory()  # type: ignore[misc]
            raise KeyError(f"{cls.__name__}.{name} has no default")
    raise KeyError(f"{cls.__name__} has no field {name!r}")


@dataclass
class Camera:
    """A perspective camera (OpenGL conventions; vertical ``fov_y`` in degrees).

    ``near`` / ``far`` are None until :meth:`Scene.fitted_camera` fits them to the scene.
    """

    eye: np.ndarray
    target: np.ndarray
    up: np.ndarray = field(default_factory=lambda: np.array([0.0, 1.0, 0.0]))
    fov_y: float = 45.0
    near: float | None = None
    far: float | None = None

    def view(self) -> np.ndarray:
        """World → view matrix (float64, 4x4)."""
        return tf.look_at(self.eye, self.target, self.up)

    def projection(self, aspect: float) -> np.ndarray:
        """View → clip matrix for ``aspect`` = width / height (needs near and far)."""
        return tf.perspective(self.fov_y, aspect, self.near, self.far)

    def pixel_rays(self, width: int, height: int) -> np.ndarray:
        """Unnormalised world-space directions through every pixel centre, float64
        (height, width, 3), row 0 = top of the image."""
        view = self.view()
        right, up, back = view[0, :3], view[1, :3], view[2, :3]
        t = np.tan(np.radians(self.fov_y) / 2.0)
        x = (2.0 * (np.arange(width) + 0.5) / width - 1.0) * t * width / height
        y = (1.0 - 2.0 * (np.arange(height) + 0.5) / height) * t
        return (-back[None, None, :] + x[None, :, None] * right[None, None, :]
                + y[:, None, None] * up[None, None, :])


@dataclass
class Material:
    """Extended Blinn material (docs/architecture.md#the-shading-pass-shadowlabgpushadingpy): diffuse, specular and ambient reflectance, shininess."""

    diffuse: np.ndarray = field(default_factory=lambda: np.array([0.8, 0.8, 0.8]))
    specular: np.ndarray = field(default_factory=lambda: np.array([0.3, 0.3, 0.3]))
    shininess: float = 32.0
    ambient: np.ndarray | None = None  # defaults to the diffuse colour

    def ambient_color(self) -> np.ndarray:
        """k_A: the ambient reflectance (the diffuse colour unless set)."""
        return self.diffuse if self.ambient is None else self.ambient


@dataclass
class SceneObject:
    """One mesh in world space: ``vertices`` float64 (V, 3), ``faces`` int64 (F, 3), CCW outward."""

    name: str
    vertices: np.ndarray
    faces: np.ndarray
    material: Material = field(default_factory=Material)
    casts: bool = True
    receives: bool = True
    source: str = ""

    @property
    def triangles(self) -> np.ndarray:
        """Triangle corners, float64 (F, 3, 3)."""
        return self.vertices[self.faces]

    def bounds(self) -> np.ndarray:
        """Axis-aligned bounds [[min xyz], [max xyz]] (2, 3)."""
        return np.stack([self.vertices.min(0), self.vertices.max(0)])

    @cached_property
    def edges(self):
        """The mesh's edge table (:class:`shadowlab.geometry.adjacency.EdgeTable`): built on first
        use and kept with the object whose geometry it describes."""
        from ..geometry.adjacency import edge_table

        return edge_table(self.vertices, self.faces)


@dataclass
class Shading:
    """Scene-wide shadow appearance for the extended Blinn model: density and colour of shadow."""

    density: float = 1.0
    shadow_color: np.ndarray = field(default_factory=lambda: np.zeros(3))


@dataclass
class Scene:
    """A validated scene: camera, lights (at least one), objects (at least one)."""

    name: str
    camera: Camera
    lights: list[Light]
    objects: list[SceneObject]
    shading: Shading = field(default_factory=Shading)
    path: Path | None = None
    #: The ``[animation]`` table (:class:`shadowlab.scene.animation.Animation`); None for a still scene.
    animation: object | None = None
    #: The metrics column this scene exists to show (``metric`` key: e.g. ``contact_gap_px`` for a
    #: contact hard case); None for a plain scene. Study pages show it beside the error.
    metric: str | None = None
    #: Its hard-case family (``family`` key, one of :data:`SCENE_FAMILIES`): what a study groups it
    #: by and judges it on; None when the file declares none (a study then falls back on the name,
    #: :func:`family_from_name`, with a note).
    family: str | None = None
    #: What reading the scene left out or decided (e.g. a glTF file's skins, extensions, exposure):
    #: carried into the run notes of compare, animate and studies.
    notes: list[str] = field(default_factory=list)

    def bounds(self) -> np.ndarray:
        """Axis-aligned bounds of every object, (2, 3)."""
        b = np.stack([o.bounds() for o in self.objects])
        return np.stack([b[:, 0].min(0), b[:, 1].max(0)])

    def extent(self) -> float:
        """The diagonal of the scene's bounds (a length scale for tolerances)."""
        b = self.bounds()
        return float(np.linalg.norm(b[1] - b[0]))

    def fitted_camera(self) -> Camera:
        """The camera with near/far fitted to the scene's bounds where the file left them out:
        far just beyond the farthest corner, near at the nearest corner in front of the eye but
        no closer than far / 1000 (keeps a 24-bit depth buffer well conditioned)."""
        cam = self.camera
        if cam.near is not None and cam.far is not None:
            return cam
        b = self.bounds()
        corners = np.array([[x, y, z] for x in b[:, 0] for y in b[:, 1] for z in b[:, 2]])
        depth = -(tf.transform_points(cam.view(), corners)[:, 2])
        far = cam.far if cam.far is not None else max(float(depth.max()) * 1.01, 1e-3)
        near = cam.near
        if near is None:
            nearest = float(depth.min()) * 0.99
            near = min(max(nearest, far / 1000.0), far * 0.5)
        return Camera(cam.eye, cam.target, cam.up, cam.fov_y, near, far)

    def describe(self) -> dict:
        """Scene summary for run.json."""
        return {
            "name": self.name,
            "path": str(self.path) if self.path else None,
            "metric": self.metric,
            "lights": [l.describe() for l in self.lights],
            "objects": [{"name": o.name, "source": o.source, "triangles": int(len(o.faces)),
                         "casts": o.casts, "receives": o.receives} for o in self.objects],
        }
