"""A hairline gap about one coarse pixel wide (controller/vision/seam_coarse.py, ``fine``).

The coarse search shrinks the image 4x (2272 px wide). A gap 1.2-2.2 px wide covers under half a
coarse pixel; where it straddles two of them each shows half its depth, under the threshold, and
the valley falls apart into pieces too short to keep. The detector then looks again with the
depth of a grid twice as fine pooled onto the coarse one. The images are drawn exactly (area
coverage of the gap per pixel, sensor noise), with the true centreline.
"""

import numpy as np
import pytest

from controller.vision.seam_coarse import coarse_candidates
from controller.vision.seam_detect import DetectParams, detect_seam
from controller.vision.seam_profiles import linear_lut


def hairline(width_px, floor, slope=0.35, seed=0, H=1704, W=2272):
    """A straight gap ``width_px`` wide whose floor is ``floor`` x the sheet's radiance, crossing
    the whole image at ``slope``; returns the image and the true centreline (u, v) per column."""
    rng = np.random.default_rng(seed)
    u = np.arange(W)
    c = 400.0 + slope * u
    rows = np.arange(H)[:, None] + (np.arange(8)[None, :] + 0.5) / 8 - 0.5  # 8 sub-rows a pixel
    cover = np.zeros((H, W))
    for k in range(8):
        cover += np.abs(rows[:, k:k + 1] - c[None, :]) <= width_px / 2
    radiance = 0.30 * (1.0 - cover / 8 * (1.0 - floor))
    img = 255.0 * radiance ** (1 / 2.2) + rng.normal(0.0, 2.0, (H, W))
    return np.clip(np.round(img), 0, 255).astype(np.uint8), np.column_stack([u, c])


@pytest.mark.parametrize("width_px,floor", [(1.2, 0.3), (1.6, 0.45), (2.2, 0.55), (1.6, 0.65)])
def test_a_hairline_gap_lost_on_the_coarse_grid_is_found_on_the_finer_one(width_px, floor):
    img, truth = hairline(width_px, floor)
    p = DetectParams()
    lut = linear_lut(p.gamma)
    # The mechanism: on the coarse grid the gap is not one candidate; on the finer one it is.
    assert not [c for c in coarse_candidates(img, lut, p)[0] if c.length_px > 1000]
    fine = coarse_candidates(img, lut, p, fine=True)[0]
    assert fine and fine[0].length_px > 2000
    det = detect_seam(img)
    off = np.abs(np.interp(det.points_px[:, 0], truth[:, 0], truth[:, 1]) - det.points_px[:, 1])
    assert off.max() < 0.6, off.max()
    assert det.end_kinds == ("image_border", "image_border")
    assert det.stats["way"] == "profiles"
    assert det.points_px[:, 0].min() < 20 and det.points_px[:, 0].max() > 2250
