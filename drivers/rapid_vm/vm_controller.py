"""``rapid://``: SGSERVER.mod itself, run by the RAPID interpreter.

The real RAPID server (``drivers/abb/rapid/SGSERVER.mod``) run by the interpreter,
on the mock's fault-injected line, pseudo-terminal and simulated arm: a third robot backend
beside ``mock://`` and the mock behind a pty, for the link's contract tests and the soak.

:class:`RapidController` has the mock controller's observable surface (``executed``,
``action_log``, ``joints_deg``, ``flange_pose()``, ``tool``, ``arc_on``, ``link_stats``,
``request_cycle``, ``restart``, ``disconnect``, ``serve_pty``, ``stop``), read from the running
program and its devices: ``executed`` gets an entry each time the program enters ``RunMotion``
(with the program's ``mid``, ``mkind``, ``session``), its result when it leaves it.
A program that stops (a run-time error, e.g. a string over 80 characters) leaves
:attr:`RapidController.stopped_with` set and answers nothing more, as a controller would.

Options (``rapid://?seed=3&drop=0.01``): the mock line's (seed, drop, corrupt, dup, delay_ms, baud,
disconnect), the arm's ``time_scale``, ``fail_at_point`` (a motion fault on the way to that weld
point), and ``reach=1`` (a controller with CalcJointT: the optional SGREACH.mod is loaded too).
What it does not model: the RAPID task's own timing (the interpreter is slower or faster than an
S4), zones (every point is reached), and everything the mock's arm does not model.
"""

from __future__ import annotations

import threading
import time
import urllib.parse
from pathlib import Path
from typing import Any, Self

import numpy as np

from controller.errors import ConfigError
from drivers.mock.mock_line import MockLine
from drivers.mock.mock_pty import PtyTransport
from drivers.mock.mock_schedule import Schedule
from drivers.rapid_vm.errors import RapidStop
from drivers.rapid_vm.machine import SIGNALS, Killed, Machine, pose_of
from drivers.rapid_vm.program import Program
from drivers.rapid_vm.vm_arm import VmArm

RAPID_DIR = Path(__file__).resolve().parents[1] / "abb" / "rapid"
RAPID_OPTIONS = {
    "seed": "random seed of the line's fault injection (int)",
    "drop": "probability that a line is dropped, each direction (0..1)",
    "corrupt": "probability that a byte is corrupted, each direction (0..1)",
    "dup": "probability that a line is duplicated, each direction (0..1)",
    "delay_ms": "extra delay of every reply (ms)",
    "baud": "simulated baud rate (0 = infinitely fast)",
    "disconnect": "probability that the link drops after a received line",
    "time_scale": "real seconds per simulated second of motion (0 = instantaneous)",
    "fail_at_point": "a motion fault on the way to this weld point (1-based)",
    "reach": "1: a controller with CalcJointT, SGREACH.mod loaded too (default 0: S4 BaseWare)",
}
_INTS = ("seed", "baud", "fail_at_point", "reach")
_KIND = {"MJ": "move_joints", "ML": "move_linear", "RW": "weld"}
_RESULT = {"D": "done", "F": "fault", "A": "aborted", "R": "running"}


class RapidLine(MockLine):
    """The mock line, sending the bytes the program writes (whole lines) as they are."""

    def send_bytes(self, data: bytes, delay_s: float = 0.0) -> None:
        """Queue bytes to the client with the line's faults (a line at a time)."""
        with self.lock:
            self.schedule.now = time.monotonic()
            self.stats["bytes_tx"] += len(data)
            self.stats["lines_tx"] += 1
            if self.drop and self._rng.random() < self.drop:
                return
            copies = 2 if self.dup and self._rng.random() < self.dup else 1
            for _ in range(copies):
                out = self._corrupt(data)
                start = max(self.schedule.now + delay_s, self._tx_free)
                self._tx_free = start + self._tx_time(len(out))
                self.schedule.at(self._tx_free,
                                 lambda d=out: self._outbuf.extend(d))  # type: ignore[misc]


def parse_rapid_options(query: str) -> dict[str, Any]:
    """``seed=7&drop=0.01`` to :class:`RapidController` keyword arguments; ConfigError if bad."""
    out: dict[str, Any] = {}
    for key, values in urllib.parse.parse_qs(query, keep_blank_values=True).items():
        if key not in RAPID_OPTIONS:
            raise ConfigError(f"unknown rapid:// option {key!r}; known options: "
                              f"{', '.join(sorted(RAPID_OPTIONS))}")
        try:
            out[key] = int(values[-1]) if key in _INTS else float(values[-1])
        except ValueError as err:
            raise ConfigError(f"rapid:// option {key}={values[-1]!r} is not a number") from err
    return out


