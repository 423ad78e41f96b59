"""A mock ABB S4 controller running the seamguide RAPID server, for tests, dry runs and benches.

It speaks SGRS/1 (``docs/protocol.md``) byte for byte as ``drivers/rapid/SGSERVER.mod`` does, with
the same sans-I/O codec, and simulates an IRB 2400 with :mod:`controller.kinematics`: motions take
time at the commanded speed (times ``time_scale``; 0 makes them instantaneous, but completion is
still reported by an event after the reply), joint limits and unreachable targets are refused with
an error reply, the tool frame is applied, the arc output is switched, a path is executed point by
point with progress events. Fault injection, seeded: corrupted bytes, dropped and duplicated lines
(both directions), slow replies (``delay_ms``), a simulated baud rate (every byte takes 10/baud s
of real time; bytes are counted so :meth:`MockController.link_time_s` computes the wire time),
a controller error at path point N (``fail_at_point``), disconnects (:meth:`disconnect`) and
controller restarts (:meth:`restart`); the operator's cycle request is :meth:`request_cycle`.

It is served on a real pseudo-terminal (``os.openpty``) with a stable symlink path by
:meth:`MockController.serve_pty`, in a thread, so the client's pyserial code runs for real.

What it does not model: dynamics and acceleration (speed is constant, motion is linear in joints
for ``MJ`` and in Cartesian space for ``ML``/welds), zones (every point is reached exactly), the
axis 2/3 interaction limit, singularities along a linear move, the RAPID task's own timing, and
the serial line's electrical faults other than the byte errors above.
"""

from __future__ import annotations

import contextlib
import heapq
import itertools
import os
import random
import select
import tempfile
import threading
import time
import tty
import urllib.parse
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from controller.errors import ConfigError, InputError, ProtocolError, ReachabilityError
from controller.kinematics import check_joint_limits, flange_pose, irb2400, solve_ik
from controller.poses import (
    Pose,
    interpolate,
    invert,
    pos_quat_from_pose,
    pose_error,
    pose_from_pos_quat,
)
from drivers import abb_codec as codec

F64 = NDArray[np.float64]

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
HOME_DEG = (0.0, 0.0, 0.0, 0.0, 30.0, 0.0)
_JOINT_SPEED_DEG_S = 100.0
_ROT_SPEED_DEG_S = 90.0


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


