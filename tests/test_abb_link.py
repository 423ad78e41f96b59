"""The link client against the mock controller over a real pseudo-terminal (pyserial for real):
retransmission, duplicates, no reply, reconnect and restart mid-path, abort during a weld, the
difference between "link returned nothing" and "robot did not finish", and a short soak.

Each test that talks to a controller runs twice (the ``scheme`` fixture): against the Python
mock (``mock://``) and against the RAPID server module itself, run by the RAPID interpreter on
the same fault-injected line and simulated arm (``rapid://``).

No sleeps: every wait is on a reply or an event, with a timeout."""

from __future__ import annotations

import collections
import importlib.util
import threading
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from controller.errors import LinkError, RobotFault, SafetyError
from controller.geometry.kinematics import flange_pose, irb2400
from controller.geometry.poses import make_pose, pose_error
from drivers.abb import abb_codec as codec
from drivers.abb.abb_link import AbbLink
from drivers.mock.mock_controller import MockController
from drivers.rapid_vm.values import PREDEFINED, copy
from drivers.rapid_vm.vm_controller import RapidController
from drivers.robot import MotionTimeout, open_robot

TOOL = make_pose(t_mm=[0.0, 0.0, 300.0])


@pytest.fixture(params=["mock", "rapid"])
def scheme(request) -> str:
    """The controller: the Python mock, or SGSERVER.mod in the RAPID interpreter."""
    return request.param


def weld_line(n: int, start=(0.0, 10.0, 0.0, 0.0, 60.0, 0.0)) -> list[np.ndarray]:
    T = flange_pose(irb2400(), start) @ TOOL
    return [T @ make_pose(t_mm=[0.0, 1.0 * i, 0.0]) for i in range(n)]


def test_basic_requests_over_a_pty(scheme):
    with open_robot(f"{scheme}://?seed=2") as robot:
        info = robot.identify()
        assert info["protocol"] == "SGRS" and info["path_capacity"] == 250
        assert np.allclose(robot.read_joints(), robot.mock.joints_deg, atol=1e-4)
        assert pose_error(robot.read_pose(), robot.mock.flange_pose())[0] < 1e-3
        h = robot.move_joints([10, 20, 10, 0, 30, 0], speed_mm_s=200)
        h.wait(5.0)
        assert h.state == "done"
        assert np.allclose(robot.mock.joints_deg, [10, 20, 10, 0, 30, 0])


def test_pose_sent_and_read_back_moves_the_tool_less_than_0_01_mm(scheme):
    rng = np.random.default_rng(4)
    with open_robot(f"{scheme}://") as robot:
        robot.set_tool(TOOL)
        assert np.allclose(robot.mock.tool, TOOL)
        for _ in range(5):
            j = rng.uniform([-60, -20, -20, -90, 30, -90], [60, 40, 30, 90, 90, 90])
            T_base_tcp = flange_pose(irb2400(), j) @ TOOL
            robot.move_linear(T_base_tcp, speed_mm_s=200).wait(5.0)
            T_back = robot.read_pose() @ TOOL
            assert pose_error(T_base_tcp, T_back)[0] < 0.01
            assert pose_error(T_base_tcp, robot.mock.flange_pose() @ TOOL)[0] < 0.01


def test_lost_lines_are_retransmitted_and_nothing_runs_twice(scheme):
    with open_robot(f"{scheme}://?seed=3&drop=0.2&dup=0.2", ack_timeout_s=0.05, retries=30,
                    status_poll_s=0.1) as robot:
        for k in range(10):
            robot.move_joints([5.0 * k, 10, 0, 0, 30, 0], speed_mm_s=200).wait(10.0)
            assert np.allclose(robot.mock.joints_deg, [5.0 * k, 10, 0, 0, 30, 0])
        mids = [e["mid"] for e in robot.mock.executed]
        assert mids == list(range(1, 11))
        assert robot.link.stats["retransmissions"] > 0
        assert robot.mock.link_stats["duplicates_suppressed"] > 0


def test_random_disconnects_nothing_lost_nothing_twice(scheme):
    with open_robot(f"{scheme}://?seed=9&disconnect=0.1", ack_timeout_s=0.1, retries=20,
                    status_poll_s=0.2) as robot:
        for k in range(15):
            robot.move_joints([3.0 * k, 10, 0, 0, 30, 0], speed_mm_s=200).wait(10.0)
            robot.read_joints()
        assert [e["mid"] for e in robot.mock.executed] == list(range(1, 16))
        assert robot.link.stats["reconnects"] >= 2
        assert robot.mock.action_log.count("disconnect") == robot.link.stats["reconnects"]


