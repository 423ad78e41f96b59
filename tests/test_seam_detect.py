import glob
import json

import cv2
import numpy as np
import pytest
from shared_data import CHESSBOARD, needs

from calibration.calibration_file import Calibration, save_calibration
from controller.cli import main
from controller.errors import AmbiguousSeam, InputError, SeamNotFound
from controller.geometry.camera_model import default_camera
from controller.vision.seam_detect import DetectParams, detect_seam
from drivers.sim.sim_render import render, suggest_view_poses
from drivers.sim.sim_scene import make_scene

# Half-size images (1136x852) seen from 250 mm: the gap is as many pixels wide as in the full
# 2272x1704 image from 350 mm, and a render takes a fraction of a second.
CAM = default_camera().scaled(0.5)
SHARED = CHESSBOARD


def dist_to_polyline(P, Q):
    A, B = Q[:-1], Q[1:]
    AB = B - A
    t = np.clip(((P[:, None] - A[None]) * AB[None]).sum(2) / ((AB**2).sum(1) + 1e-12)[None], 0, 1)
    return np.linalg.norm(P[:, None] - (A[None] + t[..., None] * AB[None]), axis=2).min(1)


def end_error(det, truth):
    e, t = det.endpoints_px, np.array([truth[0], truth[-1]])
    return min(np.linalg.norm(e - t, axis=1).max(), np.linalg.norm(e - t[::-1], axis=1).max())


def rendered(kind, seed, difficulty="medium", roll=0.0, **over):
    sc = make_scene(kind, seed, difficulty, **over)
    T = suggest_view_poses(sc, CAM, standoff_mm=250.0)[seed % 2].copy()
    c, s = np.cos(roll), np.sin(roll)
    R = np.eye(4)
    R[:2, :2] = [[c, -s], [s, c]]
    return render(sc, CAM, T @ R, seed=seed)


@pytest.fixture(scope="module")
def cases():
    return {k: rendered(k, i + 1, roll=0.4 * i + 0.3)
            for i, k in enumerate(["straight", "arc", "s_curve", "nonplanar"])}


@pytest.mark.parametrize("kind", ["straight", "arc", "s_curve", "nonplanar"])
def test_subpixel_centreline_and_honest_ends(cases, kind):
    r = cases[kind]
    det = detect_seam(r.image)
    err = dist_to_polyline(det.points_px, r.seam_px)
    assert np.sqrt(np.mean(err**2)) < 0.3
    assert err.max() < 2.0
    assert end_error(det, r.seam_px) < 3.0
    assert det.confidence > 0.7
    assert det.points_px.shape[1] == 2 and np.allclose(det.endpoints_px,
                                                       det.points_px[[0, -1]])
    steps = np.linalg.norm(np.diff(det.points_px, axis=0), axis=1)
    assert steps.max() < 10.0  # ordered end to end, no jumps back and forth
    assert len(det.reasons) >= 3 and len(det.width_px) == len(det.points_px)


def test_unbiased_when_the_sheets_differ_in_brightness():
    # The darkness centroid would be pulled toward the darker sheet; the edge midpoint is not.
    # (The table darker than both sheets: a sheet as bright as the table cannot show where it
    # ends, and such a joint is refused: tests/test_seam_one_sided_ends.py.)
    r = rendered("straight", 3, "easy", albedo_a=0.75, albedo_b=0.25, albedo_table=0.15,
                 clutter=False)
    det = detect_seam(r.image)
    d = det.points_px[5:-5]
    P = r.seam_px
    t = (P[-1] - P[0]) / np.linalg.norm(P[-1] - P[0])
    n = np.array([-t[1], t[0]])
    signed = (d - P[0]) @ n
    assert abs(np.mean(signed)) < 0.08


def test_hard_scene_with_marks_crossing_the_seam():
    r = rendered("s_curve", 2, "hard", roll=1.1)
    det = detect_seam(r.image)
    err = dist_to_polyline(det.points_px, r.seam_px)
    assert err.max() < 2.0 and end_error(det, r.seam_px) < 3.0


def test_no_seam_in_view_is_refused():
    sc = make_scene("straight", 5, "hard")
    T = suggest_view_poses(sc, CAM, standoff_mm=250.0)[0].copy()
    T[:3, 3] += T[:3, 1] * 260.0  # look at the table beside the part
    r = render(sc, CAM, T, seed=0)
    assert len(r.seam_px) == 0
    with pytest.raises(SeamNotFound) as err:
        detect_seam(r.image)
    assert "candidates_seen" in err.value.details


