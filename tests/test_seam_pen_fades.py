"""A line fading out inside a sheet beside a seam whose ends are read is no rival to it
(controller/vision/seam_decision.py: fades_beside): the joint ends at the sheets' borders, a pen
line drawn beside it ends inside the sheet. Candidates built by hand for each condition, and a
rendered tuning view where the pen line beside the joint made it refused."""

import numpy as np
import pytest
from rendered_cases import rendered_view

from controller.errors import AmbiguousSeam
from controller.vision.seam_decision import choose
from controller.vision.seam_params import OPEN_END, Candidate, DetectParams


def _joint(x0: float = 200.0, width: float = 4.0,
           kinds: tuple[str, str] = ("sheet border", "image border")) -> Candidate:
    """A seam along y = 800 from ``x0`` (its first end, a sheet border) to the image border."""
    P = np.column_stack([np.linspace(x0, 2271.0, 400), np.full(400, 800.0)])
    return Candidate(P, 100.0, 2271.0 - x0, points=P, width=np.full(400, width), depth=0.5,
                     valid_frac=1.0, score=100.0, end_kinds=kinds)


def _pen(x0: float, offset: float, score: float = 95.0, x1: float = 2271.0,
         kinds: tuple[str, str] = ("open", "image border")) -> Candidate:
    """A line ``offset`` px beside the seam from ``x0`` (fading out there) to ``x1`` (the image
    border): refused for its open end, a rival (as seam_centreline leaves it)."""
    P = np.column_stack([np.linspace(x0, x1, 400), np.full(400, 800.0 + offset)])
    return Candidate(P, score, abs(x1 - x0), points=P, width=np.full(400, 3.0), depth=0.5,
                     valid_frac=1.0, score=score, end_kinds=kinds,
                     why_rejected="dark line fades out inside the sheet at one end",
                     refused=OPEN_END, rival=True)


def test_a_pen_line_fading_out_beside_the_seam_is_no_rival() -> None:
    # Drawn 40 px beside the joint, ending 500 px in from the joint's end at a sheet border.
    joint, pen = _joint(), _pen(700.0, 40.0)
    best, ratio, conf, _ = choose([joint, pen], DetectParams(), {}, (0, 0))
    assert best is joint and ratio == 0.0 and conf > 0.9


@pytest.mark.parametrize("why, joint, pen", [
    # The line fades out beside the seam and runs the other way on to a border 100 px past
    # where the seam's sheets are read to end: that border is not where the sheets end (or the
    # seam is another line, e.g. a ground strip's edge).
    ("runs past the border", _joint(), _pen(1500.0, 40.0, x1=100.0,
                                            kinds=("open", "sheet border"))),
    # It fades out past the seam's end, not beside it.
    ("fades out past the end", _joint(), _pen(100.0, 40.0)),
    # On the seam, not beside it: a piece of the same line.
    ("on the seam", _joint(), _pen(700.0, 4.0)),
    # A dark band 8 px wide may be a gap and a shadow: its middle and ends are the less sure.
    ("wide band", _joint(width=8.0), _pen(700.0, 40.0)),
    # An end read unsure is no read end.
    ("unsure end", _joint(kinds=("unsure sheet border", "image border")), _pen(700.0, 40.0)),
    # Farther than any pen line is drawn: another line, not the joint's twin.
    ("far away", _joint(), _pen(700.0, 300.0)),
])
def test_a_line_fading_out_stays_a_rival_unless_drawn_beside_a_well_read_seam(
        why: str, joint: Candidate, pen: Candidate) -> None:
    with pytest.raises(AmbiguousSeam, match="similar strength"):
        choose([joint, pen], DetectParams(), {}, (0, 0))


@pytest.fixture(scope="module")
def pen_beside_the_joint(tmp_path_factory: pytest.TempPathFactory) -> tuple[np.ndarray, dict]:
    """Wide medium tuning 10120, view 0, rendered here: a pen line 28 px beside the joint fades
    out inside the sheet; the joint runs from a sheet border to the image border."""
    return rendered_view(tmp_path_factory.mktemp("cache"), ("wide", "medium", "tuning", 10120), 0)


def test_the_joint_beside_a_pen_line_fading_out_is_found(
        pen_beside_the_joint: tuple[np.ndarray, dict]) -> None:
    # Refused before as "two seam candidates of similar strength" (ratio 1.00).
    from bench.detect_score import score_view
    from controller.vision.seam_detect import detect_seam

    img, truth = pen_beside_the_joint
    det = detect_seam(img)
    assert score_view(det.points_px, truth, list(det.end_kinds))["result"] == "found"
    assert det.confidence >= 0.9
