"""The mock controller's simulated IRB 2400: its state, its motions, the arc and progress events.

:class:`MockRobot` adds to the line layer (:class:`drivers.mock.mock_link.MockLink`) the arm,
simulated
with :mod:`controller.geometry.kinematics`, and the RAPID program's volatile state. A motion is a
list of
segments executed in simulated time (real seconds = simulated seconds x ``time_scale``): joint
interpolation for ``MJ``, Cartesian for ``ML`` and welds; every reached path point of a weld is a
``PG`` event, the end a ``DN`` (weld) or ``IP`` (move) event, a fault at ``fail_at_point`` an
``FL`` event with the arc switched off first. The operator's cycle request and a controller
restart are here too. The requests that start these motions are in :mod:`drivers.mock.mock_server`.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from controller.geometry.kinematics import flange_pose, irb2400
from controller.geometry.poses import Pose, interpolate, invert, pose_error, pose_from_pos_quat
from drivers.abb import abb_codec as codec
from drivers.mock.mock_link import MockLink

F64 = NDArray[np.float64]

HOME_DEG = (0.0, 0.0, 0.0, 0.0, 30.0, 0.0)
_ROT_SPEED_DEG_S = 90.0


class MockRobot(MockLink):
    """The simulated arm and the RAPID program's state, on the line layer. Thread-safe."""

    def __init__(self, **options: Any) -> None:
        """Options as :class:`~drivers.mock.mock_link.MockLink` takes them."""
        super().__init__(**options)
        self._robot = irb2400()
        #: Every motion or weld the controller started: dicts with mid, kind, session, result...
        self.executed: list[dict[str, Any]] = []
        #: Ordered safety-relevant actions ("arc_on", "arc_off", "stop", "restart", ...).
        self.action_log: list[str] = []
        self.boot = 0
        self._tool = np.eye(4)  # PERS tooldata on the controller: survives a restart
        self._reset_volatile()
        self._joints = np.array(HOME_DEG)

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

    def _current(self) -> tuple[F64, Pose]:
        m = self._motion
        if m is None or m["seg_t1"] <= m["seg_t0"]:
            return self._joints.copy(), flange_pose(self._robot, self._joints, check_limits=False)
        s = min(1.0, max(0.0, (time.monotonic() - m["seg_t0"]) / (m["seg_t1"] - m["seg_t0"])))
        j = (1 - s) * m["j0"] + s * m["j1"]
        if m["kind"] == "move_joints":
            return j, flange_pose(self._robot, j, check_limits=False)
        return j, interpolate(m["T0"], m["T1"], s)

    def _event(self, body: str) -> None:
        self._event_seq = (self._event_seq + 1) % 100
        self._send("E", self._event_seq, body)

    def _target(self, k: int) -> Pose | None:
        if k not in self._slot_pos or k not in self._slot_quat:
            return None
        T_base_tcp = pose_from_pos_quat(self._slot_pos[k], self._slot_quat[k])
        return T_base_tcp @ invert(self._tool)

    def _seg_time(self, T0: Pose, T1: Pose) -> float:
        d_mm, d_deg = pose_error(T0, T1)
        return max(d_mm / self._speed_mm_s, d_deg / _ROT_SPEED_DEG_S)

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
