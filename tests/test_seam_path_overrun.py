"""A valley path that runs on past the sheets' end (controller/vision/seam_ends.border_behind).

A whole-image valley path is led on beyond the joint's end by whatever continues the valley there
(a dark table between two plate corners, a slot, a shadow), and its end, out on the table, reads
as a line fading out. The sheets' end is then behind it: read back along the path, the nearest
border that both sides of the gap cross, with the gap seen right before it, is the joint's end.
A pen line that fades out inside a sheet crosses no border on the way back, and a path that
bridged an unseen stretch to a border did not follow a gap there. Drawn images
(tests/drawn_plates.py)."""

from __future__ import annotations

import numpy as np
import pytest
from drawn_plates import S, render

from controller.vision.seam_ends import border_behind
from controller.vision.seam_params import DetectParams
from controller.vision.seam_profiles import linear_lut

LUT = linear_lut(DetectParams().gamma)


def two_sheets(seed: int) -> np.ndarray:
    """Two sheets (x 300-1300; A above y = 600, B below) with an 8 px gap, on a dark table."""
    def fill(m):
        m[:] = 40.0
        m[200 * S:596 * S, 300 * S:1300 * S] = 170.0
        m[596 * S:604 * S, 300 * S:1300 * S] = 25.0
        m[604 * S:1000 * S, 300 * S:1300 * S] = 150.0
    return render(fill, seed)


def pen_line_on_a_sheet(seed: int) -> np.ndarray:
    """One sheet (x 300-1300, y 200-1000) with a 6 px pen line at y = 600 from x = 500 to 1000."""
    def fill(m):
        m[:] = 40.0
        m[200 * S:1000 * S, 300 * S:1300 * S] = 165.0
        m[597 * S:603 * S, 500 * S:1000 * S] = 60.0
    return render(fill, seed)


def path(x0: float, x1: float) -> np.ndarray:
    """A path along y = 599.5 from x0 to x1 (px), a point every 4 px (the detector's step)."""
    xs = np.arange(x0, x1 + 0.01, 4.0)
    return np.column_stack([xs, np.full_like(xs, 599.5)])


@pytest.mark.parametrize("seed,overrun", [(1, 40.0), (2, 90.0), (3, 150.0)])
def test_the_end_behind_a_path_that_ran_on_onto_the_table(seed, overrun):
    grey = two_sheets(seed)
    seq = path(500.0, 1300.0 + overrun)
    got = border_behind(grey, LUT, seq, seq[:, 0] < 1299.0, w_med=8.0)
    assert got is not None
    n, end = got
    assert abs(end[0] - 1299.5) <= 2.0 and abs(end[1] - 599.5) <= 1.0, end
    # The points kept lie before the end, none of them out on the table.
    assert seq[n - 1, 0] <= end[0] and seq[n, 0] > end[0] - 1.0


def test_a_pen_line_crosses_no_border_on_the_way_back():
    grey = pen_line_on_a_sheet(4)
    seq = path(600.0, 1150.0)  # 150 px past the pen line's end, inside the sheet
    assert border_behind(grey, LUT, seq, seq[:, 0] < 1000.0, w_med=6.0) is None


def test_a_border_reached_across_an_unseen_stretch_is_not_the_gaps_end():
    # The gap last seen 200 px before the sheets' end: the path bridged to the border (from a
    # pen line's end to a plate's edge, say); nothing says that a gap runs there.
    grey = two_sheets(5)
    seq = path(500.0, 1360.0)
    assert border_behind(grey, LUT, seq, seq[:, 0] < 1100.0, w_med=8.0) is None
