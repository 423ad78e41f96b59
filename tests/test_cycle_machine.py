import re
from pathlib import Path

import pytest
from transitions.core import MachineError

from controller.cell.cycle_machine import TRANSITIONS, CycleState, build_machine, mermaid_diagram

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
