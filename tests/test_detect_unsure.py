"""bench.detect_unsure scores the candidates held back for an unsure end as if returned."""

from __future__ import annotations

import numpy as np

from bench.detect_unsure import table, unsure_rows
from controller.vision.seam_params import Candidate

TRUTH = {"seam_px": np.column_stack([np.linspace(0, 1000, 251), np.full(251, 300.0)]),
         "end_kinds": ["joint_end", "image_border"], "end_tol_px": 0.0, "gap_px": 3.0,
         "gap_mm": 0.3, "ragged_mm": 0.0, "family": "plain", "pens": [],
         "image_size": (1000, 600)}


def _cand(x0: float, y: float, kinds: tuple[str, str], why: str = "") -> Candidate:
    pts = np.column_stack([np.linspace(x0, 999.5, 200), np.full(200, y)])
    c = Candidate(polyline=pts, coarse_score=1.0, length_px=1000.0 - x0, points=pts,
                  why_rejected=why)
    c.end_kinds, c.valid_frac, c.depth = kinds, 0.9, 0.4
    return c


def test_held_back_candidates_are_scored_once_and_others_left_out() -> None:
    right = _cand(1.0, 300.5, ("unsure sheet border", "image border"))
    short = _cand(40.0, 300.0, ("unsure sheet border", "image border"))  # end 40 px off
    beside = _cand(1.0, 330.0, ("unsure sheet border", "image border"))  # a pen line
    sure = _cand(1.0, 300.0, ("sheet border", "image border"))  # not held back for its end
    refused = _cand(1.0, 300.0, ("unsure sheet border", "image border"), why="too shallow")
    rows = unsure_rows([[right, short, sure], [right, beside, refused]], TRUTH)
    assert [(r["result"], r["why"]) for r in rows] == [
        ("found", ""), ("wrong", "partial"), ("wrong", "elsewhere")]
    assert rows[1]["end_px"] == 40.0 and all(r["conf_uncapped"] == 1.0 for r in rows)
    md = table(rows)
    assert "3 candidates held back for an unsure end" in md
    assert "| wrong | partial | 1 | 1.00-1.00 |" in md and "| found | - | 1 | 1.00-1.00 |" in md


def test_no_cached_renders_is_said_with_what_to_run(monkeypatch, tmp_path, capsys) -> None:
    from bench import detect_cases, detect_unsure

    monkeypatch.setattr(detect_cases, "CACHE", tmp_path)  # an empty render cache
    assert detect_unsure.main(["--pairs", "1", "--strip-pairs", "1",
                               "--out", str(tmp_path / "u.json")]) == 1
    err = capsys.readouterr().err
    assert "detect_unsure: no cached renders" in err
    assert "bench.bench_detect --render-only" in err
    assert not (tmp_path / "u.json").exists()


def test_the_sets_and_pairs_come_from_the_command_line() -> None:
    from bench.detect_cases import case_list
    from bench.detect_probe import part_parser
    from bench.detect_unsure import PAIRS

    a = part_parser("x", PAIRS, "o.json").parse_args(["--part", "heldout", "--tee-pairs", "3"])
    assert (a.part, a.wide_pairs, a.tee_pairs, a.strip_pairs) == ("heldout", 150, 3, 20)
    assert len(case_list("tee", "mixed", a.part, a.tee_pairs)) == 3
