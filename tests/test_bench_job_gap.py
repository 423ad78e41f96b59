"""bench.bench_detect_job_gap: the three ways of detecting a rendered pair, counted and written."""

import json

from bench import bench_detect_job_gap, detect_cases


def test_one_rendered_pair_is_detected_three_ways_and_counted(monkeypatch, tmp_path, capsys):
    monkeypatch.setattr(detect_cases, "CACHE", tmp_path / "cache")
    case = detect_cases.case_list("wide", "easy", "tuning", 1)[0]
    assert detect_cases.render_case(case) == "rendered"
    out = tmp_path / "r.json"
    assert bench_detect_job_gap.main(["--jobs", "1", "--cases", "1", "--out", str(out)]) == 0
    rep = json.loads(out.read_text())
    assert rep["cases"] == 1 and rep["range"] == [0.5, 1.5]
    for way in bench_detect_job_gap.WAYS:
        s = rep["summary"]["tuning/all"][way]
        assert s["views"] == 2 and s["pairs"] == 1
        assert s["found"] + s["wrong"] + s["refused"] == 2
        assert rep["summary"]["heldout/all"][way]["views"] == 0
    assert "job gap" in capsys.readouterr().out


def test_no_cached_renders_is_said_with_what_to_run(monkeypatch, tmp_path, capsys):
    monkeypatch.setattr(detect_cases, "CACHE", tmp_path)
    assert bench_detect_job_gap.main(["--out", str(tmp_path / "r.json")]) == 1
    assert "bench.bench_detect --render-only" in capsys.readouterr().err
    assert not (tmp_path / "r.json").exists()
