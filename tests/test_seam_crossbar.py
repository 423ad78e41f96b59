"""The seam chosen refused where a long line ends on it from one side: a T-corner's crossbar
(controller/vision/seam_crossbar.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from rendered_cases import rendered_view

from bench.detect_score import score_view
from controller.errors import AmbiguousSeam
from controller.geometry.camera_model import default_camera
from controller.vision.seam_crossbar import stem_on
from controller.vision.seam_detect import detect_seam

SEAM = np.column_stack([np.linspace(0.0, 1000.0, 501), np.full(501, 500.0)])  # along u at v 500


def _line(start: tuple[float, float], angle_deg: float, length: float) -> np.ndarray:
    """A straight line from ``start`` (px) running ``length`` px at ``angle_deg`` to the u axis,
    upward (v decreasing), one point per px."""
    a = np.radians(angle_deg)
    t = np.arange(0.0, length + 1e-9, 1.0)
    return np.column_stack([start[0] + t * np.cos(a), start[1] - t * np.sin(a)])


def test_a_line_ending_on_the_seam_from_one_side_is_a_stem() -> None:
    found = stem_on(SEAM, 6.0, _line((400.0, 492.0), 70.0, 600.0))
    assert found is not None
    at, angle = found
    assert abs(at[0] - 400.0) <= 4.0 and at[1] == 500.0
    assert angle == pytest.approx(70.0, abs=2.0)
    # Either end of the line may be the one on the seam.
    assert stem_on(SEAM, 6.0, _line((400.0, 492.0), 70.0, 600.0)[::-1]) is not None


def test_a_curving_stem_is_read_at_the_end_that_meets_the_seam() -> None:
    # Up from the seam at 80 deg for 80 px, then bending to run nearly along it: the chord from
    # its far end meets the seam at a shallow angle, the stem itself does not.
    first = _line((400.0, 492.0), 80.0, 80.0)
    turn = _line(tuple(first[-1]), 10.0, 700.0)[1:]
    stem = np.vstack([first, turn])
    for line in (stem, stem[::-1]):
        found = stem_on(SEAM, 6.0, line)
        assert found is not None and found[1] == pytest.approx(80.0, abs=3.0)


def test_a_crossing_a_shallow_angle_a_seam_end_or_a_line_apart_is_not() -> None:
    across = _line((400.0 - 60 * np.cos(np.radians(70)), 560.0), 70.0, 600.0)  # goes on below
    assert stem_on(SEAM, 6.0, across) is None
    assert stem_on(SEAM, 6.0, _line((400.0, 492.0), 30.0, 600.0)) is None  # under 45 deg
    assert stem_on(SEAM, 6.0, _line((30.0, 492.0), 80.0, 600.0)) is None  # at the seam's end
    assert stem_on(SEAM, 6.0, _line((400.0, 460.0), 70.0, 600.0)) is None  # 40 px away


def test_a_t_corners_crossbar_is_not_returned_for_its_stem(tmp_path: Path) -> None:
    # Tee hard tuning 60037, view 1: the joint (a ragged, curving 20 px gap) ends on a straight
    # crossbar from border to border; the stem fails the profiles and the crossbar alone passed,
    # returned at confidence 0.93 (412 px RMS from the joint).
    img, truth = rendered_view(tmp_path, ("tee", "hard", "tuning", 60037), 1)
    with pytest.raises(AmbiguousSeam, match="T-corner") as err:
        detect_seam(img, camera=default_camera())
    bar = np.asarray(err.value.details["best_px"], np.float64)
    assert score_view(bar, truth, ["image_border", "image_border"])["result"] == "wrong"
    # A job whose nominal seam line is the crossbar means it: returned then.
    det = detect_seam(img, camera=default_camera(), hint=bar)
    assert np.median(np.linalg.norm(det.points_px[::10, None, :] - bar[None], axis=2)
                     .min(axis=1)) < 40.0
