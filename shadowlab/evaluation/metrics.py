"""Per-pixel and boundary metrics of a visibility image against the ground truth (docs/metrics.md),
and the one table of metrics.csv columns (:data:`COLUMNS`) that drives the CSV, the HTML report
and the CLI summary: adding a metric is one entry there.

Pure numpy/scipy, no GL: inputs are float arrays (height, width) of visibility in [0, 1]
(1 = lit), row 0 = top, and a bool mask of evaluated pixels. Thresholding is at 0.5: V < 0.5
is shadowed.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Any, Callable

import numpy as np
from scipy import ndimage

from ..util.format import format_column

THRESHOLD = 0.5


def _ratio(num: int, den: int) -> float:
    """num / den, or 0 when the denominator is empty (docs/metrics.md)."""
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


class Evaluation:
    """One visibility image judged against the truth over the evaluated pixels: the masks and
    counts every metric is computed from, each computed once.

    ``vis``, ``truth``: float (H, W) in [0, 1]; ``evaluated``: bool (H, W); ``contact``: bool
    (H, W) contact-line pixels (see :func:`contact_pixels`), or None when not known;
    ``overlap``: bool (H, W) pixels whose segment to the light crosses two or more casters
    (:func:`shadowlab.evaluation.occluder_layers.occluder_layers` ≥ 2), or None when not known.
    """

    def __init__(self, vis: np.ndarray, truth: np.ndarray, evaluated: np.ndarray, contact: np.ndarray | None = None,
                 overlap: np.ndarray | None = None, components: dict | None = None):
        if vis.shape != truth.shape or vis.shape != evaluated.shape:
            raise ValueError(f"shape mismatch: {vis.shape}, {truth.shape}, {evaluated.shape}")
        self.vis, self.truth, self.contact, self.overlap = vis, truth, contact, overlap
        #: The technique's component images (Technique.component_images): ``base`` and
        #: ``contact_shadow`` (contact shadows), ``classifier`` (hybrid ray tracing).
        self.components = dict(components or {})
        self.ev = ev = evaluated.astype(bool)
        self.v_sh = (vis < THRESHOLD) & ev
        self.g_sh = (truth < THRESHOLD) & ev
        self.n = int(ev.sum())
        self.g_lit, self.g_shadow = int((ev & ~self.g_sh).sum()), int(self.g_sh.sum())
        self.false_shadow = int((self.v_sh & ~self.g_sh).sum())
        self.false_lit = int((self.g_sh & ~self.v_sh & ev).sum())

    @cached_property
    def soft(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The truth's (umbra, penumbra, fully lit) masks, :func:`soft_regions`."""
        return soft_regions(self.truth, self.ev)

    @cached_property
    def boundaries(self) -> tuple[np.ndarray, np.ndarray]:
        """Shadow boundaries of V and G, bool (H, W) each."""
        return shadow_boundary(self.v_sh, self.ev), shadow_boundary(self.g_sh, self.ev)

    @cached_property
    def truth_boundary_pixels(self) -> int:
        """Pixels on the truth's shadow boundary (:func:`shadow_boundary` of G thresholded)."""
        return int(self.boundaries[1].sum())

    @cached_property
    def boundary_figures(self) -> tuple[float, float, float]:
        """(mean distance V → G, symmetric Hausdorff, symmetric 95th percentile), pixels. When
        only one of the two images has a shadow boundary: the image diagonal (the worst case)."""
        vb, gb = self.boundaries
        if vb.any() and gb.any():
            d_vg = boundary_distances(vb, gb)
            both = np.concatenate([d_vg, boundary_distances(gb, vb)])
            return float(d_vg.mean()), float(both.max()), float(np.percentile(both, 95))
        if vb.any() or gb.any():
            diag = float(np.hypot(*self.vis.shape))
            return diag, diag, diag
        return 0.0, 0.0, 0.0


def _visibility_mae(e: Evaluation) -> float:
    return float(np.abs(e.vis[e.ev] - e.truth[e.ev]).mean()) if e.n else 0.0


