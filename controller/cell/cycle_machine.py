"""The weld cycle's states and transitions, as data, for the ``transitions`` library.

The machine is configured for safety (../shared/STYLE.md lesson 9): Enum states, no automatic
``to_<state>`` triggers (they would bypass the order below), invalid triggers raise, and the
machine is locked so an abort from another thread (the daemon's control socket) is serialised with
the cycle's own transitions. ``fault`` and ``abort`` are allowed from every state; entering either
makes the robot safe (the model's ``on_enter_FAULT`` / ``on_enter_ABORTED``: transitions
names enter callbacks after the Enum member's name).

docs/cycle.md holds the diagram generated from this table by :func:`mermaid_diagram`; a test
checks that the two agree.
"""

from __future__ import annotations

from enum import Enum
from typing import Any

from transitions.extensions.factory import LockedGraphMachine
from transitions.extensions.locking import LockedMachine


class CycleState(Enum):
    """States of one weld cycle; ``value`` is the name shown in status and records."""

    IDLE = "idle"
    MOVING_TO_VIEW = "moving_to_view"
    CAPTURING = "capturing"
    LOCATING = "locating"
    PLANNING = "planning"
    CONFIRMING = "confirming"
    WELDING = "welding"
    DONE = "done"
    FAULT = "fault"
    ABORTED = "aborted"


S = CycleState
ACTIVE = [S.MOVING_TO_VIEW, S.CAPTURING, S.LOCATING, S.PLANNING, S.CONFIRMING, S.WELDING]

# Views of fixed cameras need no motion: a cycle that starts with them goes straight to
# capturing, and they are captured together (one CAPTURING for the group).
TRANSITIONS: list[dict[str, Any]] = [
    {"trigger": "start", "source": S.IDLE, "dest": S.CAPTURING, "conditions": "no_motion_next"},
    {"trigger": "start", "source": S.IDLE, "dest": S.MOVING_TO_VIEW},
    {"trigger": "arrived", "source": S.MOVING_TO_VIEW, "dest": S.CAPTURING},
    {"trigger": "captured", "source": S.CAPTURING, "dest": S.CAPTURING,
     "conditions": ["more_views", "no_motion_next"]},
    {"trigger": "captured", "source": S.CAPTURING, "dest": S.MOVING_TO_VIEW,
     "conditions": "more_views"},
    {"trigger": "captured", "source": S.CAPTURING, "dest": S.LOCATING},
    {"trigger": "located", "source": S.LOCATING, "dest": S.PLANNING},
    {"trigger": "planned", "source": S.PLANNING, "dest": S.CONFIRMING,
     "conditions": "needs_confirmation"},
    {"trigger": "planned", "source": S.PLANNING, "dest": S.WELDING},
    {"trigger": "confirmed", "source": S.CONFIRMING, "dest": S.WELDING},
    {"trigger": "welded", "source": S.WELDING, "dest": S.DONE},
    {"trigger": "reset", "source": [S.DONE, S.FAULT, S.ABORTED], "dest": S.IDLE},
    {"trigger": "fault", "source": [S.IDLE, *ACTIVE, S.DONE], "dest": S.FAULT},
    {"trigger": "abort", "source": [S.IDLE, *ACTIVE, S.DONE], "dest": S.ABORTED},
]


def build_machine(model: Any) -> LockedMachine:
    """Attach the cycle machine to ``model`` (which provides the conditions and callbacks)."""
    return LockedMachine(model=model, states=CycleState, transitions=TRANSITIONS,
                         initial=S.IDLE, auto_transitions=False, ignore_invalid_triggers=False,
                         after_state_change="after_state_change", send_event=False)


class _DiagramModel:
    def more_views(self) -> bool:
        return False

    def no_motion_next(self) -> bool:
        return False

    def needs_confirmation(self) -> bool:
        return False

    def after_state_change(self) -> None:
        pass


def mermaid_diagram() -> str:
    """The machine as Mermaid ``stateDiagram-v2`` text, generated from :data:`TRANSITIONS`."""
    model = _DiagramModel()
    LockedGraphMachine(model=model, states=CycleState, transitions=TRANSITIONS, initial=S.IDLE,
                       auto_transitions=False, graph_engine="mermaid", show_conditions=True,
                       title="seamguide weld cycle", after_state_change="after_state_change")
    text: str = model.get_graph().draw(None)  # type: ignore[attr-defined]
    # Drop the styling lines that only mark the active state of this particular model.
    keep = [ln for ln in text.splitlines()
            if not ln.strip().startswith(("classDef", "Class "))]
    return "\n".join(keep).rstrip() + "\n"


def write_docs(path: str = "docs/cycle.md") -> None:
    """Regenerate the diagram block of docs/cycle.md from the machine (between the markers)."""
    from pathlib import Path

    p = Path(path)
    text = p.read_text(encoding="utf-8")
    start, end = "<!-- diagram:begin -->", "<!-- diagram:end -->"
    head, rest = text.split(start, 1)
    _, tail = rest.split(end, 1)
    block = f"{start}\n```mermaid\n{mermaid_diagram()}```\n{end}"
    p.write_text(head + block + tail, encoding="utf-8")


if __name__ == "__main__":
    write_docs()