def test_slow_replies_are_waited_for_not_repeated(scheme):
    with open_robot(f"{scheme}://?delay_ms=200") as robot:  # ack timeout follows the mock's delay
        robot.move_joints([10, 0, 0, 0, 30, 0], speed_mm_s=200).wait(5.0)
        assert robot.link.stats["retransmissions"] == 0
    with open_robot(f"{scheme}://?delay_ms=200", ack_timeout_s=0.05, retries=10) as robot:
        robot.move_joints([10, 0, 0, 0, 30, 0], speed_mm_s=200).wait(5.0)
        assert robot.link.stats["retransmissions"] > 0  # too impatient: repeats, answered from
        assert len(robot.mock.executed) == 1            # memory, never executed twice


def test_no_reply_is_a_link_error_naming_the_request():
    # loop:// hands our own request back: never a reply.
    link = AbbLink("loop://", ack_timeout_s=0.02, retries=3)
    link.open()
    try:
        with pytest.raises(LinkError, match=r"no valid reply to 'Q01 RJ\*.*after 4 tries"):
            link.request("RJ", timeout_s=2.0)
    finally:
        link.close()


def test_a_controller_that_does_not_answer_leaves_nothing_open():
    # loop:// hands our own HI back: the port opens but the session never starts.
    robot = open_robot("loop://", ack_timeout_s=0.02, retries=1)
    with pytest.raises(LinkError, match="HI"):
        robot.open()
    assert not robot.link.is_open
    # A mock that drops every line: the pty it served for this robot is stopped again.
    robot = open_robot("mock://?drop=1", ack_timeout_s=0.02, retries=1)
    with pytest.raises(LinkError):
        robot.open()
    assert not robot.link.is_open and not robot.mock.pty.serving


def test_unopenable_port_is_a_link_error(tmp_path):
    with pytest.raises(LinkError, match="cannot open robot link"):
        open_robot(str(tmp_path / "nope")).open()


def test_motion_timeout_is_not_a_link_error_and_abort_stops_it(scheme):
    with open_robot(f"{scheme}://?time_scale=1") as robot:
        h = robot.move_joints([90, 0, 0, 0, 30, 0], speed_mm_s=5)  # ~1 s of motion
        with pytest.raises(MotionTimeout, match="did not finish"):
            h.wait(0.2)
        assert robot.status()["moving"]
        robot.abort()
        with pytest.raises(RobotFault, match="aborted"):
            h.wait(2.0)
        st = robot.status()
        assert not st["moving"] and st["motion_state"] == "aborted"
        assert robot.mock.action_log[-2:] == ["arc_off", "stop"]


def test_abort_from_another_thread_during_a_weld_arc_off_first(scheme):
    with open_robot(f"{scheme}://?time_scale=1") as robot:
        robot.set_tool(TOOL)
        path = weld_line(40)
        robot.move_linear(path[0], speed_mm_s=200).wait(5.0)
        robot.upload_path(path)
        # 39 mm at 5 mm/s: about 8 s, so the abort below (within 2 s) lands mid-weld even on a
        # loaded machine; the test itself ends at the abort.
        h = robot.run_weld(speed_mm_s=5.0)
        errors: list[BaseException] = []

        def waiter() -> None:
            try:
                h.wait(30.0)
            except BaseException as err:
                errors.append(err)

        t = threading.Thread(target=waiter)
        t.start()
        robot.poll_event(2.0)  # the first progress event: the arc is on and the weld moving
        assert robot.mock.arc_on
        robot.abort()
        t.join(5.0)
        assert not t.is_alive()
        assert len(errors) == 1 and isinstance(errors[0], RobotFault)
        assert not robot.mock.arc_on
        # outputs and stops only (the mock also logs the abort request, both log motion starts)
        log = [a for a in robot.mock.action_log if a != "abort" and not a.startswith("start ")]
        assert log[log.index("arc_on"):] == ["arc_on", "arc_off", "stop"]
        assert h.progress < 39


