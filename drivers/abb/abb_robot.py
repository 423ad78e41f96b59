"""The :class:`~drivers.robot_interface.Robot` for the seamguide RAPID server, over an AbbLink.

:class:`AbbRobot` turns each interface call into validated commands
(:mod:`drivers.robot_commands`, checked before a byte is encoded) and SGRS/1 requests
(``docs/protocol.md``) sent by :class:`~drivers.abb.abb_link.AbbLink`; it maps ``ER`` replies to
the product's exceptions and follows motions by their events (or by ``ST`` when an event is lost).
The real controller and the mock controller are driven by this same class.
"""

from __future__ import annotations

import contextlib
import random
import time
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from controller.errors import (
    InputError,
    LinkError,
    ProtocolError,
    RobotFault,
    SafetyError,
)
from controller.geometry.poses import Pose, pos_quat_from_pose, pose_error, pose_from_pos_quat
from drivers.abb import abb_codec as codec
from drivers.abb.abb_errors import raise_for
from drivers.abb.abb_link import AbbLink
from drivers.robot_commands import (
    MoveJoints,
    MoveLinear,
    PathTargets,
    SafetyLimits,
    ToolData,
    WeldRun,
)
from drivers.robot_interface import DEFAULT_TIMEOUT_S, Event, MotionHandle, MotionTimeout, Robot

_PUMP_SLICE_S = 0.05  # longest a waiter holds the link lock (abort() gets in between)
# how close the last linear move's target must be to a path's start for a circle from it
_AT_START_MM, _AT_START_DEG = 0.01, 0.01


