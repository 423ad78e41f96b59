"""bench.detect_rescue: which held-back lines of a refused view are tried with the other view."""

from __future__ import annotations

import numpy as np

from bench.detect_rescue import held_back, table
from controller.vision.seam_params import OPEN_END, Candidate, DetectParams


def _cand(y: float, kinds: tuple[str, str], why: str = "", refused: str = "",
          depth: float = 0.4) -> Candidate:
    pts = np.column_stack([np.linspace(0.0, 999.0, 200), np.full(200, y)])
    c = Candidate(polyline=pts, coarse_score=1.0, length_px=999.0, points=pts,
                  why_rejected=why, refused=refused)
    c.end_kinds, c.valid_frac, c.depth, c.resid = kinds, 0.9, depth, 0.0
    c.width = np.full(200, 3.0)
    return c


def test_only_lines_doubtful_for_their_ends_alone_are_tried() -> None:
    unsure = _cand(100.0, ("unsure sheet border", "image border"))
    fades = _cand(200.0, ("open", "sheet border"), why="fades out", refused=OPEN_END)
    mark = _cand(300.0, ("open", "open"), why="fades out", refused=OPEN_END)
    shallow = _cand(400.0, ("sheet border", "sheet border"), why="too shallow")
    weak = _cand(500.0, ("sheet border", "open"), depth=0.15)  # unsure without its ends too
    covered = _cand(600.0, ("covered", "sheet border"))
    tried = held_back([[unsure, fades, mark], [unsure, shallow, weak, covered]], DetectParams())
    assert tried == [unsure, fades]


def test_the_table_counts_by_the_first_views_result() -> None:
    rows = [{"a_result": "found", "result": "located"}, {"a_result": "found", "result": "none"},
            {"a_result": "wrong", "result": "wrong"}, {"a_result": "found", "result": "located"}]
    md = table(rows)
    assert "4 pairs with one view returned" in md
    assert "| found | 2 | 0 | 0 | 0 | 1 |" in md and "| wrong | 0 | 0 | 1 | 0 | 0 |" in md
