"""The foveation overlay: boxes coloured by pass, fixation and fovea drawn where they are, a
legend."""

import numpy as np

from foveation_node.core.overlay import FIXATION_COLOUR, PASS_COLOURS, Box, draw_overlay


def _has(img: np.ndarray, colour: tuple[int, int, int], ys: slice, xs: slice) -> bool:
    return bool((img[ys, xs] == np.array(colour, np.uint8)).all(axis=-1).any())


def test_passes_fixation_and_fovea_are_drawn_in_their_colours() -> None:
    image = np.full((480, 640, 3), 90, np.uint8)
    boxes = [Box(300, 200, 80, 60, 'bottle', 0.91, 0), Box(100, 300, 50, 90, 'can', 0.55, 1)]
    out = draw_overlay(image, boxes, fixation=(500.0, 100.0), fovea_radius_px=40.0)
    assert (image == 90).all()                                   # the input is not drawn on
    assert _has(out, PASS_COLOURS[0], slice(258, 262), slice(300, 381))   # bottom edge of box 1
    assert _has(out, PASS_COLOURS[1], slice(300, 391), slice(98, 102))    # left edge of box 2
    assert not _has(out, PASS_COLOURS[1], slice(258, 262), slice(300, 381))
    assert _has(out, FIXATION_COLOUR, slice(98, 103), slice(538, 543))    # fovea circle at u + r
    assert _has(out, FIXATION_COLOUR, slice(95, 106), slice(498, 503))    # the fixation cross
    assert out[2:60, 2:100].mean() < 90                          # the legend's dark box


def test_no_fixation_and_mono_images_are_fine() -> None:
    out = draw_overlay(np.zeros((120, 160), np.uint8), [], fixation=(float('nan'), 3.0),
                       fovea_radius_px=None)
    assert out.shape == (120, 160, 3)
    assert not _has(out, FIXATION_COLOUR, slice(0, 120), slice(60, 160))
