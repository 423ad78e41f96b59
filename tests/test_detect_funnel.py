"""bench.detect_funnel says where a refused view's joint was lost, from the detector's trace."""

from __future__ import annotations

import cv2
import numpy as np

from bench.detect_funnel import on_joint, table, where_lost
from controller.errors import SeamNotFound
from controller.vision.seam_detect import detect_seam
from controller.vision.seam_params import Candidate

TRUTH = np.column_stack([np.linspace(0, 1000, 251), np.full(251, 300.0)])


def _cand(y: float, x1: float = 1000.0, why: str = "", score: float = 1.0) -> Candidate:
    pts = np.column_stack([np.linspace(0, x1, 100), np.full(100, y)])
    return Candidate(polyline=pts, coarse_score=1.0, length_px=x1, points=pts, score=score,
                     why_rejected=why)


def test_a_candidate_is_the_joint_when_near_it_and_covering_half_of_it() -> None:
    assert on_joint(_cand(302.0).points, TRUTH)
    assert not on_joint(_cand(330.0).points, TRUTH)  # a pen line beside it
    assert not on_joint(_cand(300.0, x1=300.0).points, TRUTH)  # a piece of it, 30 %


def test_the_first_stage_with_the_joint_names_the_verdict_without_its_numbers() -> None:
    pen = _cand(330.0, why="dark line of 1000 px fades out inside the sheet")
    piece = _cand(300.0, x1=300.0, why="gap run only 300 px long (< 300)")
    joint = _cand(301.0, why="candidate of 1000 px has no long run of gap profiles (3 of 9 good)")
    assert where_lost([[pen, piece]], TRUTH) == ("none", "no candidate on the joint")
    # The coarse search saw the joint (its polyline, on a 4 px grid, runs along it) but the
    # refined line went 7 px beside it: the funnel says so, with that line's verdict.
    beside = _cand(307.0, why="dark line of 1000 px fades out inside the sheet")
    beside.polyline = np.column_stack([np.linspace(0, 1000, 60), np.full(60, 304.0)])
    assert where_lost([[pen, piece, beside]], TRUTH) == (
        "none", "no candidate on the joint; a coarse line along it: dark line of # px fades out "
        "inside the sheet")
    assert where_lost([[pen], [pen, joint]], TRUTH) == (
        "finer grid", "candidate of # px has no long run of gap profiles")
    joint.why_rejected += ("; 95 % of them fit a dark band 19 px wide, wider than the widest gap "
                           "at this scale (16 px)")
    assert where_lost([[pen], [pen, joint]], TRUTH) == (
        "finer grid", "candidate of # px has no long run of gap profiles: a band wider than the "
        "widest gap at this scale")
    strong = _cand(300.0)
    strong.valid_frac, strong.depth, strong.end_kinds = 1.0, 0.6, ("sheet border", "image border")
    assert where_lost([[pen, strong], [], []], TRUTH) == (
        "first way", "passed, refused for a rival")
    strong.end_kinds = ("unsure sheet border", "image border")
    assert where_lost([[pen, strong]], TRUTH) == (
        "first way", "passed, too weak (an end read as unsure)")
    rows = [{"case": ["wide", "easy", "tuning", 7], "view": 0, "stage": "first way",
             "verdict": "x", "family": "shop"},
            {"case": ["wide", "easy", "tuning", 7], "view": 1, "stage": "returned",
             "verdict": "", "family": "shop"},
            {"case": ["wide", "easy", "tuning", 8], "view": 0, "stage": "first way",
             "verdict": "x", "family": "plain"},
            {"case": ["wide", "easy", "tuning", 9], "view": 1, "stage": "first way",
             "verdict": "x", "family": "plain"}]
    md = table(rows)
    assert "3 of 4 views refused" in md
    assert "| stage | verdict on the joint's line | views | plain | shop | e.g. |" in md
    assert "| first way | x | 3 | 2 | 1 | easy 7 v0, easy 8 v0, easy 9 v1 |" in md


def test_the_detector_hands_over_every_list_it_chose_from() -> None:
    rng = np.random.default_rng(0)
    img = np.clip(cv2.GaussianBlur(np.full((600, 800), 150.0), (0, 0), 1.0)
                  + rng.normal(0, 3, (600, 800)), 0, 255).astype(np.uint8)
    stages: list[list[Candidate]] = []
    try:
        detect_seam(img, trace=stages)
    except SeamNotFound:
        pass
    else:
        raise AssertionError("a plain sheet has no seam")
    assert len(stages) == 3  # the first way, with the finer grid, the valley paths
    assert all(isinstance(c, Candidate) for s in stages for c in s)