@needs(SHARED)
def test_real_photographs_without_a_seam_are_refused():
    files = sorted(glob.glob(str(SHARED / "*.jpg")))
    assert len(files) >= 10
    for f in files:
        img = cv2.imread(f)
        with pytest.raises((SeamNotFound, AmbiguousSeam)):
            detect_seam(img)


def test_two_similar_seams_are_ambiguous_and_a_roi_resolves_a_nominal_seam_does_not(cases):
    img = cases["straight"].image
    h, w = img.shape
    two = np.hstack([img, img])
    with pytest.raises(AmbiguousSeam) as err:
        detect_seam(two)
    assert "best_px" in err.value.details and "second_px" in err.value.details
    det = detect_seam(two, roi=(w, 0, 2 * w, h))
    truth = cases["straight"].seam_px + [w, 0]
    assert dist_to_polyline(det.points_px, truth).max() < 2.0
    # The nominal seam on one of them: the other, beyond its tolerance, is not returned but
    # still counts (seam_detect.outside_corridor): a nominal seam never makes a refusal a seam.
    with pytest.raises(AmbiguousSeam, match="from the nominal seam"):
        detect_seam(two, hint=truth)


def test_an_ambiguous_refusal_draws_both_lines_on_the_overlay(cases, tmp_path, capsys):
    img = cases["straight"].image
    w = img.shape[1]
    png, overlay = tmp_path / "two.png", tmp_path / "overlay.png"
    cv2.imwrite(str(png), np.hstack([img, img]))
    assert main(["detect", str(png), "--overlay", str(overlay)]) == AmbiguousSeam.exit_code
    assert "similar strength" in capsys.readouterr().err
    pic = cv2.imread(str(overlay)).astype(int)
    f = pic.shape[1] / (2 * w)  # the picture is shrunk to at most 1600 px wide
    b, g, r = (pic[:, :, k] for k in range(3))
    cyan, magenta = (b > 200) & (g > 150) & (r < 90), (b > 200) & (g < 90) & (r > 200)
    truth = cases["straight"].seam_px
    for colour in (cyan, magenta):
        ys, xs = np.nonzero(colour)
        assert len(xs) > 100
        # Each colour on one copy's seam, the two colours on different copies.
        near = [dist_to_polyline(np.c_[xs, ys] / f, truth + [k * w, 0]) < 6.0 for k in (0, 1)]
        assert max(float(np.mean(n)) for n in near) > 0.75  # the rest: its number beside it
    assert (np.median(np.nonzero(cyan)[1]) < pic.shape[1] / 2) != (
        np.median(np.nonzero(magenta)[1]) < pic.shape[1] / 2)


def test_a_refusal_draws_the_lines_it_looked_at_with_why(tmp_path, capsys):
    # A dark line that ends inside a plain sheet at both ends: a pen line, no joint.
    img = np.full((900, 1200), 150, np.uint8)
    cv2.line(img, (200, 450), (900, 430), 40, 3, cv2.LINE_AA)
    img = np.clip(img + np.random.default_rng(1).normal(0, 2, img.shape), 0, 255)
    png, overlay = tmp_path / "pen.png", tmp_path / "overlay.png"
    cv2.imwrite(str(png), img.astype(np.uint8))
    assert main(["detect", str(png), "--overlay", str(overlay)]) == SeamNotFound.exit_code
    assert "fades out inside a sheet" in capsys.readouterr().err
    with pytest.raises(SeamNotFound) as err:
        detect_seam(img.astype(np.uint8))
    (line,) = err.value.details["looked_at_px"]
    assert err.value.details["looked_at_why"][0].startswith("dark line of")
    assert np.abs(np.array(line)[:, 0] - 550).max() > 300  # the whole line, not a point
    pic = cv2.imread(str(overlay)).astype(int)
    b, g, r = (pic[:, :, k] for k in range(3))
    ys, xs = np.nonzero((b > 200) & (g > 150) & (r < 90))  # 1, cyan, on the line
    assert len(xs) > 300
    on_line = np.abs(ys - (450 - 20 * (xs - 200) / 700)) < 5
    assert np.mean(on_line) > 0.75  # the rest: its number beside it


def with_a_fainter_twin(img, lighten):
    """``img`` beside a copy whose gap is lightened by ``lighten`` (0..1): a weaker second seam."""
    f = img.astype(np.float64)
    dark = f < 0.7 * np.median(f)
    faint = np.clip(f + lighten * (f.max() - f) * dark, 0, 255).astype(np.uint8)
    return np.hstack([img, faint])


