"""The detection benchmark locates a pair as the cycle does (controller/cell/guidance.py): with
each view's end kinds and gap width, so that its pair figures are the product's."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from bench import bench_detect
from controller.errors import SeamNotFound
from controller.geometry.camera_model import default_camera


def test_pairs_are_located_with_the_detectors_end_kinds(monkeypatch: pytest.MonkeyPatch) -> None:
    seen: dict[str, Any] = {}

    def fake_locate(views: list[Any], **kw: Any) -> Any:
        seen["views"], seen["kw"] = views, kw
        raise SeamNotFound("stop here")

    monkeypatch.setattr(bench_detect, "locate_seam", fake_locate)
    z = {"seam_index0": np.arange(5), "seam_index1": np.arange(5),
         "seam_points_mm": np.zeros((5, 3)), "T0": np.eye(4), "T1": np.eye(4),
         "centre_mm": np.zeros(3), "radius_mm": 50.0}
    curve = np.array([[10.0, 10.0], [100.0, 100.0]])
    kinds = [("joint_end", "image_border"), None]
    out = bench_detect._locate(z, [curve, curve], [4.0, None], kinds, default_camera())
    assert out["result"] == "refused"
    v1, v2 = seen["views"]
    assert v1.end_kinds == ("joint_end", "image_border") and v1.gap_width_px == 4.0
    assert v2.end_kinds is None and v2.gap_width_px is None
    centre, radius = seen["kw"]["nominal_region"]
    assert radius == 70.0 and np.allclose(centre, 0.0)
    assert seen["kw"]["clip_unseen_ends"] is False  # the job's default
    bench_detect._locate(z, [curve, curve], [4.0, None], kinds, default_camera(), clip=True)
    assert seen["kw"]["clip_unseen_ends"] is True
    # A view with a shadow split carries the whole band's reading to the pair, as the cycle.
    band = curve + [0.0, 3.0]
    bench_detect._locate(z, [curve, curve], [4.0, 4.0], kinds, default_camera(),
                         bands=[(band, 9.0), None])
    v1, v2 = seen["views"]
    assert np.array_equal(v1.band_px, band) and v1.band_width_px == 9.0 and v2.band_px is None


def test_a_split_single_view_counts_as_seamguide_detect_answers_it() -> None:
    found = {"result": "found", "alone": None, "time_s": 0.1, "confidence": 0.9}
    assert bench_detect.single_view(dict(found)) == {k: v for k, v in found.items()
                                                     if k != "alone"}
    # run_case marks a view whose shadow was split off (its band came along) before.
    split = {**found, "alone": "AmbiguousSeam: ... one image cannot tell which ...", "split": True}
    out = bench_detect.single_view(split)
    assert out["result"] == "refused" and out["core_result"] == "found" and out["split"]
    assert "one image cannot tell" in out["error"] and "confidence" not in out
    # An end called the image border left inside the image: refused too, not a split.
    inside = {**found, "result": "wrong",
              "alone": "SeamNotFound: the seam found stops 64 px inside the image at (1, 2), ..."}
    out2 = bench_detect.single_view(inside)
    assert out2["result"] == "refused" and out2["core_result"] == "wrong" and not out2["split"]
    s = bench_detect.summarise([{"views": [{"ours": out}, {"ours": found}, {"ours": out2}]}],
                               "ours")
    assert (s["found"], s["refused"], s["split"], s["wrong"]) == (1, 2, 1, 0)


def test_pair_summary_counts_the_clipped_pairs_and_old_reports_say_nothing() -> None:
    def row(plain: str, clipped: str | None) -> dict[str, Any]:
        r: dict[str, Any] = {"views": [], "pair": {"result": plain, "ends_seen": False,
                                                   "rms_mm": 0.02}}
        if clipped is not None:
            r["pair_clip"] = {"result": clipped}
        return r

    s = bench_detect.summarise([row("refused", "located"), row("located", "located"),
                                row("refused", "wrong")], "ours")
    assert (s["pairs_located"], s["pairs_clip_located"], s["pairs_clip_wrong"]) == (1, 2, 1)
    assert bench_detect._clip_cell(s) == "2/3 (67 %) / 0 / 1"
    old = bench_detect.summarise([row("refused", None)], "ours")
    assert "pairs_clip_located" not in old and bench_detect._clip_cell(old) == "-"


def test_returned_views_are_counted_by_the_detected_band_width() -> None:
    def view(result: str, width: float | None) -> dict[str, Any]:
        return {"ours": {"result": result, "width_px": width}}

    rows = {"wide/easy/tuning": [{"family": "plain", "views": [
        view("found", 2.0), view("wrong", 9.5), view("found", 8.0), view("refused", None)]}],
        "wide/easy/heldout": [{"family": "plain", "views": [view("wrong", 30.0)]}],
        "classic/easy/tuning": [{"family": "classic", "views": [view("found", 4.0)]}]}
    out = bench_detect.by_width(rows)
    assert out == {">= 16 px/heldout": {"returned": 1, "found": 0, "wrong": 1},
                   "0-3 px/tuning": {"returned": 1, "found": 1, "wrong": 0},
                   "8-12 px/tuning": {"returned": 2, "found": 1, "wrong": 1}}


def test_sets_other_than_wide_and_pen_are_counted_in_rows_of_their_own() -> None:
    # A run with the rough or T-corner set beside the wide and pen sets leaves the wide and pen
    # rows (the README's) as they are without them.
    def view(result: str, conf: float | None) -> dict[str, Any]:
        return {"ours": {"result": result, "confidence": conf, "way": "profiles"}}

    wide = {"wide/easy/tuning": [{"family": "plain", "views": [view("found", 0.97)]}],
            "pen/mixed/tuning": [{"family": "shop", "views": [view("refused", None)]}]}
    rough = {"rough/mixed/tuning": [{"family": "plain", "views": [view("wrong", 0.97)]}],
             "tee/mixed/heldout": [{"family": "closeup", "views": [view("found", 0.6)]}]}
    assert [bench_detect.part_of(k) for k in (*wide, *rough)] == [
        "tuning", "tuning", "rough tuning", "tee heldout"]
    alone, both = bench_detect.by_look(wide), bench_detect.by_look({**wide, **rough})
    assert {k: v for k, v in both.items() if k in alone} == alone
    assert both["plain/rough tuning"]["wrong"] == 1 and both["closeup/tee heldout"]["found"] == 1
    ways = bench_detect.by_way({**wide, **rough})
    assert ways["profiles/tuning"] == {"returned": 1, "found": 1, "wrong": 0}
    assert ways["profiles/rough tuning"] == {"returned": 1, "found": 0, "wrong": 1}


def test_the_reliability_table_has_a_column_per_part_and_none_without_one() -> None:
    rows = {"wide/easy/tuning": [{"family": "plain", "views": [
        {"ours": {"result": "found", "confidence": 0.97}}]}],
        "rough/mixed/tuning": [{"family": "plain", "views": [
            {"ours": {"result": "wrong", "confidence": 0.55}}]}]}
    rel = {part: bench_detect.reliability([r for k, rs in rows.items() for r in rs
                                           if bench_detect.part_of(k) == part])
           for part in ("tuning", "rough tuning")}
    lines = bench_detect._reliability_lines(rel)
    assert lines[3] == "| confidence | tuning | rough tuning |" and lines[4] == "|---|---|---|"
    assert "| 0.95-0.99 | 1/1 found, 0 wrong | - |" in lines
    assert "| 0.50-0.60 | - | 0/1 found, 1 wrong |" in lines
    # A run of the classic set alone: no table (it was a header without columns).
    assert bench_detect._reliability_lines({}) == []


def test_a_report_says_what_its_cached_renders_were_made_with(tmp_path, monkeypatch) -> None:
    # Renders are cached across library upgrades (a new OpenCV changed rendered views): each
    # render records the libraries, and a report counts the cases by them.
    import cv2
    import numpy as np

    from bench import detect_cases

    monkeypatch.setattr(detect_cases, "CACHE", tmp_path)
    old, new, missing = (("wide", "easy", "tuning", s) for s in (1, 2, 3))
    for case, extra in ((old, {}), (new, {"rendered_with": detect_cases.libraries()})):
        path = detect_cases._stem(case).with_suffix(".npz")
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez(str(path), n_views=2, **extra)
    assert cv2.__version__ in detect_cases.libraries()
    assert detect_cases.rendered_with([old, new, missing]) == {
        "unknown": 1, detect_cases.libraries(): 1}
