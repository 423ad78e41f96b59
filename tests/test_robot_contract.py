"""One test body for the Robot interface, run against every backend: the in-process ``mock://``,
a mock controller reached by its pty path through ``serial_for_url`` (as a real controller
would be), and ``rapid://``: the RAPID server module itself, run by the RAPID interpreter. A new
backend only has to pass these."""

from __future__ import annotations

import numpy as np
import pytest

from controller.errors import ConfigError, JointLimitError, ReachabilityError, SafetyError
from controller.geometry.kinematics import check_pose_consistency, flange_pose, irb2400
from controller.geometry.poses import make_pose
from drivers.mock.mock_controller import MockController
from drivers.robot import Robot, SafetyLimits, open_robot

TOOL = make_pose(t_mm=[0.0, 0.0, 250.0])


@pytest.fixture(params=["mock-url", "pty-path", "rapid-url"])
def robot(request):
    if request.param == "mock-url":
        r = open_robot("mock://?seed=5")
        mock = r.mock
    elif request.param == "rapid-url":
        r = open_robot("rapid://?seed=5")
        mock = r.mock
    else:
        mock = MockController(seed=5)
        path = mock.serve_pty()
        r = open_robot(path, ack_timeout_s=0.2, status_poll_s=0.5)
        r._owned.append(mock)
        r.mock = mock
    with r:
        yield r


def test_is_a_robot_and_identifies(robot: Robot):
    assert isinstance(robot, Robot)
    info = robot.identify()
    assert {"protocol", "version", "robot", "path_capacity", "boot"} <= set(info)


def test_joints_and_pose_are_consistent(robot: Robot):
    j = robot.read_joints()
    assert j.shape == (6,)
    check_pose_consistency(irb2400(), j, robot.read_pose(), tol_mm=0.01, tol_deg=0.001)


def test_status_has_the_agreed_keys(robot: Robot):
    st = robot.status()
    assert {"arc_on", "moving", "error"} <= set(st)
    assert st["arc_on"] is False and st["moving"] is False and st["error"] == 0


def test_move_joints_then_linear_then_weld(robot: Robot):
    robot.set_tool(TOOL)
    robot.move_joints([0, 10, 0, 0, 60, 0], speed_mm_s=200).wait(5.0)
    T = flange_pose(irb2400(), [0, 10, 0, 0, 60, 0]) @ TOOL
    target = T @ make_pose(t_mm=[0.0, -20.0, 0.0])
    robot.move_linear(target, speed_mm_s=100).wait(5.0)
    path = [target @ make_pose(t_mm=[0.0, 2.0 * i, 0.0]) for i in range(20)]
    robot.upload_path(path)
    h = robot.run_weld(speed_mm_s=8.0)
    h.wait(10.0)
    assert h.state == "done" and h.progress == 20
    kinds = [e.kind for e in iter(lambda: robot.poll_event(0.0), None)]
    assert kinds.count("progress") == 20 and kinds[-1] == "done"
    assert robot.status()["path_index"] == 20


def test_refusals_before_sending(robot: Robot):
    with pytest.raises(JointLimitError, match="axis 3"):
        robot.move_joints([0, 0, 90, 0, 0, 0])
    with pytest.raises(ReachabilityError):
        robot.move_linear(make_pose(t_mm=[1700.0, 0.0, 1500.0]))
    with pytest.raises(SafetyError, match="no path uploaded"):
        robot.run_weld(10.0)


def test_operator_cycle_request(robot: Robot):
    robot.mock.request_cycle("job_42")
    ev = robot.poll_event(2.0)
    while ev is not None and ev.kind != "cycle_request":
        ev = robot.poll_event(2.0)
    assert ev is not None and ev.job == "job_42"
    assert robot.status()["cycle_request"] is None  # cleared on the controller


def test_abort_when_idle_is_harmless(robot: Robot):
    robot.abort()
    assert robot.status()["arc_on"] is False


def test_registry_errors():
    with pytest.raises(ConfigError, match=r"known schemes: mock://, .*socket://"):
        open_robot("ftp://host/robot")
    with pytest.raises(ConfigError, match="known options"):
        open_robot("mock://?bogus=1")
    with pytest.raises(ConfigError):
        SafetyLimits(workspace_min_mm=(0, 0, 0), workspace_max_mm=(0, 1, 1))


def test_constructor_does_no_io(tmp_path):
    r = open_robot(str(tmp_path / "no-such-port"))  # fine until opened
    assert not r.link.is_open  # type: ignore[attr-defined]
    m = open_robot("mock://")
    assert m.mock.link_path is None  # the pty is made in open()


def test_weld_of_lines_and_circles(robot: Robot):
    robot.set_tool(TOOL)
    j0 = [0, 10, 0, 0, 60, 0]
    robot.move_joints(j0, speed_mm_s=200).wait(5.0)
    start = flange_pose(irb2400(), j0) @ TOOL
    # a line, a quarter circle of radius 20 mm, a line: three segments, one progress event each
    path = [start @ make_pose(t_mm=[0.0, 20.0, 0.0]), start @ make_pose(t_mm=[0.0, 40.0, 20.0]),
            start @ make_pose(t_mm=[0.0, 40.0, 40.0])]
    h = np.sqrt(0.5) * 20.0
    circles = [None, (start @ make_pose(t_mm=[0.0, 20.0 + h, 20.0 - h]))[:3, 3], None]
    robot.upload_path(path, circles)
    h = robot.run_weld(speed_mm_s=8.0)
    h.wait(10.0)
    assert h.state == "done" and h.progress == 3
    kinds = [e.kind for e in iter(lambda: robot.poll_event(0.0), None)]
    assert kinds.count("progress") == 3 and kinds[-1] == "done"
