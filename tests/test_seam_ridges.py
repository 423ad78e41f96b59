"""A gap between two bright ridges (a ground strip's specular edge): the profiles read close in.

The two-edge model takes the sheets' levels from the ends of each profile, 14 px to each side.
Where a grinder has left a bright ridge a few px wide along each gap edge, the profile is sheet,
ridge, gap, ridge, sheet: the model's flat sides miss the ridges by more than its residual
allows, and a plainly visible gap had no long run of good profiles (wide easy tuning 10029, 10064,
10105, the simulator's shop look). Such a profile is fitted again over the gap and the ridges
only (``DetectParams.ridge_half_width_px``), and kept when the sheet just beside the gap is
brighter on *both* sides than farther out: a ridge on each edge. A dark line with a bright strip
on one side only (a ground strip's outer edge) is not a gap between ridges.
The images are drawn exactly (area coverage per pixel, sensor noise), with the true centreline.
"""

import numpy as np
import pytest

from controller.vision.seam_detect import DetectParams, detect_seam
from controller.vision.seam_profiles import fit_at, linear_lut, resample


def ridged(gap_px=3.0, ridge_px=(5.0, 5.0), ridge_gain=1.8, floor=0.35, slope=0.3, seed=0,
           H=1704, W=2272):
    """A straight gap ``gap_px`` wide with a bright ridge ``ridge_px`` wide along each edge
    (``ridge_gain`` x the sheet's radiance; 0 px: none on that side), crossing the whole image;
    returns the image and the true centreline (u, v) per column."""
    rng = np.random.default_rng(seed)
    u = np.arange(W)
    c = 500.0 + slope * u
    sub = (np.arange(8) + 0.5) / 8 - 0.5
    radiance = np.zeros((H, W))
    for k in range(8):
        d = np.arange(H)[:, None] + sub[k] - c[None, :]  # signed distance, along v
        level = np.full((H, W), 0.30)
        level[(d < -gap_px / 2) & (d >= -gap_px / 2 - ridge_px[0])] = 0.30 * ridge_gain
        level[(d > gap_px / 2) & (d <= gap_px / 2 + ridge_px[1])] = 0.30 * ridge_gain
        level[np.abs(d) <= gap_px / 2] = 0.30 * floor
        radiance += level / 8
    img = 255.0 * radiance ** (1 / 2.2) + rng.normal(0.0, 2.0, (H, W))
    return np.clip(np.round(img), 0, 255).astype(np.uint8), np.column_stack([u, c])


def _valid_share(img, truth, shoulders):
    p = DetectParams()
    pts, nrm = resample(truth[::20].astype(np.float64), p.step_px, 0.0)
    return float(fit_at(img, linear_lut(p.gamma), pts, nrm, p, shoulders=shoulders)["valid"].mean())


def test_a_gap_between_two_ridges_fits_where_the_profile_reads_close_in():
    img, truth = ridged()
    # The mechanism: over 14 px to each side the ridges spoil the fit; close in it fits.
    assert _valid_share(img, truth, shoulders=False) < 0.2
    assert _valid_share(img, truth, shoulders=True) > 0.9
    det = detect_seam(img)
    off = np.abs(np.interp(det.points_px[:, 0], truth[:, 0], truth[:, 1]) - det.points_px[:, 1])
    assert off.max() < 0.6, off.max()
    assert det.end_kinds == ("image_border", "image_border")
    assert det.points_px[:, 0].min() < 20 and det.points_px[:, 0].max() > 2250


@pytest.mark.parametrize("ridge_px", [(5.0, 0.0), (0.0, 5.0)])
def test_a_dark_line_with_a_bright_strip_on_one_side_only_is_not_fitted_close_in(ridge_px):
    img, truth = ridged(ridge_px=ridge_px)
    # Close in, a one-sided strip fits the two-edge model as well as a ridged gap; it is not
    # taken, since only one side is brighter close in than farther out.
    assert _valid_share(img, truth, shoulders=True) == _valid_share(img, truth, shoulders=False)


def test_without_ridges_the_profiles_are_as_before():
    img, truth = ridged(ridge_px=(0.0, 0.0))
    assert _valid_share(img, truth, shoulders=True) == _valid_share(img, truth, shoulders=False) > 0.9