def test_ambiguity_threshold_at_its_edge(cases):
    img = cases["straight"].image
    w = img.shape[1]
    never = DetectParams(ambiguity_ratio=1.01)  # a ratio is at most 1: never ambiguous
    close = with_a_fainter_twin(img, 0.2)
    r = detect_seam(close, params=never).stats["second_best_ratio"]
    # Between the default 0.6 and 0.95: a threshold raised that far would pass it.
    assert 0.65 < r < 0.9, r
    with pytest.raises(AmbiguousSeam, match=f"ratio {r:.2f}"):
        detect_seam(close)
    with pytest.raises(AmbiguousSeam):
        detect_seam(close, params=DetectParams(ambiguity_ratio=r))  # at the threshold: refused
    det = detect_seam(close, params=DetectParams(ambiguity_ratio=r + 1e-6))
    assert det.points_px[:, 0].max() < w  # the stronger, untouched seam
    assert det.stats["second_best_ratio"] == r
    # A clearly weaker second seam (ratio under 0.6) is no reason to refuse with the defaults.
    far = with_a_fainter_twin(img, 0.3)
    r_far = detect_seam(far, params=never).stats["second_best_ratio"]
    assert 0.3 < r_far < 0.58, r_far
    assert detect_seam(far).points_px[:, 0].max() < w
    with pytest.raises(AmbiguousSeam):
        detect_seam(far, params=DetectParams(ambiguity_ratio=r_far))


def test_bad_inputs():
    img = np.zeros((100, 100), np.float32)
    with pytest.raises(InputError, match="uint8"):
        detect_seam(img)
    with pytest.raises(InputError, match="too small"):
        detect_seam(np.zeros((20, 400), np.uint8))
    with pytest.raises(InputError, match="calibration"):
        detect_seam(np.zeros((300, 400), np.uint8), camera=default_camera(640, 480))
    with pytest.raises(InputError, match="roi"):
        detect_seam(np.zeros((300, 400), np.uint8), roi=(0, 0, 10, 10))
    with pytest.raises(InputError, match="roi"):
        detect_seam(np.zeros((300, 400), np.uint8), roi=("a", 0, 10, 10))
    with pytest.raises(SeamNotFound):
        detect_seam(np.full((300, 400), 128, np.uint8))
    assert DetectParams().gamma == 2.2


def test_cli_detect(tmp_path, cases, capsys):
    r = cases["arc"]
    png = tmp_path / "view.png"
    cv2.imwrite(str(png), r.image)
    out, ov = tmp_path / "seam.json", tmp_path / "overlay.png"
    assert main(["detect", str(png), "--output", str(out), "--overlay", str(ov)]) == 0
    doc = json.loads(out.read_text())
    pts = np.array(doc["seam_px"])
    assert dist_to_polyline(pts, r.seam_px).max() < 2.0
    assert 0 < doc["confidence"] <= 1 and doc["reasons"]
    assert cv2.imread(str(ov)) is not None
    # Size check against a calibration file.
    calib = tmp_path / "cal.yaml"
    save_calibration(calib, Calibration(camera=default_camera()))
    assert main(["detect", str(png), "--calibration", str(calib)]) == InputError.exit_code
    assert "calibration is for 2272x1704" in capsys.readouterr().err
    # No seam: exit code of SeamNotFound, and the overlay says so.
    blank = tmp_path / "blank.png"
    cv2.imwrite(str(blank), np.random.default_rng(0).integers(60, 90, (400, 600), np.uint8))
    assert main(["detect", str(blank), "--overlay", str(ov)]) == SeamNotFound.exit_code
    # Not an image; bad ROI.
    txt = tmp_path / "notes.png"
    txt.write_text("hello")
    assert main(["detect", str(txt)]) == InputError.exit_code
    assert main(["detect", str(png), "--roi", "1,2,3"]) == InputError.exit_code


def test_an_end_between_two_equally_supported_border_lines_is_unsure():
    from controller.vision.seam_border import border_line

    offs = (-9.7, -4.9, 0.0, 4.9, 9.7)
    # Five lines agree on one border: sure.
    k, unsure, *_ = border_line(offs, [[3.0], [3.0], [3.0], [3.0], [3.0]])
    assert k == pytest.approx(3.0) and not unsure
    # Two lines see a border at 15.9 px, the centreline and one of them another at 11.4 px (a
    # mark meeting the seam at the border): the inner one is taken, but it is unsure.
    k, unsure, *_ = border_line(offs, [[15.9], [15.9], [11.4], [], []])
    assert k == pytest.approx(11.4) and unsure
    # Three lines against two: the three win, sure enough.
    k, unsure, *_ = border_line(offs, [[2.0], [2.0], [2.0], [10.4], [10.4]])
    assert k == pytest.approx(2.0) and not unsure


