"""bench/detect_realism.py: the joint's look across, in the simulator and in the photographs."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from shared_data import needs, shared_data_dir

from bench import detect_cases, detect_realism
from bench.detect_realism import joint_stats, photo_rows, table

REAL = shared_data_dir() / "real-seams"


def _joint(along_noise: float = 0.0, seed: int = 0) -> np.ndarray:
    """A sheet of level 100 left of x = 200 and one of 200 right of it, with a 6 px gap of 20
    between them; each row's sheets scaled by 1 + ``along_noise`` x N(0, 1) (rust, glare)."""
    rng = np.random.default_rng(seed)
    img = np.full((400, 400), 100.0)
    img[:, 200:] = 200.0
    img *= 1.0 + along_noise * rng.standard_normal((400, 1))
    img[:, 197:203] = 20.0
    return np.clip(img, 0, 255).astype(np.uint8)


LINE = np.array([[199.5, 10.0], [199.5, 390.0]])


def test_a_clean_joint_reads_as_drawn() -> None:
    st = joint_stats(_joint(), LINE, 6.0)
    assert st is not None
    lin = detect_realism.linear_lut(2.2)
    assert st["floor"] == pytest.approx(lin[20] / lin[200], abs=0.02)
    assert st["sides"] == pytest.approx(np.log(lin[100] / lin[200]), abs=0.02)
    assert st["rim"] == pytest.approx(1.0, abs=0.02) and st["along"] < 0.01
    assert st["sheet_cv"] < 0.01 and st["width_px"] == 6.0


def test_a_joint_that_changes_along_its_length_reads_so() -> None:
    calm, rough = joint_stats(_joint(0.02), LINE, 6.0), joint_stats(_joint(0.25), LINE, 6.0)
    assert calm is not None and rough is not None
    assert rough["along"] > 4 * calm["along"] and rough["sheet_cv"] > 4 * calm["sheet_cv"]


def test_scratches_beside_the_joint_are_counted_as_look_alikes() -> None:
    clean = _joint()
    scratched = clean.copy()
    # Two dark 2 px scratches on the lines the statistic looks along (6 + 40 px each side).
    scratched[:, 153:155] = 30
    scratched[:, 245:247] = 60
    a, b = joint_stats(clean, LINE, 6.0), joint_stats(scratched, LINE, 6.0)
    assert a is not None and b is not None
    assert a["look_alike"] == 0.0 and b["look_alike"] == pytest.approx(0.5, abs=0.05)


def test_covered_spans_and_lines_off_the_image_are_left_out() -> None:
    img = _joint()
    img[100:300, 150:250] = 250  # a bright tack weld over the joint and the sheets beside
    with_tack = joint_stats(img, LINE, 6.0)
    covered = joint_stats(img, LINE, 6.0, spans=[[80.0, 300.0]])
    assert with_tack is not None and covered is not None
    assert with_tack["along"] > 0.1 and covered["along"] < 0.01
    assert joint_stats(img, np.array([[-500.0, 10.0], [-500.0, 390.0]]), 6.0) is None


def test_the_table_counts_the_photographs_outside_the_simulators_range() -> None:
    sim = [{"family": "plain", **{k: float(i) for k in detect_realism.STATS}}
           for i in range(100)]
    photos = [{"photo": "a", **{k: 50.0 for k in detect_realism.STATS}},
              {"photo": "b", **{k: 500.0 for k in detect_realism.STATS}}]
    t = table(sim, photos)
    assert t.count("\n") == 1 + len(detect_realism.STATS)
    assert "| 1 of 2 |" in t and "500.00 (100 %)" in t and "50.00 (51 %)" in t


@needs(REAL)
def test_every_photograph_changes_along_its_joint_more_than_the_renderer_makes_it() -> None:
    # The finding this tool was written for (README, *Seam vision*, sixteenth session): the
    # simulator's 95th percentile of `along` is about 0.18, every photograph is above 0.3.
    rows = photo_rows(REAL)
    assert len(rows) == 9
    assert min(r["along"] for r in rows) > 0.25


@needs(REAL)
def test_the_command_writes_both_sides(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                       capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setattr(detect_cases, "CACHE", tmp_path / "cache")
    out = tmp_path / "realism.json"
    assert detect_realism.main(["--pairs", "1", "--photos", str(REAL), "--out", str(out)]) == 0
    data = json.loads(out.read_text())
    assert len(data["photos"]) == 9 and 2 <= len(data["simulated"]) <= 6
    assert "| along |" in capsys.readouterr().out
    assert detect_realism.main(["--photos", str(tmp_path / "none")]) == 1


def test_a_label_without_its_width_is_named(tmp_path: Path) -> None:
    (tmp_path / "labels").mkdir()
    (tmp_path / "labels" / "a.json").write_text(json.dumps(
        {"image": "images/a.jpg", "seam_present": True, "polyline_px": [[0, 0], [9, 9]]}))
    with pytest.raises(ValueError, match=r"a\.json has no gap_width_px"):
        photo_rows(tmp_path)


def test_a_label_whose_image_cannot_be_read_is_named(tmp_path: Path) -> None:
    from bench.real_seams import labelled_photos

    (tmp_path / "labels").mkdir()
    (tmp_path / "labels" / "b.json").write_text(json.dumps(
        {"image": "images/b.jpg", "polyline_px": [[0, 0], [9, 9]], "gap_width_px": 4.0}))
    with pytest.raises(FileNotFoundError, match=r"images/b\.jpg \(label .*b\.json\)"):
        list(labelled_photos(tmp_path))
