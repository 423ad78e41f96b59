"""The daemon's liveness for systemd's watchdog: check-ins and waits bounded by their own timeout.

The serve loop checks in between cycles; a long wait that is bounded by its own timeout (a cycle
state, a reconnect backoff) counts as alive until then. :meth:`Watchdog.run` pings systemd
(``WATCHDOG=1``) while the daemon is alive and stops pinging when it is not, so that systemd
restarts a daemon that hangs.
"""

from __future__ import annotations

import logging
import threading
import time

from controller.cell.sd_notify import notify

log = logging.getLogger(__name__)


class Watchdog:
    """When the serve loop last checked in and until when it is busy (monotonic s). Thread-safe."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._checked_in = time.monotonic()
        self._busy_until = 0.0

    def check_in(self) -> None:
        """The serve loop is alive now."""
        with self._lock:
            self._checked_in = time.monotonic()

    def busy(self, seconds: float) -> None:
        """The serve loop enters a wait bounded by ``seconds``: alive until it ends."""
        with self._lock:
            self._checked_in = time.monotonic()
            self._busy_until = self._checked_in + seconds

    def idle(self) -> None:
        """The bounded wait is over (the cycle ended)."""
        with self._lock:
            self._busy_until = 0.0

    def alive(self, interval_s: float, now: float | None = None) -> bool:
        """Checked in within two intervals, or inside a bounded wait (plus one interval)."""
        t = time.monotonic() if now is None else now
        with self._lock:
            return t - self._checked_in <= 2 * interval_s or t <= self._busy_until + interval_s

    def run(self, interval_s: float, stop: threading.Event) -> None:
        """Ping systemd's watchdog every ``interval_s`` while alive, until ``stop`` is set.

        A cycle state may last minutes (a weld); the cycle enforces that timeout itself, so a
        cycle stuck beyond it means the daemon hangs, and systemd restarts it.
        """
        while not stop.wait(interval_s):
            if self.alive(interval_s):
                notify("WATCHDOG=1")
            else:
                with self._lock:
                    silent = time.monotonic() - self._checked_in
                log.error("watchdog: the serve loop has not checked in for %.1f s; not pinging",
                          silent)
