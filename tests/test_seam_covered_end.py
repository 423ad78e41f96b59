"""A line stopped by a patch on the joint with no gap seen beyond it is measured once.

Where a line's end reads as a patch on the joint (steps on the lines beside the gap, but the
sheets go on beside it: a tack weld's bead), ``seam_centreline.refine`` extends the line across
the patch to the gap seen beyond and measures it again. Where no gap is seen beyond, there is
nothing to cross: it used to measure the same line again anyway, up to ten times, nearly always
reading the same end (164 of 408 refinements on 48 views of the wide look's tuning part).
"""

from __future__ import annotations

import numpy as np
import pytest
from drawn_plates import S, render

from controller.vision import seam_centreline
from controller.vision.seam_params import Candidate, DetectParams
from controller.vision.seam_profiles import linear_lut

ROW = 600.0  # the joint's row


def _plates(gap_beyond: bool) -> np.ndarray:
    """Two plates (x 200-1500 px) on a dark table, the gap along ROW from the plates' edge at
    x = 200 to a bright bead at x = 1100-1140 (a tack weld), and, if ``gap_beyond``, on past it
    to x = 1400."""

    def fill(m: np.ndarray) -> None:
        m[:] = 40.0
        m[int(250 * S):int(ROW * S), int(200 * S):int(1500 * S)] = 170.0
        m[int(ROW * S):int(950 * S), int(200 * S):int(1500 * S)] = 150.0
        x_end = 1400 if gap_beyond else 1100
        m[int((ROW - 3) * S):int((ROW + 3) * S), int(200 * S):int(x_end * S)] = 22.0
        m[int((ROW - 25) * S):int((ROW + 25) * S), int(1100 * S):int(1140 * S)] = 235.0

    return render(fill, seed=3)


@pytest.mark.parametrize("gap_beyond", [False, True])
def test_a_patch_is_crossed_only_to_a_gap_seen_beyond(monkeypatch, gap_beyond: bool) -> None:
    passes: list[int] = []
    refine = seam_centreline.refine

    def counted(grey, lut, c, p, crossed=0):  # type: ignore[no-untyped-def]
        passes.append(crossed)
        return refine(grey, lut, c, p, crossed)

    monkeypatch.setattr(seam_centreline, "refine", counted)  # its own calls come here too
    p = DetectParams()
    xs = np.arange(240.0, 1060.0, 8.0)  # the coarse line, up to the bead
    c = Candidate(np.column_stack([xs, np.full_like(xs, ROW + 1.0)]), 1.0, float(xs[-1] - xs[0]))
    counted(_plates(gap_beyond), linear_lut(p.gamma), c, p)
    assert c.points is not None
    if gap_beyond:
        # Crossed once, to the gap beyond the bead, and measured again to its end there.
        assert passes == [0, 1]
        assert c.points[-1][0] > 1350.0
        assert np.asarray(c.bridged, bool)[(c.points[:, 0] > 1105.0)
                                           & (c.points[:, 0] < 1135.0)].all()
    else:
        # Nothing beyond to cross to: measured once, the end is the patch, and the line is no
        # seam by itself (the end of a seam is where the sheets end, or the image).
        assert passes == [0]
        assert c.end_kinds[1] == "covered" and "covered patch" in c.why_rejected
        assert abs(c.points[-1][0] - 1100.0) < 6.0
