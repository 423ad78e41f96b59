"""A mock ABB S4 controller running the seamguide RAPID server, for tests, dry runs and benches.

It speaks SGRS/1 (``docs/protocol.md``) byte for byte as ``drivers/abb/rapid/SGSERVER.mod`` does,
with the same sans-I/O codec, and simulates an IRB 2400 with :mod:`controller.geometry.kinematics`:
motions take time at the commanded speed (times ``time_scale``; 0 makes them instantaneous, but
completion is still reported by an event after the reply), joint limits and unreachable targets
are refused with an error reply, the tool frame is applied, the arc output is switched, a path is
executed point by point with progress events. Fault injection, seeded: corrupted bytes, dropped
and duplicated lines (both directions), slow replies (``delay_ms``), a simulated baud rate (every
byte takes 10/baud s of real time), a controller error at path point N (``fail_at_point``),
disconnects (:meth:`disconnect`) and controller restarts (:meth:`restart`); the operator's cycle
request is :meth:`request_cycle`.

It is served on a real pseudo-terminal (``os.openpty``) with a stable symlink path by
:meth:`MockController.serve_pty`, in a thread, so the client's pyserial code runs for real.

What it does not model: dynamics and acceleration (speed is constant, motion is linear in joints
for ``MJ`` and in Cartesian space for ``ML``/welds), zones (every point is reached exactly), the
axis 2/3 interaction limit, singularities along a linear move, the RAPID task's own timing, and
the serial line's electrical faults other than the byte errors above.

It is built by composition, each part usable and testable alone and put together here: the
clock and its ordered actions (:mod:`drivers.mock.mock_schedule`), the seeded fault-injecting
line (:mod:`drivers.mock.mock_line`), the simulated arm and its motions
(:mod:`drivers.mock.mock_arm`), the SGRS/1 protocol server between them
(:mod:`drivers.mock.mock_server`) and the pseudo-terminal transport (:mod:`drivers.mock.mock_pty`).
The parts are attributes (``mock.line``, ``mock.arm``, ``mock.server``, ``mock.pty``); the
controller forwards what tests and callers read. Import from here.
"""

from __future__ import annotations

import time
import urllib.parse
from typing import Any, Self

from numpy.typing import NDArray

from controller.errors import ConfigError
from controller.geometry.poses import Pose
from drivers.abb import abb_codec as codec
from drivers.mock.mock_arm import HOME_DEG, MockArm
from drivers.mock.mock_line import MockLine
from drivers.mock.mock_pty import PtyTransport
from drivers.mock.mock_schedule import Schedule
from drivers.mock.mock_server import DEFAULT_CAPACITY, MockServer

