import re
from pathlib import Path

import pytest
from transitions.core import MachineError

from controller.cell.cycle_machine import TRANSITIONS, CycleState, build_machine, mermaid_diagram
from controller.errors import LinkError, SafetyError, SeamguideError

DOC = Path(__file__).parent.parent / "docs" / "cycle.md"


class Model:
    def __init__(self, views=2, confirm=False, fixed=False):
        self.views_left = views - 1
        self.confirm = confirm
        self.fixed = fixed
        self.seen = []

    def more_views(self):
        return self.views_left > 0

    def no_motion_next(self):
        return self.fixed

    def needs_confirmation(self):
        return self.confirm

    def after_state_change(self):
        self.seen.append(self.state)
        if self.state is CycleState.CAPTURING:
            pass


def test_docs_diagram_matches_the_machine():
    text = DOC.read_text()
    block = re.search(r"```mermaid\n(.*?)```", text, re.S).group(1)
    stale = "docs/cycle.md is stale: run python -m controller.cell.cycle_machine"
    assert block == mermaid_diagram(), stale


def test_diagram_lists_every_state_and_transition():
    d = mermaid_diagram()
    for s in CycleState:
        assert f'state "{s.name}"' in d
    for t in TRANSITIONS:
        if t["source"] == CycleState.IDLE and t["trigger"] == "start":
            assert "IDLE --> MOVING_TO_VIEW: start" in d


def test_fixed_cameras_go_straight_to_capturing():
    m = Model(views=2, fixed=True)
    build_machine(m)
    m.start()
    assert m.state is CycleState.CAPTURING
    m.captured()  # a fixed group, then another one captured without motion
    assert m.state is CycleState.CAPTURING
    m.views_left = 0
    m.captured()
    assert m.state is CycleState.LOCATING
    assert CycleState.MOVING_TO_VIEW not in m.seen


def test_happy_path_with_two_views():
    m = Model()
    build_machine(m)
    m.start()
    m.arrived()
    m.captured()
    assert m.state is CycleState.MOVING_TO_VIEW
    m.views_left = 0
    m.arrived()
    m.captured()
    assert m.state is CycleState.LOCATING
    m.located()
    m.planned()
    assert m.state is CycleState.WELDING
    m.welded()
    m.reset()
    assert m.state is CycleState.IDLE


def test_confirmation_state_when_the_job_asks():
    m = Model(views=1, confirm=True)
    build_machine(m)
    for trig in ("start", "arrived", "captured", "located", "planned"):
        getattr(m, trig)()
    assert m.state is CycleState.CONFIRMING
    m.confirmed()
    assert m.state is CycleState.WELDING


@pytest.mark.parametrize("upto", ["start", "arrived", "captured", "located", "planned"])
@pytest.mark.parametrize("end", ["fault", "abort"])
def test_fault_and_abort_from_every_active_state(upto, end):
    m = Model(views=1)
    build_machine(m)
    for trig in ("start", "arrived", "captured", "located", "planned"):
        getattr(m, trig)()
        if trig == upto:
            break
    getattr(m, end)()
    assert m.state is (CycleState.FAULT if end == "fault" else CycleState.ABORTED)


def test_invalid_triggers_are_loud_and_no_auto_transitions():
    m = Model()
    build_machine(m)
    with pytest.raises(MachineError):
        m.welded()
    assert not hasattr(m, "to_WELDING") and not hasattr(m, "to_welding")
    m.fault()
    with pytest.raises(MachineError):
        m.start()  # a faulted cycle must be reset before anything else


class RecordingRobot:
    """A robot that records the calls the cycle makes (no link, no motion).

    ``fail_abort`` / ``fail_move``: the exception that call raises (after being recorded).
    """

    def __init__(self, fail_abort=None, fail_move=None):
        self.calls = []
        self.fail_abort = fail_abort
        self.fail_move = fail_move

    def abort(self):
        self.calls.append("abort")
        if self.fail_abort is not None:
            raise self.fail_abort

    def move_joints(self, joints_deg, speed_mm_s):
        self.calls.append(("move_joints", tuple(float(v) for v in joints_deg), speed_mm_s))
        if self.fail_move is not None:
            raise self.fail_move
        robot = self

        class Handle:
            def wait(self, timeout_s):
                robot.calls.append(("wait", timeout_s))
        return Handle()


SAFE = (0.0, 0.0, 0.0, 0.0, 30.0, 0.0)


def _cycle(robot):
    from types import SimpleNamespace

    from controller.cell.cycle import WeldCycle

    job = SimpleNamespace(timeouts=SimpleNamespace(move_s=7.0))
    return WeldCycle(robot, None, None, job, safe_joints_deg=SAFE)


@pytest.mark.parametrize("upto", [None, "start", "arrived", "captured", "located", "planned"])
def test_entering_fault_aborts_the_robot_then_moves_it_to_the_safe_pose(upto):
    robot = RecordingRobot()
    c = _cycle(robot)
    c.more_views = lambda: False
    c.needs_confirmation = lambda: False
    for trig in ("start", "arrived", "captured", "located", "planned") if upto else ():
        getattr(c, trig)()
        if trig == upto:
            break
    c.fault()
    assert c.state is CycleState.FAULT
    assert robot.calls == ["abort", ("move_joints", SAFE, 100.0), ("wait", 7.0)]
    c._end(CycleState.FAULT, "fault", "again", SeamguideError("again"))
    assert len(robot.calls) == 3  # made safe once


def test_entering_aborted_aborts_the_robot_and_moves_nothing():
    robot = RecordingRobot()
    c = _cycle(robot)
    c.start()
    c.abort()
    assert c.state is CycleState.ABORTED and robot.calls == ["abort"]


def test_no_safe_move_when_the_abort_did_not_reach_the_robot():
    robot = RecordingRobot(fail_abort=LinkError("simulated: no reply"))
    c = _cycle(robot)
    c.start()
    c.fault()
    assert robot.calls == ["abort"]  # the link is down: nothing more is sent


def test_a_refused_safe_move_is_logged_not_raised():
    robot = RecordingRobot(fail_move=SafetyError("simulated: outside the box"))
    c = _cycle(robot)
    c.start()
    c.fault()
    assert c.state is CycleState.FAULT and [x if isinstance(x, str) else x[0]
                                            for x in robot.calls] == ["abort", "move_joints"]


def test_request_abort_from_another_thread_never_raises():
    robot = RecordingRobot(fail_abort=LinkError("simulated: no reply"))
    c = _cycle(robot)
    c.request_abort("operator pressed abort")
    assert robot.calls == ["abort"] and c._abort.is_set()


@pytest.mark.parametrize("dest", [CycleState.FAULT, CycleState.ABORTED])
def test_end_takes_the_machine_to_its_end_state_and_makes_the_robot_safe(dest):
    robot = RecordingRobot()
    c = _cycle(robot)
    c.start()
    status = "fault" if dest is CycleState.FAULT else "aborted"
    c._end(dest, status, "why", SeamguideError("why"))
    assert c.state is dest and (c.result.status, c.result.reason) == (status, "why")
    moved = [x for x in robot.calls if not isinstance(x, str) and x[0] == "move_joints"]
    assert robot.calls[0] == "abort" and len(moved) == (dest is CycleState.FAULT)


def test_end_finishes_the_result_even_when_making_safe_hits_a_bug():
    robot = RecordingRobot(fail_abort=RuntimeError("a bug in the driver"))
    c = _cycle(robot)
    c.start()
    c._end(CycleState.FAULT, "fault", "why", SeamguideError("why"))
    assert c.result.status == "fault" and robot.calls == ["abort"]
