"""The second way to a seam (whole-image valley paths) and the end rules that tell a joint from a
pen line: synthetic images with exact truth, and the real photographs when present."""

import json
import sys
from dataclasses import replace

import numpy as np
import pytest
from shared_data import needs, shared_data_dir

from controller.errors import AmbiguousSeam, SeamNotFound
from controller.vision import seam_robust
from controller.vision.seam_border import border_line
from controller.vision.seam_detect import detect_seam, faded_lines
from controller.vision.seam_params import Candidate, DetectParams
from controller.vision.seam_path_ends import over_table
from controller.vision.seam_profiles import linear_lut
from controller.vision.seam_robust import (
    END_COVER_PX,
    _bent_bridge,
    _seen_to_border,
    robust_candidates,
)
from controller.vision.seam_track import _best_subpath

REAL = shared_data_dir() / "real-seams"
#: The defaults but for the confidence needed: for tests of where a wide gap's ends are read.
_ENDS_ONLY = DetectParams(min_confidence=0.4)


def _sheets(h=900, w=1200, seed=0):
    """Two textured sheets (grey 150 and 170) meeting at x = 600 + 0.05 (y - h/2)."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
    xc = 600.0 + 0.05 * (yy - h / 2)
    img = np.where(xx < xc, 150.0, 170.0) + rng.normal(0, 6, (h, w))
    return img, xx, yy, xc


def _ragged_gap(img, xx, yy, xc, width, seed=1):
    """A ragged dark gap ``width`` px wide centred on ``xc``; returns its true centre per row."""
    rng = np.random.default_rng(seed)
    jag = np.convolve(rng.normal(0, 1.2, img.shape[0]), np.ones(9) / 9, mode="same")
    left = xc - width / 2 + jag[:, None]
    right = xc + width / 2 - jag[:, None] * 0.5
    inside = (xx > left) & (xx < right)
    img[inside] = 25.0 + rng.normal(0, 4, int(inside.sum()))
    return (left[:, 0] + right[:, 0]) / 2


def _blob(img, xx, yy, cx, cy, r, level=235.0):
    img[(xx - cx) ** 2 + (yy - cy) ** 2 < r * r] = level


def test_best_subpath_bridges_a_covered_stretch_and_stops_at_the_ends():
    gain = np.full((200, 60), -0.1, np.float32)
    gain[20:180, 30] = 0.5
    gain[90:110, 30] = -0.1  # covered for 20 rows: bridged, the gap on both sides pays for it
    rows, cols, score = _best_subpath(gain, 0.02)
    assert rows[0] == 20 and rows[-1] == 179
    assert np.all(cols == 30)
    assert score == pytest.approx(140 * 0.5 - 20 * 0.1, abs=1e-3)


def _best_subpath_by_search(gain, pen):
    """The best path's total gain by exhaustive search (every start, every step): the reference."""
    R, C = gain.shape
    best = -np.inf

    def walk(r, c, total):
        nonlocal best
        total += float(gain[r, c])
        best = max(best, total)
        if r + 1 < R:
            for d in (-1, 0, 1):
                if 0 <= c + d < C:
                    walk(r + 1, c + d, total - (pen if d else 0.0))

    for r in range(R):
        for c in range(C):
            walk(r, c, 0.0)
    return best


def test_best_subpath_is_the_best_of_all_paths_and_its_steps_add_up():
    rng = np.random.default_rng(7)
    for _ in range(40):
        R, C = int(rng.integers(1, 7)), int(rng.integers(1, 5))
        gain = np.round(rng.normal(0.0, 1.0, (R, C)), 1).astype(np.float32)
        pen = float(rng.choice([0.0, 0.3]))
        rows, cols, score = _best_subpath(gain, pen)
        assert score == pytest.approx(_best_subpath_by_search(gain, pen), abs=1e-4)
        assert np.all(np.diff(rows) == 1) and np.all(np.abs(np.diff(cols)) <= 1)
        walked = float(gain[rows, cols].sum()) - pen * int(np.count_nonzero(np.diff(cols)))
        assert walked == pytest.approx(score, abs=1e-4)


