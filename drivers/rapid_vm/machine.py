"""The controller around a RAPID program, as built-ins of the program.

The serial channel, the I/O signals and interrupts, the
teach pendant, and the motion instructions on the simulated arm, as built-ins of the program.

Two system profiles: ``s4`` has only what the S4 BaseWare RAPID reference documents for the
names the server uses; ``robotware`` adds ``CalcJointT`` and ``ERR_ROBLIMIT`` (so the optional
module ``SGREACH.mod`` loads only there, as on a controller). Error numbers are this
interpreter's, not ABB's (a program compares them by name).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from controller.errors import InputError, ReachabilityError
from controller.geometry.kinematics import flange_pose, solve_ik, solve_ik_near
from controller.geometry.poses import invert, pos_quat_from_pose, pose_error, pose_from_pos_quat
from controller.geometry.segment_motion import segment_length_mm
from drivers.rapid_vm.builtins_core import CORE_FUNCTIONS
from drivers.rapid_vm.errors import RapidError, RapidStop
from drivers.rapid_vm.program import Builtin
from drivers.rapid_vm.values import Rec, convert
from drivers.rapid_vm.vm_arm import ERR_MOTION, VmArm

ERRORS_S4 = {"err_fileacc": 1040.0, "err_dev_maxtime": 1041.0, "err_refunkprc": 1042.0,
             "err_divzero": 1036.0}
ERRORS_RW = {**ERRORS_S4, "err_roblimit": 1043.0}
SIGNALS = {"doweld": "signaldo", "dicyclereq": "signaldi"}
_JOINT_SPEED_DEG_S = 100.0


class Killed(BaseException):
    """The program is being stopped from outside (restart, shutdown); no handler sees it."""


def pose_of(rec: Rec) -> np.ndarray:
    """The pose (mm) of a RAPID ``pose`` record (trans, rot)."""
    t, q = rec.f["trans"].f, rec.f["rot"].f
    return pose_from_pos_quat([t["x"], t["y"], t["z"]], [q["q1"], q["q2"], q["q3"], q["q4"]])


def robtarget_of(T: np.ndarray) -> Rec:
    """A ``robtarget`` record of a pose (mm), configuration and external axes zero / 9E9."""
    p, q = pos_quat_from_pose(T)
    return convert([[*map(float, p)], [*map(float, q)], [0, 0, 0, 0], [9e9] * 6], "robtarget")


class Machine:
    """The controller's devices as the program sees them; ``send`` writes bytes to the line."""

    def __init__(self, arm: VmArm, send: Callable[[bytes], None], profile: str = "s4") -> None:
        self.arm = arm
        self.send = send
        self.profile = profile
        self.killed = False
        self._rx = bytearray()
        self._rx_cond = threading.Condition()
        self.signals = {name: 0.0 for name in SIGNALS}
        self._isignal: dict[str, tuple[float, float]] = {}  # signal -> (value, intnum)
        self.interrupt: Callable[[float], None] = lambda k: None
        self.delete_interrupt: Callable[[float], None] = lambda k: None
        #: Lines written with TPWrite (the teach pendant).
        self.tp_log: list[str] = []
        self.open_channels: set[str] = set()
        self.weld_move = 0  # the MoveL count inside a weld (RunMotion with mkind RW), 0 outside
        self.fail_at_point: int | None = None

    # ---- the serial line -------------------------------------------------------------------

    def feed(self, data: bytes) -> None:
        """Bytes arrived on the channel (from the line's thread)."""
        with self._rx_cond:
            self._rx += data
            self._rx_cond.notify_all()

    def clear_input(self) -> None:
        """Forget received bytes (a program restart)."""
        with self._rx_cond:
            self._rx.clear()

    def alive(self) -> None:
        """Raise :class:`Killed` when the program must stop."""
        if self.killed:
            raise Killed()

    def kill(self) -> None:
        """Stop the program at its next statement or wait."""
        self.killed = True
        with self._rx_cond:
            self._rx_cond.notify_all()

    def _read_bin(self, where: str, a: list[Any], o: dict[str, Any]) -> float:
        if a[0] not in self.open_channels:
            raise RapidError(int(ERRORS_S4["err_fileacc"]), f"{where}: channel not open")
        limit = o.get("time")
        deadline = None if limit is None else time.monotonic() + float(limit)
        with self._rx_cond:
            while not self._rx:
                self.alive()
                left = 0.05 if deadline is None else deadline - time.monotonic()
                if left <= 0:
                    raise RapidError(int(ERRORS_S4["err_dev_maxtime"]), "ReadBin: no byte in time")
                self._rx_cond.wait(min(left, 0.05))
            b = self._rx.pop(0)
        return float(b)

    def _write_bin(self, where: str, a: list[Any], o: dict[str, Any]) -> None:
        ch, buf, n = a
        if ch not in self.open_channels:
            raise RapidError(int(ERRORS_S4["err_fileacc"]), f"{where}: channel not open")
        if not (isinstance(buf, list) and 0 <= n <= len(buf)):
            raise RapidStop(f"{where}: WriteBin of {n} bytes from an array of {len(buf)}")
        data = []
        for x in buf[:int(n)]:
            if not (x == int(x) and 0 <= x <= 255):
                raise RapidStop(f"{where}: WriteBin byte {x} outside 0..255")
            data.append(int(x))
        self.send(bytes(data))

    def _open(self, where: str, a: list[Any], o: dict[str, Any]) -> None:
        if a[0] != "sio1:" or not o.get("bin"):
            raise RapidStop(f"{where}: this controller has only \"sio1:\" opened \\Bin")
        self.open_channels.add(a[0])
        a[1].set(a[0])

    def _close(self, where: str, a: list[Any], o: dict[str, Any]) -> None:
        ch = a[0].get()
        if ch is None:
            raise RapidError(int(ERRORS_S4["err_fileacc"]), f"{where}: Close of a channel "
                             "never opened")
        self.open_channels.discard(ch)

    # ---- I/O signals, interrupts, pendant --------------------------------------------------

    def set_signal(self, name: str, value: float) -> None:
        """A digital signal changes (the operator's input, or SetDO); may order an interrupt."""
        old = self.signals[name]
        self.signals[name] = value
        want = self._isignal.get(name)
        if want is not None and value == want[0] and old != value:
            self.interrupt(want[1])

    def _set_do(self, where: str, a: list[Any], o: dict[str, Any]) -> None:
        name, v = a
        if SIGNALS.get(name) != "signaldo" or v not in (0, 1):
            raise RapidStop(f"{where}: SetDO {name}, {v}")
        self.set_signal(name, float(v))
        if name == "doweld":
            self.arm.set_arc(v == 1)

    def _isignal_di(self, where: str, a: list[Any], o: dict[str, Any]) -> None:
        self._isignal[a[0]] = (float(a[1]), float(a[2]))

    def _idelete(self, where: str, a: list[Any], o: dict[str, Any]) -> None:
        k = a[0]
        self._isignal = {s: w for s, w in self._isignal.items() if w[1] != k}
        self.delete_interrupt(k)

    def _tpwrite(self, where: str, a: list[Any], o: dict[str, Any]) -> None:
        self.tp_log.append(str(a[0]))

    # ---- motion ----------------------------------------------------------------------------

    def _tool(self, t: Rec) -> np.ndarray:
        return pose_of(t.f["tframe"])

    def _move_l(self, where: str, a: list[Any], o: dict[str, Any]) -> None:
        target, speed, zone, tool = a
        self._move_cartesian(where, "MoveL", target, None, speed, zone, tool, o)

    def _move_c(self, where: str, a: list[Any], o: dict[str, Any]) -> None:
        circ, target, speed, zone, tool = a
        self._move_cartesian(where, "MoveC", target, circ, speed, zone, tool, o)

    def _move_cartesian(self, where: str, name: str, target: Rec, circ: Rec | None, speed: Rec,
                        zone: Rec, tool: Rec, o: dict[str, Any]) -> None:
        T_tool = self._tool(tool)
        T1 = pose_of(target) @ invert(T_tool)
        j0 = self.arm.last_target()
        try:
            # the configuration the arm is in, continued (ConfL \Off): the same refusals as the
            # full solution set, without computing it for every move (10 ms each)
            j1 = solve_ik_near(self.arm.model, T1, j0)
        except ReachabilityError as err:
            raise RapidError(ERR_MOTION, f"{where}: {name} target outside reach") from err
        T0 = flange_pose(self.arm.model, j0, check_limits=False)
        via = None if circ is None else pose_of(circ)[:3, 3]
        try:
            d_mm = segment_length_mm(T0 @ T_tool, T1 @ T_tool, via)
        except InputError as err:  # the controller refuses a circle it cannot make
            raise RapidError(ERR_MOTION, f"{where}: MoveC circle point on the line") from err
        dur = max(d_mm / max(speed.f["v_tcp"], 1e-6), pose_error(T0, T1)[1] / 90.0)
        if self.weld_move:
            self.weld_move += 1
        fail = self.fail_at_point is not None and self.weld_move - 1 == self.fail_at_point
        token = self.arm.move("move_linear", j1, T1, dur, fail, via, T_tool)
        if o.get("conc"):
            return
        self.arm.wait(token, "done" if zone.f["finep"] else "started", self.alive)

    def _move_abs_j(self, where: str, a: list[Any], o: dict[str, Any]) -> None:
        jt, speed, zone, tool = a
        r = jt.f["robax"].f
        j1 = np.array([r[f"rax_{i}"] for i in range(1, 7)])
        j0 = self.arm.last_target()
        model = self.arm.model
        T0, T1 = flange_pose(model, j0, check_limits=False), flange_pose(model, j1,
                                                                         check_limits=False)
        dur = max(pose_error(T0, T1)[0] / max(speed.f["v_tcp"], 1e-6),
                  float(np.max(np.abs(j1 - j0))) / _JOINT_SPEED_DEG_S)
        token = self.arm.move("move_joints", j1, T1, dur)
        if not o.get("conc"):
            self.arm.wait(token, "done" if zone.f["finep"] else "started", self.alive)

    def _cjoint_t(self, where: str, a: list[Any], o: dict[str, Any]) -> Rec:
        j = self.arm.joints_deg
        return convert([[float(x) for x in j], [9e9] * 6], "jointtarget")

    def _crob_t(self, where: str, a: list[Any], o: dict[str, Any]) -> Rec:
        T = self.arm.flange_pose()
        if "tool" in o:
            T = T @ self._tool(o["tool"])
        return robtarget_of(T)

    def _calc_joint_t(self, where: str, a: list[Any], o: dict[str, Any]) -> Rec:
        T1 = pose_of(a[0]) @ invert(self._tool(a[1]))
        try:
            j = solve_ik(self.arm.model, T1, near_deg=self.arm.last_target())
        except ReachabilityError as err:
            raise RapidError(int(ERRORS_RW["err_roblimit"]), "CalcJointT: outside reach") from err
        return convert([[float(x) for x in j], [9e9] * 6], "jointtarget")

    def _stop_move(self, where: str, a: list[Any], o: dict[str, Any]) -> None:
        self.arm.stop_and_clear()

    def _nothing(self, where: str, a: list[Any], o: dict[str, Any]) -> None:
        return None

    # ---- the system ------------------------------------------------------------------------

    def builtins(self) -> dict[str, Builtin]:
        """The instructions and functions of this controller's profile."""
        proc, func, none = False, True, frozenset[int]()
        out: dict[str, Builtin] = dict(CORE_FUNCTIONS)
        out.update({
            "readbin": (self._read_bin, none, func), "writebin": (self._write_bin, none, proc),
            "open": (self._open, frozenset({1}), proc),
            "close": (self._close, frozenset({0}), proc),
            "setdo": (self._set_do, none, proc), "isignaldi": (self._isignal_di, none, proc),
            "idelete": (self._idelete, none, proc), "tpwrite": (self._tpwrite, none, proc),
            "confl": (self._nothing, none, proc), "confj": (self._nothing, none, proc),
            "movel": (self._move_l, none, proc), "movec": (self._move_c, none, proc),
            "moveabsj": (self._move_abs_j, none, proc),
            "stopmove": (self._nothing, none, proc), "clearpath": (self._stop_move, none, proc),
            "startmove": (self._nothing, none, proc),
            "cjointt": (self._cjoint_t, none, func), "crobt": (self._crob_t, none, func),
        })
        if self.profile == "robotware":
            out["calcjointt"] = (self._calc_joint_t, none, func)
        return out

    def constants(self) -> dict[str, float]:
        """The error numbers of this profile."""
        return dict(ERRORS_RW if self.profile == "robotware" else ERRORS_S4)