def test_an_abort_takes_the_link_before_a_thread_waiting_on_the_weld(scheme):
    # The thread waiting on a weld takes and releases the link's lock in 50 ms slices; a released
    # lock is not handed to the thread that waited longest, so before the urgent lane an abort
    # waited 0.1-0.8 s (and on a loaded machine past the end of the weld: the arc stayed on).
    # With it, the waiter starts at most the one slice it was about to start.
    with open_robot(f"{scheme}://?time_scale=1") as robot:
        robot.set_tool(TOOL)
        path = weld_line(40)
        robot.move_linear(path[0], speed_mm_s=200).wait(5.0)
        robot.upload_path(path)
        h = robot.run_weld(speed_mm_s=5.0)  # about 8 s
        t = threading.Thread(target=lambda: pytest.raises(RobotFault, h.wait, 30.0))
        link = robot.link
        pumps: list[int] = []
        started: list[int] = []
        pump, write = link.pump, link._write

        def counted_pump(max_s: float) -> int:
            pumps.append(1)
            return pump(max_s)

        def noted_write(data: bytes, deadline: float) -> None:
            if b" AB" in data and not started:
                started.append(len(pumps))
            write(data, deadline)

        link.pump, link._write = counted_pump, noted_write
        t.start()
        robot.poll_event(2.0)  # the first progress event: the arc is on, the waiter pumping
        at_abort = len(pumps)
        assert at_abort >= 1 and t.is_alive()  # the abort below meets a waiter on the link
        robot.abort()
        t.join(5.0)
        assert not t.is_alive() and not robot.mock.arc_on
        assert started and started[0] - at_abort <= 1, (at_abort, started)


def test_weld_progress_and_fault_at_point_n(scheme):
    with open_robot(f"{scheme}://?fail_at_point=30") as robot:
        robot.set_tool(TOOL)
        path = weld_line(50)
        robot.move_linear(path[0], speed_mm_s=200).wait(5.0)
        robot.upload_path(path)
        h = robot.run_weld(10.0)
        with pytest.raises(RobotFault, match=r"failed \(controller error 40\) after path point 29"):
            h.wait(5.0)
        assert not robot.mock.arc_on
        st = robot.status()
        assert (st["error"], st["motion_state"], st["arc_on"]) == (40, "fault", False)
        kinds = [e["kind"] for e in robot.mock.executed]
        assert kinds.count("weld") == 1


def test_path_orientations_arrive_whether_repeated_or_not(scheme):
    from controller.geometry.poses import rotation_about

    with open_robot(f"{scheme}://") as robot:
        robot.set_tool(TOOL)
        base = weld_line(1)[0]
        path = [base @ make_pose(t_mm=[0.0, 2.0 * i, 0.0]) for i in range(10)]
        path += [path[-1] @ make_pose(rotation_about([1, 0, 0], np.radians(1.0 * i)))
                 for i in range(1, 6)]  # the torch tilts over the last five points
        robot.move_linear(path[0], speed_mm_s=200).wait(5.0)
        robot.upload_path(path)
        robot.run_weld(10.0).wait(10.0)
        assert pose_error(robot.mock.flange_pose() @ TOOL, path[-1])[0] < 0.01
        assert pose_error(robot.mock.flange_pose() @ TOOL, path[-1])[1] < 1e-4


class DropAt(MockController):
    """Does something nasty when path slot ``at`` arrives (in the mock's own thread)."""

    def __init__(self, at: int, what: str, **kw) -> None:
        super().__init__(**kw)
        self.at, self.what, self.fired = at, what, False
        xp = self.server.handlers["XP"]

        def nasty_xp(a, after):
            reply = xp(a, after)
            if not self.fired and a and a[0] == str(self.at):
                self.fired = True
                if self.what == "disconnect":
                    self.disconnect(wait=False)  # the reply is lost with the line
                else:
                    self.restart()
                    self.arm.tool = np.eye(4)  # and someone edited the tool on the pendant
            return reply

        self.server.handlers["XP"] = nasty_xp


class RapidDropAt(RapidController):
    """The same nasty thing for SGSERVER.mod in the interpreter, seen on the line (its thread)."""

    def __init__(self, at: int, what: str, **kw) -> None:
        super().__init__(**kw)
        self.at, self.what, self.fired = at, what, False
        self.lose_reply = False
        self.on_request, self.on_reply = self._nasty_request, self._nasty_reply

    def _nasty_request(self, line: bytes) -> None:
        if not self.fired and line[4:].startswith(f"XP {self.at} ".encode()):
            self.fired = True
            if self.what == "disconnect":
                self.lose_reply = True  # its reply, when the program writes it, is lost
            else:
                self.program.globals["sgtool"] = copy(PREDEFINED["tool0"][1])
                self.restart()  # and someone edited the tool on the pendant (PERS kept)

    def _nasty_reply(self, data: bytes) -> bool:
        if self.lose_reply and data.startswith(b"A"):
            self.lose_reply = False
            self.disconnect(wait=False)
            return True
        return False