__all__ = ["DEFAULT_CAPACITY", "HOME_DEG", "MOCK_OPTIONS", "MockController", "open_mock_robot",
           "parse_mock_options"]

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
    """The simulated controller: line, arm, server and pty transport put together. Thread-safe.

    Construct with the ``mock://`` options of :data:`MOCK_OPTIONS`, by keyword (each part checks
    its own and raises :class:`ConfigError`); serve it with :meth:`serve_pty`, or drive its line
    directly with :meth:`exchange` (bytes in, bytes out).
    """

    def __init__(self, *, seed: int = 0, drop: float = 0.0, corrupt: float = 0.0,
                 dup: float = 0.0, delay_ms: float = 0.0, baud: int = 0,
                 time_scale: float = 0.0, fail_at_point: int | None = None,
                 capacity: int = DEFAULT_CAPACITY, disconnect: float = 0.0) -> None:
        self.seed = seed
        self.schedule = Schedule()
        self.line = MockLine(self.schedule, seed=seed, drop=drop, corrupt=corrupt, dup=dup,
                             delay_ms=delay_ms, baud=baud, disconnect=disconnect)
        self.arm = MockArm(self.schedule, time_scale=time_scale, fail_at_point=fail_at_point)
        self.server = MockServer(self.arm, self.line, capacity=capacity)
        self.line.on_line = self.server.handle
        self.arm.notify = self.server.event
        self.pty = PtyTransport(self.line,
                                on_disconnect=lambda: self.arm.action_log.append("disconnect"))

    # ---- what callers read -------------------------------------------------------------------

    @property
    def executed(self) -> list[dict[str, Any]]:
        """Every motion or weld the controller started (:attr:`MockArm.executed`)."""
        return self.arm.executed

    @property
    def action_log(self) -> list[str]:
        """Ordered safety-relevant actions: arc_on, arc_off, stop, restart, disconnect."""
        return self.arm.action_log

    @property
    def arc_on(self) -> bool:
        """The weld (arc) digital output."""
        return self.arm.arc_on

    @property
    def joints_deg(self) -> NDArray[Any]:
        """The arm's controller axes (deg) now."""
        return self.arm.joints_deg

    def flange_pose(self) -> Pose:
        """The arm's actual ``T_base_flange`` (mm) now."""
        return self.arm.flange_pose()

    @property
    def tool(self) -> Pose:
        """The active tool ``T_flange_tcp`` (mm) as last set over the link."""
        return self.arm.tool

    @property
    def link_stats(self) -> dict[str, float]:
        """Bytes and lines each way (the line), bad lines, requests, duplicates (the server)."""
        return {**self.line.stats, **self.server.stats}

    @property
    def link_path(self) -> str | None:
        """The symlink the pty is served behind (None when not served)."""
        return self.pty.link_path

    # ---- what callers do ---------------------------------------------------------------------

    def exchange(self, data: bytes) -> bytes:
        """Bytes in, the bytes due now out (:meth:`MockLine.exchange`; for time_scale 0)."""
        return self.line.exchange(data)

    def serve_pty(self, link_path: str | None = None) -> str:
        """Serve on a pseudo-terminal in a thread; the symlink path to open (:meth:`stop`)."""
        return self.pty.serve(link_path)

    def stop(self) -> None:
        """Stop serving and remove the symlink (idempotent; :meth:`serve_pty` serves again)."""
        self.pty.stop()

    def disconnect(self, timeout_s: float = 2.0, wait: bool = True) -> None:
        """Drop the link; a new pty behind the same path (:meth:`PtyTransport.disconnect`)."""
        self.pty.disconnect(timeout_s, wait)

    def request_cycle(self, job: str) -> None:
        """The operator asks for a cycle of ``job``: latched, and a ``CY`` event is sent."""
        self.server.request_cycle(job)

    def restart(self) -> None:
        """Simulate a controller restart: motion stopped (arc off), session and path forgotten."""
        with self.schedule.lock:
            self.schedule.now = time.monotonic()
            self.arm.restart()
            self.schedule.clear()
            self.server.reset()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


def open_mock_robot(url: str, *, limits: Any = None, timeout_s: float = 5.0,
                    **link_options: Any) -> Any:
    """``mock://?opts``: a MockController on a pty and an AbbRobot on it (``robot.mock``).

    The client's ack timeout and status poll are set from the mock's simulated speeds unless given.
    The mock is stopped when the robot is closed. Raises :class:`ConfigError` for bad options.
    """
    parsed = urllib.parse.urlsplit(url)
    if parsed.netloc or parsed.path not in ("", "/"):
        raise ConfigError(f"mock URL {url!r} takes options only: mock://?seed=7&drop=0.01")
    mock = MockController(**parse_mock_options(parsed.query))
    return robot_on_simulated_controller("mock://", mock, limits=limits, timeout_s=timeout_s,
                                         processing_s=0.15, min_poll_s=0.3, **link_options)


def robot_on_simulated_controller(url: str, ctl: Any, *, limits: Any, timeout_s: float,
                                  processing_s: float, min_poll_s: float,
                                  **link_options: Any) -> Any:
    """An AbbRobot on a simulated controller ``ctl`` (the mock or the RAPID interpreter).

    Unless given, the ack timeout is the controller's ``processing_s`` (s) plus the line's delay
    and the wire time of a request and its reply at the line's baud; the status poll is four of
    those (at least ``min_poll_s``). ``robot.mock`` is ``ctl``; it is stopped with the robot.
    """
    from drivers.abb.abb_link import line_time_s
    from drivers.abb.abb_robot import AbbRobot

    wire = line_time_s(2 * (codec.MAX_LINE + 1), ctl.line.baud)
    link_options.setdefault("ack_timeout_s", processing_s + ctl.line.delay_s + wire)
    link_options.setdefault("status_poll_s", max(min_poll_s, 4 * link_options["ack_timeout_s"]))
    link_options.setdefault("session", 1 + ctl.seed % 999)
    robot = AbbRobot(url, limits=limits, timeout_s=timeout_s, **link_options)
    robot.mock = ctl
    robot.prepare = ctl.serve_pty
    robot._owned.append(ctl)
    return robot
