"""The mock controller's parts, each alone: schedule, fault-injecting line, arm, pty transport."""

from __future__ import annotations

import os
import threading

import numpy as np
import pytest
import serial

from controller.errors import ConfigError
from controller.geometry.kinematics import flange_pose, irb2400
from controller.geometry.poses import make_pose
from drivers.abb import abb_codec as codec
from drivers.mock.mock_arm import HOME_DEG, MockArm
from drivers.mock.mock_line import MockLine
from drivers.mock.mock_pty import PtyTransport
from drivers.mock.mock_schedule import Schedule


def test_schedule_runs_due_actions_in_time_order_and_clears():
    s = Schedule()
    t0 = s.now
    ran: list[str] = []
    s.at(t0 + 2.0, lambda: ran.append("b"))
    s.at(t0 + 1.0, lambda: ran.append("a"))
    s.at(t0 + 1.0, lambda: ran.append("a2"))  # same time: in the order added
    s.run_due(t0 + 1.5)
    assert ran == ["a", "a2"] and s.next_due() == t0 + 2.0
    s.clear()
    s.run_due(t0 + 3.0)
    assert ran == ["a", "a2"] and s.next_due() is None


def _echo_line(**options) -> MockLine:
    line = MockLine(Schedule(), **options)
    line.on_line = lambda ln: line.send("A", codec.decode_frame(ln).seq, "OK")
    return line


def test_line_alone_passes_lines_and_counts_bytes():
    line = _echo_line()
    out = line.exchange(codec.encode_frame("Q", 7, "ID"))
    assert out == codec.encode_frame("A", 7, "OK")
    assert line.stats["lines_rx"] == 1 and line.stats["lines_tx"] == 1


def test_line_alone_injects_its_faults():
    assert _echo_line(drop=1.0).exchange(codec.encode_frame("Q", 1, "ID")) == b""
    dup = _echo_line(dup=1.0).exchange(codec.encode_frame("Q", 1, "ID"))
    assert codec.LineSplitter().feed(dup) == [codec.encode_frame("A", 1, "OK")] * 4
    bad = _echo_line(corrupt=1.0, seed=3).exchange(codec.encode_frame("Q", 1, "ID"))
    assert codec.encode_frame("A", 1, "OK") not in bad
    with pytest.raises(ConfigError, match="probability"):
        MockLine(Schedule(), dup=1.5)


def test_line_alone_takes_its_wire_time_at_a_baud_rate():
    line = _echo_line(baud=9600)
    q = codec.encode_frame("Q", 1, "ID")
    now = line.schedule.now
    line.receive(q, now)
    assert line.run_due(now) == b""  # the request is still on the wire
    t_in = 10.0 * len(q) / 9600
    assert line.run_due(now + t_in) == b""  # executed; the reply is on the wire now
    a = codec.encode_frame("A", 1, "OK")
    assert line.run_due(now + t_in + 10.0 * len(a) / 9600 + 1e-9) == a


def test_line_drops_the_link_only_while_a_transport_serves_it():
    line = _echo_line(disconnect=1.0)
    line.exchange(codec.encode_frame("Q", 1, "ID"))  # nobody serves: no drop, no error
    drops: list[int] = []
    line.on_drop = lambda: drops.append(1)
    line.exchange(codec.encode_frame("Q", 2, "ID"))
    assert drops == [1]


def _arm(**options) -> tuple[MockArm, list[tuple]]:
    arm = MockArm(Schedule(), **options)
    events: list[tuple] = []
    arm.notify = lambda *f: events.append(f)
    return arm, events


def test_arm_alone_moves_and_reports():
    arm, events = _arm()
    assert np.allclose(arm.joints_deg, HOME_DEG)
    j1 = np.array([10.0, 0, 0, 0, 30, 0])
    T1 = flange_pose(irb2400(), j1)
    begin = arm.start(4, "move_joints", [(j1, T1, 0.5, None)], session=1)
    assert arm.moving and events == []
    begin()
    arm.schedule.run_due(arm.schedule.now)
    assert events == [("IP", 4)] and not arm.moving
    assert np.allclose(arm.joints_deg, j1) and arm.executed[-1]["result"] == "done"