def drop_at(scheme: str, at: int, what: str):
    return DropAt(at, what) if scheme == "mock" else RapidDropAt(at, what)


def _robot_on(mock: MockController, **kw):
    path = mock.serve_pty()
    robot = open_robot(path, ack_timeout_s=0.1, status_poll_s=0.3, **kw)
    robot._owned.append(mock)
    robot.mock = mock
    return robot


def test_reconnect_mid_path_resumes_without_replaying(scheme):
    mock = drop_at(scheme, 50, "disconnect")
    with _robot_on(mock) as robot:
        robot.set_tool(TOOL)
        path = weld_line(100)
        robot.move_linear(path[0], speed_mm_s=200).wait(5.0)
        robot.upload_path(path)
        assert mock.fired and robot.link.stats["reconnects"] >= 1
        assert mock.link_stats["duplicates_suppressed"] >= 1  # XP 50 answered from memory
        h = robot.run_weld(10.0)
        h.wait(10.0)
        assert h.progress == 100
        runs = collections.Counter(e["mid"] for e in mock.executed)
        assert max(runs.values()) == 1 and [e["kind"] for e in mock.executed] == [
            "move_linear", "weld"]


def test_controller_restart_mid_path_is_reported_and_nothing_replayed(scheme):
    mock = drop_at(scheme, 50, "restart")
    # the interpreter restarts by loading the module again (0.2-0.6 s on a loaded machine):
    # the retransmissions must outlast it to be answered with ER 13
    with _robot_on(mock, retries=30) as robot:
        robot.set_tool(TOOL)
        path = weld_line(100)
        robot.move_linear(path[0], speed_mm_s=200).wait(5.0)
        with pytest.raises(LinkError, match="controller restarted"):
            robot.upload_path(path)
        with pytest.raises(SafetyError, match="no path uploaded"):
            robot.run_weld(10.0)
        assert "arc_on" not in mock.action_log
        assert [e["kind"] for e in mock.executed] == ["move_linear"]
        # a new session was opened and the tool sent again; the path must go again
        assert np.allclose(mock.tool, TOOL)
        robot.upload_path(path)
        robot.run_weld(10.0).wait(10.0)
        assert [e["kind"] for e in mock.executed] == ["move_linear", "weld"]


def test_speed_goes_only_when_it_changes_and_again_after_a_restart(scheme):
    mock = MockController() if scheme == "mock" else RapidController()

    def held() -> float:  # the speed the controller holds (the mock's arm, the program's VAR)
        if scheme == "mock":
            return float(mock.arm.speed_mm_s)
        return float(mock.program.globals["sgspeed"].f["v_tcp"])

    # the interpreter restarts by loading the module again: retransmissions must outlast it
    with _robot_on(mock, retries=30) as robot:
        sent: list[str] = []
        call = robot._call

        def spy(body, timeout_s=None):
            sent.append(body)
            return call(body, timeout_s)

        robot._call = spy
        a, b = [0, 10, 0, 0, 60, 0], [5, 10, 0, 0, 60, 0]
        for j, v in ((a, 200), (b, 200), (a, 150)):
            robot.move_joints(j, speed_mm_s=v).wait(5.0)
        assert [x for x in sent if x.startswith("SV")] == ["SV 200 1", "SV 150 1"]
        assert held() == 150.0
        mock.restart()  # the program starts again with its own speed
        with pytest.raises(LinkError, match="controller restarted"):
            robot.move_joints(b, speed_mm_s=150)  # refused (no session): nothing moves
        assert [e["kind"] for e in mock.executed] == ["move_joints"] * 3
        robot.move_joints(b, speed_mm_s=150).wait(5.0)
        assert [x for x in sent if x.startswith("SV")] == ["SV 200 1", "SV 150 1", "SV 150 1"]
        assert held() == 150.0 and len(mock.executed) == 4


