"""bench.bench_gap_depth's figures on drawn images whose gap depth and ridge are known."""

import numpy as np
import pytest
from shared_data import needs

from bench.bench_gap_depth import PHOTOS, gap_figures, photo_rows
from controller.vision.seam_profiles import linear_lut


def drawn(core: float, ridge: float, gap_px: int = 6) -> np.ndarray:
    """A vertical gap at x = 100 in linear light: sheets at 0.5, the gap at ``core`` x 0.5, a
    3 px ridge at ``ridge`` x 0.5 on the right edge only; encoded with gamma 2.2."""
    lin = np.full((300, 201), 0.5)
    lo, hi = 100 - gap_px // 2, 100 + gap_px // 2
    lin[:, lo:hi + 1] = core * 0.5
    lin[:, hi + 1:hi + 4] = ridge * 0.5
    lut = linear_lut(2.2)
    return np.searchsorted(lut, lin).clip(0, 255).astype(np.uint8)


@pytest.mark.parametrize(("core", "ridge"), [(0.0, 1.0), (0.3, 1.6), (0.8, 1.0)])
def test_figures_read_the_drawn_depth_and_ridge(core, ridge):
    centre = np.array([[100.0, 20.0], [100.0, 280.0]])
    got = gap_figures(drawn(core, ridge), centre, 6.0)
    assert got is not None
    assert got[0] == pytest.approx(core, abs=0.02)
    assert got[1] == pytest.approx(ridge, abs=0.03)


def test_a_centreline_outside_the_image_gives_no_figures():
    assert gap_figures(drawn(0.2, 1.0), np.array([[5.0, 20.0], [5.0, 280.0]]), 6.0) is None


@needs(PHOTOS)
def test_the_photographs_gaps_are_read():
    rows = {r["name"]: r for r in photo_rows()}
    assert len(rows) == 9
    # 1_x4: a black crack; 2_x1: the nearly closed joint, no darker than its sheets.
    assert rows["1_x4"]["core"] < 0.05 and rows["2_x1"]["core"] > 0.9
