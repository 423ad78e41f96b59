"""bench.bench_detect_nominal: a rendered pair detected without and with the job's nominal line."""

import json

import numpy as np

from bench import bench_detect_nominal, detect_cases


def test_the_nominal_line_is_the_seam_placed_within_the_fixtures_error():
    seam = np.column_stack([np.linspace(900.0, 1100.0, 101), np.zeros(101), np.full(101, 300.0)])
    line = bench_detect_nominal.nominal_line(seam, 10005, 3.0, 1.0)
    assert np.array_equal(line, bench_detect_nominal.nominal_line(seam, 10005, 3.0, 1.0))
    assert not np.allclose(line, bench_detect_nominal.nominal_line(seam, 10006, 3.0, 1.0))
    mid = len(seam) // 2
    assert 0.0 < np.linalg.norm(line[mid] - seam[mid]) <= 3.0 + 1e-9
    # Turned by at most 1 deg about the middle: the ends move by at most 3 mm + 100 mm x 1 deg.
    assert np.linalg.norm(line - seam, axis=1).max() <= 3.0 + 100.0 * np.radians(1.0) + 1e-9
    assert np.allclose(bench_detect_nominal.nominal_line(seam, 1, 0.0, 0.0), seam)


def test_one_rendered_pair_is_detected_both_ways_and_counted(monkeypatch, tmp_path, capsys):
    monkeypatch.setattr(detect_cases, "CACHE", tmp_path / "cache")
    case = detect_cases.case_list("wide", "easy", "tuning", 1)[0]
    assert detect_cases.render_case(case) == "rendered"
    out = tmp_path / "r.json"
    assert bench_detect_nominal.main(["--jobs", "1", "--cases", "1", "--out", str(out)]) == 0
    rep = json.loads(out.read_text())
    assert rep["cases"] == 1 and rep["tolerance_mm"] == 10.0
    assert list(rep["summary"]) == ["tuning/wide"]
    for way in bench_detect_nominal.WAYS:
        s = rep["summary"]["tuning/wide"][way]
        assert s["views"] == 2 and s["pairs"] == 1
        assert s["found"] + s["wrong"] + s["refused"] == 2
        # The pair once more as a job that clips its unseen ends (the line held in 3D there).
        assert s["clip_located"] + s["clip_wrong"] <= 1
        assert rep["rows"][0][way]["pair_clip"] in ("located", "partial", "wrong", "refused")
    assert "nominal line" in capsys.readouterr().out


def test_no_cached_renders_is_said_with_what_to_run(monkeypatch, tmp_path, capsys):
    monkeypatch.setattr(detect_cases, "CACHE", tmp_path)
    assert bench_detect_nominal.main(["--out", str(tmp_path / "r.json")]) == 1
    assert "bench.bench_detect --render-only" in capsys.readouterr().err
    assert not (tmp_path / "r.json").exists()
