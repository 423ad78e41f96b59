"""The mock controller's line layer: its ``mock://`` options and its seeded, faulty serial line.

:class:`MockLink` is the sans-I/O bottom of :class:`drivers.mock.mock_controller.MockController`:
bytes from the client go in through :meth:`MockLink.receive`, the bytes to write back come out of
:meth:`MockLink.run_due`, and everything in between runs from one clock-ordered schedule. The
faults injected on the line are seeded and apply in both directions: corrupted bytes, dropped and
duplicated lines, slow replies (``delay_ms``), a simulated baud rate (every byte takes 10/baud s
of real time) and a link drop after a received line (``disconnect``, only when served on a pty).
Each received line goes to :meth:`MockLink._process`, which the protocol server
(:mod:`drivers.mock.mock_server`) implements; the pty transport (:mod:`drivers.mock.mock_pty`)
implements
:meth:`MockLink._drop_link` and serves the line.
"""

from __future__ import annotations

import contextlib
import heapq
import itertools
import os
import random
import threading
import time
import urllib.parse
from collections.abc import Callable
from typing import Any

import numpy as np

from controller.errors import ConfigError
from drivers.abb import abb_codec as codec

#: ``mock://`` URL options and their meaning (values are validated by :func:`parse_mock_options`).
MOCK_OPTIONS: dict[str, str] = {
    "seed": "random seed of the fault injection (int)",
    "drop": "probability that a line is dropped, each direction (0..1)",
    "corrupt": "probability that a byte is corrupted, each direction (0..1)",
    "dup": "probability that a line is duplicated, each direction (0..1)",
    "delay_ms": "extra delay of every reply (ms, real time)",
    "baud": "simulated baud rate (0 = infinitely fast): every byte takes 10/baud s of real "
            "time in each direction (8N1), whatever time_scale is",
    "time_scale": "real seconds per simulated second (0 = instantaneous)",
    "disconnect": "probability that the link drops after a received line, its reply lost "
                  "(pty only; the pty comes back behind the same path)",
    "fail_at_point": "controller error when the weld reaches this path point (1-based)",
    "capacity": "path buffer capacity in points (default 250, as the RAPID module)",
}

DEFAULT_CAPACITY = 250


def parse_mock_options(query: str) -> dict[str, Any]:
    """``seed=7&drop=0.01`` to MockController keyword arguments.

    Raises :class:`ConfigError` for an unknown option (listing the known ones) or a bad value.
    """
    out: dict[str, Any] = {}
    for key, values in urllib.parse.parse_qs(query, keep_blank_values=True).items():
        if key not in MOCK_OPTIONS:
            raise ConfigError(f"unknown mock:// option {key!r}; known options: "
                              f"{', '.join(sorted(MOCK_OPTIONS))}")
        raw = values[-1]
        try:
            if key in ("seed", "baud", "fail_at_point", "capacity"):  # the integers
                out[key] = int(raw)
            else:
                out[key] = float(raw)
        except ValueError as err:
            raise ConfigError(f"mock:// option {key}={raw!r} is not a number") from err
    return out


