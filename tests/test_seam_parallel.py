"""A seam leaving the image at both ends with a second line parallel to it is not chosen
(controller/vision/seam_parallel.py: parallel_valley, no_parallel_valley). Drawn images
(tests/drawn_plates.py): two sheets meeting along a gap that runs out of the image at both ends,
with or without a pen line drawn parallel to it; and a rendered tuning view where the pen line
was returned as the seam."""

import numpy as np
import pytest
from drawn_plates import S, render

from controller.errors import AmbiguousSeam
from controller.vision.seam_detect import detect_seam
from controller.vision.seam_parallel import parallel_valley
from controller.vision.seam_params import DetectParams
from controller.vision.seam_profiles import linear_lut

LUT = linear_lut(DetectParams().gamma)


def sheets(pen_offset: int | None, pen_level: float = 60.0, seed: int = 0) -> np.ndarray:
    """Two sheets (170 above, 150 below) meeting along a 4 px gap at y = 600 across the whole
    image; a pen line 3 px wide ``pen_offset`` px below it, across the whole image too."""
    def fill(m):
        m[:] = 170.0
        m[600 * S:, :] = 150.0
        m[598 * S:602 * S, :] = 30.0
        if pen_offset is not None:
            y = 600 + pen_offset
            m[(y - 1) * S:(y + 2) * S, :] = pen_level
    return render(fill, seed)


def line(y: float) -> np.ndarray:
    return np.column_stack([np.linspace(0.0, 1599.0, 200), np.full(200, y)])


@pytest.mark.parametrize("offset", [30, 80, 150])
def test_a_pen_line_parallel_to_a_seam_through_the_image_is_seen(offset):
    img = sheets(offset)
    found = parallel_valley(img, LUT, line(600.0), 4.0, DetectParams())
    assert found is not None
    off, share, own = found
    assert abs(abs(off) - offset) <= 2.0 and share > 0.9 and own > 0.9
    # And from the pen line, the joint beside it.
    found = parallel_valley(img, LUT, line(600.0 + offset), 3.0, DetectParams())
    assert found is not None and abs(abs(found[0]) - offset) <= 2.0


def test_nothing_parallel_beside_a_lone_seam_or_beyond_the_pen_line_distance():
    assert parallel_valley(sheets(None), LUT, line(600.0), 4.0, DetectParams()) is None
    # 250 px is further than a pen line is drawn from the joint (25 mm at the default scale).
    assert parallel_valley(sheets(250), LUT, line(600.0), 4.0, DetectParams()) is None


def test_the_detector_returns_neither_of_two_parallel_lines_through_the_image():
    # (Here both are candidates of the profile way, and its own rule refuses the choice; the
    # rendered view below is one where only the pen line was.)
    with pytest.raises(AmbiguousSeam):
        detect_seam(sheets(80))
    det = detect_seam(sheets(None))
    assert np.abs(det.points_px[:, 1] - 600.0).max() < 1.0
    # A nominal seam does not resolve it: a line beyond its tolerance still counts
    # (seam_detect.outside_corridor); a box around the joint leaves the other line out.
    with pytest.raises(AmbiguousSeam, match="give a --roi around the joint"):
        detect_seam(sheets(80), hint=line(600.0))
    det = detect_seam(sheets(80), roi=(0, 560, 1600, 640))
    assert np.abs(det.points_px[:, 1] - 600.0).max() < 1.0


def test_a_pen_line_returned_as_the_seam_is_refused() -> None:
    # Wide medium tuning 10284, view 0: a pen line 53 px beside the joint, both running out of
    # the image at both ends, was returned as the seam at confidence 1.0 (the joint, a 9.5 px
    # gap, was not a candidate of the way that returned it).
    from test_seam_robust import _rendered_view

    img, truth, cam = _rendered_view(("wide", "medium", "tuning", 10284), 0)
    with pytest.raises(AmbiguousSeam, match="parallel"):
        detect_seam(img, camera=cam)
