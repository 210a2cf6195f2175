"""Light space perspective shadow maps (LiSPSM; Wimmer, Scherzer & Purgathofer 2004, "Light
Space Perspective Shadow Maps", EGSR) for directional lights.

A uniform shadow map spends as many texels on a far receiver as on a near one, while the camera
magnifies the near ones: perspective aliasing. LiSPSM renders the map through a perspective
warp P whose axis lies in the map's plane (light-space y: the view direction projected
perpendicular to the light), so texels shrink towards the viewer; the light stays directional
after the warp. Only the fitting differs from a shadow map: the atlas holds one LightView whose
``view`` is the light-space rotation and whose ``proj`` is the whole warp (P, then the
orthographic fit into the unit cube); depth pass, lookup and texel mapping are the map
toolkit's (:class:`~shadowlab.techniques.maps.toolkit.DepthMapTechnique`), the bias variants and
filters shadow_map's (:class:`~shadowlab.techniques.maps.shadow_map.ComparisonVariants`). The maths is in :mod:`shadowlab.geometry.lispsm_frustum`.

The body B (the paper's "focused" body; our choice of focus box, ``fit=``): the camera's view
frustum (the frame's fitted camera: near/far fitted to the scene's bounds, so its far plane
already lies just past the scene) intersected with an axis-aligned box — the bounds of the
shadowable receivers (``shadowable``, default, like shadow_map's fit), of every evaluated
receiver (``receivers``), or of the scene (``scene``, the paper's) — which clips the far end
to what is there. Casters: B's vertices are copied towards the light up to the light-facing
side of the scene's bounds (same light-space x, y, so P treats them like B); the map covers
the hull of B and the copies, which holds every caster point between a receiver of B and the
light. z_n, z_f of n_opt are the camera's nearest and farthest view depths of B.

``n`` (world units): 0 uses n_opt = (z_n + √(z_n z_f)) / sin γ; > 0 forces it (large n →
the uniform map, small n → strong warp). When sin γ < :data:`MIN_SIN_GAMMA` (light almost along
the view) n_opt → ∞ and light space has no y axis: the map falls back to the uniform fit of the
same body, with a note (``n_used`` empty: unbounded, no warp).

Bias under the warp: window depth after P is z / y (light-space depth over the distance from the
centre of projection along the warp axis), so a constant bias in window depth (``constant``) is
a world offset that grows with the distance from the viewer's end of B — too small near, too
large far. ``slope`` (the default here) derives the offset from the map's own depth slope over
one texel at the receiver (the lookup's plane-based form), which follows the warp; its constant
part ``bias`` still applies. ``normal_offset`` uses one world texel size for the whole map
(ShadowMap's uniform ``u_texel_world``), here the median texel size over the covered receivers:
too large near the viewer and too small far away. ``receiver_plane`` and ``adaptive`` compare
each tap with the receiver's plane in the warped map itself (a plane stays a plane under the
projective warp), so, like ``slope``, they follow the warp.
"""
from __future__ import annotations

import numpy as np

from ...geometry import lispsm_frustum as lf
from ...geometry import transforms as tf
from ...geometry.bounds import box_corners
from ...geometry.frusta import LightView
from ..base import FIRST, Param, PlotStyle
from .toolkit import DEPTH_MAP_STATS, DepthMapTechnique, shadowable_receivers
from .contact import ContactShadows
from .shadow_map import COMPARISON_PARAMS, VARIANTS, ComparisonVariants

#: Central-difference step for the texel-size estimate, × the body's extent.
TEXEL_STEP = 1e-4