def test_a_wide_ragged_gap_under_tack_welds_is_bridged_and_reported_occluded():
    img, xx, yy, xc = _sheets()
    truth_x = _ragged_gap(img, xx, yy, xc, width=18.0)
    for cy in (250.0, 600.0):  # two tack welds, 90 px across
        _blob(img, xx, yy, float(np.interp(cy, np.arange(900), truth_x)), cy, 45.0)
    grey = np.clip(img, 0, 255).astype(np.uint8)
    det = detect_seam(grey)
    assert det.stats["way"] == "valley path"  # the two-edge model does not fit a ragged gap
    assert list(det.end_kinds) == ["image_border", "image_border"]
    v = det.points_px[:, 1]
    err = np.abs(det.points_px[:, 0] - np.interp(v, np.arange(900), truth_x))
    assert np.percentile(err, 95) < 3.0 and err.max() < 6.0
    assert v.min() < 5 and v.max() > 894  # border to border
    spans = np.array(det.occluded_spans_px)
    for cy in (250.0, 600.0):  # each tack weld inside a reported occluded span (arc ~ v)
        assert np.any((spans[:, 0] <= cy + 10) & (spans[:, 1] >= cy - 10))
    assert det.occluded[np.argmin(np.abs(v - 250.0))]


def test_a_gap_ending_at_a_dark_table_is_not_carried_across_it_to_the_image_border():
    # The sheets end at y = 720; below, a table as dark as the gap: the whole-image valley path
    # runs on across it (no valley there, bridged straight), but the joint ends at the sheets.
    img, xx, yy, xc = _sheets()
    truth_x = _ragged_gap(img, xx, yy, xc, width=18.0)
    _blob(img, xx, yy, float(np.interp(250.0, np.arange(900), truth_x)), 250.0, 45.0)
    table = yy >= 720
    img[table] = 30.0 + np.random.default_rng(5).normal(0, 4, int(table.sum()))
    # Where the end is read, not how sure: an 18 px band's confidence is lowered for its width
    # (seam_decision.width_factor) to 0.49 here, under the default 0.5.
    det = detect_seam(np.clip(img, 0, 255).astype(np.uint8), params=_ENDS_ONLY)
    assert det.stats["way"] == "valley path"
    ends = det.endpoints_px[np.argsort(det.endpoints_px[:, 1])]
    assert list(det.end_kinds) == (["image_border", "joint_end"] if det.points_px[0, 1] < 450
                                   else ["joint_end", "image_border"])
    assert ends[0, 1] < 5 and abs(ends[1, 1] - 720.0) < 3.0
    assert abs(ends[1, 0] - np.interp(719.0, np.arange(900), truth_x)) < 3.0


def test_a_path_that_crosses_from_one_line_to_another_under_an_unseen_stretch_is_bent():
    step = 4.0
    t = np.arange(0, 1600, step)
    kept = np.ones(len(t), bool)
    kept[150:200] = False  # 200 px unseen (a tack weld, or nothing)
    # Straight on under the patch: not bent.
    line = np.column_stack([t, 0.3 * t])
    assert _bent_bridge(line, kept, 10, 25) is None
    # A curve of 500 px radius: the chord across 200 px turns by about 12 deg; not bent.
    ang = t / 500.0
    arc = 500.0 * np.column_stack([np.sin(ang), 1 - np.cos(ang)])
    assert _bent_bridge(arc, kept, 10, 25) is None
    # Two parallel lines 150 px apart in v, joined across the unseen stretch (two pen lines
    # either side of a faint joint): the chord from sample 149 to 200 runs (204, 0.3 x 204 +
    # 150) px, at 46.0 deg, against the lines' 16.7 deg.
    jump = line + np.where(np.arange(len(t)) >= 200, 150.0, 0.0)[:, None] * [0.0, 1.0]
    jump[150:200] = np.nan  # never read: the chord runs between the last seen samples
    bent = _bent_bridge(jump, kept, 10, 25)
    assert bent is not None and abs(bent - 29.3) < 0.1
    # Unseen stretches at the ends are not bridges.
    ends = kept.copy()
    ends[:] = True
    ends[:60] = False
    assert _bent_bridge(jump, ends, 10, 25) is None


