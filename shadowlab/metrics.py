"""Per-pixel and boundary metrics of a visibility image against the ground truth (DESIGN §7).

Pure numpy/scipy, no GL: inputs are float arrays (height, width) of visibility in [0, 1]
(1 = lit) and a bool mask of evaluated pixels. Thresholding is at 0.5: V < 0.5 is shadowed.
"""
from __future__ import annotations

import numpy as np
from scipy import ndimage

THRESHOLD = 0.5


def _ratio(num: int, den: int) -> float:
    """num / den, or 0 when the denominator is empty (DESIGN §7)."""
    return float(num) / float(den) if den else 0.0


def shadow_boundary(shadowed: np.ndarray, evaluated: np.ndarray) -> np.ndarray:
    """Boundary pixels of a binary shadow mask: evaluated pixels with a 4-neighbour that is
    also evaluated and on the other side (lit vs shadowed). Bool (height, width)."""
    s = shadowed & evaluated
    out = np.zeros_like(s)
    for axis in (0, 1):
        a = [slice(None)] * 2
        b = [slice(None)] * 2
        a[axis], b[axis] = slice(0, -1), slice(1, None)
        both = evaluated[tuple(a)] & evaluated[tuple(b)]
        differ = both & (s[tuple(a)] != s[tuple(b)])
        out[tuple(a)] |= differ
        out[tuple(b)] |= differ
    return out


def boundary_distances(v_boundary: np.ndarray, g_boundary: np.ndarray) -> np.ndarray:
    """For each pixel of ``v_boundary``, the Euclidean distance in pixels to the nearest pixel
    of ``g_boundary`` (distance transform). Empty when either boundary is empty."""
    if not v_boundary.any() or not g_boundary.any():
        return np.zeros(0)
    dist = ndimage.distance_transform_edt(~g_boundary)
    return dist[v_boundary]


def compare(vis: np.ndarray, truth: np.ndarray, evaluated: np.ndarray) -> dict:
    """All metrics of ``vis`` against ``truth`` over ``evaluated`` pixels.

    Returns the contract columns (error_rate, false_shadow_rate, false_lit_rate,
    boundary_error_px, evaluated_pixels, visibility_mae) and their counts, plus the symmetric
    boundary figures (Hausdorff and 95th percentile, in pixels). When only one of the two
    images has a shadow boundary, the boundary error is the image diagonal (the worst case).
    """
    if vis.shape != truth.shape or vis.shape != evaluated.shape:
        raise ValueError(f"shape mismatch: {vis.shape}, {truth.shape}, {evaluated.shape}")
    ev = evaluated.astype(bool)
    v_sh = (vis < THRESHOLD) & ev
    g_sh = (truth < THRESHOLD) & ev
    n = int(ev.sum())
    g_lit, g_shadow = int((ev & ~g_sh).sum()), int(g_sh.sum())
    false_shadow = int((v_sh & ~g_sh).sum())
    false_lit = int((g_sh & ~v_sh & ev).sum())
    vb, gb = shadow_boundary(v_sh, ev), shadow_boundary(g_sh, ev)
    diag = float(np.hypot(*vis.shape))
    if vb.any() and gb.any():
        d_vg = boundary_distances(vb, gb)
        d_gv = boundary_distances(gb, vb)
        both = np.concatenate([d_vg, d_gv])
        boundary, hausdorff, p95 = float(d_vg.mean()), float(both.max()), float(np.percentile(both, 95))
    elif vb.any() or gb.any():
        boundary = hausdorff = p95 = diag
    else:
        boundary = hausdorff = p95 = 0.0
    mae = float(np.abs(vis[ev] - truth[ev]).mean()) if n else 0.0
    umbra = vis[g_sh & v_sh]
    # Spread of visibility inside the umbra (pixels both call shadowed, so that misplaced edges
    # do not count): 0 for a uniform shadow; multiple modulation (planar shadows' double
    # blending) makes it vary. On a receiver of constant albedo the shaded intensity is affine
    # in visibility at fixed N·L, so this is the shading's spread inside the shadow.
    umbra_std = float(umbra.std()) if umbra.size else 0.0
    return {
        "evaluated_pixels": n,
        "error_rate": _ratio(false_shadow + false_lit, n),
        "false_shadow_rate": _ratio(false_shadow, g_lit),
        "false_lit_rate": _ratio(false_lit, g_shadow),
        "boundary_error_px": boundary,
        "visibility_mae": mae,
        "umbra_visibility_std": umbra_std,
        "truth_lit_pixels": g_lit,
        "truth_shadowed_pixels": g_shadow,
        "false_shadow_pixels": false_shadow,
        "false_lit_pixels": false_lit,
        "boundary_pixels": int(vb.sum()),
        "boundary_hausdorff_px": hausdorff,
        "boundary_p95_px": p95,
    }


def error_classes(vis: np.ndarray, truth: np.ndarray, evaluated: np.ndarray) -> np.ndarray:
    """Per-pixel class, uint8 (height, width): 0 not evaluated, 1 lit (correct), 2 shadowed
    (correct), 3 false shadow, 4 false lit — the error map's legend."""
    ev = evaluated.astype(bool)
    v_sh, g_sh = vis < THRESHOLD, truth < THRESHOLD
    out = np.zeros(vis.shape, np.uint8)
    out[ev & ~v_sh & ~g_sh] = 1
    out[ev & v_sh & g_sh] = 2
    out[ev & v_sh & ~g_sh] = 3
    out[ev & ~v_sh & g_sh] = 4
    return out


def contact_pixels(object_id: np.ndarray, position: np.ndarray, footprint: np.ndarray,
                   receivers: np.ndarray, touch: float = 3.0) -> np.ndarray:
    """Receiver pixels on a contact line: a 4-neighbour shows another object whose surface
    point is within ``touch`` pixel footprints in world space (the objects touch there, rather
    than one hiding the other). ``object_id`` int (H, W), ``position`` float (H, W, 3),
    ``footprint`` float (H, W): world size of a pixel; returns bool (H, W)."""
    out = np.zeros(object_id.shape, bool)
    for axis in (0, 1):
        for shift in (1, -1):
            nb_obj = np.roll(object_id, shift, axis=axis)
            nb_pos = np.roll(position, shift, axis=axis)
            valid = np.ones_like(out)
            edge = [slice(None)] * 2
            edge[axis] = slice(0, 1) if shift == 1 else slice(-1, None)
            valid[tuple(edge)] = False  # no wrap-around
            with np.errstate(invalid="ignore"):
                close = np.linalg.norm(position - nb_pos, axis=-1) < touch * footprint
            out |= valid & receivers & (nb_obj >= 0) & (nb_obj != object_id) & close
    return out


def contact_gap(vis: np.ndarray, truth: np.ndarray, evaluated: np.ndarray, contact: np.ndarray,
                band: int = 8) -> float:
    """Peter-panning (HARD_CASES 'contact gap'): false-lit pixels within ``band`` pixels of the
    shadowed part of the contact lines (where the truth is in shadow beside the contact: only
    there can a lit gap open), divided by that part's length in pixels — the mean width, in
    pixels, of the lit gap between a caster and its shadow where they touch. 0 when no contact
    line is in shadow."""
    shadowed_contact = contact & (truth < THRESHOLD)
    if not shadowed_contact.any():
        return 0.0
    near = ndimage.binary_dilation(shadowed_contact, iterations=band)
    false_lit = (truth < THRESHOLD) & (vis >= THRESHOLD) & evaluated & near
    return float(false_lit.sum()) / float(shadowed_contact.sum())