class LiSPSM(ContactShadows, ComparisonVariants, DepthMapTechnique):
    """Light space perspective shadow map of a directional light (one warped face)."""

    name = "lispsm"
    summary = "light space perspective shadow maps (Wimmer et al. 2004): n_opt warp, directional lights"
    STYLE = PlotStyle("#ff7f0e", "h")
    #: The warp is defined for a light at infinity only (suites and tests give it scenes with a
    #: directional light; planning a compare, study or animation elsewhere is an error).
    LIGHTS = frozenset({"directional"})
    STATS = {**DEPTH_MAP_STATS, "n_used": FIRST, "gamma_deg": FIRST}
    #: The map's texel mapping, and the bias family the exact optimiser sweeps (ComparisonVariants).
    PROVIDES = frozenset({"texel_mapping", "depth_bias", "world_bias"})
    PARAMS = {
        **{k: p for k, p in COMPARISON_PARAMS.items() if k != "variant"},
        "variant": Param("slope", "depth comparison (slope: offset from the warped map's own depth slope)",
                         choices=VARIANTS),
        # Window depth by default: the warp spreads depth along the view, and on pa_long_view (a
        # long scene) a world bias of 0.002 x the extent lifted the shadows off their casters, a
        # larger error than the window-depth bias.
        "bias_space": Param("window", COMPARISON_PARAMS["bias_space"].doc, choices=("world", "window")),
        "fit": Param("shadowable", "the box the view frustum is clipped to: bounds of the shadowable receivers, "
                                   "of every visible receiver, or of the scene (the paper's)",
                     choices=("shadowable", "receivers", "scene")),
        "n": Param(0.0, "distance of the warp's centre of projection from the body's near face, world units "
                        "(0 = n_opt)", min=0.0),
    }

    def fit_views(self, frame, slot) -> tuple[list[LightView], list[str]]:
        """One LightView: light-space rotation and the LiSPSM warp fitted to the body B."""
        light = slot.light
        notes: list[str] = []
        receivers = self._receivers(frame, slot)
        focus = frame.scene.bounds() if self.fit == "scene" or len(receivers) == 0 else \
            np.stack([receivers.min(axis=0), receivers.max(axis=0)])
        cam = frame.camera
        frustum = lf.frustum_corners(frame.view, cam.fov_y, frame.width / frame.height, cam.near, cam.far)
        body = lf.hexahedra_intersection(frustum, box_corners(focus[None]))
        if len(body) == 0:  # the focus box lies outside the view: cover the box itself
            body = box_corners(focus[None])
            notes.append(f"{self.name}: the view frustum misses the focus box; the map covers the box")
        view_depth = -tf.transform_points(frame.view, body)[:, 2]
        z_near, z_far = max(float(view_depth.min()), float(cam.near)), float(view_depth.max())
        rotation, sin_gamma = lf.light_space(light.direction, cam.target - cam.eye)
        body_ls = tf.transform_points(rotation, body)
        top = float(tf.transform_points(rotation, box_corners(frame.scene.bounds()[None]))[:, 2].max())
        lifted = body_ls.copy()
        lifted[:, 2] = np.maximum(lifted[:, 2], top)  # B's points moved towards the light, onto the scene's top
        hull = np.concatenate([body_ls, lifted])
        self.gamma_deg = float(np.degrees(np.arcsin(min(sin_gamma, 1.0))))
        if sin_gamma < lf.MIN_SIN_GAMMA:
            self.n_used = None  # unbounded: no warp (written as an empty cell, never as inf in JSON)
            proj = lf.uniform_projection(hull)
            notes.append(f"{self.name}: the light is within {self.gamma_deg:.2f} degrees of the view direction "
                         f"(sin gamma < {lf.MIN_SIN_GAMMA}): n_opt is unbounded, the map is the uniform "
                         f"(orthographic) fit of the same body")
        else:
            self.n_used = float(self.n) if self.n > 0 else float(lf.n_optimal(z_near, z_far, sin_gamma))
            eye_ls = tf.transform_points(rotation, np.asarray(cam.eye, np.float64)[None])[0]
            proj = lf.warp_projection(hull, eye_ls, self.n_used)
        # B's vertices and B ∪ its copies lifted towards the light, world (rotation⁻¹ = rotationᵀ)
        self.body, self.hull = body, tf.transform_points(rotation.T, hull)
        extent = max(float(np.ptp(hull, axis=0).max()), lf.MIN_EXTENT)
        self._depth_range = float(np.ptp(hull[:, 2]))
        samples = receivers if len(receivers) else body
        sizes = lf.texel_world_sizes(proj @ rotation, rotation, samples, self.resolution, TEXEL_STEP * extent)
        return [LightView(rotation, proj, texel_world=float(np.median(sizes)))], notes

    def _receivers(self, frame, slot) -> np.ndarray:
        """The evaluated receiver points (M, 3) the focus box bounds (``fit``; empty for ``scene``)."""
        if self.fit == "scene":
            return np.zeros((0, 3))
        if self.fit == "shadowable":
            return shadowable_receivers(frame, slot)
        return frame.compact_position[slot.evaluated]

    def stats(self) -> dict:
        """The depth map's figures, the warp's ``n_used`` (None: uniform fallback) and
        ``gamma_deg``; ``depth_range`` is the map's extent along the light (world units) and
        ``texel_world`` the median world texel size over the covered receivers."""
        out = super().stats()
        out.update(depth_range=self._depth_range, n_used=self.n_used, gamma_deg=self.gamma_deg,
                   near_plane=None, far_plane=None)  # the warp's planes are not the light's
        return out