class AbbRobot(Robot):
    """:class:`Robot` over an :class:`AbbLink` to the RAPID server (or the mock controller).

    ``timeout_s`` bounds each request (retransmissions included); ``status_poll_s`` is how long a
    waiter goes without an event before it asks ``ST`` (recovers a lost completion event).
    Construct with :func:`drivers.robot.open_robot`; no I/O happens before :meth:`open`.
    """

    def __init__(self, url: str, *, limits: SafetyLimits | None = None,
                 timeout_s: float = DEFAULT_TIMEOUT_S, baudrate: int = 9600,
                 ack_timeout_s: float | None = None, retries: int = 6,
                 status_poll_s: float = 1.0, session: int | None = None,
                 weld_zone_mm: float = 1.0) -> None:
        self.limits = limits if limits is not None else SafetyLimits()
        self.timeout_s = float(timeout_s)
        self.status_poll_s = float(status_poll_s)
        self.weld_zone_mm = float(weld_zone_mm)
        self.link = AbbLink(url, baudrate=baudrate, ack_timeout_s=ack_timeout_s, retries=retries)
        self.session = session if session is not None else random.SystemRandom().randint(1, 999)
        self._mid = 0
        self._tool = ToolData(np.eye(4))
        self._path_len = 0
        self._path_start: np.ndarray | None = None  # where a circle to path point 1 starts
        self._last_linear: tuple[MotionHandle, np.ndarray] | None = None
        self._speed_zone = ""  # the last SV the controller accepted ("": unknown, send it)
        self._near: np.ndarray | None = None  # joints near the robot's: seeds the reach checks
        self._capacity = 0
        self._info: dict[str, Any] = {}
        self._last_status_t = 0.0
        self._owned: list[Any] = []  # things closed with the robot (an in-process mock)
        #: Called by open() before the port is opened; returns the URL to open (mock:// uses it
        #: to start its pseudo-terminal, so no I/O happens in the constructor).
        self.prepare: Any = None

    # -- plumbing -------------------------------------------------------------------------------

    def _call(self, body: str, timeout_s: float | None = None,
              urgent: bool = False) -> tuple[str, ...]:
        t = self.timeout_s if timeout_s is None else timeout_s
        try:
            reply = self.link.request(body, t, urgent)
        except LinkError as err:
            if err.details.get("restarted"):
                self._recover_after_restart()
            raise
        raise_for(reply, body)
        return reply.data

    def _recover_after_restart(self) -> None:
        """New session after a controller restart; the tool goes again, the path does not.

        The controller keeps its tool in a PERS variable, which survives a restart with whatever
        value it had; sending ours again keeps the two in step. The path is gone: ``run_weld``
        refuses until it is uploaded again. Nothing that moves is sent.
        """
        self._path_len = 0
        self._path_start = None
        self._last_linear = None
        self._speed_zone = ""  # the program restarted with its own speed and zone
        self.link._last_event_seq = None  # the controller numbers its events from 1 again
        self._hello()
        if not np.array_equal(self._tool.T_flange_tcp, np.eye(4)):
            p, q = pos_quat_from_pose(self._tool.T_flange_tcp)
            self._call(f"TP {codec.fmt_position(p, trim=True)}")
            self._call(f"TO {codec.fmt_quat(q, trim=True)}")

    def _hello(self) -> None:
        data = self._call(f"HI {self.session}")
        if len(data) != 3:
            raise ProtocolError(f"reply to HI has {len(data)} fields, expected 3: {data!r}")
        self._info["boot"] = codec.parse_int(data[0], "boot count")

    def _next_mid(self) -> int:
        self._mid = self._mid % 9999 + 1
        return self._mid

    def _handle(self, mid: int, kind: str, n_points: int = 0) -> MotionHandle:
        h = MotionHandle(mid=mid, kind=kind, n_points=n_points, _waiter=self._wait_motion)
        with self.link.hold():
            # Keep the registry small: only motions that may still report.
            self.link.handles = {m: x for m, x in self.link.handles.items()
                                 if x.state == "running"}
            self.link.handles[mid] = h
        return h

    # -- Robot ----------------------------------------------------------------------------------

    def open(self) -> None:
        """Open the port, start the session (``HI``) and identify the controller (``ID``).

        When that fails, the port is closed again (and a mock this robot owns stopped) before
        the error is raised: a daemon retrying a controller that does not answer would otherwise
        leave one open port (and one mock's thread) behind per attempt.
        """
        try:
            self._open()
        except BaseException:
            with contextlib.suppress(Exception):  # the error that ended open() is the one to see
                self.close()
            raise

    def _open(self) -> None:
        if self.prepare is not None and not self.link.is_open:
            self.link.url = self.prepare()
        self._speed_zone = ""  # whatever the controller holds, we have not set it yet
        self.link.open()
        self._hello()
        data = self._call("ID")
        if len(data) != 4 or data[0] != codec.PROTOCOL_NAME:
            raise ProtocolError(f"the controller on {self.link.url!r} is not a seamguide server: "
                                f"ID answered {' '.join(data)!r}")
        version = codec.parse_int(data[1], "protocol version")
        if version != codec.PROTOCOL_VERSION:
            raise ProtocolError(f"the controller speaks {codec.PROTOCOL_NAME}/{version}, this "
                                f"client {codec.PROTOCOL_NAME}/{codec.PROTOCOL_VERSION}; load the "
                                "RAPID module shipped with this version")
        self._capacity = codec.parse_int(data[3], "path capacity", 1, 9999)
        self._info.update(protocol=data[0], version=version, robot=data[2],
                          path_capacity=self._capacity, session=self.session)

    def close(self) -> None:
        """Close the link (and stop an in-process mock this robot owns)."""
        self.link.close()
        for thing in self._owned:  # stop() is idempotent; open() serves the mock again
            thing.stop()

    def identify(self) -> dict[str, Any]:
        """``ID`` again (a cheap ping) and the session facts."""
        self._call("ID")
        return dict(self._info)

    def read_joints(self) -> np.ndarray:
        """Controller axes (deg), shape (6,)."""
        return codec.parse_numbers(list(self._call("RJ")), 6, "joints reply")

    def read_pose(self) -> Pose:
        """``T_base_flange`` (mm; tool0, wobj0) from one controller snapshot (``RP`` + ``RQ``)."""
        p = codec.parse_numbers(list(self._call("RP")), 3, "pose position reply")
        q = codec.parse_numbers(list(self._call("RQ")), 4, "pose orientation reply")
        try:
            return pose_from_pos_quat(p, q, "controller pose")
        except InputError as err:
            raise ProtocolError(f"the controller reported an invalid pose: {err}") from err

    def set_tool(self, T_flange_tcp: ArrayLike) -> None:
        """Send the tool frame (``TP``, ``TO``); later targets are TCP poses with this tool."""
        tool = ToolData(np.asarray(T_flange_tcp, dtype=np.float64))
        p, q = pos_quat_from_pose(tool.T_flange_tcp)
        self._call(f"TP {codec.fmt_position(p, trim=True)}")
        self._call(f"TO {codec.fmt_quat(q, trim=True)}")
        self._tool = tool

    def _set_speed(self, speed_mm_s: float) -> None:
        """``SV`` unless the controller already holds this speed and the weld zone (sent by us).

        The zone is always :attr:`weld_zone_mm`: only the weld pass's segments use it (``MJ`` and
        ``ML`` end in a fine point), so a move and the weld at the same speed need one ``SV``.
        The controller keeps both until the next ``SV`` or a program restart (which the client
        detects and forgets them on); a request that failed leaves them unknown, so sent again.
        """
        zone = codec.fmt(self.weld_zone_mm, 1, trim=True)
        body = f"SV {codec.fmt(speed_mm_s, 1, trim=True)} {zone}"
        if body != self._speed_zone:
            self._speed_zone = ""
            self._call(body)
            self._speed_zone = body

    def move_joints(self, joints_deg: ArrayLike, speed_mm_s: float = 100.0) -> MotionHandle:
        """Check, then ``SV`` + ``MJ``; the handle completes on ``IP``."""
        cmd = MoveJoints(np.asarray(joints_deg, dtype=np.float64), speed_mm_s)
        cmd.check(self.limits, self._tool)
        self._near = cmd.joints_deg
        self._set_speed(cmd.speed_mm_s)
        mid = self._next_mid()
        h = self._handle(mid, "move_joints")
        self._call(f"MJ {mid} {codec.fmt_joints(cmd.joints_deg, trim=True)}")
        return h

    def move_linear(self, T_base_tcp: ArrayLike, speed_mm_s: float = 100.0) -> MotionHandle:
        """Check, then ``SV`` + ``MT`` (or ``XT 0`` / ``XP 0`` + ``XO 0``, then ``ML``); ``IP``."""
        cmd = MoveLinear(np.asarray(T_base_tcp, dtype=np.float64), speed_mm_s)
        self._near = cmd.check(self.limits, self._tool, self._near)
        p, q = pos_quat_from_pose(cmd.T_base_tcp)
        self._set_speed(cmd.speed_mm_s)
        mid = self._next_mid()
        *target, move = codec.linear_move_bodies(mid, p, q)
        for body in target:
            self._call(body)
        h = self._handle(mid, "move_linear")
        self._call(move)
        self._last_linear = (h, cmd.T_base_tcp.copy())
        return h

    def upload_path(self, targets: Sequence[ArrayLike],
                    circle_points_mm: Sequence[ArrayLike | None] | None = None,
                    start: ArrayLike | None = None) -> None:
        """Check every point (box, IK, length <= capacity, arcs), then ``PN n`` and each point.

        A point goes as ``XT`` (or ``XP`` + ``XO``, or ``XP`` + ``XR`` when its orientation as
        written repeats the previous point's), then ``XC`` when it has a circle point
        (``circle_points_mm``: one per point, None for a MoveL). ``start`` (``T_base_tcp``, mm):
        where the pass will start, needed only when the first point has a circle point (the
        circle from ``start`` is checked; :meth:`run_weld` then requires the robot to be there,
        reached by a completed :meth:`move_linear`). A path longer than the controller buffer
        raises :class:`SafetyError` before any byte.
        """
        circles = tuple(circle_points_mm) if circle_points_mm is not None else ()
        path = PathTargets(tuple(np.asarray(T, dtype=np.float64) for T in targets),
                           tuple(None if c is None else np.asarray(c, dtype=np.float64)
                                 for c in circles),
                           None if start is None else np.asarray(start, dtype=np.float64))
        near = path.check(self.limits, self._tool, self._capacity, self._near)
        self._path_len = 0
        self._path_start = None
        self._call(f"PN {len(path.targets)}")
        previous = ""
        for i, (T, via) in enumerate(zip(path.targets, path.circles, strict=True), start=1):
            p, q = pos_quat_from_pose(T)
            for body in codec.target_bodies(i, p, q, previous):
                self._call(body)
            previous = codec.fmt_quat(q, trim=True)
            if via is not None:
                self._call(codec.circle_body(i, via))
        self._path_len = len(path.targets)
        self._near = near  # where the robot will be after the pass
        if path.circles[0] is not None:
            self._path_start = path.start

    def _check_at_path_start(self) -> None:
        """The robot is where the circle to path point 1 was checked from, or SafetyError.

        Known only from a :meth:`move_linear` there that completed, with no motion since.
        """
        start = self._path_start
        if start is None:
            return
        last = self._last_linear
        here = None
        if last is not None and last[0].state == "done" and last[0].mid == self._mid:
            here = last[1]
        off_mm, off_deg = pose_error(here, start) if here is not None else (np.inf, np.inf)
        if off_mm > _AT_START_MM or off_deg > _AT_START_DEG:
            raise SafetyError("run_weld: the path starts with a circle from "
                              f"{np.round(start[:3, 3], 3).tolist()} mm, but the robot is not "
                              "known to be there; move_linear to the path's start first (and "
                              "wait for it), then run_weld", start_mm=start[:3, 3].tolist())

    def run_weld(self, speed_mm_s: float, arc_output: bool = True) -> MotionHandle:
        """``SV`` + ``RW``; ``handle.progress`` follows ``PG`` events, done on ``DN``.

        Raises :class:`SafetyError` before any byte when no path was uploaded, or when its first
        point is a circle and the robot is not where that circle was checked from.
        """
        cmd = WeldRun(speed_mm_s, bool(arc_output))
        cmd.check(self.limits)
        if self._path_len == 0:
            raise SafetyError("run_weld: no path uploaded in this session; call upload_path")
        self._check_at_path_start()
        self._set_speed(cmd.speed_mm_s)
        mid = self._next_mid()
        h = self._handle(mid, "weld", n_points=self._path_len)
        self._call(f"RW {mid} {1 if cmd.arc_output else 0}")
        return h

    def abort(self) -> None:
        """``AB``: the controller turns the arc off first, then stops and clears the motion."""
        self._call("AB", urgent=True)  # before a motion waiter's next turn on the link
        with self.link.hold(urgent=True):
            for h in self.link.handles.values():
                with h._changed:
                    if h.state == "running":
                        h.state = "aborted"
                        h.fault_code = 41
                        h._changed.notify_all()

    def status(self) -> dict[str, Any]:
        """``ST`` as a dict: moving, arc_on, mid, motion_state, path_index, error, cycle_request."""
        d = list(self._call("ST"))
        self._last_status_t = time.monotonic()
        if len(d) != 7 or d[3] not in "IRDFA" or len(d[3]) != 1:
            raise ProtocolError(f"status reply {' '.join(d)!r} is not 'mv arc mid ms i err cyc'")
        return {"moving": codec.parse_int(d[0], "moving", 0, 1) == 1,
                "arc_on": codec.parse_int(d[1], "arc", 0, 1) == 1,
                "mid": codec.parse_int(d[2], "motion id"),
                "motion_state": {"I": "idle", "R": "running", "D": "done", "F": "fault",
                                 "A": "aborted"}[d[3]],
                "path_index": codec.parse_int(d[4], "path index"),
                "error": codec.parse_int(d[5], "error code", 0, 99),
                "cycle_request": None if d[6] == "-" else codec.check_job_name(d[6])}

    def poll_event(self, timeout_s: float) -> Event | None:
        """Next event within ``timeout_s``; a latched cycle request found by ``ST`` counts too.

        A cycle request is cleared on the controller (``CK``) before it is returned.
        """
        deadline = time.monotonic() + max(0.0, timeout_s)
        while True:
            if self.link.events:
                ev = self.link.events.popleft()
                if ev.kind == "cycle_request":
                    self._call("CK")
                return ev
            now = time.monotonic()
            if now >= deadline:
                break
            self.link.pump(min(_PUMP_SLICE_S, deadline - now))
        if time.monotonic() - self._last_status_t >= self.status_poll_s:
            st = self.status()
            if st["cycle_request"]:
                self._call("CK")
                return Event(kind="cycle_request", job=st["cycle_request"])
        return None

    def _wait_motion(self, h: MotionHandle, timeout_s: float) -> None:
        deadline = time.monotonic() + timeout_s
        last_news = time.monotonic()
        seen = (h.progress, h.state)
        while True:
            if h.state == "done":
                return
            if h.state in ("fault", "aborted"):
                raise RobotFault(
                    f"{h.kind} {h.mid} {'was aborted' if h.state == 'aborted' else 'failed'} "
                    f"(controller error {h.fault_code}) after path point {h.progress}",
                    mid=h.mid, code=h.fault_code, progress=h.progress)
            now = time.monotonic()
            if now >= deadline:
                raise MotionTimeout(f"{h.kind} {h.mid} did not finish within {timeout_s:.1f} s "
                                    f"(last point reached {h.progress}); the link is alive: "
                                    "abort() before anything else", mid=h.mid, progress=h.progress)
            if now - last_news >= self.status_poll_s:
                self._apply_status(h, self.status())
                last_news = time.monotonic()
                continue
            self.link.pump(min(_PUMP_SLICE_S, deadline - now, last_news + self.status_poll_s - now))
            if (h.progress, h.state) != seen:
                seen = (h.progress, h.state)
                last_news = time.monotonic()

    def _apply_status(self, h: MotionHandle, st: dict[str, Any]) -> None:
        if st["mid"] != h.mid:
            raise RobotFault(f"the controller reports motion {st['mid']}, not {h.mid}: it lost "
                             "our motion (restart?); read status and start over",
                             mid=h.mid, status=st)
        with h._changed:
            state = st["motion_state"]
            if state == "done":
                h.progress, h.state = h.n_points, "done"
            elif state in ("fault", "aborted"):
                h.state, h.fault_code = state, st["error"]
                h.progress = max(h.progress, st["path_index"])
            else:
                h.progress = max(h.progress, st["path_index"])
            h._changed.notify_all()