class RapidController:
    """SGSERVER.mod in the interpreter on a simulated S4 (or, ``reach=1``, RobotWare) controller.

    ``modules``: (text, file name) of the RAPID modules to load instead of the package's;
    ``entry``: the routine to start (``main``).
    """

    def __init__(self, *, seed: int = 0, drop: float = 0.0, corrupt: float = 0.0,
                 dup: float = 0.0, delay_ms: float = 0.0, baud: int = 0, disconnect: float = 0.0,
                 time_scale: float = 0.0, fail_at_point: int | None = None, reach: int = 0,
                 modules: list[tuple[str, str]] | None = None, entry: str = "main") -> None:
        self.seed = seed
        self.entry = entry
        self.schedule = Schedule()
        self.line = RapidLine(self.schedule, seed=seed, drop=drop, corrupt=corrupt, dup=dup,
                              delay_ms=delay_ms, baud=baud, disconnect=disconnect)
        self.arm = VmArm(self.schedule, time_scale=time_scale)
        self.machine = Machine(self.arm, self._send, "robotware" if reach else "s4")
        self.machine.fail_at_point = fail_at_point
        self.line.on_line = self._on_line
        self.pty = PtyTransport(self.line,
                                on_disconnect=lambda: self.arm.action_log.append("disconnect"))
        names = ["SGSERVER.mod"] + (["SGREACH.mod"] if reach else [])
        self.modules = modules or [((RAPID_DIR / n).read_text(), n) for n in names]
        #: Every motion the program started (RunMotion): mid, kind, session, result, points.
        self.executed: list[dict[str, Any]] = []
        #: The run-time error that stopped the program (None while it runs).
        self.stopped_with: str | None = None
        #: Test hooks: sees each received line before the program; may drop a written line.
        self.on_request: Any = None
        self.on_reply: Any = None
        self._counts = {"requests": 0, "bad_lines": 0, "executed_requests": 0}
        self._pers: dict[str, Any] = {}
        self._restart = threading.Event()
        self._booted = threading.Event()
        self._thread: threading.Thread | None = None
        self.program = self._load()  # load errors now, as ConfigError

    # ---- the program -----------------------------------------------------------------------

    def _load(self) -> Program:
        m = self.machine
        prog = Program(m.builtins(), m.constants(), SIGNALS, persistent=self._pers)
        for text, name in self.modules:
            prog.load(text, name)
        prog.probes = {"decode": self._probe_decode, "execute": self._probe_execute,
                       "runmotion": self._probe_motion, "abort": self._probe_abort}
        prog.link()
        m.interrupt, m.delete_interrupt = prog.interrupt, prog.delete_interrupt
        prog.killed = m.alive
        return prog

    def _probe_decode(self, phase: str, result: Any) -> None:
        if phase == "exit":
            self._counts["requests" if result else "bad_lines"] += 1

    def _probe_execute(self, phase: str, result: Any) -> None:
        if phase == "enter":
            self._counts["executed_requests"] += 1

    def _probe_abort(self, phase: str, result: Any) -> None:
        if phase == "enter":  # as the mock logs it: "abort" before its "arc_off", "stop"
            self.arm.action_log.append("abort")

    def _probe_motion(self, phase: str, result: Any) -> None:
        g = self.program.globals
        if phase == "enter":
            self.arm.action_log.append(f"start {_KIND[g['mkind']]}")
            self.executed.append({"mid": int(g["mid"]), "kind": _KIND[g["mkind"]],
                                  "session": int(g["session"]), "result": "running",
                                  "points_reached": 0})
            self.machine.weld_move = 1 if g["mkind"] == "RW" else 0
        else:
            self.executed[-1].update(result=_RESULT[g["mstate"]], points_reached=int(g["pidx"]))
            self.machine.weld_move = 0

    def _run(self) -> None:
        while True:
            self.machine.killed = False
            self.machine.clear_input()
            self._booted.set()
            try:
                self.program.run(self.entry)
                self.stopped_with = "the program ended"
            except RapidStop as err:
                self.stopped_with = str(err)
            except Killed:
                pass
            if not self._restart.is_set():
                return
            self._restart.clear()
            self._pers = self.program.persistent()
            self.program = self._load()

    def _kill(self) -> None:
        self.machine.kill()
        self.program.pending.append(None)  # type: ignore[arg-type]  # seen between statements

    # ---- the line --------------------------------------------------------------------------

    def _on_line(self, line: bytes) -> None:
        if self.on_request is not None:
            self.on_request(line)
        self.machine.feed(line if line.endswith(b"\n") else line + b"\n")

    def _send(self, data: bytes) -> None:
        if self.on_reply is not None and self.on_reply(data):
            return
        self.line.send_bytes(data, self.line.delay_s if data[:1] == b"A" else 0.0)

    # ---- what callers read and do ----------------------------------------------------------

    @property
    def action_log(self) -> list[str]:
        """Ordered safety-relevant actions, named as the mock names them.

        ``start <kind>`` (the program starts a motion), ``abort`` (its Abort), ``arc_on`` /
        ``arc_off`` (each SetDO doWeld), ``stop`` (ClearPath), ``restart``, ``disconnect``.
        """
        return self.arm.action_log

    @property
    def arc_on(self) -> bool:
        """The doWeld output."""
        return self.machine.signals["doweld"] == 1.0

    @property
    def joints_deg(self) -> np.ndarray:
        """The arm's controller axes now (deg)."""
        return self.arm.joints_deg

    def flange_pose(self) -> np.ndarray:
        """The arm's ``T_base_flange`` now (mm)."""
        return self.arm.flange_pose()

    @property
    def tool(self) -> np.ndarray:
        """The program's PERS ``sgtool`` as ``T_flange_tcp`` (mm)."""
        return pose_of(self.program.globals["sgtool"].f["tframe"])

    @property
    def link_stats(self) -> dict[str, float]:
        """Bytes and lines each way, requests read, bad lines, duplicates answered from memory."""
        c = self._counts
        return {**self.line.stats, "requests": c["requests"], "bad_lines": c["bad_lines"],
                "duplicates_suppressed": c["requests"] - c["executed_requests"]}

    @property
    def tp_log(self) -> list[str]:
        """What the program wrote on the teach pendant (TPWrite)."""
        return self.machine.tp_log

    @property
    def link_path(self) -> str | None:
        """The pty's stable path while served."""
        return self.pty.link_path

    def serve_pty(self, link_path: str | None = None) -> str:
        """Start the program and serve its channel on a pseudo-terminal; the path to open."""
        path = self.pty.serve(link_path)
        if self._thread is None:
            self._booted.clear()
            self._thread = threading.Thread(target=self._run, name="rapid-program", daemon=True)
            self._thread.start()
            self._booted.wait(5.0)
        return path

    def stop(self) -> None:
        """Stop the program and the pty (idempotent)."""
        self._restart.clear()
        self._kill()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None
        self.pty.stop()

    def disconnect(self, timeout_s: float = 2.0, wait: bool = True) -> None:
        """Drop the link and plug it back (a new pty behind the same path)."""
        self.pty.disconnect(timeout_s, wait)

    def restart(self) -> None:
        """A controller restart: arc off, motion stopped, the program started again from main.

        PERS data are kept, everything else forgotten. Returns at once; usable from any thread.
        """
        self.arm.stop_and_clear()
        self.machine.signals["doweld"] = 0.0
        self.arm.set_arc(False)
        self.arm.action_log.append("restart")
        self._restart.set()
        self._kill()

    def request_cycle(self, job: str) -> None:
        """The operator sets ``sg_job`` on the pendant and presses the cycle button."""
        self.program.globals["sg_job"] = job
        self.machine.set_signal("dicyclereq", 1.0)
        self.machine.set_signal("dicyclereq", 0.0)

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


def open_rapid_robot(url: str, *, limits: Any = None, timeout_s: float = 5.0,
                     **link_options: Any) -> Any:
    """``rapid://?opts``: SGSERVER.mod in the interpreter on a pty, and an AbbRobot on it.

    ``robot.mock`` is the :class:`RapidController`. ConfigError for bad options or a module that
    does not load.
    """
    from drivers.mock.mock_controller import robot_on_simulated_controller

    parsed = urllib.parse.urlsplit(url)
    if parsed.netloc or parsed.path not in ("", "/"):
        raise ConfigError(f"rapid URL {url!r} takes options only: rapid://?seed=7&drop=0.01")
    ctl = RapidController(**parse_rapid_options(parsed.query))
    # The interpreter is slower per request than the mock: more processing time, slower polls.
    return robot_on_simulated_controller("rapid://", ctl, limits=limits, timeout_s=timeout_s,
                                         processing_s=0.3, min_poll_s=0.5, **link_options)
