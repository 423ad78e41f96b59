"""A returned seam's confidence falls with its dark band's width (seam_decision.width_factor).

Measured on the simulator's extended tuning part (README, *Confidence and the band's width*):
returned seams with a band wider than 8 px were wrong several times as often as narrower ones
(tuning 32 % / 5 %, held-out 29 % / 9 %): a shadow, the far sheet's cut face or a ragged edge
inside the band moves the gap's middle.
"""

from dataclasses import replace

import numpy as np
import pytest

from controller.vision.seam_decision import WIDE_FLOOR, rate_confidence, width_factor
from controller.vision.seam_params import Candidate, DetectParams


def _candidate(width_px: float) -> Candidate:
    pts = np.column_stack([np.linspace(0, 1000, 50), np.full(50, 100.0)])
    return Candidate(pts, 1.0, 1000.0, points=pts, width=np.full(50, width_px), depth=0.8,
                     valid_frac=1.0, resid=0.02, end_kinds=("sheet border", "image border"))


def test_a_narrow_band_keeps_its_confidence_a_wide_one_loses_some() -> None:
    p = DetectParams()
    assert width_factor(4.0, p) == 1.0 and width_factor(6.0, p) == 1.0
    assert width_factor(8.0, p) == pytest.approx(0.94)
    assert width_factor(12.0, p) == pytest.approx(0.82)
    assert width_factor(40.0, p) == WIDE_FLOOR
    narrow, why_n = rate_confidence(_candidate(4.0), 0.0, p)
    wide, why_w = rate_confidence(_candidate(12.0), 0.0, p)
    assert narrow == pytest.approx(1.0) and wide == pytest.approx(0.82)
    assert not any("px wide" in r for r in why_n)
    assert any("dark band 12.0 px wide" in r for r in why_w)


def test_the_knee_follows_the_scale_set_for_the_working_distance() -> None:
    # At twice the px per mm (a close-up, seam_scale.params_for_scale) the widest gap accepted
    # doubles, and a band twice as wide in px is judged as the narrow one was.
    p = DetectParams()
    close = replace(p, max_gap_px=2 * p.max_gap_px)
    assert width_factor(24.0, close) == pytest.approx(width_factor(12.0, p))
    assert width_factor(12.0, close) == 1.0
