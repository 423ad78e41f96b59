"""The mock controller's protocol server: each SGRS/1 request executed on the simulated arm.

:class:`MockServer` is the RAPID server's logic (``drivers/abb/rapid/SGSERVER.mod``,
``docs/protocol.md``) between a line (:class:`drivers.mock.mock_line.MockLine`: it sends frames)
and an arm (:class:`drivers.mock.mock_arm.MockArm`): a received line (:meth:`MockServer.handle`)
is decoded with the sans-I/O codec, a repeated sequence number gets the remembered reply (never a
second execution), a request without a session is refused, and every request ``XY`` is handled by
``handlers["XY"]`` (the method ``_cmd_XY``), which returns the reply body (an ``OK`` or an ``ER``
with the protocol's error code). Work that must follow the reply (the start of a motion) is
appended to ``after``. The arm's events go out as ``E`` frames through :meth:`MockServer.event`.
The server owns the program's volatile data: session, path slots, the cycle request.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from controller.errors import ConfigError, InputError, ProtocolError, ReachabilityError
from controller.geometry.kinematics import (
    check_joint_limits,
    flange_pose,
    solve_ik_near,
)
from controller.geometry.poses import (
    Pose,
    invert,
    pos_quat_from_pose,
    pose_error,
    pose_from_pos_quat,
)
from controller.geometry.segment_motion import circle_through
from drivers.abb import abb_codec as codec
from drivers.mock.mock_arm import MockArm, Segment
from drivers.mock.mock_line import MockLine

F64 = NDArray[np.float64]

DEFAULT_CAPACITY = 250
_JOINT_SPEED_DEG_S = 100.0
Handler = Callable[[list[str], list[Callable[[], None]]], str]


class MockServer:
    """The SGRS/1 request handlers of the mock controller, serving ``line`` with ``arm``."""

    def __init__(self, arm: MockArm, line: MockLine, *,
                 capacity: int = DEFAULT_CAPACITY) -> None:
        if not 1 <= capacity <= 9999:
            raise ConfigError(f"mock option capacity={capacity} must be in 1..9999")
        self.arm, self.line = arm, line
        self.capacity = int(capacity)
        self.stats: dict[str, float] = {"bad_lines": 0, "requests": 0,
                                        "duplicates_suppressed": 0}
        #: Request name -> handler; a test may wrap one to inject a fault at that request.
        self.handlers: dict[str, Handler] = {
            n[len("_cmd_"):]: getattr(self, n) for n in dir(self) if n.startswith("_cmd_")}
        self.boot = 0
        self.reset()

    def reset(self) -> None:
        """Program start: no session, no path, no cycle request (the boot count goes up)."""
        self.boot += 1
        self.session: int | None = None
        self._last_seq: int | None = None
        self._last_reply = ""
        self._last_mid = 0
        self._event_seq = 0
        self._slot_pos: dict[int, F64] = {}
        self._slot_quat: dict[int, F64] = {}
        self._slot_joints: dict[int, tuple[Pose, F64 | None]] = {}
        self._slot_via: dict[int, F64] = {}
        self._path_n = 0
        self._snapshot: Pose | None = None
        self.cycle_job: str | None = None

    # ---- lines in, frames out ----------------------------------------------------------------

    def handle(self, line: bytes) -> None:
        """Execute one received line and send its reply (then start what follows the reply)."""
        try:
            frame = codec.decode_frame(line)
            if frame.kind != "Q" or frame.seq == 0:
                raise ProtocolError("not a request")
        except ProtocolError:
            self.stats["bad_lines"] += 1
            self.line.send("A", 0, codec.error_body(10, "bad line"), self.line.delay_s)
            return
        self.stats["requests"] += 1
        if self._last_seq is not None and frame.seq == self._last_seq:
            # Duplicate suppression: the remembered reply, never a second execution.
            self.stats["duplicates_suppressed"] += 1
            self.line.send("A", frame.seq, self._last_reply, self.line.delay_s)
            return
        after: list[Callable[[], None]] = []
        body = self._execute(frame.fields, after)
        if self.session is not None:
            self._last_seq, self._last_reply = frame.seq, body
        self.line.send("A", frame.seq, body, self.line.delay_s)
        for fn in after:
            fn()

    def event(self, *fields: object) -> None:
        """Send the event ``fields`` (e.g. ``"PG", mid, i``) under the next event number."""
        self._event_seq = (self._event_seq + 1) % 100
        self.line.send("E", self._event_seq, " ".join(str(f) for f in fields))

    def request_cycle(self, job: str) -> None:
        """The operator asks for a cycle of ``job``: latched, and a ``CY`` event is sent."""
        codec.check_job_name(job)
        with self.line.lock:
            self.line.schedule.now = time.monotonic()
            self.cycle_job = job
            self.event("CY", job)

    def _execute(self, f: list[str], after: list[Callable[[], None]]) -> str:
        cmd, args = f[0], f[1:]
        handler = self.handlers.get(cmd) if cmd.isalpha() and len(cmd) == 2 else None
        if handler is None:
            return codec.error_body(11, f"unknown request {cmd[:8]}")
        if self.session is None and cmd not in ("HI", "ID", "ST"):
            return codec.error_body(13, "no session")
        try:
            return handler(args, after)
        except ProtocolError as err:
            return codec.error_body(12, f"bad arguments to {cmd}: {str(err)[:20]}")

    def _start(self, mid: int, kind: str, segs: list[Segment], after: list[Callable[[], None]],
               **record: Any) -> None:
        self._last_mid = mid
        after.append(self.arm.start(mid, kind, segs, self.session, **record))

    def _target(self, k: int) -> Pose | None:
        """Slot ``k`` as ``T_base_flange`` (the slots hold TCP targets of the active tool)."""
        if k not in self._slot_pos or k not in self._slot_quat:
            return None
        T_base_tcp = pose_from_pos_quat(self._slot_pos[k], self._slot_quat[k])
        return T_base_tcp @ invert(self.arm.tool)

    # ---- the RAPID server's requests ---------------------------------------------------------

    @staticmethod
    def _nargs(args: list[str], n: int, cmd: str) -> None:
        if len(args) != n:
            raise ProtocolError(f"{cmd} takes {n}")

    def _cmd_HI(self, a: list[str], after: list[Callable[[], None]]) -> str:
        self._nargs(a, 1, "HI")
        s = codec.parse_int(a[0], "session", 1, 999)
        if s != self.session:
            self.session, self._last_seq, self._last_mid = s, None, 0
        return codec.ok_body(str(self.boot), str(self.arm.status_mid), self.arm.status_state)

    def _cmd_ID(self, a: list[str], after: list[Callable[[], None]]) -> str:
        self._nargs(a, 0, "ID")
        return codec.ok_body(codec.PROTOCOL_NAME, str(codec.PROTOCOL_VERSION), "IRB2400",
                             str(self.capacity))

    def _cmd_RJ(self, a: list[str], after: list[Callable[[], None]]) -> str:
        self._nargs(a, 0, "RJ")
        return codec.ok_body(codec.fmt_joints(self.arm.current()[0]))

    def _cmd_RP(self, a: list[str], after: list[Callable[[], None]]) -> str:
        self._nargs(a, 0, "RP")
        self._snapshot = self.arm.current()[1]
        return codec.ok_body(codec.fmt_position(self._snapshot[:3, 3]))

    def _cmd_RQ(self, a: list[str], after: list[Callable[[], None]]) -> str:
        self._nargs(a, 0, "RQ")
        snap = self._snapshot if self._snapshot is not None else self.arm.current()[1]
        return codec.ok_body(codec.fmt_quat(pos_quat_from_pose(snap)[1]))

    @staticmethod
    def _quat(a: list[str], name: str) -> F64:
        q = codec.parse_numbers(a, 4, name)
        if abs(float(np.linalg.norm(q)) - 1.0) > 1e-3:
            raise ProtocolError(f"{name} not unit")
        return q

    def _cmd_TP(self, a: list[str], after: list[Callable[[], None]]) -> str:
        p = codec.parse_numbers(a, 3, "tool position")
        self.arm.tool = pose_from_pos_quat(p, pos_quat_from_pose(self.arm.tool)[1])
        return codec.ok_body()

    def _cmd_TO(self, a: list[str], after: list[Callable[[], None]]) -> str:
        q = self._quat(a, "tool quaternion")
        self.arm.tool = pose_from_pos_quat(self.arm.tool[:3, 3], q)
        return codec.ok_body()

    def _cmd_SV(self, a: list[str], after: list[Callable[[], None]]) -> str:
        v, z = codec.parse_numbers(a, 2, "speed zone")
        if not (0 < v <= 1000 and 0 <= z <= 200):
            return codec.error_body(50, "speed or zone out of range")
        self.arm.speed_mm_s = float(v)  # the zone is checked, not modelled: points are exact
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

    def _cmd_XT(self, a: list[str], after: list[Callable[[], None]]) -> str:
        self._nargs(a, 8, "XT")
        k = self._slot(a[0])
        if k is None:
            return codec.error_body(24, "slot out of range")
        p = codec.parse_numbers(a[1:4], 3, "target position")
        self._slot_quat[k] = self._quat(a[4:], "target quaternion")
        self._slot_pos[k] = p
        self._solve_slot(k)
        return codec.ok_body()

    def _cmd_XC(self, a: list[str], after: list[Callable[[], None]]) -> str:
        self._nargs(a, 4, "XC")
        k = self._slot(a[0])
        if k is None or k < 1:
            return codec.error_body(24, "slot out of range")
        self._slot_via[k] = codec.parse_numbers(a[1:], 3, "circle point")
        return codec.ok_body()

    def _solve_slot(self, k: int) -> None:
        """IK of a completed path slot, near the previous point (the real server does it in RW).

        Done at upload so that RW answers at once; the result is cached with the tool it used.
        """
        T = self._target(k) if k > 0 else None
        if T is None:
            return
        near = self._slot_joints.get(k - 1, (None, None))[1] if k > 1 else self.arm.current()[0]
        try:
            j = solve_ik_near(self.arm.model, T, near)
        except ReachabilityError:
            j = None
        self._slot_joints[k] = (self.arm.tool, j)

    def _cmd_PN(self, a: list[str], after: list[Callable[[], None]]) -> str:
        self._nargs(a, 1, "PN")
        n = codec.parse_int(a[0], "path length", 1, 9999)
        if n > self.capacity:
            return codec.error_body(23, f"path of {n} exceeds buffer {self.capacity}")
        for d in (self._slot_pos, self._slot_quat, self._slot_joints):
            for k in [k for k in d if k > 0]:
                del d[k]
        self._slot_via.clear()
        self._path_n = n
        return codec.ok_body(str(n))

    def _motion_preamble(self, a: list[str], n: int, cmd: str) -> tuple[int, str | None]:
        self._nargs(a, n, cmd)
        mid = codec.parse_int(a[0], "motion id", 1, 9999)
        if self.arm.moving:
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
            j = check_joint_limits(self.arm.model, j)
        except (ReachabilityError, InputError):
            return codec.error_body(31, "joints outside limits")
        j0, T0 = self.arm.current()
        T1 = flange_pose(self.arm.model, j)
        dur = max(pose_error(T0, T1)[0] / self.arm.speed_mm_s,
                  float(np.max(np.abs(j - j0))) / _JOINT_SPEED_DEG_S)
        self._start(mid, "move_joints", [(j, T1, dur, None)], after,
                    target=[float(v) for v in j])
        return codec.ok_body(str(mid))

    def _cmd_ML(self, a: list[str], after: list[Callable[[], None]], cmd: str = "ML") -> str:
        mid, err = self._motion_preamble(a, 1, cmd)
        if err:
            return err
        T1 = self._target(0)
        if T1 is None:
            return codec.error_body(21, "target slot 0 incomplete")
        j0, T0 = self.arm.current()
        try:
            j1 = solve_ik_near(self.arm.model, T1, j0)  # the arm's configuration, continued
        except ReachabilityError:
            return codec.error_body(30, "target unreachable")
        self._slot_pos.pop(0, None)
        self._slot_quat.pop(0, None)
        self._start(mid, "move_linear", [(j1, T1, self.arm.seg_time(T0, T1), None)], after,
                    target=[float(v) for v in T1[:3, 3]])
        return codec.ok_body(str(mid))

    def _cmd_MT(self, a: list[str], after: list[Callable[[], None]]) -> str:
        """``XT 0`` and ``ML mid`` in one request; slot 0 is emptied when the move is refused."""
        self._nargs(a, 8, "MT")
        p = codec.parse_numbers(a[1:4], 3, "target position")
        self._slot_quat[0] = self._quat(a[4:], "target quaternion")
        self._slot_pos[0] = p
        reply = ""
        try:
            reply = self._cmd_ML(a[:1], after, "MT")
        finally:
            if not reply.startswith("OK"):
                self._slot_pos.pop(0, None)
                self._slot_quat.pop(0, None)
        return reply

    def _cmd_RW(self, a: list[str], after: list[Callable[[], None]]) -> str:
        mid, err = self._motion_preamble(a, 2, "RW")
        if err:
            return err
        arc = codec.parse_int(a[1], "arc", 0, 1) == 1
        n = self._path_n
        targets = [self._target(k) for k in range(1, n + 1)]
        if n == 0 or any(T is None for T in targets):
            return codec.error_body(22, "path incomplete")
        j_prev = self.arm.current()[0]
        segs = []
        for i, T in enumerate(targets, start=1):
            assert T is not None
            cached = self._slot_joints.get(i)
            if cached is not None and np.array_equal(cached[0], self.arm.tool):
                j = cached[1]
            else:
                try:
                    j = solve_ik_near(self.arm.model, T, j_prev)
                except ReachabilityError:
                    j = None
            if j is None:
                return codec.error_body(30, f"path point {i} unreachable")
            segs.append((j, T, 0.0, self._slot_via.get(i)))
            j_prev = j
        # a circle starts at the point before it (for point 1: where the robot is)
        T_prev = self.arm.current()[1]
        for i, (j, T, _, via) in enumerate(segs, start=1):
            if via is not None:
                tool = self.arm.tool
                try:
                    circle_through((T_prev @ tool)[:3, 3], via, (T @ tool)[:3, 3])
                except InputError:
                    return codec.error_body(12, f"circle point {i} makes no circle")
            segs[i - 1] = (j, T, self.arm.seg_time(T_prev, T, via), via)
            T_prev = T
        self._start(mid, "weld", segs, after, arc=arc, points=n)
        return codec.ok_body(str(mid))

    def _cmd_AB(self, a: list[str], after: list[Callable[[], None]]) -> str:
        self._nargs(a, 0, "AB")
        self.arm.abort()
        return codec.ok_body()

    def _cmd_ST(self, a: list[str], after: list[Callable[[], None]]) -> str:
        self._nargs(a, 0, "ST")
        return codec.ok_body("1" if self.arm.moving else "0", "1" if self.arm.arc_on else "0",
                             str(self.arm.status_mid), self.arm.status_state,
                             str(self.arm.status_index), str(self.arm.error), self.cycle_job or "-")

    def _cmd_CK(self, a: list[str], after: list[Callable[[], None]]) -> str:
        self._nargs(a, 0, "CK")
        self.cycle_job = None
        return codec.ok_body()
