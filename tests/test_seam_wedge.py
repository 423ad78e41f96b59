"""A gap opening out between two rounded plate corners (controller/vision/seam_wedge.py), told from
what else can lie beyond where the gap stops fitting. Drawn images with exact area coverage (4x
supersampled), blur and sensor noise, mixed in linear light: a horizontal gap along y = 300,
read from a point on it (x = 600 unless a test says otherwise) toward +x, and beyond that
point either the wedge of table between two rounded corners (from x = 700) or something that
is not one."""

import cv2
import numpy as np
import pytest

from controller.vision.seam_detect import detect_seam
from controller.vision.seam_profiles import linear_lut
from controller.vision.seam_wedge import wedge_end

S = 4
SHEET, TABLE = 170.0, 35.0
END = np.array([600.0, 300.0])
TANG = np.array([1.0, 0.0])
LUT = linear_lut(2.2)


def _render(mask: np.ndarray, seed: int, table_grey: float = TABLE) -> np.ndarray:
    """Image from a supersampled sheet mask (255 sheet, 0 table grey ``table_grey``), blurred
    and noisy.

    Light is mixed and blurred in linear radiance, as a lens does, then encoded with the
    camera's gamma of 2.2 (the detector's default).
    """
    cov = cv2.resize(mask.astype(np.float32) / 255, (mask.shape[1] // S, mask.shape[0] // S),
                     interpolation=cv2.INTER_AREA)
    sheet, table = LUT[int(SHEET)], LUT[int(table_grey)]
    lin = cv2.GaussianBlur(table + (sheet - table) * cov, (0, 0), 1.0)
    img = 255.0 * lin ** (1 / 2.2) + np.random.default_rng(seed).normal(0, 2.0, lin.shape)
    return np.clip(img, 0, 255).astype(np.uint8)


def _sheets(gap: float) -> np.ndarray:
    """Two sheets meeting along y = 300 with a gap ``gap`` px wide, over the whole width."""
    m = np.full((600 * S, 1000 * S), 255, np.uint8)
    m[int((300 - gap / 2) * S):int((300 + gap / 2) * S)] = 0
    return m


def corners(gap: float, radius: float, seed: int, table_grey: float = TABLE
            ) -> tuple[np.ndarray, float]:
    """(image, x of the truth end): each sheet's edge along the gap curves away from it from
    x = 700 on, a corner of ``radius`` px; beyond, the table (grey ``table_grey``)."""
    m = _sheets(gap)
    g, R, xc = gap * S, radius * S, 700 * S
    for sgn in (-1, 1):  # upper sheet (edge at y = 300 - gap / 2), lower sheet
        y_edge = 300 * S + sgn * g / 2
        cy = y_edge + sgn * R  # the corner's centre, inside the sheet
        ys = sorted((int(y_edge), int(cy)))
        m[ys[0]:ys[1], xc:] = 0
        cv2.circle(m, (xc, int(cy)), int(R), 255, -1)
        # the sheet beyond the corner's quarter: gone (table)
        m[ys[0]:ys[1], xc + int(R):] = 0
    # The gap has opened to twice its width where each edge has receded by gap / 2.
    x_end = 700 + np.sqrt(radius ** 2 - (radius - gap / 2) ** 2)
    return _render(m, seed, table_grey), float(x_end) - 0.5 + 0.5 / S


@pytest.mark.parametrize("gap,radius", [(2.0, 100.0), (3.0, 150.0), (4.0, 200.0), (2.0, 40.0),
                                        (6.0, 120.0), (7.0, 60.0)])
def test_the_end_is_where_the_wedge_has_opened_to_twice_the_gap(gap, radius):
    img, x_end = corners(gap, radius, seed=int(gap * 10))
    # Read from where the profiles stopped, somewhere before the true end.
    for start in (x_end - 20.0, x_end - 6.0, x_end, x_end + 8.0):
        k = wedge_end(img, LUT, np.array([start, 300.0]), TANG, gap)
        assert k is not None
        assert abs(start + k - x_end) <= 1.5, (start, k, x_end)


def test_a_line_that_fades_out_inside_the_sheet_opens_into_nothing():
    m = _sheets(3.0)
    m[:, 600 * S:] = 255  # the sheet goes on beyond the line's end
    assert wedge_end(_render(m, 1), LUT, END, TANG, 3.0) is None


def test_a_wider_dark_line_beyond_the_gap_keeps_its_width():
    # A pen line lying on the joint: its round cap widens to the line's width, then stays.
    m = _sheets(3.0)
    cv2.line(m, (610 * S, 300 * S), (990 * S, 300 * S), 0, 10 * S)
    assert wedge_end(_render(m, 2), LUT, END, TANG, 3.0) is None


def test_a_table_hole_beyond_the_end_closes_again():
    m = _sheets(3.0)
    m[int(297 * S):int(303 * S), 600 * S:] = 255  # the gap is covered beyond x = 600 ...
    cv2.circle(m, (640 * S, 300 * S), 30 * S, 0, -1)  # ... and a dark disc lies there
    assert wedge_end(_render(m, 3), LUT, END, TANG, 3.0) is None


def test_a_straight_sheet_border_darkens_the_whole_profile_at_once():
    m = _sheets(3.0)
    m[:, 620 * S:] = 0  # both sheets end square across the seam: not this reading's case
    assert wedge_end(_render(m, 4), LUT, END, TANG, 3.0) is None


def test_a_gap_that_goes_on_does_not_open():
    m = _sheets(3.0)
    assert wedge_end(_render(m, 5), LUT, END, TANG, 3.0) is None


def test_a_plate_edge_on_one_side_only_is_no_wedge():
    # One sheet ends in a rounded corner, the other goes on: the dark region grows on one side.
    m = _sheets(3.0)
    R, xc = 80 * S, 700 * S
    y_edge = int(298.5 * S)
    cy = y_edge - R
    m[cy:y_edge, xc:] = 0
    cv2.circle(m, (xc, cy), R, 255, -1)
    m[cy:y_edge, xc + R:] = 0
    assert wedge_end(_render(m, 6), LUT, np.array([700.0, 300.0]), TANG, 3.0) is None


def test_a_perforated_table_in_the_wedge_is_no_single_level_to_read_edges_against():
    # The same corners over a grey perforated table: the holes are darker than the table, and
    # a half-way level read off either is no edge of the sheets.
    img, _ = corners(3.0, 100.0, seed=7)
    lin = LUT[img]
    holes = np.zeros(img.shape, np.uint8)
    for x in range(712, 1000, 24):
        for y in range(240, 361, 24):
            cv2.circle(holes, (x, y), 6, 1, -1)
    # The table beyond x = 705, where the wedge has opened (the gap before it is left alone).
    table = (lin < 0.5 * (LUT[int(SHEET)] + LUT[int(TABLE)])) & (np.arange(img.shape[1]) > 705)
    lin = np.where(table & (holes == 0), 0.15, lin)
    lin = np.where(table & (holes == 1), 0.0, lin)
    grey = np.clip(255.0 * lin ** (1 / 2.2), 0, 255).astype(np.uint8)
    assert wedge_end(grey, LUT, np.array([700.0, 300.0]), TANG, 3.0) is None


@pytest.mark.parametrize("share", [0.6, 0.68])
def test_a_wedge_on_a_grey_table_is_read(share: float) -> None:
    # A table at 60-68 % of the sheets' level (linear radiance; grey 135-143 beside sheets of
    # 170): the wedge reads as plainly as on a dark one. Under half was asked before, and such
    # ends were called open (wide easy tuning 10067: a grey table beside white sheets). With a
    # third of the contrast the end is read within 2.5 px (1.5 px on the dark table above).
    grey = SHEET * share ** (1 / 2.2)
    img, x_end = corners(3.0, 150.0, seed=31, table_grey=grey)
    for start in (x_end - 20.0, x_end - 6.0, x_end):
        k = wedge_end(img, LUT, np.array([start, 300.0]), TANG, 3.0)
        assert k is not None and abs(start + k - x_end) <= 2.5, (start, k, x_end)


def test_a_table_almost_as_bright_as_the_sheets_is_no_wedge_to_read() -> None:
    # At 85 % of the sheets' level the region half-way is under 8 % darker than the sheets:
    # nearer the noise than the shape checks are made for.
    img, x_end = corners(3.0, 150.0, seed=32, table_grey=SHEET * 0.85 ** (1 / 2.2))
    assert wedge_end(img, LUT, np.array([x_end - 6.0, 300.0]), TANG, 3.0) is None


def test_a_band_of_8_px_or_more_is_not_read_so():
    # A wide dark band is often a gap with a shadow beside it, which runs on into the table:
    # its end is left to the lines beside it (seam_border), however plain the wedge.
    img, x_end = corners(8.0, 60.0, seed=8)
    assert wedge_end(img, LUT, np.array([x_end - 6.0, 300.0]), TANG, 8.0) is None
    assert wedge_end(img, LUT, np.array([x_end - 6.0, 300.0]), TANG, 7.5) is not None


@pytest.mark.parametrize("gap,radius", [(2.0, 100.0), (3.0, 150.0), (4.0, 200.0)])
def test_the_detector_returns_the_joint_ending_between_two_large_rounded_corners(gap, radius):
    # The whole detector on a hairline to 4 px gap between corners of 100-200 px: the lines
    # beside the gap read no end there (the end was called open, or covered: the wedge looked
    # like more of the gap beyond a patch) and the seam was refused.
    img, x_end = corners(gap, radius, seed=int(gap * 10) + 1)
    det = detect_seam(img)
    assert det.end_kinds == ("image_border", "joint_end")
    assert abs(det.endpoints_px[1][0] - x_end) <= 2.0 and abs(det.endpoints_px[1][1] - 300) <= 1.0


def test_a_simulated_joint_between_rounded_corners_on_a_grey_table_is_found(
        tmp_path_factory: pytest.TempPathFactory) -> None:
    # Wide easy tuning 10067, view 0: white sheets with corners of 24 mm on a grey table (just
    # over half the darker sheet's level), refused as a line fading out inside a sheet until the
    # wedge was read on tables up to 0.7 of the sheets.
    from rendered_cases import rendered_view

    from bench.detect_score import score_view

    img, truth = rendered_view(tmp_path_factory.mktemp("cache"), ("wide", "easy", "tuning", 10067),
                               0)
    det = detect_seam(img)
    assert det.end_kinds == ("joint_end", "joint_end")
    assert score_view(det.points_px, truth, list(det.end_kinds))["result"] == "found"
