"""An end called the image border beyond which the sheets end is a sheet border, not the image's
(controller/vision/seam_edge_ends.py). Drawn images as in test_seam_wedge (linear light, blur,
noise): a horizontal gap along y = 300 in a 1000 px wide image, the candidate's points running
toward +x."""

import numpy as np
from test_seam_wedge import LUT, S, _render, _sheets

from controller.vision.seam_edge_ends import gap_seen_to_edge, reject_ends_short_of_edge
from controller.vision.seam_params import Candidate


def _points(x_end: float) -> np.ndarray:
    return np.column_stack([np.arange(200.0, x_end + 0.1, 4.0), np.full(
        len(np.arange(200.0, x_end + 0.1, 4.0)), 300.0)])


def _cand(x_end: float) -> Candidate:
    pts = _points(x_end)
    return Candidate(pts, 1.0, x_end - 200.0, points=pts, width=np.full(len(pts), 3.0),
                     score=1000.0, end_kinds=("sheet border", "image border"))


def test_a_gap_running_out_of_the_image_is_seen_to_the_edge():
    img = _render(_sheets(3.0), 1)
    dist, share, over_table = gap_seen_to_edge(img, LUT, _points(980.0), 3.0)
    assert abs(dist - 19.5) < 0.6 and share == 1.0 and not over_table
    c = _cand(980.0)
    reject_ends_short_of_edge(img, LUT, [c])
    assert c.why_rejected == ""


def test_a_gap_covered_up_to_the_edge_leaves_the_image_under_the_patch():
    # A tack weld (as bright as the sheets) covers the gap from x = 950 to the edge: no gap is
    # seen beyond the end, but the sheets go on, and the seam leaves the image under the patch.
    m = _sheets(3.0)
    m[:, 950 * S:] = 255
    img = _render(m, 2)
    dist, share, over_table = gap_seen_to_edge(img, LUT, _points(944.0), 3.0)
    assert share < 0.2 and not over_table
    c = _cand(944.0)
    reject_ends_short_of_edge(img, LUT, [c])
    assert c.why_rejected == ""


def test_sheets_ending_before_the_edge_make_no_image_border_end():
    # The sheets end at x = 960, the table beyond: the end is a sheet border, not the image's.
    m = _sheets(3.0)
    m[:, 960 * S:] = 0
    img = _render(m, 3)
    dist, share, over_table = gap_seen_to_edge(img, LUT, _points(956.0), 3.0)
    assert share < 0.2 and over_table
    c = _cand(956.0)
    reject_ends_short_of_edge(img, LUT, [c])
    assert "show the table" in c.why_rejected and c.rival
    # The other end, a sheet border, is not this check's business.
    c = _cand(956.0)
    c.end_kinds = ("image border", "sheet border")
    reject_ends_short_of_edge(img, LUT, [c])
    assert c.why_rejected == ""


def test_an_end_a_few_px_from_the_edge_is_not_checked():
    m = _sheets(3.0)
    m[:, 994 * S:] = 0
    img = _render(m, 4)
    c = _cand(993.0)
    reject_ends_short_of_edge(img, LUT, [c])
    assert c.why_rejected == ""


def test_a_rendered_seam_whose_end_near_the_edge_is_a_sheet_border_is_not_returned():
    # Wide easy tuning 10171, view 0 (perforated table): the joint ends at a sheet border 30-50 px
    # inside the image, and the detector returned it with that end called the image border (a
    # wrong end kind: the weld's stop would be taken from the other view or clipped). Between the
    # end and the edge lies the table: refused now, saying so.
    import pytest

    from bench.detect_cases import make_case_scene, pair_poses
    from controller.errors import SeamguideError
    from controller.geometry.camera_model import default_camera
    from controller.vision.seam_detect import detect_seam
    from drivers.sim.sim_render import render

    cam = default_camera()
    case = ("wide", "easy", "tuning", 10171)
    scene = make_case_scene(case)
    T = pair_poses(scene, cam, case[3])[0]
    img = np.asarray(render(scene, cam, T, seed=case[3]).image)
    with pytest.raises(SeamguideError, match=r"its end at the image border lies \d+ px inside the "
                       r"image, and the \d+ px to the edge show the table"):
        detect_seam(img, camera=cam)
