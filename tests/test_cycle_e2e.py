"""End-to-end weld cycles: mock controller on a pty + real client, simulated camera, real vision.

Each injected fault must end in ``fault`` with the arc off, the robot stopped, the reason in the
record, and no weld command sent after the fault.
"""


import threading
import time
from pathlib import Path

import cv2
import numpy as np
import pytest
from shared_data import CHESSBOARD, needs

from calibration.calibration_file import Calibration
from controller.cell.cycle_record import read_record
from controller.cell.dry_run import HOME_JOINTS_DEG, SimRig, run_dry_run
from controller.errors import CameraError
from controller.geometry.poses import make_pose
from controller.path.path_fit import deviation

pytestmark = pytest.mark.slow
DATA = CHESSBOARD


def welds(mock):
    return [e for e in mock.executed if e["kind"] == "weld"]


def assert_safe_fault(rig, result, reason_part, weld_allowed=False, safe_pose=True):
    """Fault with ``reason_part`` in the reason; arc off, nothing running, at the safe pose."""
    assert reason_part, "give the reason expected: an empty one is always in the reason"
    assert result.status == "fault", result.reason
    assert reason_part.lower() in (result.reason or "").lower(), result.reason
    assert rig.mock.arc_on is False
    assert not any(e["result"] == "running" for e in rig.mock.executed)
    if safe_pose:  # after the fault the cycle moved the robot to the safe pose, last
        last = rig.mock.executed[-1]
        assert last["kind"] == "move_joints" and last["result"] == "done"
        assert np.allclose(last["target"], HOME_JOINTS_DEG)
        assert np.allclose(rig.mock.joints_deg, HOME_JOINTS_DEG, atol=1e-6)
        # the controller saw the abort (arc off, stop) and then the safe move, in that order
        assert rig.mock.action_log[-4:] == ["abort", "arc_off", "stop", "start move_joints"]
    if not weld_allowed:
        assert welds(rig.mock) == []
    doc = read_record(result.record_path)
    assert doc["status"] == "fault" and reason_part.lower() in doc["reason"].lower()


def test_good_cycle_welds_within_a_third_of_a_millimetre(tmp_path):
    rep = run_dry_run(tmp_path, scene_kind="s_curve", seed=1, speedup=200.0)
    r = rep.result
    assert r.status == "done", r.reason
    assert rep.path_rms_mm <= 0.3 and rep.seam_rms_mm <= 0.3
    assert rep.arc_on_after is False
    doc = read_record(r.record_path)
    assert doc["status"] == "done"
    states = [s["state"] for s in doc["states"]]
    assert states == ["moving_to_view", "capturing", "moving_to_view", "capturing", "locating",
                      "planning", "welding", "done"]
    for f in ("view1.png", "view2.png", "view1.json", "seam.json", "weld_path.mod",
              "seam_plot.png", "calibration.yaml"):
        assert (r.record_path / f).is_file(), f


def test_views_rolled_alike_are_warned_about_in_the_record(tmp_path):
    import dataclasses

    from controller.cell.dry_run import view_joints

    with SimRig(speedup=200.0) as rig:
        assert "view_layout_warning" not in read_record(rig.cycle(tmp_path / "a").run()
                                                         .record_path)
        alike = view_joints(rig.scene, rig.cell, roll_deg=0.0)
        views = [dataclasses.replace(v, joints_deg=tuple(float(x) for x in j))
                 for v, j in zip(rig.job.views, alike, strict=True)]
        result = rig.cycle(tmp_path / "b", job=dataclasses.replace(rig.job, views=views)).run()
        assert "would go unnoticed" in read_record(result.record_path)["view_layout_warning"]