def test_pieces_of_a_faint_gap_are_joined_but_not_a_branch():
    """A faint gap breaks into pieces shorter than a seam: pieces that continue each other are
    joined across a short hole (even with a small sideways step), a piece at an angle is not."""
    from controller.vision.seam_coarse import _join_candidates
    from controller.vision.seam_params import Candidate

    def piece(p0, p1):
        t = np.linspace(0.0, 1.0, 40)[:, None]
        poly = np.asarray(p0, float) + t * (np.asarray(p1, float) - p0)
        return Candidate(poly, 1.0, float(np.linalg.norm(np.subtract(p1, p0))))

    a, b = piece((0, 0), (200, 0)), piece((210, 6), (400, 8))
    joined = _join_candidates([a, b], 48.0, 8.0)
    assert len(joined) == 1 and joined[0].length_px > 390
    branch = piece((205, 5), (260, 150))  # starts near the end but turns away
    assert len(_join_candidates([piece((0, 0), (200, 0)), branch], 48.0, 8.0)) == 2
    far = piece((300, 0), (500, 0))  # lines up but the hole is too long for pieces
    assert len(_join_candidates([piece((0, 0), (200, 0)), far], 48.0, 8.0)) == 2


def test_several_views_at_once_match_one_by_one_and_raise_in_order(cases):
    from controller.vision.seam_views import detect_seams

    images = [cases["arc"].image, cases["s_curve"].image]
    together = detect_seams(images)
    for im, det in zip(images, together, strict=True):
        assert np.array_equal(det.points_px, detect_seam(im).points_px)
    blank = np.full_like(images[0], 120)
    with pytest.raises(SeamNotFound):
        detect_seams([images[0], blank])
    # Every view's outcome is kept before the error is raised: the found one and the refusal.
    outcomes: list = []
    with pytest.raises(SeamNotFound, match="^blank: ") as err:
        detect_seams([blank, images[1]], names=["blank", "s_curve"], outcomes=outcomes)
    assert outcomes[0] is err.value and isinstance(err.value.__cause__, SeamNotFound)
    assert np.array_equal(outcomes[1].points_px, together[1].points_px)
    with pytest.raises(InputError, match="regions of interest"):
        detect_seams(images, rois=[None])


def _expected_kinds(det, r):
    """The true end kinds of ``r`` in the order of ``det.points_px``."""
    kinds = ["joint_end" if e else "image_border" for e in r.ends_in_image]
    first = r.seam_px[0]
    if np.linalg.norm(det.points_px[0] - first) > np.linalg.norm(det.points_px[-1] - first):
        kinds = kinds[::-1]
    return kinds


def test_ends_say_what_they_are(cases):
    for r in cases.values():
        det = detect_seam(r.image)
        assert list(det.end_kinds) == _expected_kinds(det, r)
        assert [e["kind"] for e in det.ends] == list(det.end_kinds)
        assert np.allclose([e["px"] for e in det.ends], det.points_px[[0, -1]])
        d = det.to_dict()
        assert [e["kind"] for e in d["ends"]] == list(det.end_kinds)


def test_a_seam_that_leaves_the_image_is_returned_with_image_border_ends():
    sc = make_scene("straight", 4, "easy", length_mm=250.0)
    T = suggest_view_poses(sc, CAM, standoff_mm=150.0)[0].copy()
    r = render(sc, CAM, T, seed=4)
    assert not any(r.ends_in_image)
    det = detect_seam(r.image)
    assert list(det.end_kinds) == ["image_border", "image_border"]
    assert dist_to_polyline(det.points_px, r.seam_px).max() < 2.0
    # One end in view, the other out: the kinds follow the seam order.
    T2 = T.copy()
    t = (r.seam_points_mm[-1] - r.seam_points_mm[0])
    T2[:3, 3] += t / np.linalg.norm(t) * 150.0
    r2 = render(sc, CAM, T2, seed=4)
    assert r2.ends_in_image.count(True) == 1
    det2 = detect_seam(r2.image)
    assert sorted(det2.end_kinds) == ["image_border", "joint_end"]
    assert list(det2.end_kinds) == _expected_kinds(det2, r2)


