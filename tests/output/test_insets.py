"""Zoom insets common to every configuration (shadowlab.output.insets): where several
configurations go wrong, centred on the errors, the same boxes for all, CSS geometry."""
import numpy as np

from shadowlab.output import insets


def _truth(h=120, w=160):
    t = np.ones((h, w), np.float32)
    t[:, :80] = 0.0            # left half shadowed
    t[:5, :] = np.nan          # a strip not evaluated
    return t


def test_insets_land_where_several_configurations_are_wrong():
    truth = _truth()
    masks = []
    for k in range(4):         # four configurations wrong on the same few pixels near (120, 90)
        m = truth.copy()
        m[88:91, 118 + k:121 + k] = 0.0
        masks.append(m)
    big = truth.copy()         # one configuration wrong over a large area elsewhere
    big[20:60, 90:150] = 0.0
    masks.append(big)
    found = insets.common_insets(truth, masks)
    assert len(found) == 2
    x0, y0, x1, y1 = found[0].box
    assert x1 - x0 == y1 - y0 == insets.inset_window(160, 120)
    # the first box holds the shared errors, centred on them (centroid within a pixel of the centre)
    assert x0 <= 118 and x1 >= 124 and y0 <= 88 and y1 >= 91
    assert abs((x0 + x1) / 2 - 120.5) <= 1.5 and abs((y0 + y1) / 2 - 89.5) <= 1.5
    # the second box is the big error; counts are real wrong pixels, pooled over configurations
    assert found[1].box[1] >= 20 and found[1].box[3] <= 60
    assert found[0].wrong == 4 * 9 and found[1].wrong == insets.inset_window(160, 120) ** 2


def test_no_insets_when_everything_is_right():
    truth = _truth()
    assert insets.common_insets(truth, [truth.copy(), truth.copy()]) == []
    # NaN (not evaluated) pixels never count as wrong
    m = truth.copy()
    m[:5, :] = 0.0
    assert insets.common_insets(truth, [m]) == []


def test_css_geometry():
    i = insets.Inset((40, 30, 60, 50), (160, 120), 5, 1)
    assert i.box_style() == "left:25.000%;top:25.000%;width:12.500%;height:16.667%"
    z = i.zoom_style("a.png")
    # scaled 8 x 6; the region's corner on the box's corner: 40 / (160 - 20) = 28.571 %
    assert "background-size:800.000% 600.000%" in z and "background-position:28.571% 30.000%" in z
    assert "url('a.png')" in z and "aspect-ratio:20/20" in z