def test_controller_error_mid_weld(tmp_path):
    with SimRig(robot_options="fail_at_point=5", speedup=200.0) as rig:
        result = rig.cycle(tmp_path).run()
        assert_safe_fault(rig, result, "failed (controller error 40) after path point 4",
                          weld_allowed=True)
        w = welds(rig.mock)
        assert len(w) == 1 and w[0]["result"] == "fault"  # no weld started after the fault
        log = rig.mock.action_log  # the controller's own fault, then the cycle's make-safe
        assert log[log.index("arc_on"):] == ["arc_on", "arc_off", "stop", "abort", "arc_off",
                                             "stop", "start move_joints"]


def test_link_corruption_before_the_weld(tmp_path):
    with SimRig(speedup=200.0) as rig:
        def on_state(name):
            if name == "capturing" and rig.mock.executed and len(rig.mock.executed) >= 2:
                rig.mock.line.corrupt = 1.0  # the line goes bad for good while view 2 is taken
        result = rig.cycle(tmp_path, on_state=on_state).run()
        rig.mock.line.corrupt = 0.0
        # the next request after the line went bad is the joints read of planning
        assert type(result.error).__name__ == "LinkError"
        assert_safe_fault(rig, result, "the link returned nothing usable", safe_pose=False)
        assert [e["kind"] for e in rig.mock.executed] == ["move_joints"] * 2  # no safe move


class FailingCamera:
    def __init__(self, inner, fail_on):
        self.inner, self.fail_on, self.n = inner, fail_on, 0

    def grab(self):
        self.n += 1
        if self.n == self.fail_on:
            raise CameraError("simulated camera failure: no frame within 2 s")
        return self.inner.grab()


class ReplacingCamera:
    def __init__(self, inner, image_for):
        self.inner, self.image_for, self.n = inner, image_for, 0

    def grab(self):
        self.n += 1
        return self.image_for(self.n, self.inner.grab())


def test_camera_failure(tmp_path):
    with SimRig(speedup=200.0) as rig:
        result = rig.cycle(tmp_path, camera=FailingCamera(rig.camera, 2)).run()
        assert_safe_fault(rig, result, "camera")


@needs(DATA)
def test_no_seam_in_a_real_photograph(tmp_path):
    photo = cv2.imread(str(DATA / "left01.jpg"), cv2.IMREAD_GRAYSCALE)
    assert photo is not None, f"{DATA / 'left01.jpg'} is not a readable image"
    with SimRig(speedup=200.0) as rig:
        cam = rig.calibration.camera
        big = cv2.resize(photo, (cam.width, cam.height), interpolation=cv2.INTER_LINEAR)
        result = rig.cycle(tmp_path, camera=ReplacingCamera(rig.camera, lambda n, im: big)).run()
        reason = {"SeamNotFound": "seam", "AmbiguousSeam": "two seam candidates"}
        assert type(result.error).__name__ in reason, result.reason
        assert_safe_fault(rig, result, reason[type(result.error).__name__])
        assert result.reason.startswith("view1: "), result.reason  # both views: the first named
        if type(result.error).__name__ == "SeamNotFound":
            assert ("no weld seam found" in result.reason
                    or "best seam candidate too weak" in result.reason), result.reason


def test_no_seam_in_view_two_names_view_two(tmp_path):
    rng = np.random.default_rng(11)

    def plain(n, im):  # the second view sees bare, noisy metal: no joint at all
        return im if n == 1 else np.clip(128 + rng.normal(0, 6, im.shape), 0, 255).astype(im.dtype)

    with SimRig(speedup=200.0) as rig:
        result = rig.cycle(tmp_path, camera=ReplacingCamera(rig.camera, plain)).run()
        assert type(result.error).__name__ == "SeamNotFound", result.reason
        assert result.reason.startswith("view2: "), result.reason
        assert_safe_fault(rig, result, "view2: ")
        record = read_record(result.record_path)
        assert record["details"]["view"] == "view2"
        # Both views' pictures are kept: the found seam, and why view2 was refused.
        assert record["detections"][1] == {"view": "view2", "refused": "SeamNotFound"}
        assert record["detections"][0]["view"] == "view1"
        assert 0 < record["detections"][0]["confidence"] <= 1
        for name in ("view1", "view2"):
            assert cv2.imread(str(Path(result.record_path) / f"{name}_overlay.png")) is not None


