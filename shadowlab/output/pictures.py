"""The pictures of a run (PNG, row 0 = top) and the two plots of a comparison page.

Colours of the error map:
correct lit and correct shadow in greys, false shadow in orange, false lit in blue, pixels
that are not evaluated dimmed from the shaded image. Soft configurations (an area light, or
fractional visibility) also get a signed difference map V − G on a diverging colour map
centred at 0, blue where the technique is too bright and red where it is too dark — the same
sides as the error map's blue false lit and orange false shadow. Shadow-map configurations also
get their texel-footprint map (Lloyd et al.'s m, log colour scale, :func:`footprint_picture`).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd


BACKGROUND = np.array([0.16, 0.18, 0.22])
NOT_EVALUATED = np.array([0.30, 0.32, 0.40])
#: Error-map legend: class id (metrics.error_classes) → (label, RGB in [0, 1]).
ERROR_COLORS = {
    1: ("lit, correct", (0.85, 0.85, 0.85)),
    2: ("shadowed, correct", (0.35, 0.35, 0.35)),
    3: ("false shadow (acne, over-darkening)", (0.93, 0.45, 0.05)),
    4: ("false lit (leak, missing shadow)", (0.10, 0.45, 0.90)),
}


def srgb_encode(linear: np.ndarray) -> np.ndarray:
    """The sRGB transfer function (IEC 61966-2-1): linear values in [0, 1] → encoded values in
    [0, 1], linear below 0.0031308, a 1/2.4 power above (what PNG viewers assume)."""
    c = np.clip(linear, 0.0, 1.0)
    return np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1.0 / 2.4) - 0.055)


def to_display(linear: np.ndarray, covered: np.ndarray) -> np.ndarray:
    """Linear RGB (H, W, 3) → sRGB-encoded RGB float in [0, 1], background where uncovered."""
    rgb = srgb_encode(linear)
    rgb[~covered] = BACKGROUND
    return rgb


def visibility_picture(vis: np.ndarray, evaluated: np.ndarray, covered: np.ndarray) -> np.ndarray:
    """Visibility as grey levels on evaluated pixels (white = lit), a slate colour elsewhere."""
    rgb = np.repeat(np.nan_to_num(vis, nan=1.0)[..., None], 3, axis=2).astype(np.float64)
    rgb[~evaluated] = NOT_EVALUATED
    rgb[~covered] = BACKGROUND
    return rgb


def error_picture(classes: np.ndarray, shaded_display: np.ndarray) -> np.ndarray:
    """The error map: one colour per class of :func:`shadowlab.evaluation.metrics.error_classes`."""
    rgb = shaded_display * 0.35
    for cls, (_, color) in ERROR_COLORS.items():
        rgb[classes == cls] = color
    return rgb


#: Diverging colour map of the signed difference map (matplotlib name): low (V < G, too dark)
#: red, 0 white, high (V > G, too bright) blue.
SIGNED_COLORMAP = "RdBu"
#: Step the signed map's symmetric limit is rounded up to, and its least value: the truth's
#: own sampling noise (<= 0.5/sqrt(1024) = 0.016 at the default samples) stays pale.
SIGNED_LIMIT_STEP = 0.05
SIGNED_CAPTION = ("signed difference V − G (technique − truth, first light), in visibility units: "
                  "positive (blue) = the technique is too bright (false light), negative (red) = too dark "
                  "(false shadow), white = agrees; slate = not evaluated")


def is_soft(light, vis: np.ndarray, truth: np.ndarray, evaluated: np.ndarray) -> bool:
    """Whether a configuration is judged as a soft shadow (and gets a signed difference map):
    the light is an area light, or the technique's or the truth's visibility (float (H, W),
    row 0 = top) is fractional (strictly between 0 and 1) on some evaluated pixel."""
    from ..scene.area_lights import AreaLight

    if isinstance(light, AreaLight):
        return True
    ev = evaluated.astype(bool)
    return any(bool(((a[ev] > 0.0) & (a[ev] < 1.0)).any()) for a in (vis, truth))


def signed_difference(light, vis: np.ndarray, truth: np.ndarray, evaluated: np.ndarray) -> np.ndarray | None:
    """V − G float (H, W), row 0 = top, NaN off the evaluated pixels, for a soft configuration
    (:func:`is_soft`); None for a hard one (it gets no signed map)."""
    if not is_soft(light, vis, truth, evaluated):
        return None
    return np.where(evaluated.astype(bool), vis - truth, np.nan)


def signed_limit(diffs) -> float:
    """The symmetric limit ±L of the signed maps of one run: the largest |V − G| (NaN ignored)
    over the float arrays ``diffs``, rounded up to :data:`SIGNED_LIMIT_STEP` and at least that
    step, and at most 1 (visibility lies in [0, 1]); one scale for every configuration, so
    their maps compare."""
    peak = max((float(np.nanmax(np.abs(d))) for d in diffs if np.isfinite(d).any()), default=0.0)
    steps = max(1, int(np.ceil(peak / SIGNED_LIMIT_STEP - 1e-9)))
    return min(1.0, steps * SIGNED_LIMIT_STEP)


def signed_picture(diff: np.ndarray, limit: float, evaluated: np.ndarray, covered: np.ndarray) -> np.ndarray:
    """The signed difference map: ``diff`` = V − G float (H, W), row 0 = top, through
    :data:`SIGNED_COLORMAP` with −``limit`` → one end, 0 → the white centre, +``limit`` → the
    other (clipped beyond); not-evaluated pixels slate, uncovered ones the background. RGB
    float (H, W, 3) in [0, 1]."""
    import matplotlib

    if not limit > 0:
        raise ValueError(f"the signed map's limit must be > 0, got {limit}")
    t = np.clip((np.nan_to_num(diff, nan=0.0) + limit) / (2.0 * limit), 0.0, 1.0)
    rgb = matplotlib.colormaps[SIGNED_COLORMAP](t)[..., :3].astype(np.float64)
    rgb[~evaluated.astype(bool)] = NOT_EVALUATED
    rgb[~covered.astype(bool)] = BACKGROUND
    return rgb


def signed_legend(path: Path, limit: float) -> None:
    """A horizontal colour bar of the signed map (PNG): −``limit`` … 0 … +``limit``, labelled
    in visibility units, its ends named (too dark / too bright)."""
    import matplotlib

    from matplotlib.colors import Normalize

    fig, ax = _figure((5.0, 0.95))
    cb = fig.colorbar(matplotlib.cm.ScalarMappable(Normalize(-limit, limit), SIGNED_COLORMAP), cax=ax,
                      orientation="horizontal", ticks=[-limit, -limit / 2, 0.0, limit / 2, limit])
    cb.set_label("V − G, visibility   (← too dark: false shadow | too bright: false light →)", fontsize=8)
    cb.ax.tick_params(labelsize=8)
    fig.subplots_adjust(left=0.05, right=0.95, top=0.92, bottom=0.55)
    fig.savefig(path)


#: The texel-footprint image (Lloyd et al.'s m, :mod:`shadowlab.evaluation.texel_footprint`): colour map and
#: the ends of its logarithmic scale, in pixels per texel — a tenth of a pixel (a map ten times
#: finer than the screen) to a hundred pixels (severe aliasing); values beyond are clipped.
FOOTPRINT_COLORMAP = "magma"
FOOTPRINT_RANGE = (0.1, 100.0)
FOOTPRINT_CAPTION = ("texel footprint m: the longest axis, in pixels, of the shadow-map texel covering each pixel "
                     "(Lloyd et al. 2008), log scale; m <= 1 alias-free, m > 10 severe; slate = not evaluated")


def footprint_picture(m: np.ndarray, evaluated: np.ndarray, covered: np.ndarray) -> np.ndarray:
    """The texel-footprint map: m float (H, W), row 0 = top, through :data:`FOOTPRINT_COLORMAP`
    on a log scale over :data:`FOOTPRINT_RANGE` (clipped beyond; inf = the top colour); pixels
    not evaluated or without an m slate, uncovered ones the background. RGB float (H, W, 3)."""
    import matplotlib

    lo, hi = np.log10(FOOTPRINT_RANGE)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.clip((np.log10(np.nan_to_num(m, nan=FOOTPRINT_RANGE[0], posinf=FOOTPRINT_RANGE[1])) - lo) / (hi - lo),
                    0.0, 1.0)
    rgb = matplotlib.colormaps[FOOTPRINT_COLORMAP](t)[..., :3].astype(np.float64)
    rgb[~(evaluated.astype(bool) & ~np.isnan(m))] = NOT_EVALUATED
    rgb[~covered.astype(bool)] = BACKGROUND
    return rgb


def footprint_legend(path: Path) -> None:
    """A horizontal colour bar of the texel-footprint map (PNG): :data:`FOOTPRINT_RANGE` on a
    log scale, in pixels per texel."""
    import matplotlib

    from matplotlib.colors import LogNorm

    fig, ax = _figure((5.0, 0.95))
    cb = fig.colorbar(matplotlib.cm.ScalarMappable(LogNorm(*FOOTPRINT_RANGE), FOOTPRINT_COLORMAP), cax=ax,
                      orientation="horizontal")
    cb.set_label("texel footprint m, pixels   (<= 1 alias-free | > 10 severe)", fontsize=8)
    cb.ax.tick_params(labelsize=8)
    fig.subplots_adjust(left=0.05, right=0.95, top=0.92, bottom=0.55)
    fig.savefig(path)


#: Resolution of the run page's plots, dots per inch.
PLOT_DPI = 110


def _figure(size: tuple[float, float]):
    """A figure of ``size`` inches and its one axes, on an Agg canvas of its own (object-oriented
    matplotlib: no pyplot state, nothing to close)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=size, dpi=PLOT_DPI)
    FigureCanvasAgg(fig)
    return fig, fig.add_subplot()


