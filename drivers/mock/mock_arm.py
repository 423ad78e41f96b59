"""The mock controller's simulated IRB 2400: joints, tool, arc output and motions in simulated time.

:class:`MockArm` is the arm and the RAPID program's motion task, simulated with
:mod:`controller.geometry.kinematics`. A motion is a list of segments executed in simulated time
(real seconds = simulated seconds x ``time_scale``; 0 makes them instantaneous) on a
:class:`~drivers.mock.mock_schedule.Schedule`: joint interpolation for a joint move, Cartesian for
a linear move and a weld. What happens is told through :attr:`MockArm.notify` as the controller's
events: ``PG mid i`` for every path point of a weld, ``DN mid`` at its end, ``IP mid`` at the end
of a move, ``FL mid code i`` for a fault at ``fail_at_point`` (arc switched off first) or an
abort. Usable alone with a schedule; the protocol server (:mod:`drivers.mock.mock_server`) starts
the motions and turns the events into frames.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from controller.errors import ConfigError
from controller.geometry.kinematics import flange_pose, irb2400
from controller.geometry.poses import Pose, invert, pose_error
from controller.geometry.segment_motion import segment_length_mm, segment_pose, segment_poses
from drivers.mock.mock_schedule import Schedule

F64 = NDArray[np.float64]
#: One motion segment: controller joints (deg) and ``T_base_flange`` at its end, duration (s), and
#: for a circle (MoveC) its circle point (TCP, mm), else None.
Segment = tuple[F64, Pose, float, F64 | None]

HOME_DEG = (0.0, 0.0, 0.0, 0.0, 30.0, 0.0)
_ROT_SPEED_DEG_S = 90.0


class MockArm:
    """The simulated arm: state, motions, arc, the log of what it did. Thread-safe."""

    def __init__(self, schedule: Schedule, *, time_scale: float = 0.0,
                 fail_at_point: int | None = None) -> None:
        if not (np.isfinite(time_scale) and time_scale >= 0):
            raise ConfigError(f"mock option time_scale={time_scale} must be >= 0")
        if fail_at_point is not None and fail_at_point < 1:
            raise ConfigError(f"mock option fail_at_point={fail_at_point} must be >= 1")
        self.schedule = schedule
        self.time_scale = float(time_scale)
        #: A controller error (40) when a weld reaches this path point (1-based); None: never.
        self.fail_at_point = fail_at_point
        #: Told each event as its fields, e.g. ``("PG", mid, i)`` (the protocol server).
        self.notify: Callable[..., None] = lambda *fields: None
        self.model = irb2400()
        #: Every motion or weld started: dicts with mid, kind, session, result, points_reached...
        self.executed: list[dict[str, Any]] = []
        #: Ordered safety-relevant actions: "start <kind>" (a motion accepted), "arc_on",
        #: "arc_off", "abort" (an abort request, before its "arc_off", "stop"), "stop", "restart".
        self.action_log: list[str] = []
        self._joints = np.array(HOME_DEG)
        self._tool = np.eye(4)  # PERS tooldata on the controller: survives a restart
        self.reset()

    def reset(self) -> None:
        """Program start: no motion, arc off, default speed, idle status (joints and tool stay)."""
        self._motion: dict[str, Any] | None = None
        self._arc = False
        self.speed_mm_s = 100.0
        self.status_mid = 0
        self.status_state = "I"
        self.status_index = 0
        self.error = 0

    # ---- state -------------------------------------------------------------------------------

    @property
    def joints_deg(self) -> F64:
        """The arm's current controller axes (deg), interpolated during a motion."""
        with self.schedule.lock:
            return self.current()[0]

    def flange_pose(self) -> Pose:
        """The arm's actual ``T_base_flange`` (mm) now, interpolated during a motion."""
        with self.schedule.lock:
            return self.current()[1]

    @property
    def arc_on(self) -> bool:
        """The weld (arc) digital output."""
        with self.schedule.lock:
            return self._arc

    @property
    def tool(self) -> Pose:
        """The active tool ``T_flange_tcp`` (mm)."""
        with self.schedule.lock:
            return self._tool.copy()

    @tool.setter
    def tool(self, T_flange_tcp: Pose) -> None:
        with self.schedule.lock:
            self._tool = np.array(T_flange_tcp, dtype=np.float64)

    @property
    def moving(self) -> bool:
        """True while a motion runs."""
        return self._motion is not None

    def current(self) -> tuple[F64, Pose]:
        """Controller joints (deg) and ``T_base_flange`` (mm) at this instant."""
        m = self._motion
        if m is None or m["seg_t1"] <= m["seg_t0"]:
            return self._joints.copy(), flange_pose(self.model, self._joints, check_limits=False)
        s = min(1.0, max(0.0, (time.monotonic() - m["seg_t0"]) / (m["seg_t1"] - m["seg_t0"])))
        j = (1 - s) * m["j0"] + s * m["j1"]
        if m["kind"] == "move_joints":
            return j, flange_pose(self.model, j, check_limits=False)
        # the TCP moves on the line or circle (MoveL / MoveC), the flange follows it
        tool = m["tool"]
        T_tcp = segment_pose(m["T0"] @ tool, m["T1"] @ tool, s, m["via"])
        return j, T_tcp @ invert(tool)

    def seg_time(self, T0: Pose, T1: Pose, via_mm: F64 | None = None) -> float:
        """Simulated time (s) of a Cartesian segment at the current speed.

        ``T0``, ``T1`` are flange poses; ``via_mm`` the TCP's circle point of a MoveC.
        """
        tool = self._tool
        d_mm = segment_length_mm(T0 @ tool, T1 @ tool, via_mm)
        d_deg = pose_error(T0, T1)[1]
        return max(d_mm / self.speed_mm_s, d_deg / _ROT_SPEED_DEG_S)

    def trace(self, entry: dict[str, Any], step_mm: float = 0.1) -> F64:
        """The TCP path a motion executed (``executed`` entry): poses (N, 4, 4), ``T_base_tcp``.

        Each Cartesian segment the arm ran is sampled every ``step_mm`` or closer, with the same
        motion model the arm moves by (:mod:`controller.geometry.segment_motion`); a segment cut
        short (abort, fault) is traced to its end.
        """
        out = []
        for T0, T1, via in entry.get("tcp_segments", []):
            n = max(2, int(np.ceil(segment_length_mm(T0, T1, via) / step_mm)) + 1)
            out.append(segment_poses(T0, T1, np.linspace(0.0, 1.0, n), via))
        return np.concatenate(out) if out else np.zeros((0, 4, 4))

    # ---- motions -----------------------------------------------------------------------------

    def _set_arc(self, on: bool) -> None:
        if self._arc != on:
            self._arc = on
            self.action_log.append("arc_on" if on else "arc_off")

    def start(self, mid: int, kind: str, segs: list[Segment], session: int | None,
              **record: Any) -> Callable[[], None]:
        """Accept motion ``mid`` (``move_joints``, ``move_linear`` or ``weld``) of ``segs``.

        Returns the function that sets it going (called after the reply is sent); a weld with
        ``arc=True`` in ``record`` switches the arc on when it begins.
        """
        self.status_mid, self.status_state, self.status_index, self.error = mid, "R", 0, 0
        self.action_log.append(f"start {kind}")
        entry = {"mid": mid, "kind": kind, "session": session, "result": "running",
                 "points_reached": 0, **record}
        self.executed.append(entry)
        j0, T0 = self.current()
        m = {"mid": mid, "kind": kind, "segs": segs, "index": 0, "entry": entry, "j0": j0,
             "T0": T0, "j1": j0, "T1": T0, "seg_t0": 0.0, "seg_t1": 0.0, "via": None,
             "tool": self._tool.copy()}
        self._motion = m

        def begin() -> None:
            if self._motion is not m:
                return
            if kind == "weld" and record.get("arc"):
                self._set_arc(True)
            self._next_segment(m)

        return begin

    def _next_segment(self, m: dict[str, Any]) -> None:
        j1, T1, dur, via = m["segs"][m["index"]]
        if m["index"] > 0 or m["kind"] != "weld":
            m["j0"], m["T0"] = self.current()
        m["j1"], m["T1"], m["via"], m["tool"] = j1, T1, via, self._tool.copy()
        if m["kind"] != "move_joints":
            tool = m["tool"]
            m["entry"].setdefault("tcp_segments", []).append((m["T0"] @ tool, T1 @ tool, via))
        now = self.schedule.now
        m["seg_t0"] = now
        m["seg_t1"] = now + dur * self.time_scale
        self.schedule.after(dur * self.time_scale, lambda: self._reach(m))

    def _reach(self, m: dict[str, Any]) -> None:
        if self._motion is not m:
            return  # aborted or replaced meanwhile
        i = m["index"] + 1
        if m["kind"] == "weld" and self.fail_at_point is not None and i == self.fail_at_point:
            self._set_arc(False)
            self.action_log.append("stop")
            self._joints = self.current()[0]
            self._finish(m, "F", 40, "fault")
            self.notify("FL", m["mid"], 40, i)
            return
        self._joints = np.array(m["j1"], dtype=np.float64)
        m["index"] = i
        m["entry"]["points_reached"] = i
        self.status_index = i if m["kind"] == "weld" else 0
        if i < len(m["segs"]):
            self.notify("PG", m["mid"], i)
            self._next_segment(m)
            return
        if m["kind"] == "weld":
            self.notify("PG", m["mid"], i)
            self._set_arc(False)
            self._finish(m, "D", 0, "done")
            self.notify("DN", m["mid"])
        else:
            self._finish(m, "D", 0, "done")
            self.notify("IP", m["mid"])

    def _finish(self, m: dict[str, Any], state: str, error: int, result: str) -> None:
        self._motion = None
        self.status_state, self.error = state, error
        m["entry"]["result"] = result

    def abort(self) -> None:
        """Arc output off first (always written, as SetDO does), then stop the motion (FL 41)."""
        self._arc = False
        self.action_log += ["abort", "arc_off", "stop"]
        m = self._motion
        if m is not None:
            self._joints = self.current()[0]
            self._finish(m, "A", 41, "aborted")
            # the path point it stopped before; 0 for a move that is not a path (protocol)
            self.notify("FL", m["mid"], 41, m["index"] + 1 if m["kind"] == "weld" else 0)

    def restart(self) -> None:
        """A controller restart: arc off, the motion stopped where it is, then :meth:`reset`."""
        with self.schedule.lock:
            self._set_arc(False)
            m = self._motion
            if m is not None:
                self._joints = self.current()[0]
                m["entry"]["result"] = "restart"
            self.action_log.append("restart")
            self.reset()