class MockController:
    """The simulated controller. Thread-safe; inspect it with the properties below."""

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
        self._robot = irb2400()
        self._lock = threading.RLock()
        self._heap: list[tuple[float, int, Callable[[], None]]] = []
        self._counter = itertools.count()
        self._splitter = codec.LineSplitter()
        self._outbuf = bytearray()
        self._tx_free = 0.0
        self._now = time.monotonic()
        #: Every motion or weld the controller started: dicts with mid, kind, session, result...
        self.executed: list[dict[str, Any]] = []
        #: Ordered safety-relevant actions ("arc_on", "arc_off", "stop", "restart", ...).
        self.action_log: list[str] = []
        self.link_stats: dict[str, float] = {"bytes_rx": 0, "bytes_tx": 0, "lines_rx": 0,
                                             "lines_tx": 0, "bad_lines": 0, "requests": 0,
                                             "duplicates_suppressed": 0}
        self.boot = 0
        self._tool = np.eye(4)  # PERS tooldata on the controller: survives a restart
        self._reset_volatile()
        self._joints = np.array(HOME_DEG)
        # pty serving
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._wake_r, self._wake_w = -1, -1
        self._master = self._slave = -1
        self.link_path: str | None = None
        self._tmpdir: str | None = None
        self._swap_request = threading.Event()
        self._swap_done = threading.Event()

    # ---- state -------------------------------------------------------------------------------

    def _reset_volatile(self) -> None:
        """Program start: no session, no path, no motion, arc off (PERS boot count survives)."""
        self.boot += 1
        self.session: int | None = None
        self._last_seq: int | None = None
        self._last_reply = ""
        self._last_mid = 0
        self._event_seq = 0
        self._speed_mm_s = 100.0
        self._zone_mm = 0.0
        self._slot_pos: dict[int, F64] = {}
        self._slot_quat: dict[int, F64] = {}
        self._slot_joints: dict[int, tuple[Pose, F64 | None]] = {}
        self._path_n = 0
        self._snapshot: Pose | None = None
        self._motion: dict[str, Any] | None = None
        self._status_mid = 0
        self._status_state = "I"
        self._status_index = 0
        self._error = 0
        self._arc = False
        self.cycle_job: str | None = None

    @property
    def joints_deg(self) -> F64:
        """The arm's current controller axes (deg), interpolated during a motion."""
        with self._lock:
            return self._current()[0]

    def flange_pose(self) -> Pose:
        """The arm's actual ``T_base_flange`` (mm) now, interpolated during a motion."""
        with self._lock:
            return self._current()[1]

    @property
    def arc_on(self) -> bool:
        """The weld (arc) digital output."""
        with self._lock:
            return self._arc

    @property
    def tool(self) -> Pose:
        """The active tool ``T_flange_tcp`` (mm) as last set over the link."""
        with self._lock:
            return self._tool.copy()

    def link_time_s(self, baud: int) -> float:
        """Wire time (s) of all bytes so far at ``baud`` (8N1), both directions, stop-and-wait."""
        return 10.0 * (self.link_stats["bytes_rx"] + self.link_stats["bytes_tx"]) / baud

    def _current(self) -> tuple[F64, Pose]:
        m = self._motion
        if m is None or m["seg_t1"] <= m["seg_t0"]:
            return self._joints.copy(), flange_pose(self._robot, self._joints, check_limits=False)
        s = min(1.0, max(0.0, (time.monotonic() - m["seg_t0"]) / (m["seg_t1"] - m["seg_t0"])))
        j = (1 - s) * m["j0"] + s * m["j1"]
        if m["kind"] == "move_joints":
            return j, flange_pose(self._robot, j, check_limits=False)
        return j, interpolate(m["T0"], m["T1"], s)

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

    def _event(self, body: str) -> None:
        self._event_seq = (self._event_seq + 1) % 100
        self._send("E", self._event_seq, body)

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

    # ---- the RAPID server's logic -------------------------------------------------------------

    def _process(self, line: bytes) -> None:
        try:
            frame = codec.decode_frame(line)
            if frame.kind != "Q" or frame.seq == 0:
                raise ProtocolError("not a request")
        except ProtocolError:
            self.link_stats["bad_lines"] += 1
            self._send("A", 0, codec.error_body(10, "bad line"), self.delay_s)
            return
        self.link_stats["requests"] += 1
        if self._last_seq is not None and frame.seq == self._last_seq:
            # Duplicate suppression: the remembered reply, never a second execution.
            self.link_stats["duplicates_suppressed"] += 1
            self._send("A", frame.seq, self._last_reply, self.delay_s)
            return
        after: list[Callable[[], None]] = []
        body = self._execute(frame.fields, after)
        if self.session is not None:
            self._last_seq, self._last_reply = frame.seq, body
        self._send("A", frame.seq, body, self.delay_s)
        for fn in after:
            fn()

    def _execute(self, f: list[str], after: list[Callable[[], None]]) -> str:
        cmd, args = f[0], f[1:]
        handler = getattr(self, f"_cmd_{cmd}", None) if cmd.isalpha() and len(cmd) == 2 else None
        if handler is None:
            return codec.error_body(11, f"unknown request {cmd[:8]}")
        if self.session is None and cmd not in ("HI", "ID", "ST"):
            return codec.error_body(13, "no session")
        try:
            result: str = handler(args, after)
            return result
        except ProtocolError as err:
            return codec.error_body(12, f"bad arguments to {cmd}: {str(err)[:20]}")

    @staticmethod
    def _nargs(args: list[str], n: int, cmd: str) -> None:
        if len(args) != n:
            raise ProtocolError(f"{cmd} takes {n}")

    def _cmd_HI(self, a: list[str], after: list[Callable[[], None]]) -> str:
        self._nargs(a, 1, "HI")
        s = codec.parse_int(a[0], "session", 1, 999)
        if s != self.session:
            self.session, self._last_seq, self._last_mid = s, None, 0
        return codec.ok_body(str(self.boot), str(self._status_mid), self._status_state)

    def _cmd_ID(self, a: list[str], after: list[Callable[[], None]]) -> str:
        self._nargs(a, 0, "ID")
        return codec.ok_body(codec.PROTOCOL_NAME, str(codec.PROTOCOL_VERSION), "IRB2400",
                             str(self.capacity))

    def _cmd_RJ(self, a: list[str], after: list[Callable[[], None]]) -> str:
        self._nargs(a, 0, "RJ")
        return codec.ok_body(codec.fmt_joints(self._current()[0]))

    def _cmd_RP(self, a: list[str], after: list[Callable[[], None]]) -> str:
        self._nargs(a, 0, "RP")
        self._snapshot = self._current()[1]
        return codec.ok_body(codec.fmt_position(self._snapshot[:3, 3]))

    def _cmd_RQ(self, a: list[str], after: list[Callable[[], None]]) -> str:
        self._nargs(a, 0, "RQ")
        snap = self._snapshot if self._snapshot is not None else self._current()[1]
        return codec.ok_body(codec.fmt_quat(pos_quat_from_pose(snap)[1]))

    @staticmethod
    def _quat(a: list[str], name: str) -> F64:
        q = codec.parse_numbers(a, 4, name)
        if abs(float(np.linalg.norm(q)) - 1.0) > 1e-3:
            raise ProtocolError(f"{name} not unit")
        return q

    def _cmd_TP(self, a: list[str], after: list[Callable[[], None]]) -> str:
        p = codec.parse_numbers(a, 3, "tool position")
        self._tool = pose_from_pos_quat(p, pos_quat_from_pose(self._tool)[1])
        return codec.ok_body()

    def _cmd_TO(self, a: list[str], after: list[Callable[[], None]]) -> str:
        q = self._quat(a, "tool quaternion")
        self._tool = pose_from_pos_quat(self._tool[:3, 3], q)
        return codec.ok_body()

    def _cmd_SV(self, a: list[str], after: list[Callable[[], None]]) -> str:
        v, z = codec.parse_numbers(a, 2, "speed zone")
        if not (0 < v <= 1000 and 0 <= z <= 200):
            return codec.error_body(50, "speed or zone out of range")
        self._speed_mm_s, self._zone_mm = float(v), float(z)
        return codec.ok_body()

    def _slot(self, text: str) -> int | None:
        k = codec.parse_int(text, "slot")
        return k if k <= self.capacity else None

    def _cmd_XP(self, a: list[str], after: list[Callable[[], None]]) -> str:
        self._nargs(a, 4, "XP")
        k = self._slot(a[0])
        if k is None:
            return codec.error_body(24, "slot out of range")
        self._slot_pos[k] = codec.parse_numbers(a[1:], 3, "target position")
        self._slot_joints.pop(k, None)
        if k in self._slot_quat:
            self._solve_slot(k)
        return codec.ok_body()

    def _cmd_XO(self, a: list[str], after: list[Callable[[], None]]) -> str:
        self._nargs(a, 5, "XO")
        k = self._slot(a[0])
        if k is None:
            return codec.error_body(24, "slot out of range")
        self._slot_quat[k] = self._quat(a[1:], "target quaternion")
        self._solve_slot(k)
        return codec.ok_body()

    def _cmd_XR(self, a: list[str], after: list[Callable[[], None]]) -> str:
        self._nargs(a, 1, "XR")
        k = self._slot(a[0])
        if k is None:
            return codec.error_body(24, "slot out of range")
        if k < 2 or (k - 1) not in self._slot_quat:
            return codec.error_body(21, "no orientation to repeat")
        self._slot_quat[k] = self._slot_quat[k - 1].copy()
        self._solve_slot(k)
        return codec.ok_body()

    def _solve_slot(self, k: int) -> None:
        """IK of a completed path slot, near the previous point (the real server does it in RW).

        Done at upload so that RW answers at once; the result is cached with the tool it used.
        """
        T = self._target(k) if k > 0 else None
        if T is None:
            return
        near = self._slot_joints.get(k - 1, (None, None))[1] if k > 1 else self._current()[0]
        try:
            j = solve_ik(self._robot, T, near_deg=near)
        except ReachabilityError:
            j = None
        self._slot_joints[k] = (self._tool.copy(), j)

    def _cmd_PN(self, a: list[str], after: list[Callable[[], None]]) -> str:
        self._nargs(a, 1, "PN")
        n = codec.parse_int(a[0], "path length", 1, 9999)
        if n > self.capacity:
            return codec.error_body(23, f"path of {n} exceeds buffer {self.capacity}")
        for d in (self._slot_pos, self._slot_quat, self._slot_joints):
            for k in [k for k in d if k > 0]:
                del d[k]
        self._path_n = n
        return codec.ok_body(str(n))

    def _target(self, k: int) -> Pose | None:
        if k not in self._slot_pos or k not in self._slot_quat:
            return None
        T_base_tcp = pose_from_pos_quat(self._slot_pos[k], self._slot_quat[k])
        return T_base_tcp @ invert(self._tool)

    def _motion_preamble(self, a: list[str], n: int, cmd: str) -> tuple[int, str | None]:
        self._nargs(a, n, cmd)
        mid = codec.parse_int(a[0], "motion id", 1, 9999)
        if self._motion is not None:
            return mid, codec.error_body(20, "busy: a motion is running")
        if mid == self._last_mid:
            return mid, codec.error_body(25, f"motion {mid} already executed")
        return mid, None

    def _cmd_MJ(self, a: list[str], after: list[Callable[[], None]]) -> str:
        mid, err = self._motion_preamble(a, 7, "MJ")
        if err:
            return err
        j = codec.parse_numbers(a[1:], 6, "joints")
        try:
            j = check_joint_limits(self._robot, j)
        except (ReachabilityError, InputError):
            return codec.error_body(31, "joints outside limits")
        j0, T0 = self._current()
        T1 = flange_pose(self._robot, j)
        dur = max(pose_error(T0, T1)[0] / self._speed_mm_s,
                  float(np.max(np.abs(j - j0))) / _JOINT_SPEED_DEG_S)
        self._start(mid, "move_joints", [(j, T1, dur)], after, target=[float(v) for v in j])
        return codec.ok_body(str(mid))

    def _cmd_ML(self, a: list[str], after: list[Callable[[], None]]) -> str:
        mid, err = self._motion_preamble(a, 1, "ML")
        if err:
            return err
        T1 = self._target(0)
        if T1 is None:
            return codec.error_body(21, "target slot 0 incomplete")
        j0, T0 = self._current()
        try:
            j1 = solve_ik(self._robot, T1, near_deg=j0)
        except ReachabilityError:
            return codec.error_body(30, "target unreachable")
        self._slot_pos.pop(0, None)
        self._slot_quat.pop(0, None)
        self._start(mid, "move_linear", [(j1, T1, self._seg_time(T0, T1))], after,
                    target=[float(v) for v in T1[:3, 3]])
        return codec.ok_body(str(mid))

    def _seg_time(self, T0: Pose, T1: Pose) -> float:
        d_mm, d_deg = pose_error(T0, T1)
        return max(d_mm / self._speed_mm_s, d_deg / _ROT_SPEED_DEG_S)

    def _cmd_RW(self, a: list[str], after: list[Callable[[], None]]) -> str:
        mid, err = self._motion_preamble(a, 2, "RW")
        if err:
            return err
        arc = codec.parse_int(a[1], "arc", 0, 1) == 1
        n = self._path_n
        targets = [self._target(k) for k in range(1, n + 1)]
        if n == 0 or any(T is None for T in targets):
            return codec.error_body(22, "path incomplete")
        j_prev, T_prev = self._current()
        segs = []
        for i, T in enumerate(targets, start=1):
            assert T is not None
            cached = self._slot_joints.get(i)
            if cached is not None and np.array_equal(cached[0], self._tool):
                j = cached[1]
            else:
                try:
                    j = solve_ik(self._robot, T, near_deg=j_prev)
                except ReachabilityError:
                    j = None
            if j is None:
                return codec.error_body(30, f"path point {i} unreachable")
            segs.append((j, T, self._seg_time(T_prev, T)))
            j_prev, T_prev = j, T
        self._start(mid, "weld", segs, after, arc=arc, points=n)
        return codec.ok_body(str(mid))

    def _cmd_AB(self, a: list[str], after: list[Callable[[], None]]) -> str:
        self._nargs(a, 0, "AB")
        self._arc = False  # arc output off FIRST (always written, as SetDO does)
        self.action_log.append("arc_off")
        self.action_log.append("stop")
        m = self._motion
        if m is not None:
            j, T = self._current()
            self._joints = j
            self._finish(m, "A", 41, "aborted")
            self._event(f"FL {m['mid']} 41 {m['index'] + 1}")
        return codec.ok_body()

    def _cmd_ST(self, a: list[str], after: list[Callable[[], None]]) -> str:
        self._nargs(a, 0, "ST")
        return codec.ok_body("1" if self._motion is not None else "0", "1" if self._arc else "0",
                             str(self._status_mid), self._status_state,
                             str(self._status_index), str(self._error), self.cycle_job or "-")

    def _cmd_CK(self, a: list[str], after: list[Callable[[], None]]) -> str:
        self._nargs(a, 0, "CK")
        self.cycle_job = None
        return codec.ok_body()

    # ---- motion simulation ---------------------------------------------------------------------

    def _set_arc(self, on: bool) -> None:
        if self._arc != on:
            self._arc = on
            self.action_log.append("arc_on" if on else "arc_off")

    def _start(self, mid: int, kind: str, segs: list[tuple[F64, Pose, float]],
               after: list[Callable[[], None]], **record: Any) -> None:
        self._last_mid = mid
        self._status_mid, self._status_state, self._status_index, self._error = mid, "R", 0, 0
        entry = {"mid": mid, "kind": kind, "session": self.session, "result": "running",
                 "points_reached": 0, **record}
        self.executed.append(entry)
        j0, T0 = self._current()
        m = {"mid": mid, "kind": kind, "segs": segs, "index": 0, "entry": entry, "j0": j0,
             "T0": T0, "j1": j0, "T1": T0, "seg_t0": 0.0, "seg_t1": 0.0}
        self._motion = m

        def begin() -> None:
            if self._motion is not m:
                return
            if kind == "weld" and record.get("arc"):
                self._set_arc(True)
            self._next_segment(m)

        after.append(begin)

    def _next_segment(self, m: dict[str, Any]) -> None:
        j1, T1, dur = m["segs"][m["index"]]
        if m["index"] > 0 or m["kind"] != "weld":
            m["j0"], m["T0"] = self._current()
        m["j1"], m["T1"] = j1, T1
        m["seg_t0"] = self._now
        m["seg_t1"] = self._now + dur * self.time_scale
        self._schedule(dur * self.time_scale, lambda: self._reach(m))

    def _reach(self, m: dict[str, Any]) -> None:
        if self._motion is not m:
            return  # aborted or replaced meanwhile
        i = m["index"] + 1
        if m["kind"] == "weld" and self.fail_at_point is not None and i == self.fail_at_point:
            self._set_arc(False)
            self.action_log.append("stop")
            self._joints = self._current()[0]
            self._finish(m, "F", 40, "fault")
            self._event(f"FL {m['mid']} 40 {i}")
            return
        self._joints = np.array(m["j1"], dtype=np.float64)
        m["index"] = i
        m["entry"]["points_reached"] = i
        self._status_index = i if m["kind"] == "weld" else 0
        if i < len(m["segs"]):
            self._event(f"PG {m['mid']} {i}")
            self._next_segment(m)
            return
        if m["kind"] == "weld":
            self._event(f"PG {m['mid']} {i}")
            self._set_arc(False)
            self._finish(m, "D", 0, "done")
            self._event(f"DN {m['mid']}")
        else:
            self._finish(m, "D", 0, "done")
            self._event(f"IP {m['mid']}")

    def _finish(self, m: dict[str, Any], state: str, error: int, result: str) -> None:
        self._motion = None
        self._status_state, self._error = state, error
        m["entry"]["result"] = result

    # ---- operator and faults -------------------------------------------------------------------

    def request_cycle(self, job: str) -> None:
        """The operator asks for a cycle of ``job``: latched, and a ``CY`` event is sent."""
        codec.check_job_name(job)
        with self._lock:
            self._now = time.monotonic()
            self.cycle_job = job
            self._event(f"CY {job}")
            self._wake()

    def restart(self) -> None:
        """Simulate a controller restart: motion stopped (arc off), session and path forgotten."""
        with self._lock:
            self._now = time.monotonic()
            self._set_arc(False)
            m = self._motion
            if m is not None:
                self._joints = self._current()[0]
                m["entry"]["result"] = "restart"
            self.action_log.append("restart")
            self._heap = []
            self._reset_volatile()

    def _drop_link(self) -> None:
        self._swap_done.clear()
        self._swap_request.set()

    def disconnect(self, timeout_s: float = 2.0, wait: bool = True) -> None:
        """Drop the link: close the pty and open a new one behind the same symlink path.

        The controller state (session, remembered reply, motion) survives, as when a cable is
        pulled and plugged back; replies not yet written are lost. Only for a mock served with
        :meth:`serve_pty`. ``wait=False`` returns at once (for use inside the mock's own thread).
        """
        if self._thread is None:
            raise ConfigError("disconnect() needs a mock served on a pty (serve_pty)")
        self._swap_done.clear()
        self._swap_request.set()
        self._wake()
        if wait and not self._swap_done.wait(timeout_s):
            raise ConfigError("mock controller did not swap its pty in time")

    # ---- serving on a pseudo-terminal ----------------------------------------------------------

    def _open_pty(self) -> str:
        master, slave = os.openpty()
        tty.setraw(slave)
        os.set_blocking(master, False)
        self._master, self._slave = master, slave
        return os.ttyname(slave)

    def _point_link(self, target: str) -> None:
        assert self.link_path is not None
        tmp = f"{self.link_path}.{os.getpid()}.tmp"
        if os.path.lexists(tmp):
            os.unlink(tmp)
        os.symlink(target, tmp)
        os.replace(tmp, self.link_path)

    def serve_pty(self, link_path: str | None = None) -> str:
        """Serve on a new pseudo-terminal in a thread; return the stable symlink path to open.

        ``link_path`` (default: a new temporary directory's ``robot``) must not be an existing
        non-symlink file. Stop with :meth:`stop`.
        """
        if self._thread is not None:
            raise ConfigError("this mock controller is already serving")
        if link_path is None:
            self._tmpdir = tempfile.mkdtemp(prefix="seamguide-mock-")
            link_path = str(Path(self._tmpdir) / "robot")
        lp = Path(link_path)
        if lp.exists() and not lp.is_symlink():
            raise ConfigError(f"--link {link_path!r} exists and is not a symlink; choose another "
                              "path (the mock makes a symlink to its pseudo-terminal there)")
        self.link_path = str(lp.absolute())
        self._point_link(self._open_pty())
        self._wake_r, self._wake_w = os.pipe()
        os.set_blocking(self._wake_r, False)
        os.set_blocking(self._wake_w, False)
        self._stop.clear()
        self._thread = threading.Thread(target=self._serve, name="mock-controller", daemon=True)
        self._thread.start()
        return self.link_path

    def _serve(self) -> None:
        pending = b""
        while not self._stop.is_set():
            pending += self.run_due()
            if self._swap_request.is_set():  # after run_due: replies not yet written are lost
                self._swap_request.clear()
                with self._lock:
                    old = (self._master, self._slave)
                    name = self._open_pty()  # before closing: a new /dev/pts number
                    for fd in old:
                        os.close(fd)
                    pending = b""
                    self._splitter.clear()
                    self._point_link(name)
                    self.action_log.append("disconnect")
                self._swap_done.set()
            if pending:
                try:
                    n = os.write(self._master, pending)
                    pending = pending[n:]
                except BlockingIOError:
                    pass
                except OSError:
                    pending = b""
            due = self.next_due()
            now = time.monotonic()
            wait = 0.2 if due is None else max(0.0, min(0.2, due - now))
            if pending:
                wait = min(wait, 0.005)
            try:
                ready, _, _ = select.select([self._master, self._wake_r], [], [], wait)
            except (OSError, ValueError):
                continue
            if self._wake_r in ready:
                with contextlib.suppress(BlockingIOError):
                    os.read(self._wake_r, 4096)
            if self._master in ready:
                try:
                    data = os.read(self._master, 4096)
                except (BlockingIOError, OSError):
                    data = b""
                if data:
                    self.receive(data)

    def stop(self) -> None:
        """Stop serving and remove the symlink (and the temporary directory it made)."""
        if self._thread is None:
            return
        self._stop.set()
        self._wake()
        self._thread.join(timeout=5.0)
        self._thread = None
        for fd in (self._master, self._slave, self._wake_r, self._wake_w):
            with contextlib.suppress(OSError):
                os.close(fd)
        self._master = self._slave = self._wake_r = self._wake_w = -1
        if self.link_path and os.path.islink(self.link_path):
            os.unlink(self.link_path)
        if self._tmpdir:
            with contextlib.suppress(OSError):
                os.rmdir(self._tmpdir)
            self._tmpdir = None

    def __enter__(self) -> MockController:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