def test_no_cached_renders_is_said_with_what_to_run(monkeypatch, tmp_path, capsys) -> None:
    from bench import detect_cases, detect_funnel

    monkeypatch.setattr(detect_cases, "CACHE", tmp_path)  # an empty render cache
    assert detect_funnel.main(["--pairs", "1", "--pen-pairs", "1",
                               "--out", str(tmp_path / "f.json")]) == 1
    err = capsys.readouterr().err
    assert "no cached renders" in err and "bench.bench_detect --render-only" in err
    assert not (tmp_path / "f.json").exists()


def test_an_open_end_says_how_far_short_of_the_true_end_it_lies() -> None:
    from bench.detect_funnel import open_ends

    # The joint runs x = 0..1000 (a sheet border at 0, the image border at 1000); its line stops
    # 30 px short of the border at 0 (28 px: read at the nearest true point, every 4 px) and
    # 200 px short of the image border, both read as open.
    c = _cand(300.0)
    c.points = np.column_stack([np.linspace(30, 800, 100), np.full(100, 300.0)])
    c.end_kinds = ("open", "open")
    ends = open_ends(c, TRUTH, ["joint_end", "image_border"])
    assert ends == [{"short_px": 28.0, "truth_kind": "joint_end"},
                    {"short_px": 200.0, "truth_kind": "image_border"}]
    c.end_kinds = ("sheet border", "open")
    assert open_ends(c, TRUTH, ["joint_end", "image_border"]) == [ends[1]]
    # Refused before its ends were read (no long run of gap profiles): "open" is the default,
    # not a reading (the eleventh session's table counted them).
    unread = _cand(300.0, why="candidate of 1000 px has no long run of gap profiles (3 of 9)")
    unread.points = None
    assert unread.end_kinds == ("open", "open") and open_ends(unread, TRUTH, ["joint_end"]) == []
    # A line that runs on past the true end (into the wedge between two rounded corners) is not
    # "0 px short": it says how far past (negative). Was 0.0: the table's "<= 8 px" column held
    # ends 5-10 px past the joint's (wide easy tuning 10169, twenty-third session).
    c.points = np.column_stack([np.linspace(-7, 800, 100), np.full(100, 301.0)])
    c.end_kinds = ("open", "sheet border")
    past = open_ends(c, TRUTH, ["joint_end", "image_border"])
    assert past == [{"short_px": -7.0, "truth_kind": "joint_end"}]
    rows = [{"case": ["wide", "easy", "tuning", 7], "view": 0, "stage": "first way",
             "verdict": "x", "open_ends": ends + past},
            {"case": ["wide", "easy", "tuning", 8], "view": 0, "stage": "first way",
             "verdict": "x", "open_ends": [{"short_px": 8.0, "truth_kind": "joint_end"}]}]
    md = table(rows)
    assert ("| true end | past it | <= 8 px | 8-20 px | 20-50 px | 50-150 px | > 150 px |"
            in md), md
    assert "| joint_end | 1 | 1 | 0 | 1 | 0 | 0 |" in md
    assert "| image_border | 0 | 0 | 0 | 0 | 0 | 1 |" in md


def test_the_t_corner_close_ups_are_read_when_asked_for() -> None:
    from bench.detect_cases import case_list
    from bench.detect_funnel import PAIRS
    from bench.detect_probe import part_parser

    plain = part_parser("x", PAIRS, "o.json").parse_args([])
    assert (plain.wide_pairs, plain.pen_pairs, plain.tee_pairs, plain.rough_pairs,
            plain.strip_pairs) == (50, 25, 0, 0, 0)  # as before: the wide and pen sets
    assert case_list("tee", "mixed", plain.part, plain.tee_pairs) == []
    a = part_parser("x", PAIRS, "o.json").parse_args(["--pairs", "0", "--tee-pairs", "3"])
    assert (a.wide_pairs, a.tee_pairs) == (0, 3)
    assert len(case_list("tee", "mixed", a.part, a.tee_pairs)) == 3