def save_png(path: Path, rgb: np.ndarray) -> None:
    """Write an RGB float image in [0, 1] (H, W, 3), row 0 = top."""
    Path(path).write_bytes(encode_png(rgb))


def encode_png(rgb: np.ndarray) -> bytes:
    """An RGB float image in [0, 1] (H, W, 3), row 0 = top, as PNG file bytes (8 bits per channel)."""
    import io

    import matplotlib.image as mpimg

    buf = io.BytesIO()
    mpimg.imsave(buf, np.clip(rgb, 0.0, 1.0), format="png")
    return buf.getvalue()


def speed_error_plot(df: pd.DataFrame, path: Path) -> None:
    """Scatter of error rate against median time, one point per configuration and light (a
    note instead when no row has a time: every timing run of the scene failed)."""
    fig, ax = _figure((6.4, 4.2))
    key = "short_label" if "short_label" in df.columns else "label"
    timed = "time_ms_median" in df.columns and df["time_ms_median"].notna().any()
    if not timed:
        ax.text(0.5, 0.5, "no times: every timing run failed (see the notes)", ha="center", va="center",
                transform=ax.transAxes)
    for (label, light), g in (df.groupby([key, "light"], sort=False) if timed else []):
        iqr = g["time_ms_iqr"] / 2 if "time_ms_iqr" in g else None
        ax.errorbar(g["time_ms_median"], 100 * g["error_rate"], xerr=iqr, fmt="o", capsize=3,
                    label=f"{label} (light {light})" if df["light"].nunique() > 1 else label)
    ax.set_xlabel("time per frame, ms (median; bar = IQR)")
    ax.set_ylabel("error rate, % of evaluated pixels")
    ax.set_title("Speed vs error against the ray-traced ground truth")
    ax.grid(alpha=0.3)
    if timed:
        ax.legend(fontsize=7, loc="best")
    fig.tight_layout()
    fig.savefig(path)


