"""The robot link transport: SGRS/1 (``docs/protocol.md``) over pyserial's ``serial_for_url``.

:class:`AbbLink` owns the port, the sequence numbers, the deadlines, retransmission and reconnects;
:class:`~drivers.abb.abb_robot.AbbRobot` is the :class:`~drivers.robot_interface.Robot` built on
it. The bytes are made and read by the sans-I/O :mod:`drivers.abb.abb_codec`.

This is the only module that catches ``serial.SerialException`` / ``OSError``; they leave it as
:class:`LinkError` ``from`` the original. Waiting is always against a monotonic deadline; the only
timed waits are the reconnect backoff (an interruptible ``Event.wait``).

Rules it keeps (protocol section 2-3): one request outstanding; a retransmission re-sends the same
line under the same seq, so the controller answers it from memory and never executes it twice; a
request is never re-issued under a new seq; after a reconnect the outstanding line is retransmitted
(same session); a controller restart (``ER 13``) fails the outstanding request with ``LinkError``
and is never papered over by replaying a motion.
"""

from __future__ import annotations

import collections
import contextlib
import logging
import threading
import time
from typing import Any

import serial

from controller.errors import LinkError, ProtocolError
from drivers.abb import abb_codec as codec
from drivers.robot_interface import Event, MotionHandle

log = logging.getLogger(__name__)

_READ_SLICE_S = 0.01  # port read timeout: the longest a single read blocks
_EVENT_NAMES = {"IP": "in_position", "PG": "progress", "DN": "done", "FL": "fault",
                "CY": "cycle_request"}


def line_time_s(n_bytes: int, baudrate: int) -> float:
    """Time (s) to send ``n_bytes`` at ``baudrate`` with 8N1 framing (10 bits per byte)."""
    return 10.0 * n_bytes / baudrate if baudrate > 0 else 0.0


