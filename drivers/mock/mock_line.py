"""The mock controller's serial line: seeded fault injection, sans-I/O (bytes in, bytes out).

:class:`MockLine` splits the client's bytes into lines and hands each to :attr:`MockLine.on_line`
(the protocol server, :mod:`drivers.mock.mock_server`) when its wire time has passed; what the
server sends comes out of :meth:`MockLine.run_due` when due. The faults are seeded and apply in
both directions: corrupted bytes, dropped and duplicated lines, slow replies (``delay_ms``), a
simulated baud rate (every byte takes 10/baud s of real time) and a link drop after a received
line (``disconnect``: only while a transport serves the line and set :attr:`MockLine.on_drop`).
Usable alone: give it a :class:`~drivers.mock.mock_schedule.Schedule` and an ``on_line``.
"""

from __future__ import annotations

import random
import threading
import time
from collections.abc import Callable

import numpy as np

from controller.errors import ConfigError
from drivers.abb import abb_codec as codec
from drivers.mock.mock_schedule import Schedule


class MockLine:
    """A fault-injecting line between the client and the mock controller. Thread-safe."""

    def __init__(self, schedule: Schedule, *, seed: int = 0, drop: float = 0.0,
                 corrupt: float = 0.0, dup: float = 0.0, delay_ms: float = 0.0, baud: int = 0,
                 disconnect: float = 0.0) -> None:
        for name, p in (("drop", drop), ("corrupt", corrupt), ("dup", dup),
                        ("disconnect", disconnect)):
            if not 0.0 <= p <= 1.0:
                raise ConfigError(f"mock option {name}={p} must be a probability in 0..1")
        for name, v in (("delay_ms", delay_ms), ("baud", baud)):
            if not (np.isfinite(v) and v >= 0):
                raise ConfigError(f"mock option {name}={v} must be >= 0")
        self.schedule = schedule
        self.seed, self.drop, self.corrupt, self.dup = seed, drop, corrupt, dup
        self.disconnect_p = disconnect
        self.delay_s = delay_ms / 1000.0
        self.baud = int(baud)
        #: Receives each line that got through (the protocol server).
        self.on_line: Callable[[bytes], None] = lambda line: None
        #: Drops the link after a line (set by the transport while it serves; None otherwise).
        self.on_drop: Callable[[], None] | None = None
        self.stats: dict[str, float] = {"bytes_rx": 0, "bytes_tx": 0, "lines_rx": 0,
                                        "lines_tx": 0}
        self._rng = random.Random(seed)
        self._splitter = codec.LineSplitter()
        self._outbuf = bytearray()
        self._tx_free = 0.0

    @property
    def lock(self) -> threading.RLock:
        """The lock of the controller this line belongs to (its schedule's)."""
        return self.schedule.lock

    def _tx_time(self, n: int) -> float:
        return 10.0 * n / self.baud if self.baud else 0.0

    def _corrupt(self, data: bytes) -> bytes:
        if self.corrupt <= 0:
            return data
        out = bytearray(data)
        for i in range(len(out)):
            if self._rng.random() < self.corrupt:
                out[i] = (out[i] + self._rng.randrange(1, 256)) % 256
        return bytes(out)

    def send(self, kind: str, seq: int, body: str, delay_s: float = 0.0) -> None:
        """Queue a frame to the client ``delay_s`` after now, behind the bytes already queued."""
        line = codec.encode_frame(kind, seq, body)
        self.stats["bytes_tx"] += len(line)
        self.stats["lines_tx"] += 1
        if self.drop and self._rng.random() < self.drop:
            return
        copies = 2 if self.dup and self._rng.random() < self.dup else 1
        for _ in range(copies):
            data = self._corrupt(line)
            start = max(self.schedule.now + delay_s, self._tx_free)
            self._tx_free = start + self._tx_time(len(data))
            self.schedule.at(self._tx_free,
                             lambda d=data: self._outbuf.extend(d))  # type: ignore[misc]

    def clear(self) -> None:
        """Forget a partly received line (the link was dropped)."""
        self._splitter.clear()

    def receive(self, data: bytes, now: float | None = None) -> None:
        """Bytes from the client (fault injection applied here), at monotonic time ``now``."""
        with self.lock:
            self.schedule.now = time.monotonic() if now is None else now
            for line in self._splitter.feed(self._corrupt(data)):
                self.stats["bytes_rx"] += len(line)
                self.stats["lines_rx"] += 1
                if self.drop and self._rng.random() < self.drop:
                    continue
                copies = 2 if self.dup and self._rng.random() < self.dup else 1
                for _ in range(copies):
                    self.schedule.after(self._tx_time(len(line)),
                                        lambda ln=line: self.on_line(ln))  # type: ignore[misc]
                drop_link = self.on_drop
                if (self.disconnect_p and drop_link is not None
                        and self._rng.random() < self.disconnect_p):
                    # the line is executed, then the link drops before its reply is written
                    self.schedule.after(self._tx_time(len(line)), drop_link)

    def next_due(self) -> float | None:
        """Monotonic time of the next scheduled action (None when idle)."""
        return self.schedule.next_due()

    def run_due(self, now: float | None = None) -> bytes:
        """Run every action due by ``now``; return the bytes to write to the client."""
        with self.lock:
            self.schedule.run_due(time.monotonic() if now is None else now)
            out = bytes(self._outbuf)
            self._outbuf.clear()
            return out

    def exchange(self, data: bytes) -> bytes:
        """Feed ``data`` and run everything due now; for instantaneous mocks (time_scale 0)."""
        with self.lock:
            now = time.monotonic()
            self.receive(data, now)
            out = bytearray()
            while (due := self.next_due()) is not None and due <= now:
                out += self.run_due(now)
            out += self.run_due(now)
            return bytes(out)
