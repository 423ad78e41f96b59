"""Ends between rounded plate corners (controller/vision/seam_ends.py): each sheet's edge curves
away from the gap toward the border, so the border is no straight line across the seam and a
line through three of its crossings, or the inner of two such lines, can be far from the end.
The sheets stop facing each other where the gap has opened to twice its width (the renderer's
truth, sim_scene._corner_trim). Drawn images, not our renderer: two sheets on a dark table with
exact area coverage (4x supersampled), corners rounded with a 12-60 px radius, a gap 6-10 px
wide, blur and sensor noise; the truth end is computed from the drawing."""

import cv2
import numpy as np
import pytest

from controller.vision.seam_border import border_line
from controller.vision.seam_detect import detect_seam

S = 4  # supersampling


def drawn(gap, radius, seed, size=(1600, 1200)):
    """(image, true ends (2, 2) px): a horizontal joint at y = 600 from x = 300 to 1300."""
    W, H = size
    g, R = gap * S, radius * S
    x0, x1, yc = 300 * S, 1300 * S, 600 * S
    m = np.zeros((H * S, W * S), np.uint8)
    for y_out, y_in in ((200 * S, yc - g / 2), (1000 * S, yc + g / 2)):
        top, bot = sorted((y_out, y_in))
        cv2.rectangle(m, (x0, int(top)), (x1 - 1, int(bot) - 1), 255, -1)
        sgn = 1 if y_in > y_out else -1  # the joint's side of the sheet, seen from its middle
        for xc, dx in ((x0 + R, -1), (x1 - R, 1)):
            # The corner square at the joint cut away, a quarter disc put back.
            ys = sorted((int(y_in), int(y_in - sgn * R)))
            xs = sorted((int(xc), int(xc + dx * R)))
            m[ys[0]:ys[1], xs[0]:xs[1]] = 0
            cv2.circle(m, (int(xc), int(y_in - sgn * R)), int(R), 255, -1)
    cov = cv2.resize(m.astype(np.float32) / 255, (W, H), interpolation=cv2.INTER_AREA)
    img = 35.0 + 135.0 * cov
    img = cv2.GaussianBlur(img, (0, 0), 1.0)
    img += np.random.default_rng(seed).normal(0, 2.0, img.shape)
    x_end = radius - np.sqrt(radius ** 2 - (radius - gap / 2) ** 2)
    ends = np.array([[300 + x_end, 600.0], [1300 - x_end, 600.0]]) - 0.5 + 0.5 / S
    return np.clip(img, 0, 255).astype(np.uint8), ends


@pytest.mark.parametrize("gap,radius", [(6.0, 12.0), (8.0, 24.0), (10.0, 40.0), (6.0, 30.0),
                                        (10.0, 20.0), (8.0, 60.0)])
def test_the_end_between_two_rounded_corners_is_where_the_gap_has_opened(gap, radius):
    img, ends = drawn(gap, radius, seed=int(gap))
    det = detect_seam(img)
    E = det.endpoints_px[np.argsort(det.endpoints_px[:, 0])]
    # Within 1.5 px (the straight-border reading: 3-15 px off, or refused as unsure). Not yet:
    # wider gaps between larger corners (12 px / 40 px: half the seeds 7 px off; 14 / 50 and
    # 16 / 60: 8-10 px), where an outer line reaches the border beyond the 20 px looked past
    # the last fitted profile and the straight reading is kept.
    assert np.linalg.norm(E - ends, axis=1).max() <= 1.5, (E, ends)
    assert det.end_kinds == ("joint_end", "joint_end") and det.confidence >= 0.5


def test_two_receding_edges_are_read_as_rounded_corners_a_straight_border_as_its_line():
    # Steps on the lines at offsets (-2d, -d, 0, d, 2d): each sheet receding from the gap toward
    # the border (the outer line steps later) is read as two rounded corners; a straight oblique
    # border (one side recedes, the other advances) as the line through its steps.
    offs = (-25.0, -12.5, 0.0, 12.5, 25.0)
    # The edge has receded by 2.5 px at the inner lines, 15 px at the outer ones; the end is
    # where it has receded by w / 2 = 10 px, read as a rounded edge does (the distance along
    # goes as the root of the recess).
    t = (np.sqrt(10.0) - np.sqrt(2.5)) / (np.sqrt(15.0) - np.sqrt(2.5))
    k, unsure, *_ = border_line(offs, [[-2.0], [-10.0], [], [-10.0], [-2.0]], w=20.0)
    assert k == pytest.approx(-10.0 + 8.0 * t) and not unsure
    k, unsure, *_ = border_line(offs, [[-5.0], [-2.5], [0.0], [2.5], [5.0]], w=20.0)
    assert k == pytest.approx(0.0) and not unsure