def test_ambiguous_seam(tmp_path):
    def doubled(n, im):
        # a second, equally strong joint 120 px away: the image holds two seams
        shifted = np.roll(im, 120, axis=0 if n == 1 else 1)
        return np.minimum(im, shifted)

    with SimRig(speedup=200.0) as rig:
        result = rig.cycle(tmp_path, camera=ReplacingCamera(rig.camera, doubled)).run()
        assert type(result.error).__name__ == "AmbiguousSeam", result.reason
        assert result.reason.startswith("view1: "), result.reason
        assert_safe_fault(rig, result, "two seam candidates of similar strength")
        # The record's picture of view1 draws the two lines it could not choose between.
        pic = cv2.imread(str(Path(result.record_path) / "view1_overlay.png")).astype(int)
        b, g, r = (pic[:, :, k] for k in range(3))
        assert ((b > 200) & (g > 150) & (r < 90)).sum() > 100  # 1, cyan
        assert ((b > 200) & (g < 90) & (r > 200)).sum() > 100  # 2, magenta


def test_bad_triangulation_from_a_wrong_hand_eye(tmp_path):
    with SimRig(speedup=200.0) as rig:
        he = rig.cell.T_flange_cam @ make_pose(np.eye(3), [5.0, 0.0, 0.0])
        wrong = Calibration(rig.cell.camera, he)
        result = rig.cycle(tmp_path, calibration=wrong).run()
        assert type(result.error).__name__ == "TriangulationError"
        assert_safe_fault(rig, result, "quality")


def test_unreachable_path(tmp_path):
    import dataclasses

    with SimRig(speedup=200.0) as rig:
        # The job's box ends 60 mm above the seam: the views (and the safe pose) are inside it,
        # the weld path is not; the planner refuses it before anything is sent for welding.
        z = rig.job.seam.nominal_centre_mm[2] + 60.0
        lim = dataclasses.replace(rig.job.limits, workspace_min_mm=(300.0, -900.0, z))
        job = dataclasses.replace(rig.job, limits=lim)
        result = rig.cycle(tmp_path / "path", job=job).run()
        assert type(result.error).__name__ == "ReachabilityError", result.reason
        assert_safe_fault(rig, result, "workspace")
        # A box the views leave (they look from 540-890 mm, the box ends at 300 mm): the robot,
        # holding the job's limits, refuses the first view move; nothing moves, not even to the
        # safe pose (outside the box too).
        moves = len(rig.mock.executed)
        lim = dataclasses.replace(rig.job.limits, workspace_max_mm=(1600.0, 900.0, 300.0))
        result = rig.cycle(tmp_path / "views", job=dataclasses.replace(rig.job, limits=lim)).run()
        assert type(result.error).__name__ == "SafetyError", result.reason
        assert "outside the safety workspace box" in result.reason and "300.0] mm" in \
            result.reason, result.reason
        assert_safe_fault(rig, result, "move_joints target", safe_pose=False)
        assert len(rig.mock.executed) == moves


class WeldStarted:
    """The robot, calling ``then()`` once the controller has accepted the weld (``RW``).

    The mock switches the arc on right after its reply and before it reads the next request, so
    whatever ``then`` sends to the robot reaches it with the arc on.
    """

    def __init__(self, robot, then):
        self._robot, self._then = robot, then

    def __getattr__(self, name):
        return getattr(self._robot, name)

    def run_weld(self, *args, **kwargs):
        handle = self._robot.run_weld(*args, **kwargs)
        self._then()
        return handle


def assert_weld_stopped_with_the_arc_on(mock):
    """The weld was running with the arc on when the abort (``AB``) reached the controller.

    Returns the controller's actions from the arc going on.
    """
    w = welds(mock)
    assert len(w) == 1 and w[0]["result"] == "aborted", w
    assert 0 <= w[0]["points_reached"] < w[0]["points"]
    log = mock.action_log
    after = log[log.index("arc_on"):]
    assert after[:4] == ["arc_on", "abort", "arc_off", "stop"], log
    assert mock.arc_on is False
    return after


