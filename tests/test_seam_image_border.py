"""An end read as the image border only where the gap is seen to run on up to it (drawn images)."""

import numpy as np

from controller.vision.seam_border import NEAR_IMAGE_BORDER_PX, gap_reaches_image_border
from controller.vision.seam_profiles import linear_lut

H, W = 400, 300


def _gap_to(stop_v: float, seed: int = 0) -> np.ndarray:
    """Two sheets (150 | 170, noise 5) with a dark gap 4 px wide at u = 150 from the top down
    to ``stop_v``; the sheets go on below it."""
    rng = np.random.default_rng(seed)
    vv, uu = np.mgrid[0:H, 0:W].astype(np.float64)
    img = np.where(uu < 150.0, 150.0, 170.0) + rng.normal(0.0, 5.0, (H, W))
    img[(np.abs(uu - 150.0) < 2.0) & (vv < stop_v)] = 40.0
    return np.clip(img, 0, 255).astype(np.uint8)


def _reaches(grey: np.ndarray, v0: float) -> bool:
    e_pt, tang = np.array([150.0, v0]), np.array([0.0, 1.0])
    return gap_reaches_image_border(grey, linear_lut(2.2), e_pt, tang, 4.0, H - 0.5 - v0)


def test_a_gap_running_out_of_the_image_reaches_its_border() -> None:
    assert _reaches(_gap_to(H + 1.0), H - 35.0)


def test_a_gap_ending_25_px_inside_the_image_does_not_reach_its_border() -> None:
    # Profiles stop 10 px before the gap's end, 35 px from the border: the gap is seen on 10 of
    # the 34 px ahead. (The image searched shrunk by 2: wide medium tuning 10105 view 0,
    # a joint end 25-28 px inside the image taken for the image border.)
    assert not _reaches(_gap_to(H - 25.0), H - 35.0)


def test_nothing_left_to_read_next_to_the_border_is_the_border() -> None:
    assert _reaches(_gap_to(H - 25.0), H - NEAR_IMAGE_BORDER_PX + 2.0)


def test_no_gap_before_the_end_point_is_no_evidence_against_the_border() -> None:
    # Nothing clear to compare with: the rule says nothing, the caller's reading stands.
    assert _reaches(_gap_to(0.0), H - 35.0)
