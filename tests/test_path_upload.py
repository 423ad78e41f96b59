"""A weld path as MoveL / MoveC segments over the link: what is sent, what the mock controller's
arm executes (circles through three points), what is refused before a byte is sent."""

from __future__ import annotations

import numpy as np
import pytest

from controller.errors import InputError, ProtocolError, SafetyError
from controller.geometry.kinematics import flange_pose, irb2400
from controller.geometry.poses import make_pose, pos_quat_from_pose, rotation_about
from drivers.abb import abb_codec as codec
from drivers.robot import SafetyLimits, open_robot

TOOL = make_pose(t_mm=[0.0, 0.0, 300.0])
J0 = [0.0, 10.0, 0.0, 0.0, 60.0, 0.0]


def start_pose():
    return flange_pose(irb2400(), J0) @ TOOL


A0 = -np.pi / 2


def torch_on_circle(radius, ang):
    """A TCP pose on a circle through the start pose in its y-z plane (centre ``radius`` along
    z), turning with the circle (about local x); the start pose at ``A0``."""
    return start_pose() @ make_pose(rotation_about([1, 0, 0], ang - A0),
                                    [0.0, radius * np.cos(ang), radius + radius * np.sin(ang)])


@pytest.fixture()
def robot():
    with open_robot("mock://?seed=4") as r:
        r.set_tool(TOOL)
        r.move_joints(J0, speed_mm_s=200).wait(5.0)
        yield r


def test_mock_arm_executes_movec_on_the_circle_through_three_points(robot):
    r, a1 = 30.0, A0 + 1.0
    first = robot.mock.arm.flange_pose() @ TOOL
    assert np.allclose(first, torch_on_circle(r, A0), atol=1e-6)
    end = torch_on_circle(r, a1)
    via = torch_on_circle(r, A0 + 0.4)[:3, 3]
    # slot 1 is where the robot is (a MoveL of length 0), slot 2 the circle's end
    robot.upload_path([first, end], [None, via])
    robot.run_weld(10.0).wait(10.0)
    entry = robot.mock.executed[-1]
    assert entry["result"] == "done" and entry["points_reached"] == 2
    trace = robot.mock.arm.trace(entry, step_mm=0.2)
    assert len(trace) > 100
    centre = (start_pose() @ make_pose(t_mm=[0.0, 0.0, r]))[:3, 3]
    # on the circle, to the wire's precision (positions go with 3 decimals)
    assert np.allclose(np.linalg.norm(trace[:, :3, 3] - centre, axis=1), r, atol=1e-3)
    # the torch turned with the circle: at each point it is the planned torch at that angle
    local = (trace[:, :3, 3] - centre) @ start_pose()[:3, :3]
    ang = np.arctan2(local[:, 2], local[:, 1])
    assert ang[0] == pytest.approx(A0, abs=1e-4) and ang[-1] == pytest.approx(a1, abs=1e-4)
    for T, a in zip(trace, ang, strict=True):
        assert np.allclose(T, torch_on_circle(r, a), atol=1e-3)
    assert np.allclose(robot.mock.arm.flange_pose() @ TOOL, end, atol=1e-3)


def test_points_go_as_one_line_or_repeat_the_orientation(robot):
    sent: list[str] = []
    call = robot._call

    def spy(body, timeout_s=None):
        sent.append(body)
        return call(body, timeout_s)

    robot._call = spy
    s = start_pose()
    path = [s @ make_pose(t_mm=[0.0, 10.0, 0.0]), s @ make_pose(t_mm=[0.0, 20.0, 0.0]),
            s @ make_pose(rotation_about([1, 0, 0], 0.3), [0.0, 30.0, 5.0])]
    robot.upload_path(path, [None, None, (s @ make_pose(t_mm=[0.0, 26.0, 1.0]))[:3, 3]])
    words = [b.split()[0] for b in sent]
    assert words == ["PN", "XT", "XP", "XR", "XT", "XC"]
    assert sent[-1] == codec.circle_body(3, (s @ make_pose(t_mm=[0.0, 26.0, 1.0]))[:3, 3])


def test_target_bodies_fall_back_to_two_lines_when_one_does_not_fit():
    q = np.array([0.512345, -0.487655, -0.512344, -0.487656])
    q /= np.linalg.norm(q)  # no trailing zeros to drop: the longest numbers
    long = codec.target_bodies(250, [-1800.123, -1800.456, -1800.789], q)
    assert [b.split()[0] for b in long] == ["XP", "XO"]
    short = codec.target_bodies(12, [1000.0, -50.0, 300.0], q)
    assert [b.split()[0] for b in short] == ["XT"]
    repeat = codec.target_bodies(3, [1.0, 2.0, 3.0], q, codec.fmt_quat(q, trim=True))
    assert [b.split()[0] for b in repeat] == ["XP", "XR"]
    for body in long + short + repeat:
        assert len(codec.encode_frame("Q", 99, body).rstrip(b"\n")) <= codec.MAX_LINE
    # one line: the same slot position and orientation as the two lines
    f = short[0].split()
    p, qq = pos_quat_from_pose(make_pose(t_mm=[1000.0, -50.0, 300.0]))
    assert f[2:5] == codec.fmt_position(p, trim=True).split() == ["1000", "-50", "300"]
    assert [float(v) for v in f[5:]] == [float(v) for v in long[1].split()[2:]]
    # a linear move: target and move in one line (MT), or the target's lines and ML
    assert codec.linear_move_bodies(12, [1000.0, -50.0, 300.0], q) == [
        f"MT 12 {' '.join(f[2:])}"]
    assert [b.split()[0] for b in codec.linear_move_bodies(
        9999, [-1800.123, -1800.456, -1800.789], q)] == ["XP", "XO", "ML"]