def test_operator_abort_during_the_weld(tmp_path):
    with SimRig(speedup=20.0) as rig:
        cycle = rig.cycle(tmp_path)
        cycle.robot = WeldStarted(rig.robot, lambda: threading.Thread(
            target=cycle.request_abort, args=("operator pressed abort",)).start())
        result = cycle.run()
        assert result.status == "aborted" and result.reason == "operator pressed abort"
        after = assert_weld_stopped_with_the_arc_on(rig.mock)
        assert not any(a.startswith("start") for a in after)  # aborted: no motion after it
        assert read_record(result.record_path)["status"] == "aborted"


def test_a_fault_of_the_pc_while_the_arc_is_on_aborts_then_moves_to_the_safe_pose(tmp_path):
    # The weld state's time runs out right after the weld started: the cycle itself faults while
    # the controller is welding. It must abort the robot (arc off, stop) and move to safe.
    jump = [0.0]
    with SimRig(speedup=20.0) as rig:
        cycle = rig.cycle(tmp_path, clock=lambda: time.monotonic() + jump[0])
        cycle.robot = WeldStarted(rig.robot, lambda: jump.__setitem__(0, 1e6))
        result = cycle.run()
        assert type(result.error).__name__ == "CycleTimeout"
        assert_safe_fault(rig, result, "state welding took longer than its", weld_allowed=True)
        # abort (arc off, stop) first, then the safe move, and nothing else
        assert assert_weld_stopped_with_the_arc_on(rig.mock) == [
            "arc_on", "abort", "arc_off", "stop", "start move_joints"]


def test_a_whole_cycle_through_the_rapid_server_itself(tmp_path):
    # the controller is SGSERVER.mod run by the RAPID interpreter (rapid://), not the mock
    with SimRig(speedup=200.0, robot_scheme="rapid") as rig:
        sent: list[str] = []
        call = rig.robot._call
        rig.robot._call = lambda body, timeout_s=None: (sent.append(body), call(body, timeout_s))[1]
        result = rig.cycle(tmp_path).run()
        assert result.status == "done", result.reason
        # joints read once per view (planning starts from the last view's), speed and zone
        # only when they change, the weld's start (where the dry line left the torch) not sent
        words = [b.split()[0] for b in sent]
        assert words.count("RJ") == len(rig.job.views) == 2
        assert [b for b in sent if b.startswith("SV")] == ["SV 200 1", "SV 8 1"]
        path = result.path
        assert path is not None and len(path.segments) >= 2
        assert f"PN {len(path.segments)}" in sent
        assert words.count("XC") == sum(g.via_mm is not None for g in path.segments)
        # what the interpreter's arm ran with the arc on, segment by segment, against the dense
        # planned path it replaces: within the job's tolerance (the wire's rounding included)
        ran = [g for e in rig.mock.arm.segments_run if e["arc"] for g in e["tcp_segments"]]
        assert len(ran) == len(path.segments)
        dense = np.array([t.T_base_tcp for t in path.weld_targets])
        tol = rig.job.path_tolerance()
        for (T0, T1, via), g in zip(ran, path.segments, strict=True):
            dev = deviation(T0, T1, via, dense[g.first:g.last + 1])
            assert tol.admits(dev), (g.first, g.last, dev)
        w = welds(rig.mock)
        assert len(w) == 1 and w[0]["result"] == "done" and w[0]["points_reached"] >= 2
        assert rig.mock.arc_on is False and rig.mock.stopped_with is None
        log = rig.mock.action_log
        # the arc is on over the weld pass only: its first point reached dry, departed dry
        assert log[log.index("arc_on") - 2:] == ["start move_linear", "start weld", "arc_on",
                                                 "arc_off", "start move_linear"]
