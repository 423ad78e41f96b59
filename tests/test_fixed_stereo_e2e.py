"""The fixed-stereo cell end to end: two fixed cameras with different lenses, the robot only welds.

Mock controller on a pty + real client, two simulated fixed cameras captured together, real
vision; the record is replayed by `seamguide locate` with one calibration per camera.
"""

import json

import numpy as np
import pytest

from controller.cell.cycle_record import read_record
from controller.cell.dry_run import SimRig, run_dry_run
from controller.cli import main
from controller.stereo.triangulate import PolylineDistance
from drivers.sim.sim_scene import make_scene

pytestmark = pytest.mark.slow


def test_fixed_stereo_dry_run_has_no_motion_before_the_weld(tmp_path, capsys):
    with SimRig(scene_kind="s_curve", seed=1, speedup=200.0, cell="fixed-stereo") as rig:
        cycle = rig.cycle(tmp_path)
        rep = rig.report(cycle.run(), cycle)
        kinds = [e["kind"] for e in rig.mock.executed]
    r = rep.result
    assert r.status == "done", r.reason
    assert rep.seam_rms_mm <= 0.05 and rep.path_rms_mm <= 0.05
    doc = read_record(r.record_path)
    states = [s["state"] for s in doc["states"]]
    assert states == ["capturing", "locating", "planning", "welding", "done"]
    assert doc["robot_motions_before_weld"] == 0 and len(doc["capture_skew_ms"]) == 1
    # The controller's own log: the weld step's approach moves (to the approach point, then dry
    # to the seam's first point), the weld, the dry depart; nothing before.
    assert kinds == ["move_joints", "move_linear", "weld", "move_linear"], kinds
    # The record's view files replay with one calibration per camera.
    views = [json.loads((r.record_path / f"{n}.json").read_text()) for n in ("left", "right")]
    assert [v["camera"] for v in views] == ["left", "right"]
    out = tmp_path / "replay.json"
    assert main(["locate", "--calibration", f"left={r.record_path / 'calibration_left.yaml'}",
                 "--calibration", f"right={r.record_path / 'calibration_right.yaml'}",
                 "--view", str(r.record_path / "left.json"),
                 "--view", str(r.record_path / "right.json"), "--no-path",
                 "--output", str(out)]) == 0
    pts = np.array(json.loads(out.read_text())["seam_points_mm"])
    err = PolylineDistance(make_scene("s_curve", 1, "medium").seam_points_mm)(pts)
    assert np.sqrt(np.mean(err**2)) <= 0.05


def test_fixed_stereo_calibrations_are_checked(tmp_path):
    with pytest.raises(Exception, match="one calibration per camera"):
        run_dry_run(None, cell="fixed-stereo", calibration="c.yaml")
    with pytest.raises(Exception, match="no camera 'middle'"):
        run_dry_run(None, cell="fixed-stereo", calibration={"middle": "c.yaml"})
