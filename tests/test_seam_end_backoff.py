"""An end point that ran on past the sheets over a dark table is read again further back
(controller/vision/seam_ends.py: end_offset, _backed_off). Drawn images (tests/drawn_plates.py):
two sheets with rounded corners on a dark table, where a wide gap merges with the table between
the corners and the line followed runs on into it; and a pen line ending inside a sheet, which
must stay open however far past its end it is read."""

import numpy as np
import pytest
from drawn_plates import S, render

from controller.vision.seam_ends import _end_at, end_offset
from controller.vision.seam_params import DetectParams
from controller.vision.seam_profiles import linear_lut

LUT = linear_lut(DetectParams().gamma)
X0, Y_END = 800, 700  # the gap runs down x = X0 from the image's top to the sheets' end


def rounded_sheets(radius: int, gap: int, seed: int = 0) -> np.ndarray:
    """Two sheets (200) either side of a vertical gap ``gap`` px wide on a dark table (30); each
    sheet's corner at the gap's end is rounded with ``radius`` px."""
    def fill(m):
        H, W = m.shape
        m[:] = 30.0
        yy, xx = np.mgrid[0:H, 0:W].astype(np.float32) / S
        for side in (-1, 1):
            edge = X0 + side * gap / 2
            sheet = (side * (xx - edge) >= 0) & (yy <= Y_END)
            cx, cy = edge + side * radius, Y_END - radius
            sheet &= ~((side * (xx - cx) <= 0) & (yy > cy)
                       & ((xx - cx) ** 2 + (yy - cy) ** 2 > radius ** 2))
            m[sheet] = 200.0
    return render(fill, seed)


def the_neck(radius: int, gap: int) -> float:
    """Where the gap has opened to twice its width between the corners (y, px): the joint's end."""
    r = float(radius)
    return Y_END - r + float(np.sqrt(r * r - (r - gap / 2) ** 2))


@pytest.mark.parametrize("radius,gap", [(15, 6), (25, 12), (40, 20), (60, 20)])
def test_an_end_read_past_the_sheets_over_the_table_is_read_back_at_their_border(radius, gap):
    img = rounded_sheets(radius, gap)
    tang = np.array([0.0, 1.0])
    for past in (20.0, 40.0):
        e_pt = np.array([float(X0), Y_END + past])
        # Where it was read: only the table around, nothing steps.
        assert _end_at(img, LUT, e_pt, tang, float(gap))[1] == "open"
        k, kind, _ = end_offset(img, LUT, e_pt, tang, float(gap))
        assert kind == "sheet border"
        assert abs(e_pt[1] + k - the_neck(radius, gap)) < 3.0


def test_a_pen_line_read_past_its_end_inside_the_sheet_stays_open():
    def fill(m):
        m[:] = 30.0
        m[:, 300 * S:1300 * S] = 200.0  # one sheet, wider than the image is tall
        m[:Y_END * S, (X0 - 3) * S:(X0 + 3) * S] = 60.0  # the pen line, 6 px, ending inside
    img = render(fill, 1)
    tang = np.array([0.0, 1.0])
    for past in (0.0, 20.0, 40.0, 60.0):
        e_pt = np.array([float(X0), Y_END + past])
        assert end_offset(img, LUT, e_pt, tang, 6.0)[1] == "open"


def test_a_sheet_border_read_where_the_end_is_is_not_moved():
    img = rounded_sheets(15, 6)
    e_pt = np.array([float(X0), float(Y_END)])
    tang = np.array([0.0, 1.0])
    assert end_offset(img, LUT, e_pt, tang, 6.0) == _end_at(img, LUT, e_pt, tang, 6.0)[:3]
