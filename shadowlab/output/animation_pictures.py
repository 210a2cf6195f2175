"""The pictures of ``shadowlab animate``: per technique, a labelled strip per frame (truth |
technique | error map) written as an animated GIF, and the flicker heat map over the grey scene.

The GIFs are written, and their frames labelled, with Pillow (GIF writer, ImageDraw and its
default font): Pillow is already installed (matplotlib depends on it), whereas imageio would be a
new dependency for the same few lines; the strips are flat colour pictures that a 256-colour
palette holds without visible loss.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..evaluation import metrics
from . import pictures

#: Display time of one GIF frame, milliseconds.
GIF_FRAME_MS = 150
#: Width of the dark separator between the panels of a strip, pixels.
STRIP_GAP = 2
#: Colour map of the flicker heat maps (matplotlib name): dark = few flips, bright = many.
FLICKER_COLORMAP = "inferno"
#: Where on :data:`FLICKER_COLORMAP` a count of 1 starts: its near-black low end would read as
#: shadow over the grey scene, so the overlay uses the map from here up.
FLICKER_COLORMAP_FLOOR = 0.3
#: Entries of that cut colour map (matplotlib's usual resolution).
FLICKER_COLORMAP_STEPS = 256
#: The grey scene under the flicker counts: luminance of the shaded truth mapped linearly onto
#: [low, high], so the scene is visible but never as bright as the brightest overlay colours.
FLICKER_UNDERLAY_GREY = (0.15, 0.75)
#: Rec. 709 luma weights (sRGB-encoded RGB → grey) of the flicker picture's underlay.
LUMA_WEIGHTS = np.array([0.2126, 0.7152, 0.0722])
#: Panel names of a strip, left to right, drawn on every GIF frame.
STRIP_PANELS = ("truth", "technique", "error")
#: Margin of a GIF label from its panel's corner, and padding of its dark box, pixels.
LABEL_MARGIN = 2
LABEL_PAD = 1
#: Opacity (0–255) of the dark box behind a GIF label.
LABEL_BOX_ALPHA = 170
#: The flicker figure: width and title height (inches), resolution, and its colour bar's width
#: and gap from the picture (matplotlib axes_grid1 sizes).
FLICKER_FIGURE_WIDTH = 5.0
FLICKER_TITLE_HEIGHT = 0.6
FLICKER_DPI = 110
COLORBAR_WIDTH = "4%"
COLORBAR_PAD = 0.08


def to_uint8(rgb: np.ndarray) -> np.ndarray:
    """RGB float in [0, 1] as uint8, rounded to the nearest step (values outside clipped)."""
    return (np.clip(rgb, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)


def strip_picture(vis: np.ndarray, truth: np.ndarray, evaluated: np.ndarray, covered: np.ndarray) -> np.ndarray:
    """truth's visibility | the technique's | its error map (over the truth's visibility), uint8
    (H, 3W + 2·gap, 3), row 0 = top."""
    truth_pic = pictures.visibility_picture(truth, evaluated, covered)
    vis_pic = pictures.visibility_picture(vis, evaluated, covered)
    err_pic = pictures.error_picture(metrics.error_classes(vis, truth, evaluated), truth_pic.copy())
    gap = np.zeros((vis.shape[0], STRIP_GAP, 3))
    return to_uint8(np.concatenate([truth_pic, gap, vis_pic, gap, err_pic], axis=1))


def label_strip(strip: np.ndarray, k: int, n: int) -> np.ndarray:
    """One strip picture (uint8 (H, 3W + 2·gap, 3), :func:`strip_picture`) with its labels drawn
    in: each panel's name (:data:`STRIP_PANELS`) at its top left and "frame k/n" (1-based) at the
    bottom left, white on a translucent dark box, so a GIF frame says what it shows and when
    (Pillow ImageDraw, default font). Returns a new array of the same shape."""
    from PIL import Image, ImageDraw, ImageFont

    h, total, _ = strip.shape
    panel = (total - (len(STRIP_PANELS) - 1) * STRIP_GAP) // len(STRIP_PANELS)
    image = Image.fromarray(strip, "RGB").convert("RGBA")
    overlay = Image.new("RGBA", image.size, (0, 0, 0, 0))
    draw = ImageDraw.Draw(overlay)
    font = ImageFont.load_default()

    def text(x: int, y: int, words: str, anchor: str) -> None:
        box = draw.textbbox((x, y), words, font=font, anchor=anchor)
        draw.rectangle((box[0] - LABEL_PAD, box[1] - LABEL_PAD, box[2] + LABEL_PAD, box[3] + LABEL_PAD),
                       fill=(0, 0, 0, LABEL_BOX_ALPHA))
        draw.text((x, y), words, font=font, fill=(255, 255, 255, 255), anchor=anchor)

    for i, name in enumerate(STRIP_PANELS):
        text(i * (panel + STRIP_GAP) + LABEL_MARGIN, LABEL_MARGIN, name, "la")
    text(LABEL_MARGIN, h - LABEL_MARGIN, f"frame {k + 1}/{n}", "ld")
    return np.asarray(Image.alpha_composite(image, overlay).convert("RGB")).copy()


def write_gif(path: Path, strip: list[np.ndarray]) -> None:
    """An animated, looping GIF of uint8 RGB pictures (H, W, 3), :data:`GIF_FRAME_MS` each
    (Pillow's GIF writer, see the module docstring)."""
    from PIL import Image

    images = [Image.fromarray(p, "RGB") for p in strip]
    images[0].save(path, save_all=True, append_images=images[1:], duration=GIF_FRAME_MS, loop=0)


def flicker_colormap():
    """:data:`FLICKER_COLORMAP` from :data:`FLICKER_COLORMAP_FLOOR` up (a matplotlib colour map):
    the overlay's colours, none of them dark enough to pass for shadow."""
    import matplotlib
    from matplotlib.colors import ListedColormap

    base = matplotlib.colormaps[FLICKER_COLORMAP]
    return ListedColormap(base(np.linspace(FLICKER_COLORMAP_FLOOR, 1.0, FLICKER_COLORMAP_STEPS)),
                          name=f"{FLICKER_COLORMAP}_floor")


def flicker_overlay(counts: np.ndarray, covered: np.ndarray, underlay: np.ndarray) -> np.ndarray:
    """The flicker picture's pixels, RGB float in [0, 1] (H, W, 3), row 0 = top: the scene in grey
    (``underlay``: sRGB-encoded shaded RGB (H, W, 3), its luma mapped onto
    :data:`FLICKER_UNDERLAY_GREY`), the flip ``counts`` in :func:`flicker_colormap` colours where
    a count is above 0 (1 → the floor colour, the largest count → the top), background where
    nothing is covered. Why: counts alone are black wherever nothing flickers, which hides the
    scene the flicker is on."""
    lo, hi = FLICKER_UNDERLAY_GREY
    grey = lo + (hi - lo) * np.clip(underlay @ LUMA_WEIGHTS, 0.0, 1.0)
    rgb = np.repeat(grey[..., None], 3, axis=2)
    top = max(1, int(counts.max()))
    hot = (counts > 0) & covered
    if hot.any():
        rel = (counts[hot] - 1) / max(1, top - 1)
        rgb[hot] = flicker_colormap()(rel)[:, :3]
    rgb[~covered] = pictures.BACKGROUND
    return rgb


def flicker_picture(path: Path, counts: np.ndarray, covered: np.ndarray, underlay: np.ndarray, title: str,
                    caption: str) -> None:
    """The flicker heat map (PNG, matplotlib): :func:`flicker_overlay` — per pixel the number of
    frame pairs in which the technique's thresholded visibility flipped while the truth's did not,
    coloured over the grey scene ``underlay`` — with a colour bar of the counts (from 1)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize
    from matplotlib.ticker import MaxNLocator
    from mpl_toolkits.axes_grid1 import make_axes_locatable

    h, w = counts.shape
    top = max(1, int(counts.max()))
    fig, ax = plt.subplots(figsize=(FLICKER_FIGURE_WIDTH, FLICKER_FIGURE_WIDTH * h / w + FLICKER_TITLE_HEIGHT),
                           dpi=FLICKER_DPI)
    ax.imshow(flicker_overlay(counts, covered, underlay), interpolation="nearest")
    ax.set_axis_off()
    ax.set_title(title, fontsize=8)
    # counts 1..top on the colour bar, as the overlay maps them (a single count still gets a bar),
    # in an axes as tall as the picture
    cax = make_axes_locatable(ax).append_axes("right", size=COLORBAR_WIDTH, pad=COLORBAR_PAD)
    cb = fig.colorbar(ScalarMappable(Normalize(1, max(top, 2)), flicker_colormap()), cax=cax)
    cb.locator = MaxNLocator(integer=True)
    cb.update_ticks()
    cb.set_label(caption, fontsize=7)
    cb.ax.tick_params(labelsize=7)
    fig.savefig(path, bbox_inches="tight")
    plt.close(fig)
