r"""The simulated arm under the RAPID interpreter.

The mock's :class:`~drivers.mock.mock_arm.MockArm`
driven the way RAPID motion instructions drive a robot.

A move instruction queues one segment; the arm runs the queue in order in simulated time. The
program waits as the controller makes it wait: ``\\Conc`` not at all, a ``fine`` point until the
robot is there, a zone point until the robot has started that segment (so the program runs about
one point ahead). ``StopMove`` + ``ClearPath`` stop the arm where it is and empty the queue.
A fault can be injected on the segment that ends at a given point of a weld: the arm stops
there and the waiting instruction gets a recoverable motion error (the server's ERROR handler
reports it). The arc output is the ``doWeld`` signal, written by ``SetDO``.
"""

from __future__ import annotations

import threading
from typing import Any

import numpy as np

from drivers.mock.mock_arm import MockArm, Segment
from drivers.mock.mock_schedule import Schedule
from drivers.rapid_vm.errors import RapidError

#: The error number the interpreter gives a motion fault (a recoverable motion error).
ERR_MOTION = 50024


class VmArm(MockArm):
    """The mock arm with a queue of RAPID move segments; thread-safe (the schedule's lock)."""

    def __init__(self, schedule: Schedule, *, time_scale: float = 0.0) -> None:
        super().__init__(schedule, time_scale=time_scale)
        self._queue: list[tuple[int, str, Segment, np.ndarray | None]] = []
        self._done = 0
        self._started = 0
        self._issued = 0
        self._faulted = 0  # a token: the segment that failed (0 none)
        self._cond = threading.Condition(schedule.lock)
        self.notify = self._on_arm_event
        self.fail_token = 0  # the segment that ends in a fault (0: none)
        #: Every segment the arm started, in order: the mock's ``executed`` entry of a one-segment
        #: motion (``tcp_segments``, for :meth:`trace`) and ``arc``, the arc output as it began.
        self.segments_run: list[dict[str, Any]] = []

    def _on_arm_event(self, kind: str, token: int, *rest: Any) -> None:
        if kind == "IP":
            self._done = token
            self._start_next()
            self._cond.notify_all()

    def _start_next(self) -> None:
        if self._motion is not None or not self._queue or self._faulted:
            return
        token, kind, seg, tool = self._queue.pop(0)
        self._started = token
        if token == self.fail_token:  # the robot stops on its way to this segment's end

            def fault() -> None:
                self._faulted = token
                self._queue.clear()
                self._cond.notify_all()
            self.schedule.after(0.0, fault)
            return
        if tool is not None:
            self._tool = tool  # the move instruction's tool: the TCP path it traces
        self.start(token, kind, [seg], None)()
        # the arm logs each segment as a motion; the controller logs the program's motions
        entry = self.executed.pop()
        entry["arc"] = self._arc
        self.segments_run.append(entry)
        if self.action_log and self.action_log[-1].startswith("start "):
            self.action_log.pop()

    def move(self, kind: str, j1: np.ndarray, T1: np.ndarray, dur: float,
             fail: bool = False, via_mm: np.ndarray | None = None,
             tool: np.ndarray | None = None) -> int:
        """Queue a segment (``move_joints`` / ``move_linear``); its token.

        ``fail``: the robot stops with a fault on its way to this segment's end. ``via_mm``: for
        a MoveC, the circle point the TCP passes (mm). ``tool``: the instruction's
        ``T_flange_tcp`` (mm), the arm's tool from this segment on (None: unchanged).
        """
        with self._cond:
            self._issued += 1
            token = self._issued
            if fail:
                self.fail_token = token
            self._queue.append((token, kind, (j1, T1, dur, via_mm), tool))
            self._start_next()
            return token

    def wait(self, token: int, until: str, alive: Any) -> None:
        """Wait until segment ``token`` is ``started`` or ``done``; raise its motion fault.

        ``alive()`` is checked while waiting (it raises to end the program).
        """
        with self._cond:
            while True:
                if self._done >= token or (until == "started" and self._started >= token):
                    return
                if self._faulted and self._faulted <= token:
                    raise RapidError(ERR_MOTION, f"motion fault before segment {token} ended")
                alive()
                self._cond.wait(0.05)

    def last_target(self) -> np.ndarray:
        """Controller joints at the end of the queue (the start of the next segment)."""
        with self._cond:
            if self._queue:
                return np.array(self._queue[-1][2][0])
            m = self._motion
            return np.array(m["j1"]) if m is not None else self._joints.copy()

    def stop_and_clear(self) -> None:
        """StopMove + ClearPath: stop where the arm is, forget the queue."""
        with self._cond:
            if self._motion is not None:
                self._joints = self.current()[0]
                self._motion = None
            self._queue.clear()
            self._done = self._started = self._issued
            self._faulted = 0
            self.action_log.append("stop")
            self._cond.notify_all()

    def set_arc(self, on: bool) -> None:
        """The arc output written (SetDO doWeld): logged at every write, as SetDO writes."""
        with self._cond:
            self._arc = on
            self.action_log.append("arc_on" if on else "arc_off")
