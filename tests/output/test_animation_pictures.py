"""The pictures of ``shadowlab animate`` (shadowlab.output.animation_pictures): the flicker
overlay and the labels drawn on each GIF frame of a strip."""
from __future__ import annotations

import numpy as np


def test_flicker_overlay_shows_the_scene_and_colours_only_flips():
    """flicker_overlay: the scene in grey where nothing flipped (bright where it is lit), the
    colour map's colours (none near black) where something did, background where uncovered."""
    from shadowlab.output.animation_pictures import FLICKER_UNDERLAY_GREY, flicker_colormap, flicker_overlay
    from shadowlab.output import pictures

    h, w = 6, 8
    covered = np.ones((h, w), bool)
    covered[0] = False
    underlay = np.full((h, w, 3), 0.8)
    counts = np.zeros((h, w), np.int32)
    counts[3, 2], counts[4, 5] = 1, 4
    rgb = flicker_overlay(counts, covered, underlay)
    quiet = covered & (counts == 0)
    assert np.allclose(rgb[quiet], rgb[quiet][:, :1])  # grey
    assert rgb[quiet].mean() > FLICKER_UNDERLAY_GREY[0] + 0.5 * (FLICKER_UNDERLAY_GREY[1] - FLICKER_UNDERLAY_GREY[0])
    assert np.allclose(rgb[3, 2], flicker_colormap()(0.0)[:3]) and np.allclose(rgb[4, 5], flicker_colormap()(1.0)[:3])
    assert rgb[3, 2].max() > 0.3  # the lowest count is no near-black
    assert np.allclose(rgb[0], pictures.BACKGROUND)
    # nothing flipped at all: the picture is the grey scene
    assert np.allclose(flicker_overlay(np.zeros((h, w), np.int32), covered, underlay)[quiet], rgb[quiet])


#: A label's text pixels: white, give or take the rounding of the alpha compositing.
TEXT_WHITE = 240


def test_label_strip_draws_frame_and_panel_names():
    """label_strip writes white text on a dark box at each panel's top left and at the bottom
    left, and leaves the rest of the strip alone."""
    from shadowlab.output.animation_pictures import STRIP_GAP, STRIP_PANELS, label_strip

    w, h = 64, 48
    strip = np.full((h, 3 * w + 2 * STRIP_GAP, 3), 128, np.uint8)
    out = label_strip(strip, 0, 3)
    assert out.shape == strip.shape and out.dtype == np.uint8
    changed = (out != strip).any(axis=2)
    for i in range(len(STRIP_PANELS)):
        x0 = i * (w + STRIP_GAP)
        corner = out[:h // 4, x0:x0 + w // 2]
        assert (corner >= TEXT_WHITE).all(axis=2).any() and (corner < 128).all(axis=2).any(), STRIP_PANELS[i]
    bottom = out[-h // 4:, :w // 2]
    assert (bottom >= TEXT_WHITE).all(axis=2).any() and (bottom < 128).all(axis=2).any()
    assert not changed[h // 3:2 * h // 3, w // 2:].any()  # the middle of the pictures is untouched
    assert not np.array_equal(label_strip(strip, 0, 3), label_strip(strip, 1, 3))  # "frame 1/3" vs "frame 2/3"