def test_refused_before_a_byte_is_sent(robot):
    s = start_pose()
    a, b = s @ make_pose(t_mm=[0.0, 10.0, 0.0]), s @ make_pose(t_mm=[0.0, 30.0, 0.0])
    before = robot.link.stats["bytes_out"]
    with pytest.raises(InputError, match="no circle"):  # circle point on the line
        robot.upload_path([a, b], [None, (s @ make_pose(t_mm=[0.0, 20.0, 0.0]))[:3, 3]])
    with pytest.raises(InputError, match="first path point"):
        robot.upload_path([a, b], [(s @ make_pose(t_mm=[0.0, 5.0, 3.0]))[:3, 3], None])
    with pytest.raises(InputError, match="circle points for"):
        robot.upload_path([a, b], [None])
    assert robot.link.stats["bytes_out"] == before


def test_an_arc_bulging_out_of_the_safety_box_is_refused(robot):
    s = start_pose()
    a, b = s @ make_pose(t_mm=[0.0, 0.0, 0.0]), s @ make_pose(t_mm=[0.0, 40.0, 0.0])
    # circle point near the start: the arc (centre 20 mm along, radius 20) rises 20 mm in the
    # middle, twice as high as any of the three points
    ang = np.radians(150.0)
    via = (s @ make_pose(t_mm=[0.0, 20.0 + 20.0 * np.cos(ang), 20.0 * np.sin(ang)]))[:3, 3]
    pts = np.array([a[:3, 3], b[:3, 3], via])
    robot.limits = SafetyLimits(tuple(pts.min(axis=0) - 1.0), tuple(pts.max(axis=0) + 1.0))
    before = robot.link.stats["bytes_out"]
    with pytest.raises(SafetyError, match="circle to path point 2"):
        robot.upload_path([a, b], [None, via])
    assert robot.link.stats["bytes_out"] == before


def test_server_refuses_a_circle_point_that_makes_no_circle(robot):
    s = start_pose()
    a, b = s @ make_pose(t_mm=[0.0, 10.0, 0.0]), s @ make_pose(t_mm=[0.0, 30.0, 0.0])
    robot.upload_path([a, b])
    robot._call(codec.circle_body(2, (s @ make_pose(t_mm=[0.0, 20.0, 0.0]))[:3, 3]))
    with pytest.raises(ProtocolError, match="circle point 2"):
        robot.run_weld(8.0)
    assert robot.mock.arc_on is False and robot.mock.executed[-1]["kind"] == "move_joints"


def test_a_path_may_start_with_a_circle_from_where_a_linear_move_left_the_robot(robot):
    r, a1 = 30.0, A0 + 1.0
    first = torch_on_circle(r, A0)
    end, via = torch_on_circle(r, a1), torch_on_circle(r, A0 + 0.4)[:3, 3]
    robot.upload_path([end], [via], start=first)  # one point: where the robot is is not sent
    before = robot.link.stats["bytes_out"]
    # the robot got here by a joint move: where the circle starts is not known to the client
    with pytest.raises(SafetyError, match="not known to be there"):
        robot.run_weld(10.0)
    robot.move_linear(first @ make_pose(t_mm=[0.0, 0.0, -5.0]), speed_mm_s=50).wait(5.0)
    with pytest.raises(SafetyError, match="not known to be there"):  # a linear move elsewhere
        robot.run_weld(10.0)
    assert robot.mock.executed[-1]["kind"] == "move_linear"
    assert "arc_on" not in robot.mock.action_log
    robot.move_linear(first, speed_mm_s=50).wait(5.0)
    h = robot.run_weld(10.0)
    h.wait(10.0)
    assert h.progress == 1 and robot.link.stats["bytes_out"] > before
    trace = robot.mock.arm.trace(robot.mock.executed[-1], step_mm=0.2)
    centre = (start_pose() @ make_pose(t_mm=[0.0, 0.0, r]))[:3, 3]
    assert np.allclose(np.linalg.norm(trace[:, :3, 3] - centre, axis=1), r, atol=1e-3)
    assert np.allclose(trace[0], first, atol=1e-3) and np.allclose(trace[-1], end, atol=1e-3)
    with pytest.raises(SafetyError, match="not known to be there"):  # now it is at the end
        robot.run_weld(10.0)


def test_the_circle_to_the_first_point_is_checked_from_the_given_start(robot):
    s = start_pose()
    a, b = s @ make_pose(t_mm=[0.0, 0.0, 0.0]), s @ make_pose(t_mm=[0.0, 40.0, 0.0])
    ang = np.radians(150.0)  # the arc rises 20 mm in the middle (as in the test above)
    via = (s @ make_pose(t_mm=[0.0, 20.0 + 20.0 * np.cos(ang), 20.0 * np.sin(ang)]))[:3, 3]
    pts = np.array([a[:3, 3], b[:3, 3], via])
    robot.limits = SafetyLimits(tuple(pts.min(axis=0) - 1.0), tuple(pts.max(axis=0) + 1.0))
    before = robot.link.stats["bytes_out"]
    with pytest.raises(SafetyError, match="circle to path point 1"):
        robot.upload_path([b], [via], start=a)
    with pytest.raises(InputError, match="first path point"):  # no start: nothing to check from
        robot.upload_path([b], [via])
    assert robot.link.stats["bytes_out"] == before