def test_arm_alone_faults_at_point_n_with_the_arc_off_first():
    arm, events = _arm(fail_at_point=2)
    T = flange_pose(irb2400(), [0, 10, 0, 0, 60, 0])
    j = np.array([0.0, 10, 0, 0, 60, 0])
    arm.start(9, "weld", [(j, T, 0.1, None)] * 3, session=1, arc=True)()
    arm.schedule.run_due(arm.schedule.now)
    assert events == [("PG", 9, 1), ("FL", 9, 40, 2)]
    assert arm.action_log == ["start weld", "arc_on", "arc_off", "stop"] and not arm.arc_on
    assert (arm.status_state, arm.error) == ("F", 40)


def test_arm_alone_restart_stops_the_arc_and_keeps_the_tool():
    arm, _ = _arm(time_scale=1.0)
    arm.tool = make_pose(t_mm=[0.0, 0.0, 250.0])
    T = flange_pose(irb2400(), [0, 10, 0, 0, 60, 0])
    arm.start(3, "weld", [(np.array([0.0, 10, 0, 0, 60, 0]), T, 5.0, None)], session=1,
              arc=True)()
    assert arm.arc_on
    arm.restart()
    assert not arm.arc_on and not arm.moving and arm.action_log[-2:] == ["arc_off", "restart"]
    assert arm.executed[-1]["result"] == "restart" and arm.tool[2, 3] == 250.0


def test_pty_transport_alone_serves_a_line(tmp_path):
    line = _echo_line()
    drops: list[int] = []
    pty = PtyTransport(line, on_disconnect=lambda: drops.append(1))
    link = pty.serve(str(tmp_path / "robot"))
    try:
        assert pty.serving and line.on_drop is not None
        with serial.serial_for_url(link, timeout=2.0) as port:
            port.write(codec.encode_frame("Q", 5, "anything"))
            assert codec.decode_frame(port.readline()).seq == 5
        first = os.readlink(link)
        pty.disconnect()
        assert os.readlink(link) != first and drops == [1]
    finally:
        pty.stop()
    assert not pty.serving and line.on_drop is None and not os.path.lexists(link)


def test_a_stop_that_times_out_leaves_the_descriptors_to_the_serving_thread(tmp_path,
                                                                              monkeypatch):
    line = _echo_line()
    entered, release = threading.Event(), threading.Event()
    real_run_due = line.run_due

    def held_run_due(*args, **kwargs):  # the serving thread held inside, as by a slow action
        entered.set()
        release.wait(10.0)
        return real_run_due(*args, **kwargs)

    pty = PtyTransport(line)
    pty.serve(str(tmp_path / "robot"))
    thread = pty._thread
    fds = {pty._master, pty._slave, pty._wake_r, pty._wake_w}
    closed: list[tuple[int, str]] = []
    real_close = os.close

    def spy(fd: int) -> None:
        closed.append((fd, threading.current_thread().name))
        real_close(fd)

    monkeypatch.setattr(os, "close", spy)
    monkeypatch.setattr(line, "run_due", held_run_due)
    try:
        assert entered.wait(5.0)
        pty.stop(timeout_s=0.2)
        assert thread is not None and thread.is_alive() and closed == []
        with pytest.raises(ConfigError, match="not ended yet"):
            pty.serve(str(tmp_path / "robot2"))
    finally:
        release.set()
    thread.join(5.0)
    assert not thread.is_alive()
    # Each descriptor closed once, by the thread that used it, none by stop().
    assert sorted(fd for fd, _ in closed) == sorted(fds)
    assert {name for _, name in closed} == {"mock-controller"}
