"""The benchmark's scorer and reports: end kinds at the image border, scenes, gallery."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from bench.detect_score import score_view

W, H = 2272, 1704


def _truth(x0: float, kinds: tuple[str, str], image_size: Any = (W, H)) -> dict[str, Any]:
    """A straight seam along v = 800 from u = x0 to u = 1500 (px), 4 px gap."""
    u = np.linspace(x0, 1500.0, 200)
    t = {"seam_px": np.column_stack([u, np.full_like(u, 800.0)]), "end_kinds": list(kinds),
         "end_tol_px": 0.0, "pens": [], "gap_px": 4.0, "gap_mm": 0.4, "ragged_mm": 0.0,
         "family": "plain"}
    if image_size is not None:
        t["image_size"] = image_size
    return t


def _seam(x0: float) -> np.ndarray:
    u = np.linspace(x0, 1500.0, 150)
    return np.column_stack([u, np.full_like(u, 800.4)])


def test_a_joint_end_at_the_image_border_may_be_called_the_image_border() -> None:
    # The sheets end 4 px inside the image: no view shows that border; "image_border" is the
    # careful answer and counts as found, counted apart.
    truth = _truth(4.0, ("joint_end", "joint_end"))
    r = score_view(_seam(0.0), truth, ["image_border", "joint_end"])
    assert r["result"] == "found" and r["kind_near_border"] == 1
    # Said either way it is found; the right kind is not counted as lenient.
    r = score_view(_seam(4.0), truth, ["joint_end", "joint_end"])
    assert r["result"] == "found" and r["kind_near_border"] == 0


@pytest.mark.parametrize("x0", [40.0, 200.0])
def test_a_joint_end_well_inside_the_image_must_be_called_a_joint_end(x0: float) -> None:
    truth = _truth(x0, ("joint_end", "joint_end"))
    r = score_view(_seam(x0), truth, ["image_border", "joint_end"])
    assert (r["result"], r["why"]) == ("wrong", "end kind")


def test_a_seam_leaving_the_image_called_a_joint_end_stays_wrong() -> None:
    # The other direction would stop the weld short: never lenient, however near the border.
    truth = _truth(0.0, ("image_border", "joint_end"))
    r = score_view(_seam(0.0), truth, ["joint_end", "joint_end"])
    assert (r["result"], r["why"]) == ("wrong", "end kind")


def test_without_the_image_size_the_kinds_must_match() -> None:
    truth = _truth(4.0, ("joint_end", "joint_end"), image_size=None)
    r = score_view(_seam(4.0), truth, ["image_border", "joint_end"])
    assert (r["result"], r["why"]) == ("wrong", "end kind")


def test_the_lenient_end_is_matched_in_either_orientation() -> None:
    truth = _truth(4.0, ("joint_end", "joint_end"))
    r = score_view(_seam(0.0)[::-1], truth, ["joint_end", "image_border"])
    assert r["result"] == "found" and r["kind_near_border"] == 1
    r = score_view(_seam(0.0)[::-1], truth, ["image_border", "joint_end"])
    assert r["result"] == "wrong"


def test_wrong_seams_are_counted_by_what_the_scene_had() -> None:
    from bench.bench_detect import scene_features, wrong_by_scene

    # Tuning view 10005 easy: a step shadow darker than the gap floor (its returned seam lies
    # on the middle of gap + shadow); 10063 easy: a lighter shadow.
    dark = scene_features(("wide", "easy", "tuning", 10005))
    light = scene_features(("wide", "easy", "tuning", 10063))
    assert dark["step_shadow"] and dark["shadow_vs_floor"] <= 1.0
    assert light["step_shadow"] and light["shadow_vs_floor"] > 1.0
    view = {"ours": {"result": "wrong"}}
    rows = {"wide/easy/tuning": [{"scene": dark, "views": [view, {"ours": {"result": "found"}}]},
                                 {"scene": light, "views": [{"ours": {"result": "refused"}}]}],
            "classic/easy/tuning": [{"scene": dark, "views": [view]}]}
    out = wrong_by_scene(rows)
    assert out["step shadow: as dark as the floor/tuning"] == {"views": 2, "found": 1, "wrong": 1}
    assert out["step shadow: lighter/tuning"] == {"views": 1, "found": 0, "wrong": 0}
    assert out[f"table {dark['table']}/tuning"]["wrong"] >= 1
    # Per view: whether a joint end is in view, and the plates' corners there.
    rounded = {**dark, "corner_mm": 12.0}
    ends = {"end_kinds": ["joint_end", "image_border"]}
    rows = {"wide/easy/heldout": [
        {"scene": rounded, "views": [{**ends, "ours": {"result": "refused"}},
                                     {"end_kinds": ["image_border"] * 2,
                                      "ours": {"result": "found"}}]},
        {"scene": {**dark, "corner_mm": 0.0}, "views": [{**ends, "ours": {"result": "found"}}]}]}
    out = wrong_by_scene(rows)
    assert out["plate corners: a joint end in view, rounded/heldout"] == {
        "views": 1, "found": 0, "wrong": 0}
    assert out["plate corners: a joint end in view, square/heldout"]["found"] == 1
    assert out["plate corners: no joint end in view/heldout"]["found"] == 1
    # A report from before corner_mm was recorded: no corner rows, rather than wrong ones.
    old = {"wide/easy/tuning": [{"scene": {"table": "dark", "step_shadow": False},
                                 "views": [{**ends, "ours": {"result": "found"}}]}]}
    assert not any(k.startswith("plate corners") for k in wrong_by_scene(old))


def test_the_gallery_draws_the_truth_under_the_detection_and_picks_by_part() -> None:
    from bench.detect_gallery import TRUTH_BGR, chosen, picture

    img = np.full((200, 400), 128, np.uint8)
    truth = {"seam_px": np.array([[20.0, 100.0], [380.0, 100.0]]), "pens": []}
    out = picture(img, truth, None, "refused: no seam", max_width=400)
    assert out.shape == (200, 400, 3)
    # The true centreline is drawn (dimmed with the image, as the overlay dims it).
    b, g, r = (int(v) for v in out[100, 200])
    assert b > r + 80 and b > g and b > 0.6 * TRUTH_BGR[0]
    rows = {"wide/easy/tuning": [{"case": ["wide", "easy", "tuning", 1],
                                  "views": [{"ours": {"result": "wrong"}},
                                            {"ours": {"result": "found"}}]}],
            "wide/easy/heldout": [{"case": ["wide", "easy", "heldout", 2],
                                   "views": [{"ours": {"result": "wrong"}}]}],
            "classic/easy/tuning": [{"case": ["classic", "easy", "tuning", 0],
                                     "views": [{"ours": {"result": "wrong"}}]}]}
    assert [(c[3], i) for c, i, _ in chosen({"rows": rows}, "wrong", "tuning")] == [(1, 0)]
    assert [(c[3], i) for c, i, _ in chosen({"rows": rows}, "wrong", "heldout")] == [(2, 0)]
    # By a scene feature, named as in the benchmark's table by what the scene had.
    rounded = {"table": "dark", "step_shadow": False, "corner_mm": 10.0}
    rows = {"wide/easy/tuning": [
        {"case": ["wide", "easy", "tuning", 3], "scene": rounded,
         "views": [{"end_kinds": ["joint_end", "image_border"], "ours": {"result": "wrong"}},
                   {"end_kinds": ["image_border"] * 2, "ours": {"result": "wrong"}}]}]}
    corner = "plate corners: a joint end in view, rounded"
    assert [(c[3], i) for c, i, _ in chosen({"rows": rows}, "wrong", "tuning", corner)] == [(3, 0)]
    assert len(chosen({"rows": rows}, "wrong", "tuning", "table dark")) == 2
    assert chosen({"rows": rows}, "wrong", "tuning", "table plain") == []


def test_the_gallery_says_so_when_no_view_has_the_feature_asked_for(tmp_path, capsys) -> None:
    import json

    from bench.detect_gallery import main

    report = tmp_path / "detect.json"
    report.write_text(json.dumps({"rows": {"wide/easy/tuning": [
        {"case": ["wide", "easy", "tuning", 1], "scene": {"table": "dark", "step_shadow": False},
         "views": [{"end_kinds": ["image_border"] * 2, "ours": {"result": "wrong"}}]}]}}))
    assert main(["--report", str(report), "--feature", "table nonsense",
                 "--out", str(tmp_path / "g")]) == 1
    err = capsys.readouterr().err
    assert "'table nonsense'" in err and "by what the scene had" in err
    assert not (tmp_path / "g").exists()
