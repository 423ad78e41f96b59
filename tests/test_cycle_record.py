import json

import numpy as np
import pytest

from controller.cell.cycle_record import CycleRecord, mark_interrupted, read_record


class FakeClock:
    def __init__(self):
        self.t = 100.0

    def __call__(self):
        return self.t


def test_record_lifecycle(tmp_path):
    clock = FakeClock()
    rec = CycleRecord(tmp_path, "demo", clock=clock)
    assert read_record(rec.path)["status"] == "incomplete"
    rec.state("moving_to_view")
    clock.t += 1.5
    rec.state("capturing")
    rec.save_image("view1.png", np.zeros((10, 12), np.uint8))
    rec.save_json("seam.json", {"seam_points_mm": [[1, 2, 3]]})
    clock.t += 0.25
    rec.finish("fault", "camera failed", code=8)
    doc = read_record(rec.path)
    assert doc["status"] == "fault" and doc["reason"] == "camera failed"
    assert doc["states"][0] == {"state": "moving_to_view", "t_s": 0.0, "duration_s": 1.5}
    assert doc["states"][1]["duration_s"] == 0.25
    assert set(doc["files"]) == {"view1.png", "seam.json"}
    assert json.loads((rec.path / "seam.json").read_text())["seam_points_mm"] == [[1, 2, 3]]
    assert not list(rec.path.glob("*.tmp"))


def test_two_records_in_the_same_second_do_not_collide(tmp_path):
    a = CycleRecord(tmp_path, "demo", wall_clock=lambda: 0.0)
    b = CycleRecord(tmp_path, "demo", wall_clock=lambda: 0.0)
    assert a.path != b.path


def test_incomplete_records_are_marked_interrupted(tmp_path):
    done = CycleRecord(tmp_path, "demo")
    done.finish("done")
    crashed = CycleRecord(tmp_path, "demo")
    crashed.state("welding")
    marked = mark_interrupted(tmp_path)
    assert marked == [crashed.path]
    assert read_record(crashed.path)["status"] == "interrupted"
    assert read_record(done.path)["status"] == "done"


def test_unknown_status_refused(tmp_path):
    with pytest.raises(ValueError):
        CycleRecord(tmp_path, "demo").finish("great")
