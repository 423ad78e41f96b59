"""bench.detect_trace shows one view's candidates and reads an open end again."""

from __future__ import annotations

import numpy as np

from bench.detect_trace import candidate_line, end_reading, ends_to_read, main, shrunk_readings
from controller.vision.seam_params import Candidate, DetectParams

TRUTH = np.column_stack([np.linspace(0, 1000, 251), np.full(251, 300.0)])


def _cand(y: float, x0: float = 0.0, x1: float = 1000.0, why: str = "",
          kinds: tuple[str, str] = ("open", "open")) -> Candidate:
    pts = np.column_stack([np.linspace(x0, x1, 100), np.full(100, y)])
    return Candidate(polyline=pts, coarse_score=1.0, length_px=x1 - x0, points=pts,
                     width=np.full(100, 4.0), end_kinds=kinds, why_rejected=why)


def test_a_candidate_line_marks_the_joint_and_says_why_it_was_refused() -> None:
    on = candidate_line(_cand(301.0, why="dark line of 1000 px fades out"), TRUTH)
    off = candidate_line(_cand(340.0), TRUTH)
    assert on.startswith("J ") and "1 px off" in on and "| dark line of 1000 px fades out" in on
    assert off.startswith("  ") and "40 px off" in off and "|" not in off


def test_only_ends_that_were_read_are_read_again() -> None:
    assert ends_to_read(_cand(300.0, kinds=("open", "sheet border"))) == [0]
    assert ends_to_read(_cand(300.0, kinds=("image border", "open"))) == [1]
    # Refused before its ends were read (no long run of gap profiles): the kinds are the
    # default ("open", "open"), not a reading.
    unread = _cand(300.0, why="candidate of 1000 px has no long run of gap profiles")
    unread.points = None
    assert ends_to_read(unread) == []


def _sheets(fades: bool) -> np.ndarray:
    """A 4 px gap along v = 300 from the left edge to u = 600, where the sheets end on a dark
    table (or, ``fades``, the sheet goes on and only the line stops)."""
    rng = np.random.default_rng(3)
    img = np.full((600, 900), 170.0)
    if not fades:
        img[:, 600:] = 60.0  # the table beyond the sheets' border
    img[298:302, :600] = 50.0
    return np.clip(img + rng.normal(0, 2.0, img.shape), 0, 255).astype(np.uint8)


def test_an_open_end_is_read_again_with_the_steps_beside_the_gap() -> None:
    c = _cand(299.5, x0=0.0, x1=598.0)
    border = end_reading(_sheets(fades=False), c, 1, DetectParams())
    assert border["end"][1] == "sheet border" and abs(border["end"][0] - 2.0) < 2.0
    assert border["border"][1] == (True, True)  # both sheets end there
    assert all(st for st in border["steps"].values())  # every line steps
    fades = end_reading(_sheets(fades=True), c, 1, DetectParams())
    assert fades["end"][1] == "open" and fades["border"][0] is None
    assert fades["steps"][0.0] and not any(fades["steps"][o] for o in (-9.0, -4.5, 4.5, 9.0))


def test_a_view_not_in_the_cache_is_said_with_what_to_run(monkeypatch, tmp_path, capsys) -> None:
    from bench import detect_cases

    monkeypatch.setattr(detect_cases, "CACHE", tmp_path)  # an empty render cache
    assert main(["wide", "easy", "10012", "0"]) == 1
    err = capsys.readouterr().err
    assert "not in the render cache" in err and "bench.bench_detect --render-only" in err


def test_the_shrunk_look_s_scales_are_read_and_scored() -> None:
    # A drawn 20 px soft gap (tests/drawn_plates.py), as the look at the image shrunk is made for.
    from test_seam_smaller import ENDS, _plates

    img = _plates(blur_px=2.8)
    truth = {"seam_px": np.array(ENDS), "end_kinds": ["joint_end", "joint_end"], "gap_px": 20.0,
             "gap_mm": 2.0, "ragged_mm": 0.0, "end_tol_px": 0.0, "pens": [], "family": "closeup",
             "image_size": (img.shape[1], img.shape[0])}
    lines = shrunk_readings(img, truth)
    assert [ln.split(":")[0] for ln in lines] == [
        "shrunk by 2", "shrunk by 3", "shrunk by 1.5", "shrunk by 2.5", "shrunk by 4"]
    assert lines[0].startswith("shrunk by 2: found, ends joint_end / joint_end, confidence")