def open_mock_robot(url: str, *, limits: Any = None, timeout_s: float = 5.0,
                    **link_options: Any) -> Any:
    """``mock://?opts``: a MockController on a pty and an AbbRobot on it (``robot.mock``).

    The client's ack timeout and status poll are set from the mock's simulated speeds unless given.
    The mock is stopped when the robot is closed. Raises :class:`ConfigError` for bad options.
    """
    from drivers.abb_link import AbbRobot, line_time_s

    parsed = urllib.parse.urlsplit(url)
    if parsed.netloc or parsed.path not in ("", "/"):
        raise ConfigError(f"mock URL {url!r} takes options only: mock://?seed=7&drop=0.01")
    mock = MockController(**parse_mock_options(parsed.query))
    wire = line_time_s(2 * (codec.MAX_LINE + 1), mock.baud)
    link_options.setdefault("ack_timeout_s", 0.15 + mock.delay_s + wire)
    link_options.setdefault("status_poll_s", max(0.3, 4 * link_options["ack_timeout_s"]))
    link_options.setdefault("session", 1 + mock.seed % 999)
    robot = AbbRobot("mock://", limits=limits, timeout_s=timeout_s, **link_options)
    robot.mock = mock
    robot.prepare = mock.serve_pty
    robot._owned.append(mock)
    return robot