def _umbra_visibility_std(e: Evaluation) -> float:
    # Spread of visibility inside the umbra (pixels both call shadowed, so that misplaced edges
    # do not count): 0 for a uniform shadow; multiple modulation (planar shadows' double
    # blending) makes it vary. On a receiver of constant albedo the shaded intensity is affine
    # in visibility at fixed N·L, so this is the shading's spread inside the shadow.
    umbra = e.vis[e.g_sh & e.v_sh]
    return float(umbra.std()) if umbra.size else 0.0


def _contact_gap_px(e: Evaluation) -> float:
    return contact_gap(e.vis, e.truth, e.ev, e.contact)


# Soft-shadow metrics (docs/metrics.md). Visibility of an area light from a point P is the fraction,
# by area, of the emitting surface facing P that P sees unoccluded; light samples below P's
# tangent plane count as occluded, and a point behind a one-sided light sees none of it (V = 0).
# The truth's visibility splits the evaluated pixels in three: umbra (G <= PENUMBRA_LOW), fully
# lit (G >= PENUMBRA_HIGH) and the penumbra between them. The bounds sit a little inside 0 and 1
# so that a sampled truth's few stray samples (1/1024 per sample at the default) do not turn an
# umbra or a lit pixel into penumbra.
PENUMBRA_LOW = 0.02
PENUMBRA_HIGH = 0.98


def _visibility_rmse(e: Evaluation) -> float:
    return float(np.sqrt(np.mean((e.vis[e.ev] - e.truth[e.ev]) ** 2))) if e.n else 0.0