def test_occluded_spans_are_arc_length_ranges_of_the_bridged_points():
    from controller.vision.seam_decision import spans_of

    pts = np.column_stack([np.arange(0.0, 100.0, 4.0), np.zeros(25)])
    mask = np.zeros(25, bool)
    mask[5:8] = True
    mask[20:22] = True
    assert spans_of(pts, mask) == [(16.0, 32.0), (76.0, 88.0)]
    assert spans_of(pts, np.zeros(25, bool)) == []


def test_a_refusal_says_each_reason_once_with_how_many_candidates_gave_it():
    from controller.vision.seam_decision import choose
    from controller.vision.seam_params import Candidate

    line = np.column_stack([np.linspace(0, 500, 20), np.zeros(20)])
    why = ["a straight line ...: a line of the table's grid, not a joint"] * 3 + ["too short"]
    cands = [Candidate(line, 1.0, 500.0, why_rejected=w) for w in why]
    with pytest.raises(SeamNotFound) as err:
        choose(cands, DetectParams(), {}, (0, 0))
    assert "not a joint (x3); too short)" in str(err.value)
    assert err.value.details["rejected"] == why


@pytest.mark.parametrize("offset_px, score, ambiguous", [
    (60.0, 50.0, True),    # a pen line 60 px beside the seam, half as strong: which is the joint?
    (60.0, 30.0, False),   # a faint line beside it: the seam stands out
    (400.0, 50.0, False),  # farther than any pen line (25 mm): another line, not a doubt
])
def test_a_line_running_beside_the_seam_makes_it_ambiguous(offset_px, score, ambiguous):
    from controller.errors import AmbiguousSeam
    from controller.vision.seam_decision import choose
    from controller.vision.seam_params import Candidate

    def cand(y: float, s: float) -> Candidate:
        P = np.column_stack([np.linspace(0, 1500, 300), np.full(300, y)])
        return Candidate(P, s, 1500.0, points=P, width=np.full(300, 4.0), depth=0.5,
                         valid_frac=1.0, score=s, end_kinds=("image border", "image border"))

    cands = [cand(800.0, 100.0), cand(800.0 + offset_px, score)]
    if ambiguous:
        with pytest.raises(AmbiguousSeam, match="beside the seam"):
            choose(cands, DetectParams(), {}, (0, 0))
    else:
        assert choose(cands, DetectParams(), {}, (0, 0))[0] is cands[0]


def test_a_best_candidate_of_score_zero_with_a_rival_is_ambiguous_not_a_crash() -> None:
    # Found by an experiment that let such a valley path through (2026-12-06): choose() divided
    # the rival's score by the best's and raised ZeroDivisionError instead of a refusal.
    from controller.errors import AmbiguousSeam
    from controller.vision.seam_decision import choose
    from controller.vision.seam_params import Candidate

    P = np.column_stack([np.linspace(0, 1500, 300), np.full(300, 800.0)])
    best = Candidate(P, 0.0, 1500.0, points=P, width=np.full(300, 4.0), depth=0.5,
                     valid_frac=1.0, score=0.0, end_kinds=("image border", "image border"))
    rival = Candidate(P + [0.0, 400.0], 0.0, 1500.0, points=P + [0.0, 400.0], score=0.0,
                      why_rejected="dark line fades out inside the sheet at one end", rival=True)
    with pytest.raises(AmbiguousSeam, match="similar strength"):
        choose([best, rival], DetectParams(), {}, (0, 0))


def test_overlay_text_is_wrapped_not_cut() -> None:
    from controller.vision.seam_overlay import MAX_TEXT_LINES, overlay_text, text_lines

    parts = [f"candidate {k}: dark line of {300 + k} px fades out inside a sheet" for k in range(4)]
    reason = "no weld seam found in the image (" + "; ".join(parts) + ")"
    lines = text_lines(["seam found, confidence 0.90", reason], 50)
    assert lines[0] == "seam found, confidence 0.90"
    assert all(len(t) <= 50 for t in lines)
    # Every word of the reason is on the picture, in order.
    assert " ".join(lines[1:]).split() == reason.split()
    many = text_lines([reason] * 10, 50)
    assert len(many) == MAX_TEXT_LINES and many[-1].endswith(" ...")
    # The legend of the lines drawn stays whole: the long message is cut short before it.
    legend = ["1 (cyan), 2 (magenta): the strongest lines looked at, each refused:",
              "1: dark line of 712 px fades out inside a sheet", "2: valley path too shallow"]
    text = overlay_text([reason] * 10, legend, 50)
    assert len(text) == MAX_TEXT_LINES and " ".join(text).endswith(" ".join(legend))
    assert overlay_text([reason], [], 50) == text_lines([reason], 50)