def test_a_dark_line_that_fades_out_inside_the_sheet_is_never_returned():
    # A pen line on one sheet: dark, thin, ending 150 px inside the image at both ends.
    img, xx, yy, xc = _sheets(seed=3)
    img[:] = np.where(xx < 9999, 160.0, 0) + np.random.default_rng(3).normal(0, 6, img.shape)
    on = (np.abs(xx - 500.0) < 2.5) & (yy > 150) & (yy < 750)
    img[on] = 40.0
    grey = np.clip(img, 0, 255).astype(np.uint8)
    with pytest.raises((SeamNotFound, AmbiguousSeam)) as err:
        detect_seam(grey)
    assert "fades out" in str(err.value) or "no weld seam" in str(err.value)
    for c in robust_candidates(grey, linear_lut(2.2), DetectParams()):
        if c.points is not None and np.median(np.abs(c.points[:, 0] - 500.0)) < 5:
            assert c.why_rejected  # the pen line is a candidate only to be rejected


def test_two_paths_measured_onto_one_gap_are_one_candidate(monkeypatch: pytest.MonkeyPatch
                                                         ) -> None:
    # The path search can return a second path along the same gap that strays 14-20 px off it
    # in its middle (too far for the raw paths to count as one line); both are measured onto
    # the gap. Kept twice, the seam was its own rival (AmbiguousSeam: simulated close-up, hard
    # tuning 10077 view 1) and a pen line's second path escaped the pen line's rejection.
    img, xx, yy, xc = _sheets()
    _ragged_gap(img, xx, yy, xc, 9.0)
    grey = np.clip(img, 0, 255).astype(np.uint8)
    f = seam_robust.work_factor(grey.shape)
    found = seam_robust.find_paths

    def twice(resp, thetas, bias, cap):
        paths = found(resp, thetas, bias, cap)
        pts = paths[0].points.copy()
        n = len(pts)
        pts[n // 5:4 * n // 5, 0] += 16.0 / f
        return [paths[0], replace(paths[0], points=pts, score=0.9 * paths[0].score)] + paths[1:]

    monkeypatch.setattr(seam_robust, "find_paths", twice)
    on_gap = [c for c in robust_candidates(grey, linear_lut(2.2), DetectParams())
              if c.points is not None and np.median(np.abs(c.points[:, 0] - (
                  600.0 + 0.05 * (c.points[:, 1] - 450.0)))) < 3.0]
    assert len(on_gap) == 1 and not on_gap[0].why_rejected


def test_a_line_stopped_by_a_patch_and_fading_out_at_its_other_end_is_a_faded_line() -> None:
    # Wide easy tuning 10260 view 1: a pen line beside the joint, cut by a marker dot at one
    # end ("covered") and fading out at the other, was not passed on as a faded line, and a
    # valley path along it to the image border was returned as the seam.
    line = np.column_stack([np.full(50, 500.0), np.linspace(150.0, 750.0, 50)])
    cands = [Candidate(polyline=line, coarse_score=1.0, length_px=600.0, points=line,
                       end_kinds=kinds, why_rejected=why)
             for kinds, why in ((("covered", "open"), "gap of 600 px stops at a covered patch"),
                                (("open", "open"), "dark line of 600 px fades out inside the "
                                                   "sheet at both ends"),
                                (("covered", "sheet border"), "gap of 600 px stops at a "
                                                              "covered patch"),
                                (("image border", "sheet border"), ""))]
    faded = faded_lines(cands)
    assert len(faded) == 2 and faded[0] is line and faded[1] is line


def test_a_sheet_border_the_gap_was_not_seen_to_run_to_is_no_joint_end():
    # The simulator's pen tuning case 50006 view 1 (returned at confidence 1.00 before): a valley
    # path along a pen line that ends mid-sheet, bridged about 300 px across the sheet to the
    # plates' corner, where a sheet border was read as the joint's end.
    step = 4.0
    seen = np.ones(300, bool)
    assert _seen_to_border("sheet border", seen, step) == "sheet border"
    # A tack weld at the end (up to END_COVER_PX unseen) still ends at the border.
    seen[-int(END_COVER_PX / step):] = False
    assert _seen_to_border("sheet border", seen, step) == "sheet border"
    assert _seen_to_border("unsure sheet border", seen, step) == "unsure sheet border"
    # Longer: the path was led to the border, not along a gap.
    seen[-int(END_COVER_PX / step) - 2:] = False
    assert _seen_to_border("sheet border", seen, step) == "open"
    assert _seen_to_border("unsure sheet border", seen, step) == "open"
    # Toward the image border the seam may run on out of view under a patch: not judged so.
    assert _seen_to_border("image border", seen, step) == "image border"
    assert _seen_to_border("sheet border", np.zeros(10, bool), step) == "sheet border"
    assert _seen_to_border("sheet border", np.zeros(40, bool), step) == "open"


def test_only_the_centreline_stepping_is_not_a_sheet_border():
    offs = (-9.7, -4.9, 0.0, 4.9, 9.7)
    # The dark floor ends but both sides go on: the end of a line drawn on a sheet.
    k, *_ = border_line(offs, [[], [], [3.0], [], []])
    assert k is None
    # The sheets end too: a border line crossing the side lines.
    k, *_ = border_line(offs, [[3.0], [3.0], [3.0], [3.0], []])
    assert k == pytest.approx(3.0)


@needs(REAL)
def test_real_photographs_found_or_refused_never_wrong():
    sys.path.insert(0, str(REAL))
    try:
        from score import score_detection
    finally:
        sys.path.remove(str(REAL))
    import cv2

    verdicts = {}
    for lf in sorted((REAL / "labels").glob("*.json")):
        label = json.loads(lf.read_text())
        img = cv2.imread(str(REAL / label["image"]))
        try:
            det = detect_seam(img)
        except (SeamNotFound, AmbiguousSeam):
            verdicts[lf.stem] = "refused"
            continue
        r = score_detection(label, det.points_px, list(det.end_kinds))
        verdicts[lf.stem] = r["verdict"]
    assert "wrong" not in verdicts.values(), verdicts
    # Today: 6 of 9 found (1_x2 and 1_x5 ambiguous with the ground strip's edge line, 2_x1
    # nearly closed); fewer means the detector got worse on real photographs.
    assert sum(v == "found" for v in verdicts.values()) >= 6, verdicts


def _sheets_on_table(bead: bool) -> tuple[np.ndarray, np.ndarray]:
    """Two sheets (grey 160) meeting at x = 300 (gap 6 px, grey 40) from y = 200 down; above,
    a dark table (grey 25), or (``bead``) the sheets go on under a tack weld: a dark crater
    ringed by a bright bead. Returns the image and a straight path x = 300 from y = 0 to 599."""
    rng = np.random.default_rng(3)
    img = np.full((600, 600), 160.0)
    img[:, 297:303] = 40.0
    if bead:
        yy, xx = np.mgrid[0:600, 0:600]
        r = np.hypot(xx - 300.0, yy - 110.0)
        img[r < 95] = 230.0  # the bead, brighter than the sheets
        img[r < 70] = 30.0  # its crater
    else:
        img[:200] = 25.0
    img = np.clip(img + rng.normal(0, 4, img.shape), 0, 255).astype(np.uint8)
    centre = np.column_stack([np.full(600, 300.0), np.arange(600.0)])
    return img, centre


@pytest.mark.parametrize("bead", [False, True])
def test_a_path_carried_over_a_dark_table_is_told_from_a_covered_joint(bead: bool) -> None:
    # A valley path through the whole image runs on past the sheets' end over a dark table (the
    # gap no longer seen): that stretch is table on both sides all along, not a covered
    # stretch of the joint. A tack weld over the joint is as dark in its crater, but its bead
    # (or the sheets) is as bright as the sheets somewhere beside the path.
    img, centre = _sheets_on_table(bead)
    lut = linear_lut(DetectParams().gamma)
    stretch, seen = np.arange(0, 150), np.arange(250, 400)
    assert over_table(img, lut, centre, stretch, seen, 6.0) is (not bead)
    # Where the gap is seen, the sides are the sheets: never table.
    assert over_table(img, lut, centre, np.arange(300, 500), seen, 6.0) is False


def _rendered_view(case: tuple[str, str, str, int], view: int):
    """A benchmark case's view rendered as bench/detect_cases.py does, with its truth."""
    from bench.detect_cases import make_case_scene, pair_poses
    from controller.geometry.camera_model import default_camera
    from drivers.sim.sim_render import render

    cam = default_camera()
    scene = make_case_scene(case)
    T = pair_poses(scene, cam, case[3])[view]
    r = render(scene, cam, T, seed=case[3] + 7919 * view)
    truth = {"seam_px": r.seam_px, "end_kinds": list(r.end_kinds), "end_tol_px": r.end_tol_px,
             "spans": np.array(r.occluded_spans_px, float).reshape(-1, 2),
             "pens": list(r.pen_lines_px), "gap_px": r.gap_px, "gap_mm": scene.gap_mm,
             "ragged_mm": scene.look.ragged_mm, "family": scene.look.family}
    return np.asarray(r.image), truth, cam


def test_a_valley_path_that_ran_on_into_the_table_is_not_returned() -> None:
    # Wide medium tuning 10081, view 0 (a curved joint reaching a dark table): with the gap
    # followed to the sheets' end at one end (below), the whole-image path's other end ran on
    # 340 px over the table to the image border and was returned as a seam leaving the image
    # there (a wrong seam). The stretch over the table is cut off; the end where the gap was
    # last seen is then judged as it is.
    from bench.detect_score import end_kinds_of, score_view

    img, truth, cam = _rendered_view(("wide", "medium", "tuning", 10081), 0)
    try:
        det = detect_seam(img, camera=cam)
    except (SeamNotFound, AmbiguousSeam):
        return
    assert score_view(det.points_px, truth, end_kinds_of(det))["result"] == "found"


def test_the_gap_is_followed_to_the_sheets_end_where_the_path_runs_straight_on() -> None:
    # Wide hard tuning 10066, view 0: the smoothed valley path cut the corner where the joint
    # curves to the sheets' end, and the profiles read across it stopped seeing the gap before
    # the sheets ended; it was returned 123 px past the end (a wrong seam). The gap is now
    # followed from where it was last seen to the sheets' end.
    from bench.detect_score import end_kinds_of, score_view

    img, truth, cam = _rendered_view(("wide", "hard", "tuning", 10066), 0)
    det = detect_seam(img, camera=cam)
    assert score_view(det.points_px, truth, end_kinds_of(det))["result"] == "found"


def test_a_wide_gap_between_rounded_corners_is_ended_at_the_corners() -> None:
    # Wide medium tuning 10027, view 0 (a wide gap between two sheets with rounded corners on a
    # dark table): the valley path ran on past the corners into the table, where nothing steps,
    # and the seam was refused as fading out inside a sheet. The end is read again further back
    # (seam_ends._backed_off).
    from bench.detect_score import end_kinds_of, score_view

    img, truth, cam = _rendered_view(("wide", "medium", "tuning", 10027), 0)
    # At the default scale its 18.8 px band lowers the confidence to 0.45 (width_factor): refused
    # unless the job states its gap (then found by the profiles at 0.83); the ends are the point.
    det = detect_seam(img, camera=cam, params=_ENDS_ONLY)
    assert score_view(det.points_px, truth, end_kinds_of(det))["result"] == "found"
