"""The daemon's cycle requests: waiting in order (job, source), and the pause switch.

Requests come from the control socket (``ctl start``) and are taken by the serve loop, which
waits on :meth:`RequestQueue.next` at most a short while before it looks at the controller's own
events. ``ctl pause`` holds the queue (nothing is taken), ``ctl abort`` empties it.
"""

from __future__ import annotations

import collections
import threading


class RequestQueue:
    """Cycle requests waiting to run, first in first out. Thread-safe."""

    def __init__(self) -> None:
        self._changed = threading.Condition()
        self._pending: collections.deque[tuple[str, str]] = collections.deque()
        self._paused = False

    def __len__(self) -> int:
        with self._changed:
            return len(self._pending)

    @property
    def paused(self) -> bool:
        """True while ``ctl pause`` holds the queue."""
        with self._changed:
            return self._paused

    def put(self, job: str, source: str) -> int:
        """Queue a cycle of ``job`` requested by ``source``; returns the queue's length."""
        with self._changed:
            self._pending.append((job, source))
            self._changed.notify_all()
            return len(self._pending)

    def clear(self) -> int:
        """Drop every waiting request; returns how many were dropped."""
        with self._changed:
            n = len(self._pending)
            self._pending.clear()
            return n

    def set_paused(self, paused: bool) -> None:
        """Hold (True) or release (False) the queue."""
        with self._changed:
            self._paused = paused
            self._changed.notify_all()

    def wake(self) -> None:
        """Wake a waiting :meth:`next` (to look at a stop flag)."""
        with self._changed:
            self._changed.notify_all()

    def next(self, stop: threading.Event, timeout_s: float) -> tuple[str, str] | None:
        """The next request (job, source), waiting at most ``timeout_s`` for one.

        None when ``stop`` is set, the queue is paused, or nothing came in time.
        """
        with self._changed:
            self._changed.wait_for(lambda: stop.is_set() or (self._pending and not self._paused),
                                   timeout=timeout_s)
            if stop.is_set() or self._paused or not self._pending:
                return None
            return self._pending.popleft()
