"""A seam ending at a T-corner: the stem chosen over the crossbar it ends on, its end at the
crossbar's near edge (drawn images and candidates with exact truth, and a simulated T-corner
close-up)."""

import cv2
import numpy as np
import pytest
from rendered_cases import rendered_view

from bench.detect_score import score_view
from controller.errors import AmbiguousSeam
from controller.vision.seam_decision import choose
from controller.vision.seam_detect import detect_seam
from controller.vision.seam_params import (
    JOINED_LINES,
    OPEN_END,
    Candidate,
    DetectParams,
)
from controller.vision.seam_profiles import linear_lut
from controller.vision.seam_tee import cut_stems, find_tees

LUT = linear_lut(DetectParams().gamma)
#: Plates everywhere (sheets and the third plate as bright), for the geometry alone.
PLATES = np.full((900, 1200), 170, np.uint8)

BAR_X, BAR_W = 900.0, 10.0


def _stem_y(x: np.ndarray | float) -> np.ndarray | float:
    """The drawn stem's centreline: y (px) at x."""
    return 450.0 + 0.04 * (np.asarray(x) - 450.0)


def _t_image(seed: int = 0) -> np.ndarray:
    """Sheets A (above) and B (below) meeting along a gap 8 px wide from the left border to a
    crossbar gap BAR_W px wide at x = BAR_X, border to border, with a third plate beyond it."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:900, 0:1200].astype(np.float64)
    img = np.where(yy < 450, 160.0, 175.0)
    img = np.where(xx > BAR_X, 168.0, img)
    stem = (np.abs(yy - _stem_y(xx)) < 4.0) & (xx < BAR_X)
    img[stem | (np.abs(xx - BAR_X) < BAR_W / 2)] = 30.0
    img = cv2.GaussianBlur(img, (0, 0), 1.2) + rng.normal(0, 4, img.shape)
    return np.clip(img, 0, 255).astype(np.uint8)


def test_the_stem_of_a_t_is_returned_with_its_end_at_the_crossbars_near_edge() -> None:
    # Before: the crossbar, border to border, was returned ("no other candidate"); the stem's
    # end at it was read as a patch with the gap going on beyond (the crossbar's gap).
    det = detect_seam(_t_image())
    assert det.end_kinds == ("image_border", "joint_end")
    end = det.points_px[-1]
    assert end[0] == pytest.approx(BAR_X - BAR_W / 2, abs=1.0)
    assert end[1] == pytest.approx(_stem_y(end[0]), abs=1.0)
    assert np.abs(det.points_px[:, 1] - _stem_y(det.points_px[:, 0])).max() < 1.0
    assert any("T-corner" in r for r in det.reasons)


def _line(p0, p1, width=8.0, kinds=("sheet border", "sheet border"), score=1000.0, why="",
          step=2.0, bridged=None, refused=None) -> Candidate:
    """A candidate along the straight line p0 -> p1 (px), a point every ``step`` px.

    ``why``, ``refused``: its refusal's message and code (by default ``OPEN_END`` with a message).
    """
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    n = int(np.linalg.norm(p1 - p0) / step) + 1
    pts = p0 + np.outer(np.linspace(0, 1, n), p1 - p0)
    br = np.zeros(n, bool) if bridged is None else bridged(pts)
    return Candidate(pts, 1.0, float(np.linalg.norm(p1 - p0)), points=pts, width=np.full(n, width),
                     depth=0.8, valid_frac=1.0, score=score, end_kinds=kinds, bridged=br,
                     way="valley path", why_rejected=why, rival=bool(why),
                     refused=(OPEN_END if why else "") if refused is None else refused)


def _bar() -> Candidate:
    return _line((900, 0), (900, 900), width=10.0, kinds=("image border", "image border"),
                 score=1500.0)


def test_a_stem_run_on_across_the_crossbar_is_cut_at_its_near_edge() -> None:
    stem = _line((0, 450), (930, 450), kinds=("image border", "open"),
                 why="dark line of 930 px fades out inside a sheet (a pen or soapstone line)")
    stem.stats = {"support": 1.0}
    bar = _bar()
    tees = find_tees(PLATES, LUT, [bar, stem])
    assert len(tees) == 1 and tees[0].stem is stem and tees[0].end == 1
    cut_stems(tees)
    assert stem.points[-1] == pytest.approx([895.0, 450.0], abs=0.5)
    assert stem.end_kinds == ("image border", "sheet border") and not stem.why_rejected
    assert len(stem.width) == len(stem.points) == len(stem.bridged)


@pytest.mark.parametrize("case", ["crossing", "corner", "parallel", "bridged", "border beyond"])
def test_what_is_not_a_t(case: str) -> None:
    bar = _bar()
    if case == "crossing":  # runs on 200 px past the bar: two lines crossing
        stem = _line((0, 450), (1100, 450), kinds=("image border", "open"))
    elif case == "corner":  # the bar ends where the stem meets it
        bar = _line((900, 0), (900, 450), width=10.0, kinds=("image border", "sheet border"))
        stem = _line((0, 450), (895, 450))
    elif case == "parallel":
        stem = _line((895, 0), (895, 900))
    elif case == "bridged":  # nothing seen of it over the 150 px before the bar
        stem = _line((0, 450), (895, 450), bridged=lambda p: p[:, 0] > 745)
    else:  # crossed the bar and ran on to a sheet border of its own 40 px past it
        stem = _line((0, 450), (945, 450), kinds=("image border", "sheet border"))
    assert find_tees(PLATES, LUT, [bar, stem]) == []


def test_a_line_along_the_sheets_outer_edge_with_the_table_beyond_is_no_crossbar() -> None:
    # The sheets end at x = 905 with a dark table beyond; a dark line runs along their edge.
    img = PLATES.copy()
    img[:, 905:] = 40
    stem = _line((0, 450), (895, 450), kinds=("image border", "unsure sheet border"))
    assert find_tees(img, LUT, [_bar(), stem]) == []
    assert len(find_tees(PLATES, LUT, [_bar(), stem])) == 1


@pytest.mark.parametrize("why", ["fades out at both ends", "joins two lines"])
def test_a_piece_of_a_line_or_a_joined_path_is_no_crossbar(why: str) -> None:
    # A scratch ending on the joint: the joint's piece it meets fades out at both ends, or the
    # path it meets joined two lines across an unseen stretch; neither is a crossbar.
    stem = _line((0, 450), (895, 450), kinds=("image border", "open"),
                 why="dark line of 895 px fades out inside a sheet")
    stem.stats = {"support": 1.0}
    bar = _line((900, 200), (900, 700), width=10.0)
    if why == "fades out at both ends":
        bar.end_kinds, bar.why_rejected = ("open", "open"), "dark line of 500 px fades out"
    else:
        bar.why_rejected = "valley path turns 40 deg across an unseen stretch: it joins two lines"
        bar.refused = JOINED_LINES
    assert find_tees(PLATES, LUT, [bar, stem]) == []


def test_what_a_line_was_refused_for_is_read_from_its_code_not_its_wording() -> None:
    # The rules read a refusal again by its code (seam_params): a message worded otherwise, or
    # one naming an open end for another refusal, changes nothing.
    def stem(why: str, refused: str) -> Candidate:
        c = _line((0, 450), (930, 450), kinds=("image border", "open"), why=why, refused=refused)
        c.stats = {"support": 1.0}
        return c

    assert len(find_tees(PLATES, LUT, [_bar(), stem("ends nowhere", OPEN_END)])) == 1
    other = stem("valley path along a dark line that fades out inside a sheet", "")
    assert find_tees(PLATES, LUT, [_bar(), other]) == []
    joined = _line((900, 0), (900, 900), width=10.0, kinds=("image border", "image border"),
                   why="two lines", refused=JOINED_LINES)
    assert find_tees(PLATES, LUT, [joined, stem("ends nowhere", OPEN_END)]) == []


def _choose(cands):
    return choose(cands, DetectParams(), {}, (0, 0), find_tees(PLATES, LUT, cands))


def test_the_stem_is_chosen_over_a_stronger_crossbar_and_a_weak_one_is_a_doubt() -> None:
    stem = _line((0, 450), (895, 450), kinds=("image border", "sheet border"), score=1200.0)
    best, ratio, conf, reasons = _choose([_bar(), stem])
    assert best is stem and ratio == 0.0 and any("T-corner" in r for r in reasons)
    weak = _line((0, 450), (895, 450), kinds=("image border", "sheet border"), score=600.0)
    with pytest.raises(AmbiguousSeam, match="T-corner"):
        _choose([_bar(), weak])


def test_a_simulated_t_corner_close_up_is_found(tmp_path_factory: pytest.TempPathFactory) -> None:
    # Hard tuning tee 60009 view 0: refused as ambiguous (the crossbar) before; the stem's valley
    # path ran 45 px past the crossbar into the third plate and was read as fading out there.
    case = ("tee", "hard", "tuning", 60009)
    img, truth = rendered_view(tmp_path_factory.mktemp("cache"), case, 0)
    det = detect_seam(img)
    assert score_view(det.points_px, truth, list(det.end_kinds))["result"] == "found"
    assert any("T-corner" in r for r in det.reasons)