def test_lost_completion_event_is_recovered_from_status(scheme):
    mock: MockController | RapidController
    if scheme == "mock":
        mock = MockController()
        send = mock.line.send

        def lose_in_position(kind, seq, body, delay_s=0.0):
            if not (kind == "E" and body.startswith("IP")):  # swallowed; its number is spent
                send(kind, seq, body, delay_s)

        mock.line.send = lose_in_position
    else:
        mock = RapidController()
        mock.on_reply = lambda data: data.startswith(b"E") and data[4:6] == b"IP"
    with _robot_on(mock) as robot:
        h = robot.move_joints([10, 0, 0, 0, 30, 0], speed_mm_s=200)
        h.wait(5.0)
        assert h.state == "done"


def test_safety_checks_happen_before_any_byte(scheme):
    with open_robot(f"{scheme}://") as robot:
        robot.set_tool(TOOL)
        path = weld_line(5)
        path[2] = path[2] @ make_pose(t_mm=[0.0, 0.0, -5000.0])
        before = robot.mock.link_stats["bytes_rx"]
        with pytest.raises(SafetyError, match="path point 3"):
            robot.upload_path(path)
        with pytest.raises(SafetyError, match="speed"):
            robot.move_joints([0, 0, 0, 0, 30, 0], speed_mm_s=5000)
        with pytest.raises(SafetyError, match="buffer holds 250"):
            robot.upload_path(weld_line(251))
        assert robot.mock.link_stats["bytes_rx"] == before


class FakePort:
    def __init__(self, data: bytes) -> None:
        self.data = bytearray(data)

    def write(self, b: bytes) -> int:
        return len(b)

    def read(self, n: int) -> bytes:
        out = bytes(self.data[:n])
        del self.data[:n]
        return out

    @property
    def in_waiting(self) -> int:
        return len(self.data)

    def close(self) -> None:
        pass


@settings(max_examples=150, deadline=None)
@given(st.binary(max_size=200))
def test_fuzz_client_reply_parser(data):
    link = AbbLink("loop://", ack_timeout_s=0.001, retries=0)
    link._port = FakePort(data)
    try:
        reply = link.request("RJ", timeout_s=0.05)
    except LinkError:  # ProtocolError is a LinkError
        return
    # only a well-formed reply to our seq gets through
    assert isinstance(reply, codec.Reply) and reply.seq == 1


def _soak_module():
    path = Path(__file__).resolve().parents[1] / "bench" / "soak_link.py"
    spec = importlib.util.spec_from_file_location("soak_link", path)
    assert spec and spec.loader
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_short_soak_nothing_lost_nothing_twice(scheme):
    r = _soak_module().run_soak(requests=300, corrupt=0.02, drop=0.01, dup=0.01, seed=11,
                                ack_timeout_s=0.03, backend=scheme)
    assert r["requests"] >= 300 and r["motions_accepted"] >= 15
    assert r["lost"] == 0 and r["executed_twice"] == 0 and r["unreported"] == 0
    assert r["wrong_position"] == 0
    assert r["retransmissions"] > 0  # the faults really happened


# ---- the CLI: seamguide mock-robot / seamguide robot ---------------------------------------


def test_cli_robot_against_the_mock_url(capsys):
    import json

    from controller.cli import main

    assert main(["robot", "--port", "mock://", "joints"]) == 0
    assert json.loads(capsys.readouterr().out) == {"joints_deg": [0.0, 0.0, 0.0, 0.0, 30.0, 0.0]}
    assert main(["robot", "--port", "mock://", "pose"]) == 0
    pose = json.loads(capsys.readouterr().out)
    assert np.allclose(pose["position_mm"],
                       flange_pose(irb2400(), [0, 0, 0, 0, 30, 0])[:3, 3], atol=1e-3)
    assert main(["robot", "--port", "mock://?nope=1", "ping"]) == 2  # ConfigError exit code


def test_cli_mock_robot_process_serves_until_terminated(tmp_path, capsys):
    import json
    import signal
    import subprocess
    import sys

    from controller.cli import main

    link = tmp_path / "robot"
    proc = subprocess.Popen([sys.executable, "-m", "controller.cli", "mock-robot", "--link",
                             str(link), "--options", "seed=3"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        first = proc.stdout.readline()  # waits for the ready message (no sleep)
        assert first.strip() == "{"
        assert link.is_symlink()
        assert main(["robot", "--port", str(link), "ping"]) == 0
        info = json.loads(capsys.readouterr().out)
        assert info["protocol"] == "SGRS" and info["session"] >= 1
    finally:
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=10) == 0
    assert not link.exists()
