"""The mock controller's clock: actions ordered by due time, and the one lock of its parts.

The fault-injected line (:mod:`drivers.mock.mock_line`) puts its delayed lines and bytes here, the
simulated arm (:mod:`drivers.mock.mock_arm`) the ends of its motion segments; whoever serves the
controller (a test calling :meth:`Schedule.run_due`, or the pseudo-terminal thread of
:mod:`drivers.mock.mock_pty`) runs what is due. Times are ``time.monotonic()`` seconds.
"""

from __future__ import annotations

import heapq
import itertools
import threading
import time
from collections.abc import Callable


class Schedule:
    """Clock-ordered actions of one mock controller; every part of it locks :attr:`lock`."""

    def __init__(self) -> None:
        self.lock = threading.RLock()
        #: The simulated present (monotonic s): the due time of the action running, else the
        #: time of the last receive or run.
        self.now = time.monotonic()
        #: Called after an action is added (the pty thread's wake-up; None when nobody serves).
        self.on_change: Callable[[], None] | None = None
        self._heap: list[tuple[float, int, Callable[[], None]]] = []
        self._counter = itertools.count()

    def at(self, t: float, fn: Callable[[], None]) -> None:
        """Run ``fn`` at monotonic time ``t`` (after the actions already due then)."""
        heapq.heappush(self._heap, (t, next(self._counter), fn))
        if self.on_change is not None:
            self.on_change()

    def after(self, delay_s: float, fn: Callable[[], None]) -> None:
        """Run ``fn`` ``delay_s`` seconds after :attr:`now`."""
        self.at(self.now + delay_s, fn)

    def next_due(self) -> float | None:
        """Monotonic time of the next action (None when idle)."""
        with self.lock:
            return self._heap[0][0] if self._heap else None

    def run_due(self, t: float) -> None:
        """Run every action due by ``t``, in order; :attr:`now` is each one's due time."""
        with self.lock:
            while self._heap and self._heap[0][0] <= t:
                due, _, fn = heapq.heappop(self._heap)
                self.now = max(due, self.now)
                fn()
            self.now = t

    def clear(self) -> None:
        """Forget every pending action (a controller restart)."""
        with self.lock:
            self._heap = []