class AbbLink:
    """Request/reply transport with sequence numbers, retransmission, events and reconnects.

    Constructing does no I/O; :meth:`open` opens the port. ``ack_timeout_s`` is how long one copy
    of a request waits for its reply before it is re-sent (default: two 80-character line times at
    ``baudrate`` plus 0.3 s of controller turnaround); ``retries`` bounds the re-sends.
    """

    def __init__(self, url: str, *, baudrate: int = 9600, ack_timeout_s: float | None = None,
                 retries: int = 6) -> None:
        self.url = url
        self.baudrate = int(baudrate)
        self.ack_timeout_s = (ack_timeout_s if ack_timeout_s is not None
                              else 0.3 + line_time_s(2 * (codec.MAX_LINE + 1), self.baudrate))
        self.retries = int(retries)
        self._port: Any = None
        self._lock = threading.RLock()
        # An urgent request (``AB``) is let in before any other taker of the lock: a thread that
        # waits for a motion takes and releases the lock in a tight loop, and a released RLock is
        # not handed to the thread that waited longest, so an abort could wait a whole weld.
        self._urgent = threading.Condition(threading.Lock())
        self._n_urgent = 0
        self._held_here = threading.local()
        self._closing = threading.Event()
        self._splitter = codec.LineSplitter()
        self._seq = 0
        self._last_event_seq: int | None = None
        self.events: collections.deque[Event] = collections.deque(maxlen=1000)
        self.handles: dict[int, MotionHandle] = {}
        self.stats = {"requests": 0, "retransmissions": 0, "bad_lines": 0, "stale_replies": 0,
                      "reconnects": 0, "bytes_out": 0, "bytes_in": 0, "events": 0}

    # -- port -----------------------------------------------------------------------------------

    def _open_port(self) -> None:
        try:
            self._port = serial.serial_for_url(self.url, baudrate=self.baudrate,
                                               timeout=_READ_SLICE_S, write_timeout=2.0)
        except (serial.SerialException, OSError, ValueError) as err:
            raise LinkError(f"cannot open robot link {self.url!r}: {err}; check the port or URL "
                            "(and that the controller or mock is running)", url=self.url) from err
        self._splitter.clear()

    @contextlib.contextmanager
    def hold(self, urgent: bool = False) -> Any:
        """The link's lock; an ``urgent`` taker goes before every non-urgent one that waits."""
        depth = getattr(self._held_here, "depth", 0)
        if urgent:
            with self._urgent:
                self._n_urgent += 1
            try:
                self._lock.acquire()
            finally:
                with self._urgent:
                    self._n_urgent -= 1
                    self._urgent.notify_all()
        else:
            if depth == 0:  # a thread that holds the lock already must not wait for itself
                with self._urgent:
                    self._urgent.wait_for(lambda: self._n_urgent == 0)
            self._lock.acquire()
        self._held_here.depth = depth + 1
        try:
            yield
        finally:
            self._held_here.depth = depth
            self._lock.release()

    def open(self) -> None:
        """Open the port (raises LinkError naming the URL when it cannot be opened)."""
        with self.hold():
            self._closing.clear()
            if self._port is None:
                self._open_port()

    def close(self) -> None:
        """Close the port; a reconnect in progress gives up."""
        self._closing.set()
        with self.hold(urgent=True):
            if self._port is not None:
                with contextlib.suppress(serial.SerialException, OSError):
                    self._port.close()
                self._port = None

    @property
    def is_open(self) -> bool:
        """True while the port is open."""
        return self._port is not None

    def _reconnect(self, deadline: float, reason: str) -> None:
        """Reopen the port with backoff until ``deadline``; LinkError when it never comes back."""
        log.warning("robot link %s lost (%s); reconnecting", self.url, reason)
        if self._port is not None:
            with contextlib.suppress(serial.SerialException, OSError):
                self._port.close()
            self._port = None
        backoff = 0.05
        last: Exception | None = None
        while not self._closing.is_set():
            try:
                self._open_port()
                self.stats["reconnects"] += 1
                return
            except LinkError as err:
                last = err
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                break
            self._closing.wait(min(backoff, remaining))
            backoff = min(1.0, backoff * 2)
        raise LinkError(f"robot link {self.url!r} lost ({reason}) and not back before the "
                        f"deadline: {last}", url=self.url)

    def _write(self, data: bytes, deadline: float) -> None:
        if self._port is None:
            self._reconnect(deadline, "port closed")
        try:
            self._port.write(data)
            self.stats["bytes_out"] += len(data)
        except (serial.SerialException, OSError) as err:
            self._reconnect(deadline, f"write failed: {err}")
            raise _Retry(f"write failed: {err}") from err

    def _read_lines(self, deadline: float) -> list[bytes]:
        """Lines that arrive before ``deadline`` (returns at the first non-empty batch)."""
        while True:
            if self._port is None:
                self._reconnect(deadline, "port closed")
            try:
                data = self._port.read(1)
                if data:
                    waiting = self._port.in_waiting
                    if waiting:
                        data += self._port.read(waiting)
            except (serial.SerialException, OSError) as err:
                self._reconnect(deadline, f"read failed: {err}")
                raise _Retry(f"read failed: {err}") from err
            if data:
                self.stats["bytes_in"] += len(data)
                lines = self._splitter.feed(data)
                if lines:
                    return lines
            if time.monotonic() >= deadline:
                return []

    # -- frames -----------------------------------------------------------------------------

    def _next_seq(self) -> int:
        self._seq = self._seq % 99 + 1
        return self._seq

    def _handle_event(self, frame: codec.Frame) -> bool:
        """Decode, de-duplicate and dispatch an event; True when it was new."""
        ev = codec.parse_event(frame)
        if ev.seq == self._last_event_seq:
            return False
        self._last_event_seq = ev.seq
        event = Event(kind=_EVENT_NAMES[ev.kind], mid=ev.mid, index=ev.index, code=ev.code,
                      job=ev.job)
        self.stats["events"] += 1
        self.events.append(event)
        h = self.handles.get(ev.mid) if ev.kind != "CY" else None
        if h is not None:
            with h._changed:
                if ev.kind == "PG":
                    h.progress = max(h.progress, ev.index)
                elif ev.kind in ("IP", "DN"):
                    h.progress = h.n_points
                    h.state = "done"
                elif ev.kind == "FL":
                    h.state = "aborted" if ev.code == 41 else "fault"
                    h.fault_code = ev.code
                    h.progress = max(h.progress, ev.index - 1)
                h._changed.notify_all()
        return True

    def _classify(self, line: bytes, seq: int | None) -> codec.Reply | str | None:
        """A reply for ``seq``, a reason to retransmit (str), or None (nothing for us)."""
        try:
            frame = codec.decode_frame(line)
            if frame.kind == "E":
                self._handle_event(frame)
                return None
            if frame.kind != "A":
                raise ProtocolError(f"unexpected {frame.kind} line from the controller")
            reply = codec.parse_reply(frame)
        except ProtocolError as err:
            self.stats["bad_lines"] += 1
            return f"unreadable line from the controller ({err})"
        if reply.seq == 0 and not reply.ok and reply.code == 10:
            return "the controller could not read the request (ER 10)"
        if seq is not None and reply.seq == seq:
            return reply
        self.stats["stale_replies"] += 1
        return None

    def request(self, body: str, timeout_s: float, urgent: bool = False) -> codec.Reply:
        """Send one request and return its reply (``OK`` or ``ER``), retransmitting as needed.

        An ``urgent`` request (the abort) takes the link before any waiting non-urgent one.

        Raises :class:`LinkError` when no reply came after ``retries`` re-sends or before
        ``timeout_s``, or when the controller restarted (``ER 13``); :class:`ProtocolError` when
        the request cannot be encoded.
        """
        with self.hold(urgent):
            seq = self._next_seq()
            line = codec.encode_frame("Q", seq, body)
            self.stats["requests"] += 1
            deadline = time.monotonic() + timeout_s
            attempts = 0
            last = "no reply"
            while attempts <= self.retries:
                if attempts:
                    self.stats["retransmissions"] += 1
                attempts += 1
                try:
                    self._write(line, deadline)
                    ack_deadline = min(deadline, time.monotonic() + self.ack_timeout_s)
                    outcome: codec.Reply | str | None = None
                    while outcome is None:
                        lines = self._read_lines(ack_deadline)
                        if not lines:
                            outcome = f"no reply within {self.ack_timeout_s:.3f} s"
                            break
                        reason = None
                        for raw in lines:  # every line: events after the reply count too
                            got = self._classify(raw, seq)
                            if isinstance(got, codec.Reply):
                                if not isinstance(outcome, codec.Reply):
                                    outcome = got
                            elif got is not None:
                                reason = got
                        if outcome is None:
                            outcome = reason
                except _Retry as err:
                    outcome = str(err)
                if isinstance(outcome, codec.Reply):
                    if not outcome.ok and outcome.code == 13:
                        raise LinkError(
                            f"the controller restarted (it answered {line.decode().strip()!r} "
                            f"with ER 13 "
                            f"{outcome.text}); nothing is replayed: read status, upload the path "
                            "again", request=line.decode().strip(), restarted=True)
                    return outcome
                last = outcome or last
                if time.monotonic() >= deadline:
                    break
            raise LinkError(f"no valid reply to {line.decode().strip()!r} after {attempts} "
                            f"tries within {timeout_s:.2f} s (last: {last}); the link returned "
                            "nothing usable", request=line.decode().strip(), attempts=attempts)

    def pump(self, max_s: float) -> int:
        """Read and dispatch incoming events for at most ``max_s`` seconds; returns lines read."""
        with self.hold():
            deadline = time.monotonic() + max_s
            n = 0
            try:
                lines = self._read_lines(deadline)
            except _Retry:
                return 0
            for raw in lines:
                self._classify(raw, None)
                n += 1
            return n


class _Retry(Exception):
    """Internal: the port failed and was reopened; re-send the outstanding line."""