def soft_regions(truth: np.ndarray, evaluated: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The truth's umbra (G <= PENUMBRA_LOW), penumbra (PENUMBRA_LOW < G < PENUMBRA_HIGH) and
    fully lit region (G >= PENUMBRA_HIGH) over the evaluated pixels: three disjoint bool
    (H, W) masks whose union is ``evaluated``. ``truth`` float (H, W) in [0, 1]."""
    ev = evaluated.astype(bool)
    umbra = ev & (truth <= PENUMBRA_LOW)
    lit = ev & (truth >= PENUMBRA_HIGH)
    return umbra, ev & ~umbra & ~lit, lit


def _penumbra_mae(e: Evaluation) -> float:
    pen = e.soft[1]
    return float(np.abs(e.vis[pen] - e.truth[pen]).mean()) if pen.any() else 0.0


def _umbra_error_pixels(e: Evaluation) -> int:
    # in the truth's umbra, G thresholded is shadowed: an error is V lit
    return int((e.soft[0] & (e.vis >= THRESHOLD)).sum())


def _lit_error_pixels(e: Evaluation) -> int:
    # in the truth's fully lit region, G thresholded is lit: an error is V shadowed
    return int((e.soft[2] & (e.vis < THRESHOLD)).sum())


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
    """Peter-panning (docs/hard-cases.md 'contact gap'): false-lit pixels within ``band`` pixels of the
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


def bleeding_region(truth: np.ndarray, evaluated: np.ndarray, overlap: np.ndarray) -> np.ndarray:
    """Where light bleeding can be judged: evaluated pixels in the truth's umbra (G <=
    PENUMBRA_LOW) whose segment to the light crosses two or more casters (``overlap``): casters
    overlapping in depth, the configuration that makes filtered maps leak (Donnelly & Lauritzen
    2006 §5). Bool (H, W)."""
    return evaluated.astype(bool) & (truth <= PENUMBRA_LOW) & overlap.astype(bool)


def light_bleeding(vis: np.ndarray, truth: np.ndarray, evaluated: np.ndarray, overlap: np.ndarray) -> float:
    """Light bleeding (docs/hard-cases.md; issue 13): the mean wrongly passed light max(0, V − G) over
    :func:`bleeding_region` — the share of that region a technique lights, weighted by how much
    (for a binary V exactly the false-lit share). 0 when the region is empty."""
    region = bleeding_region(truth, evaluated, overlap)
    return float(np.clip(vis[region] - truth[region], 0.0, None).mean()) if region.any() else 0.0


def over_darkening(vis: np.ndarray, truth: np.ndarray, evaluated: np.ndarray, contact: np.ndarray,
                   band: int = 8) -> float:
    """Over-darkening (issue 13; the mirror of :func:`contact_gap`): the missing light
    max(0, G − V) summed over truly lit pixels (G >= 0.5) within ``band`` pixels of the lit part
    of the contact lines, divided by that part's length in pixels — the mean width, in pixels,
    of a false shadow along lit contacts (for a binary V: false-shadow pixels per contact
    pixel). Filtered maps darken there when the filter mixes the caster's depth with its
    receiver's. 0 when no contact line is lit."""
    lit_contact = contact & (truth >= THRESHOLD) & evaluated
    if not lit_contact.any():
        return 0.0
    near = ndimage.binary_dilation(lit_contact, iterations=band) & evaluated & (truth >= THRESHOLD)
    return float(np.clip(truth[near] - vis[near], 0.0, None).sum()) / float(lit_contact.sum())


# --------------------------------------------------------------------------- the parts of a combined technique

#: Pixels either side of an edge that count as where two shadows' edges meet (:func:`seam_band`).
SEAM_BAND = 3


def seam_band(base: np.ndarray, contact_shadow: np.ndarray, evaluated: np.ndarray, band: int = SEAM_BAND) -> np.ndarray:
    """Where contact shadows and the map's shadow meet (issue 39; Unity HDRP's docs warn of "a
    visible seam between the two types of shadow"): evaluated pixels within ``band`` 4-neighbour
    steps (an L1 distance) of both the contact shadow's boundary and the map shadow's boundary
    (each thresholded at 0.5).
    Bool (H, W); empty where either shadow has no edge."""
    ev = evaluated.astype(bool)
    near = []
    for image in (base, contact_shadow):
        edge = shadow_boundary(image < THRESHOLD, ev)
        if not edge.any():
            return np.zeros_like(ev)
        near.append(ndimage.binary_dilation(edge, iterations=band))
    return near[0] & near[1] & ev


def _contact_changed(e: Evaluation) -> np.ndarray:
    """Pixels the contact shadow turned from lit (the map alone) to shadowed (combined)."""
    return e.ev & (e.components["base"] >= THRESHOLD) & (e.vis < THRESHOLD)


def _seam(e: Evaluation) -> tuple[int, int]:
    """(pixels in the seam band, wrong pixels there), computed once per evaluation."""
    if "seam" not in e.__dict__:
        band = seam_band(e.components["base"], e.components["contact_shadow"], e.ev)
        e.__dict__["seam"] = (int(band.sum()), int(((e.v_sh != e.g_sh) & band).sum()))
    return e.__dict__["seam"]


def _contact_gap_closed(e: Evaluation) -> float:
    return (contact_gap(e.components["base"], e.truth, e.ev, e.contact)
            - contact_gap(e.vis, e.truth, e.ev, e.contact))


def classifier_errors(classifier: np.ndarray, truth: np.ndarray, evaluated: np.ndarray) -> tuple[int, int]:
    """(pixels a classifier decided, those it decided wrongly): ``classifier`` is 1 where it called
    a pixel surely lit, 0 surely shadowed, NaN undecided; wrong where the truth, thresholded at
    0.5, disagrees (a pixel called surely lit that is in shadow, or the reverse)."""
    sure = evaluated.astype(bool) & np.isfinite(classifier)
    wrong = sure & ((np.nan_to_num(classifier, nan=0.5) >= THRESHOLD) != (truth >= THRESHOLD))
    return int(sure.sum()), int(wrong.sum())


# --------------------------------------------------------------------------- degenerate configurations

#: A configuration is *degenerate* on a light when the truth has a shadow worth drawing there —
#: more than :data:`DEGENERATE_TRUTH_SHARE` of the evaluated pixels shadowed — and the
#: configuration draws under :data:`DEGENERATE_KEPT_SHARE` of it: it shadows fewer pixels than a
#: tenth of the truth's shadowed pixels (both thresholded at :data:`THRESHOLD`, V < 0.5 shadowed,
#: as the thresholded rates count them). Why: the error rate is a share of *all* evaluated
#: pixels, so a configuration that draws no shadow at all scores the truth's shadowed share —
#: a few per cent on box_on_plane, the share of the evaluated pixels the box shadows — a number
#: that reads as "slightly wrong" while the picture has lost every shadow (issue 35). The truth's share must be
#: above 1 % so that a scene whose shadow is a few pixels (a shadow clipped by the frame, a
#: grazing light) is not called degenerate over pixel noise; a tenth leaves room for a
#: configuration that draws a thin or partial shadow (peter-panning, a blurred umbra) and still
#: catches one whose shadow is gone but for stray acne or a few edge pixels.
DEGENERATE_TRUTH_SHARE = 0.01
DEGENERATE_KEPT_SHARE = 0.1


def shadowed_pixels(row) -> int:
    """The evaluated pixels a configuration shadows (V < 0.5), from a metrics row's counts: the
    truth's shadowed pixels, less those it lit wrongly, plus those it shadowed wrongly."""
    return int(row["truth_shadowed_pixels"]) - int(row["false_lit_pixels"]) + int(row["false_shadow_pixels"])


def is_degenerate(truth_shadowed: int, shadowed: int, evaluated: int) -> bool:
    """Whether a configuration that shadows ``shadowed`` of ``evaluated`` pixels, where the truth
    shadows ``truth_shadowed``, is degenerate: the truth shadows more than
    :data:`DEGENERATE_TRUTH_SHARE` of the evaluated pixels and the configuration under
    :data:`DEGENERATE_KEPT_SHARE` of the truth's count (see there for why)."""
    return bool(evaluated > 0 and truth_shadowed > DEGENERATE_TRUTH_SHARE * evaluated
                and shadowed < DEGENERATE_KEPT_SHARE * truth_shadowed)


def row_is_degenerate(row) -> bool:
    """:func:`is_degenerate` of a metrics row (its ``evaluated_pixels``, ``truth_shadowed_pixels``,
    ``false_lit_pixels``, ``false_shadow_pixels``); False when a count is missing."""
    try:
        return is_degenerate(int(row["truth_shadowed_pixels"]), shadowed_pixels(row), int(row["evaluated_pixels"]))
    except (KeyError, TypeError, ValueError):
        return False


# --------------------------------------------------------------------------- the column table

@dataclass(frozen=True)
class Column:
    """One metrics.csv column: its meaning, how it is shown, and — for metrics — how it is
    computed from an :class:`Evaluation`.

    ``fmt``: 'percent' (a rate), 'px', 'ms', 'count', 'value' or 'text'; ``contract``: required
    by docs/contracts.md#run-directory (these come first in the CSV, in table order); ``summary``: shown in the CLI's
    summary; ``report``: shown in the HTML metrics table; ``needs``: inputs of the evaluation the
    metric cannot do without (a metric whose input is missing is left out).
    """

    name: str
    doc: str
    fmt: str = "value"
    compute: Callable[[Evaluation], Any] | None = None
    contract: bool = False
    summary: bool = False
    report: bool = False
    needs: tuple[str, ...] = ()
    #: A soft-shadow metric: the HTML report shows it only for runs with a penumbra
    #: (:func:`format_table`); on hard shadows it repeats the thresholded rates.
    soft: bool = False
    #: Artefact metrics a baseline holds (``shadowlab check``): (absolute, relative) tolerance —
    #: a value is a regression when it exceeds baseline + max(abs, rel × baseline). Larger is worse.
    tolerance: tuple[float, float] | None = None

    def format(self, value) -> str:
        """``value`` as shown in the report and the CLI (:func:`shadowlab.util.format.format_column`)."""
        return format_column(value, self.fmt)


#: Baseline tolerances (absolute, relative). Rates: 0.02 % of the pixels (61 pixels at 640x480)
#: or 5 % of the value — wide enough for the few pixels of rasterisation ties that differ
#: between drivers (docs/architecture.md#full-pass-state-shadowlabgpuglstatepy), below what a tenfold too small bias does to the grazing
#: receivers of sm_grazing. Distances: a quarter of a pixel or 10 %.
RATE_TOLERANCE = (2e-4, 0.05)
DISTANCE_TOLERANCE = (0.25, 0.1)
#: visibility_rmse: the rate tolerance's share of pixels flipped from right to wholly wrong
#: raises the mean square by at most 2e-4, the RMSE by at most its square root (0.014).
RMSE_TOLERANCE = (float(np.sqrt(RATE_TOLERANCE[0])), 0.05)


def _metric(name, doc, compute, fmt="value", **kw) -> Column:
    return Column(name, doc, fmt, compute, **kw)


#: The columns every metrics.csv has, in CSV order (then ``param_<name>`` per parameter,
#: ``pass_<name>_ms`` per timed pass, and the techniques' own cost columns: see
#: :func:`order_columns`). The contract columns of docs/contracts.md#run-directory are marked.
COLUMNS: tuple[Column, ...] = (
    Column("scene", "scene name", "text", contract=True),
    Column("light", "index of the light in the scene file", "count", contract=True, summary=True, report=True),
    Column("technique", "technique name", "text", contract=True),
    Column("params", "every parameter, key=value,...", "text", contract=True),
    Column("width", "image width, pixels", "count", contract=True),
    Column("height", "image height, pixels", "count", contract=True),
    _metric("evaluated_pixels", "pixels evaluated: visible receivers facing the light inside its footprint",
            lambda e: e.n, "count", contract=True, report=True),
    _metric("error_rate", "wrong / evaluated pixels (V, G thresholded at 0.5)",
            lambda e: _ratio(e.false_shadow + e.false_lit, e.n), "percent", contract=True, summary=True, report=True,
            tolerance=RATE_TOLERANCE),
    _metric("false_shadow_rate", "wrongly shadowed / truly lit pixels (acne, over-darkening)",
            lambda e: _ratio(e.false_shadow, e.g_lit), "percent", contract=True, summary=True, report=True,
            tolerance=RATE_TOLERANCE),
    _metric("false_lit_rate", "wrongly lit / truly shadowed pixels (leaks, peter-panning, missing shadows)",
            lambda e: _ratio(e.false_lit, e.g_shadow), "percent", contract=True, summary=True, report=True,
            tolerance=RATE_TOLERANCE),
    _metric("boundary_error_px", "mean distance from V's shadow boundary to G's, pixels",
            lambda e: e.boundary_figures[0], "px", contract=True, summary=True, report=True,
            tolerance=DISTANCE_TOLERANCE),
    Column("time_ms_median", "median time of the technique's timed passes, ms", "ms", contract=True, summary=True,
           report=True),
    Column("time_ms_iqr", "interquartile range of those times, ms", "ms", contract=True, report=True),
    _metric("edge_error_rate", "wrong pixels per pixel of the truth's shadow boundary (hard-shadow verdicts: what "
                               "differs between techniques happens along edges); 0 when the truth has no boundary",
            lambda e: _ratio(e.false_shadow + e.false_lit, e.truth_boundary_pixels), "percent", summary=True,
            report=True),
    Column("time_ms_q25", "first quartile of the timed renders, ms (with time_ms_q75: the repeat interval)", "ms"),
    Column("time_ms_q75", "third quartile of the timed renders, ms", "ms"),
    Column("setup_ms", "set-up for the light (preprocessing, GL objects, programs), ms: paid once for a static "
                       "light, every frame for a moving one", "ms", summary=True, report=True),
    Column("peak_rss_mib", "peak resident memory of the process during the measurement, MiB", "value"),
    Column("light_type", "point, directional, spot or target_direct", "text"),
    Column("label", "the full spec, name:key=value,...", "text"),
    Column("short_label", "name and the parameters that differ from their defaults", "text"),
    Column("reference", "True on the ground truth's own row", "text"),
    _metric("visibility_mae", "mean |V - G| over evaluated pixels, without thresholding",
            _visibility_mae, report=True, tolerance=RATE_TOLERANCE),
    _metric("umbra_visibility_std", "spread of V inside the shadow (multiple modulation)",
            _umbra_visibility_std, report=True, tolerance=(0.01, 0.1)),
    _metric("truth_lit_pixels", "evaluated pixels the truth has lit", lambda e: e.g_lit, "count"),
    _metric("truth_shadowed_pixels", "evaluated pixels the truth has shadowed", lambda e: e.g_shadow, "count"),
    _metric("truth_boundary_pixels", "evaluated pixels on the truth's shadow boundary (edge_error_rate's denominator)",
            lambda e: e.truth_boundary_pixels, "count"),
    _metric("false_shadow_pixels", "wrongly shadowed pixels", lambda e: e.false_shadow, "count"),
    _metric("false_lit_pixels", "wrongly lit pixels", lambda e: e.false_lit, "count"),
    _metric("boundary_pixels", "pixels on V's shadow boundary", lambda e: int(e.boundaries[0].sum()), "count"),
    _metric("boundary_hausdorff_px", "symmetric Hausdorff distance between the boundaries, pixels",
            lambda e: e.boundary_figures[1], "px"),
    _metric("boundary_p95_px", "95th percentile of the symmetric boundary distances, pixels",
            lambda e: e.boundary_figures[2], "px", tolerance=DISTANCE_TOLERANCE),
    _metric("visibility_rmse", "root mean square of V - G over evaluated pixels, without thresholding",
            _visibility_rmse, report=True, soft=True, tolerance=RMSE_TOLERANCE),
    _metric("penumbra_mae", f"mean |V - G| over the truth's penumbra ({PENUMBRA_LOW} < G < {PENUMBRA_HIGH}); "
                            "0 when it is empty", _penumbra_mae, report=True, soft=True, tolerance=(0.01, 0.1)),
    _metric("penumbra_pixels", "evaluated pixels in the truth's penumbra", lambda e: int(e.soft[1].sum()), "count"),
    _metric("umbra_error_rate", f"wrongly lit / umbra pixels (G <= {PENUMBRA_LOW}): light through a full shadow",
            lambda e: _ratio(_umbra_error_pixels(e), int(e.soft[0].sum())), "percent", report=True, soft=True,
            tolerance=RATE_TOLERANCE),
    _metric("umbra_leak", f"mean wrongly passed light max(0, V - G) over the truth's umbra (G <= {PENUMBRA_LOW}): "
                          "light leaking into a full shadow, however faint (umbra_error_rate counts only V >= 0.5)",
            lambda e: float(np.clip(e.vis[e.soft[0]] - e.truth[e.soft[0]], 0.0, None).mean()) if e.soft[0].any()
            else 0.0, soft=True),
    _metric("umbra_pixels", f"evaluated pixels in the truth's umbra (G <= {PENUMBRA_LOW})",
            lambda e: int(e.soft[0].sum()), "count"),
    _metric("umbra_error_pixels", "umbra pixels V has lit", _umbra_error_pixels, "count"),
    _metric("lit_error_rate", f"wrongly shadowed / fully lit pixels (G >= {PENUMBRA_HIGH}): shadow where the "
                              "whole light is seen", lambda e: _ratio(_lit_error_pixels(e), int(e.soft[2].sum())),
            "percent", report=True, soft=True, tolerance=RATE_TOLERANCE),
    _metric("lit_pixels", f"evaluated pixels the truth has fully lit (G >= {PENUMBRA_HIGH})",
            lambda e: int(e.soft[2].sum()), "count"),
    _metric("lit_error_pixels", "fully lit pixels V has shadowed", _lit_error_pixels, "count"),
    Column("truth_stderr_max", "the sampled truth's per-pixel standard error bound (<= 0.5/sqrt(samples); 0 for "
                               "a point-like light): soft-shadow errors mean something only well above it", "value"),
    Column("flip_mean", "mean FLIP error (Andersson et al. 2020) of the shaded image against the truth's, over covered "
                        "pixels; 0 = identical (optional: shadowlab[perceptual])", "value", report=True),
    Column("ssim", "mean SSIM (Wang et al. 2004; Gaussian window 1.5) of the shaded image against the truth's, over "
                   "covered pixels; 1 = identical (optional: shadowlab[perceptual])", "value", report=True),
    Column("radiance_error", "the shaded image (every light) against the truth's: mean relative luminance error "
                             "|L - L*| / max(L*, floor) over covered pixels (floor: 5 % of the truth's mean); the same "
                             "on every light's row", "percent", summary=True, report=True),
    Column("radiance_error_p95", "95th percentile over covered pixels of the relative luminance error", "percent",
           report=True),
    Column("radiance_bias", "signed mean relative luminance error: > 0 brighter than the truth (dropped shadows), "
                            "< 0 darker (dropped lights)", "percent", report=True),
    Column("radiance_error_light", "this light's share of the image error: mean |L_i - L*_i| / max(L*, floor) over "
                                   "covered pixels (its error weighted by its contribution)", "percent"),
    Column("light_share", "this light's share of the truth image's luminance", "percent"),
    _metric("contact_gap_px", "peter-panning: mean width of the false-lit band along shadowed contact lines, pixels",
            _contact_gap_px, "px", report=True, needs=("contact",), tolerance=(0.5, 0.1)),
    _metric("over_darkening_px", "over-darkening: mean width of the false shadow (weighted by the missing light) "
                                 "along lit contact lines, pixels", lambda e: over_darkening(e.vis, e.truth, e.ev, e.contact),
            "px", report=True, needs=("contact",), tolerance=(0.5, 0.1)),
    _metric("light_bleeding", "light bleeding: mean wrongly passed light max(0, V - G) in the truth's umbra where "
                              "two or more casters overlap in depth; 0 when there is no such region",
            lambda e: light_bleeding(e.vis, e.truth, e.ev, e.overlap), report=True, needs=("overlap",),
            tolerance=(0.01, 0.1)),
    _metric("bleeding_pixels", "evaluated pixels in the truth's umbra behind two or more casters (light_bleeding's "
                               "region)", lambda e: int(bleeding_region(e.truth, e.ev, e.overlap).sum()), "count",
            needs=("overlap",)),
    _metric("contact_recovered_pixels", "contact shadows: truly shadowed pixels the map alone left lit and the "
                                        "contact march shadowed (the contact gap closed)",
            lambda e: int((_contact_changed(e) & e.g_sh).sum()), "count", report=True, needs=("base", "contact_shadow")),
    _metric("contact_false_pixels", "contact shadows: truly lit pixels the map alone left lit and the contact march "
                                    "shadowed (thickness halos: false shadows it introduced)",
            lambda e: int((_contact_changed(e) & ~e.g_sh).sum()), "count", report=True,
            needs=("base", "contact_shadow")),
    _metric("contact_gap_closed_px", "contact shadows: the map alone's contact gap minus the combination's, pixels",
            _contact_gap_closed, "px", needs=("base", "contact_shadow", "contact")),
    _metric("seam_pixels", f"contact shadows: evaluated pixels within {SEAM_BAND} px of both the contact shadow's and "
                           "the map shadow's edges (where the two meet)", lambda e: _seam(e)[0], "count",
            needs=("base", "contact_shadow")),
    _metric("seam_error_rate", "contact shadows: wrong / seam pixels (the error where contact and map shadows meet); "
                               "0 when they do not meet", lambda e: _ratio(_seam(e)[1], _seam(e)[0]), "percent",
            report=True, needs=("base", "contact_shadow")),
    _metric("classifier_sure_pixels", "hybrid ray tracing: evaluated pixels its shadow-map classifier called surely lit "
                                      "or surely shadowed (no ray traced)",
            lambda e: classifier_errors(e.components["classifier"], e.truth, e.ev)[0], "count", needs=("classifier",)),
    _metric("classifier_error_pixels", "hybrid ray tracing: pixels its classifier called surely lit or shadowed that the "
                                       "truth disagrees with", lambda e: classifier_errors(e.components["classifier"],
                                                                                           e.truth, e.ev)[1],
            "count", report=True, needs=("classifier",)),
    Column("degenerate", f"True when the truth shadows more than {100 * DEGENERATE_TRUTH_SHARE:g} % of the evaluated "
                         f"pixels and the configuration under {DEGENERATE_KEPT_SHARE:g} of the truth's shadowed pixels "
                         "(it draws almost no shadow); False on the truth's rows and on lights a shadow budget mostly dropped", "text"),
    Column("occluder_height_median", "median distance along the shadow ray from the truth's shadowed pixels to their "
                                     "first caster (the casters' height above their shadows), world units; NaN when "
                                     "no shadowed pixel meets one", "value"),
    Column("texel_footprint_p50", "median texel footprint m (Lloyd et al. 2008): the longest axis of the shadow-map "
                                  "texel covering a pixel, in pixels (<= 1 alias-free, > 10 severe); maps only", "px",
           report=True),
    Column("texel_footprint_p95", "95th percentile of the texel footprint m over evaluated pixels, pixels", "px",
           report=True),
    Column("texel_footprint_max", "largest texel footprint m over evaluated pixels, pixels", "px", report=True),
    Column("time_repeats", "timed runs behind the median", "count"),
    Column("gpu_time_ms_median", "median GL_TIME_ELAPSED of the timed passes, ms (real GPUs only)", "ms"),
)
COLUMN_BY_NAME = {c.name: c for c in COLUMNS}
#: The docs/contracts.md#run-directory columns every metrics.csv starts with, in order.
CONTRACT_COLUMNS = [c.name for c in COLUMNS if c.contract]
METRIC_COLUMNS = [c for c in COLUMNS if c.compute is not None]
#: The artefact metrics a baseline holds (``shadowlab check``), with their tolerances.
HELD_COLUMNS = [c for c in COLUMNS if c.tolerance is not None]


def compare(vis: np.ndarray, truth: np.ndarray, evaluated: np.ndarray, contact: np.ndarray | None = None,
            overlap: np.ndarray | None = None, components: dict | None = None) -> dict:
    """Every metric column of ``vis`` against ``truth`` over ``evaluated`` pixels (those that
    need contact lines only when ``contact`` is given, those that need the overlapping-casters
    mask only when ``overlap`` is, those that judge a technique's parts only when its
    ``components`` hold them: :meth:`shadowlab.techniques.base.Technique.component_images`), as
    {column: value}."""
    e = Evaluation(vis, truth, evaluated, contact, overlap, components)
    have = {"contact": contact is not None, "overlap": overlap is not None, **{k: True for k in e.components}}
    return {c.name: c.compute(e) for c in METRIC_COLUMNS if all(have.get(k, False) for k in c.needs)}


def order_columns(names, pass_order=()) -> list[str]:
    """Column names in CSV order: the table's columns in table order; then ``param_<name>``;
    then ``pass_<name>_ms`` in ``pass_order`` (the techniques' drawing order); then the
    techniques' own cost columns, as given."""
    names = list(dict.fromkeys(names))
    known = [c.name for c in COLUMNS if c.name in names]
    rest = [n for n in names if n not in COLUMN_BY_NAME]
    params = [n for n in rest if n.startswith("param_")]
    rank = {f"pass_{p}_ms": i for i, p in enumerate(dict.fromkeys(pass_order))}
    passes = sorted((n for n in rest if n.startswith("pass_") and n.endswith("_ms")), key=lambda n: rank.get(n, len(rank)))
    return known + params + passes + [n for n in rest if n not in params and n not in passes]


def _numeric(series) -> np.ndarray:
    """A column as float (NaN where not a number)."""
    import pandas as pd

    return pd.to_numeric(series, errors="coerce").to_numpy(dtype=float)


def format_table(df, which: str, first: str = "short_label"):
    """The rows of ``df`` as strings for display: ``first`` (the configuration), then the table
    columns marked ``which`` ('summary' or 'report') that ``df`` has, each in its format; the
    soft-shadow columns only when some row has a penumbra (``penumbra_pixels`` > 0)."""
    soft = "penumbra_pixels" in df.columns and bool((_numeric(df["penumbra_pixels"]) > 0).any())
    cols = [c for c in COLUMNS if getattr(c, which) and c.name in df.columns and c.name != first
            and (soft or not c.soft)]
    out = df[[first] + [c.name for c in cols]].copy()
    for c in cols:
        out[c.name] = out[c.name].map(c.format)
    return out
