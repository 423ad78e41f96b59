"""A candidate whose profiles fit a band wider than the scale's widest gap is refused saying so,
and the detector's refusal says to state the working distance and the joint's gap; with them the
same band is measured (controller.vision.seam_centreline._too_wide,
controller.vision.seam_centreline.scale_advice, controller.vision.seam_scale.params_for_scale)."""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest
from drawn_plates import S, render

from controller.errors import SeamNotFound
from controller.vision.seam_centreline import refine
from controller.vision.seam_detect import DetectParams, detect_seam
from controller.vision.seam_params import Candidate
from controller.vision.seam_profiles import fit_at, linear_lut, resample
from controller.vision.seam_scale import params_for_scale

X0, X1 = 300.0, 1300.0  # where the plates stop facing each other (columns, px)
ROW = 600.0  # the joint's middle row
ADVICE = "wider than the widest gap at this scale (16 px)"


def _plates(half_gap_px: float, blur_px: float) -> np.ndarray:
    """Two plates on a dark table meeting along row ROW at a gap ``2 half_gap_px`` wide with a
    dark floor, blurred by ``blur_px`` (sigma) on top of the drawing's own 1 px."""

    def fill(m: np.ndarray) -> None:
        m[:] = 40.0
        x0, x1 = int(X0 * S), int(X1 * S)
        m[int(250 * S):int(ROW * S), x0:x1] = 170.0
        m[int(ROW * S):int(950 * S), x0:x1] = 150.0
        m[int((ROW - half_gap_px) * S):int((ROW + half_gap_px) * S), x0:x1] = 22.0
        if blur_px > 0:
            cv2.GaussianBlur(m, (0, 0), blur_px * S, dst=m)

    return render(fill, seed=5)


def _refined(img: np.ndarray, p: DetectParams) -> Candidate:
    """The coarse line along the joint (2 px off its middle, as the coarse search gives it),
    refined with ``p``."""
    xs = np.arange(X0 + 40.0, X1 - 40.0, 8.0)
    c = Candidate(np.column_stack([xs, np.full_like(xs, ROW + 2.0)]), 1.0, float(xs[-1] - xs[0]))
    refine(img, linear_lut(p.gamma), c, p)
    return c


def test_fit_at_says_which_profiles_fit_but_too_wide() -> None:
    img = _plates(11.0, blur_px=3.0)  # a 22 px gap
    p = DetectParams()
    xs = np.arange(X0 + 100.0, X1 - 100.0, 4.0)
    pts, nrm = resample(np.column_stack([xs, np.full_like(xs, ROW)]), 4.0, extend=0.0)
    fit = fit_at(img, linear_lut(p.gamma), pts, nrm, p)
    assert fit["too_wide"].mean() > 0.9 and not fit["valid"].any()
    assert np.all(fit["width"][fit["too_wide"]] >= p.max_gap_px)


@pytest.mark.parametrize("blur_px", [0.0, 3.0])
def test_a_band_wider_than_the_widest_gap_is_refused_saying_so(blur_px: float) -> None:
    c = _refined(_plates(11.0, blur_px), DetectParams())
    assert c.points is None
    assert "no long run of gap profiles" in c.why_rejected
    assert "fit a dark band" in c.why_rejected and ADVICE in c.why_rejected


def test_with_the_working_distance_and_the_gap_the_band_is_measured() -> None:
    # 10 px per mm and a 2.2 mm gap stated (the drawn gap is 22 px): what the advice asks for.
    p = params_for_scale(10.0, (1.5, 2.5))
    c = _refined(_plates(11.0, blur_px=3.0), p)
    assert not c.why_rejected and c.points is not None
    inner = c.points[(c.points[:, 0] > X0 + 60) & (c.points[:, 0] < X1 - 60)]
    assert np.max(np.abs(inner[:, 1] - ROW)) < 1.0
    assert 18.0 < float(np.median(c.width)) < 26.0


def test_a_gap_the_scale_accepts_gets_no_such_advice() -> None:
    c = _refined(_plates(3.0, blur_px=0.0), DetectParams())  # a 6 px gap
    assert not c.why_rejected and ADVICE not in c.why_rejected


def _search(params: DetectParams) -> DetectParams:
    """``params`` with the first way's search only: no valley paths, no look shrunk (which find
    a drawn wide gap by other means)."""
    return replace(params, robust=False, smaller=False)


def test_the_detector_s_refusal_says_what_to_give_and_with_it_finds_the_gap() -> None:
    img = _plates(9.5, blur_px=0.0)  # a 19 px gap
    with pytest.raises(SeamNotFound) as err:
        detect_seam(img, params=_search(DetectParams()))
    assert "1 line(s) looked at fit a dark band " + ADVICE in str(err.value)
    assert "give the working distance and the joint's gap" in str(err.value)
    assert "a wide gap or a gap with a shadow or a mark beside it" in str(err.value)
    assert err.value.details["rejected"]  # the error's data kept
    det = detect_seam(img, params=_search(params_for_scale(10.0, (1.5, 2.5))))
    assert det.end_kinds == ("joint_end", "joint_end")
    assert np.median(np.abs(det.points_px[:, 1] - ROW)) < 1.0


def test_with_the_scales_set_too_narrow_the_refusal_says_to_check_them() -> None:
    p = params_for_scale(10.0, (0.5, 1.2))  # widest gap 12 px: a band up to 17 px
    with pytest.raises(SeamNotFound) as err:
        detect_seam(_plates(9.5, blur_px=0.0), params=_search(p))
    assert "wider than the widest gap at this scale (17 px)" in str(err.value)
    assert "check the working distance and the widest gap given" in str(err.value)