def pass_time_plot(df: pd.DataFrame, path: Path) -> str | None:
    """A stacked horizontal bar per configuration (first light): its ``pass_<name>_ms``
    columns, in the order the passes run, beside the median total. Returns the file name, or
    None when no pass was timed."""
    import matplotlib


    cols = [c for c in df.columns if c.startswith("pass_") and c.endswith("_ms")]
    if not cols:
        return None
    rows = df[df["light"] == df["light"].min()].reset_index(drop=True)
    fig, ax = _figure((7.5, 0.45 * len(rows) + 1.6))
    colors = matplotlib.colormaps["tab20"]
    left = np.zeros(len(rows))
    for k, col in enumerate(cols):
        vals = rows[col].fillna(0.0).to_numpy()
        ax.barh(range(len(rows)), vals, left=left, color=colors(k % 20), label=col[len("pass_"):-len("_ms")])
        left += vals
    if "time_ms_median" in rows.columns:
        ax.scatter(rows["time_ms_median"], range(len(rows)), marker="|", s=200, color="k", label="total (median)")
    ax.set_yticks(range(len(rows)), rows["short_label"], fontsize=7)
    ax.invert_yaxis()
    ax.set_xlabel("ms per frame (median per pass; timed in runs of their own)")
    ax.set_title("Where the time goes, pass by pass (first light)")
    ax.legend(fontsize=7, loc="lower right")
    ax.grid(alpha=0.3, axis="x")
    fig.tight_layout()
    fig.savefig(path)
    return Path(path).name


def config_pictures(shaded: np.ndarray, vis0: np.ndarray, truth0: np.ndarray | None, evaluated: np.ndarray,
                    covered: np.ndarray, signed: tuple[np.ndarray, float] | None = None,
                    footprint: np.ndarray | None = None) -> dict[str, bytes]:
    """A configuration's pictures as PNG bytes, keyed by kind: ``shaded`` (``shaded``: the shaded
    image, sRGB-encoded RGB (H, W, 3), :func:`to_display`), ``visibility`` (the first light's,
    ``vis0``); against ``truth0`` (None for the truth itself) the ``error`` map; with ``signed`` =
    (V − G, limit) the ``signed`` map; with ``footprint`` (texel footprint m) the ``footprint``
    map. All float (H, W) arrays row 0 = top; ``evaluated`` = the first light's evaluated pixels.
    What ``compare`` and a study's workers both draw, so their run directories are alike."""
    out = {"shaded": encode_png(shaded), "visibility": encode_png(visibility_picture(vis0, evaluated, covered))}
    if truth0 is not None:
        from ..evaluation.metrics import error_classes

        out["error"] = encode_png(error_picture(error_classes(vis0, truth0, evaluated), shaded))
    if signed is not None:
        out["signed"] = encode_png(signed_picture(signed[0], signed[1], evaluated, covered))
    if footprint is not None:
        out["footprint"] = encode_png(footprint_picture(footprint, evaluated, covered))
    return out