class MockLink:
    """Options, the schedule and the fault-injected line of the mock controller. Thread-safe."""

    def __init__(self, *, seed: int = 0, drop: float = 0.0, corrupt: float = 0.0,
                 dup: float = 0.0, delay_ms: float = 0.0, baud: int = 0,
                 time_scale: float = 0.0, fail_at_point: int | None = None,
                 capacity: int = DEFAULT_CAPACITY, disconnect: float = 0.0) -> None:
        for name, p in (("drop", drop), ("corrupt", corrupt), ("dup", dup),
                        ("disconnect", disconnect)):
            if not 0.0 <= p <= 1.0:
                raise ConfigError(f"mock option {name}={p} must be a probability in 0..1")
        for name, v in (("delay_ms", delay_ms), ("baud", baud), ("time_scale", time_scale)):
            if not (np.isfinite(v) and v >= 0):
                raise ConfigError(f"mock option {name}={v} must be >= 0")
        if fail_at_point is not None and fail_at_point < 1:
            raise ConfigError(f"mock option fail_at_point={fail_at_point} must be >= 1")
        if not 1 <= capacity <= 9999:
            raise ConfigError(f"mock option capacity={capacity} must be in 1..9999")
        self.seed, self.drop, self.corrupt, self.dup = seed, drop, corrupt, dup
        self.disconnect_p = disconnect
        self.delay_s = delay_ms / 1000.0
        self.baud, self.time_scale = int(baud), float(time_scale)
        self.fail_at_point = fail_at_point
        self.capacity = int(capacity)
        self._rng = random.Random(seed)
        self._lock = threading.RLock()
        self._heap: list[tuple[float, int, Callable[[], None]]] = []
        self._counter = itertools.count()
        self._splitter = codec.LineSplitter()
        self._outbuf = bytearray()
        self._tx_free = 0.0
        self._now = time.monotonic()
        self.link_stats: dict[str, float] = {"bytes_rx": 0, "bytes_tx": 0, "lines_rx": 0,
                                             "lines_tx": 0, "bad_lines": 0, "requests": 0,
                                             "duplicates_suppressed": 0}
        # the serving thread and its wake-up pipe, set by the pty transport
        # (drivers/mock/mock_pty.py)
        self._thread: threading.Thread | None = None
        self._wake_r, self._wake_w = -1, -1

    def _process(self, line: bytes) -> None:
        """Execute one received line and send its reply (the protocol server implements it)."""
        raise NotImplementedError

    def _drop_link(self) -> None:
        """Drop the link after the current line (the pty transport implements it)."""
        raise NotImplementedError

    def link_time_s(self, baud: int) -> float:
        """Wire time (s) of all bytes so far at ``baud`` (8N1), both directions, stop-and-wait."""
        return 10.0 * (self.link_stats["bytes_rx"] + self.link_stats["bytes_tx"]) / baud

    # ---- scheduling and output -----------------------------------------------------------------

    def _schedule(self, delay_s: float, fn: Callable[[], None]) -> None:
        heapq.heappush(self._heap, (self._now + delay_s, next(self._counter), fn))
        self._wake()

    def _wake(self) -> None:
        if self._wake_w >= 0:
            with contextlib.suppress(BlockingIOError, OSError):
                os.write(self._wake_w, b"x")

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

    def _send(self, kind: str, seq: int, body: str, delay_s: float = 0.0) -> None:
        line = codec.encode_frame(kind, seq, body)
        self.link_stats["bytes_tx"] += len(line)
        self.link_stats["lines_tx"] += 1
        if self.drop and self._rng.random() < self.drop:
            return
        copies = 2 if self.dup and self._rng.random() < self.dup else 1
        for _ in range(copies):
            data = self._corrupt(line)
            start = max(self._now + delay_s, self._tx_free)
            self._tx_free = start + self._tx_time(len(data))
            heapq.heappush(self._heap, (self._tx_free, next(self._counter),
                                        lambda d=data: self._outbuf.extend(d)))  # type: ignore[misc]

    # ---- sans-I/O core: bytes in, bytes out ---------------------------------------------------

    def receive(self, data: bytes, now: float | None = None) -> None:
        """Bytes from the client (fault injection applied here), at monotonic time ``now``."""
        with self._lock:
            self._now = time.monotonic() if now is None else now
            for line in self._splitter.feed(self._corrupt(data)):
                self.link_stats["bytes_rx"] += len(line)
                self.link_stats["lines_rx"] += 1
                if self.drop and self._rng.random() < self.drop:
                    continue
                copies = 2 if self.dup and self._rng.random() < self.dup else 1
                for _ in range(copies):
                    self._schedule(self._tx_time(len(line)),
                                   lambda ln=line: self._process(ln))  # type: ignore[misc]
                if (self.disconnect_p and self._thread is not None
                        and self._rng.random() < self.disconnect_p):
                    # the line is executed, then the link drops before its reply is written
                    self._schedule(self._tx_time(len(line)), self._drop_link)

    def next_due(self) -> float | None:
        """Monotonic time of the next scheduled action (None when idle)."""
        with self._lock:
            return self._heap[0][0] if self._heap else None

    def run_due(self, now: float | None = None) -> bytes:
        """Run every action due by ``now``; return the bytes to write to the client."""
        with self._lock:
            t = time.monotonic() if now is None else now
            while self._heap and self._heap[0][0] <= t:
                due, _, fn = heapq.heappop(self._heap)
                self._now = max(due, self._now)
                fn()
            self._now = t
            out = bytes(self._outbuf)
            self._outbuf.clear()
            return out

    def exchange(self, data: bytes) -> bytes:
        """Feed ``data`` and run everything due now; for instantaneous mocks (time_scale 0)."""
        with self._lock:
            now = time.monotonic()
            self.receive(data, now)
            out = bytearray()
            while self._heap and self._heap[0][0] <= now:
                out += self.run_due(now)
            out += self.run_due(now)
            return bytes(out)
