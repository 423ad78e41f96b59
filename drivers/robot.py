"""The ``Robot`` interface, its command value objects, safety limits, and ``open_robot(url)``.

The controller only sees :class:`Robot`; it cannot tell the mock from the real controller. Robots
are chosen by URL through one explicit registry (:func:`open_robot`):

* ``mock://?seed=7&drop=0.01&...``: an in-process
:class:`~drivers.mock.mock_controller.MockController`
  served on a real pseudo-terminal and driven by the same client as the real robot; the mock
  object is reachable as ``robot.mock`` (for tests and the simulated camera).
* anything else (``/dev/ttyS0``, ``/dev/pts/N``, a pty symlink, ``socket://host:port``,
  ``loop://``, ``spy://...``) goes to pyserial's ``serial_for_url`` untouched.

Every motion command is a frozen value object validated against :class:`SafetyLimits` (workspace
box, speed) and the robot model (joint limits, reachability) *before* a byte is encoded.
"""

from __future__ import annotations

import abc
import importlib
import pkgutil
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from controller.errors import ConfigError, InputError, RobotFault, SafetyError
from controller.geometry.kinematics import check_joint_limits, flange_pose, irb2400, solve_ik
from controller.geometry.poses import Pose, check_pose, invert

F64 = NDArray[np.float64]

#: Default timeout (s) of one request/reply exchange, retries included.
DEFAULT_TIMEOUT_S = 5.0


class MotionTimeout(RobotFault):
    """The link answered, but the robot did not report the end of the motion within the timeout.

    Distinct from :class:`LinkError` (the link returned nothing). The motion may still be running:
    call ``abort()``.
    """


@dataclass(frozen=True)
class SafetyLimits:
    """Workspace box of the TCP in the base frame (mm) and the maximum TCP speed (mm/s).

    Every motion target, each path point too, is checked against these before it is encoded.
    """

    workspace_min_mm: tuple[float, float, float] = (-1800.0, -1800.0, -400.0)
    workspace_max_mm: tuple[float, float, float] = (1800.0, 1800.0, 2100.0)
    max_speed_mm_s: float = 250.0

    def __post_init__(self) -> None:
        lo = np.asarray(self.workspace_min_mm, dtype=np.float64)
        hi = np.asarray(self.workspace_max_mm, dtype=np.float64)
        if lo.shape != (3,) or hi.shape != (3,) or not np.all(np.isfinite(lo)) \
                or not np.all(np.isfinite(hi)) or np.any(lo >= hi):
            raise ConfigError(f"safety workspace box must be min < max, 3 finite values each "
                              f"(mm), got {self.workspace_min_mm} .. {self.workspace_max_mm}")
        if not np.isfinite(self.max_speed_mm_s) or self.max_speed_mm_s <= 0:
            raise ConfigError(f"safety max_speed_mm_s must be > 0, got {self.max_speed_mm_s}")

    def check_point(self, p_mm: ArrayLike, name: str) -> None:
        """Raise :class:`SafetyError` naming ``name`` if the point (mm, base) is outside the box."""
        p = np.asarray(p_mm, dtype=np.float64)
        lo = np.asarray(self.workspace_min_mm)
        hi = np.asarray(self.workspace_max_mm)
        if not np.all(np.isfinite(p)) or np.any(p < lo) or np.any(p > hi):
            raise SafetyError(
                f"{name} at ({p[0]:.1f}, {p[1]:.1f}, {p[2]:.1f}) mm is outside the safety "
                f"workspace box {list(self.workspace_min_mm)} .. {list(self.workspace_max_mm)} "
                "mm; nothing was sent", position_mm=[float(v) for v in p])

    def check_speed(self, speed_mm_s: float, name: str) -> None:
        """Raise :class:`SafetyError` when the speed is not in (0, max_speed_mm_s]."""
        if not np.isfinite(speed_mm_s) or not 0 < speed_mm_s <= self.max_speed_mm_s:
            raise SafetyError(f"{name}: speed {speed_mm_s} mm/s is not in (0, "
                              f"{self.max_speed_mm_s}] mm/s (safety limit); nothing was sent",
                              speed_mm_s=float(speed_mm_s))


def _speed(v: object, name: str) -> float:
    try:
        s = float(v)  # type: ignore[arg-type]
    except (TypeError, ValueError) as err:
        raise InputError(f"{name} must be a speed in mm/s, got {v!r}") from err
    if not np.isfinite(s) or s <= 0:
        raise InputError(f"{name} must be a positive finite speed in mm/s, got {v!r}")
    return s


@dataclass(frozen=True)
class ToolData:
    """RAPID ``tooldata`` (tframe only): the TCP in the flange frame, ``T_flange_tcp`` (mm)."""

    T_flange_tcp: F64

    def __post_init__(self) -> None:
        object.__setattr__(self, "T_flange_tcp", check_pose(self.T_flange_tcp, "T_flange_tcp"))


@dataclass(frozen=True)
class MoveJoints:
    """RAPID ``MoveAbsJ``: controller axes 1-6 in degrees, TCP speed in mm/s, fine point."""

    joints_deg: F64
    speed_mm_s: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "joints_deg",
                           check_joint_limits(irb2400(), self.joints_deg, "move_joints target"))
        object.__setattr__(self, "speed_mm_s", _speed(self.speed_mm_s, "move_joints speed"))

    def check(self, limits: SafetyLimits, tool: ToolData) -> None:
        """Safety check: the TCP at the target inside the box, the speed within the limit."""
        T_base_tcp = flange_pose(irb2400(), self.joints_deg) @ tool.T_flange_tcp
        limits.check_point(T_base_tcp[:3, 3], "move_joints target (TCP)")
        limits.check_speed(self.speed_mm_s, "move_joints")


@dataclass(frozen=True)
class MoveLinear:
    """RAPID ``MoveL`` of the active tool to ``T_base_tcp`` (mm, wobj0), speed in mm/s, fine."""

    T_base_tcp: F64
    speed_mm_s: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "T_base_tcp", check_pose(self.T_base_tcp, "move_linear target"))
        object.__setattr__(self, "speed_mm_s", _speed(self.speed_mm_s, "move_linear speed"))

    def check(self, limits: SafetyLimits, tool: ToolData) -> None:
        """Box, speed, and IK reachability (raises ReachabilityError / JointLimitError)."""
        limits.check_point(self.T_base_tcp[:3, 3], "move_linear target")
        limits.check_speed(self.speed_mm_s, "move_linear")
        solve_ik(irb2400(), self.T_base_tcp @ invert(tool.T_flange_tcp), name="move_linear target")


@dataclass(frozen=True)
class PathTargets:
    """A weld path: TCP poses ``T_base_tcp`` (mm, wobj0), in order; uploaded, never truncated."""

    targets: tuple[F64, ...]

    def __post_init__(self) -> None:
        if len(self.targets) == 0:
            raise InputError("upload_path: the path has no points")
        object.__setattr__(self, "targets", tuple(
            check_pose(T, f"path point {i + 1}") for i, T in enumerate(self.targets)))

    def check(self, limits: SafetyLimits, tool: ToolData, capacity: int) -> None:
        """Length within ``capacity``, every point in the box and reachable; names the point."""
        if len(self.targets) > capacity:
            raise SafetyError(f"the path has {len(self.targets)} points, the controller buffer "
                              f"holds {capacity}; split the weld, nothing was sent",
                              points=len(self.targets), capacity=capacity)
        T_tcp_flange = invert(tool.T_flange_tcp)
        near = None
        for i, T in enumerate(self.targets):
            limits.check_point(T[:3, 3], f"path point {i + 1}")
            near = solve_ik(irb2400(), T @ T_tcp_flange, near_deg=near, name=f"path point {i + 1}")


@dataclass(frozen=True)
class WeldRun:
    """Run the weld pass over the uploaded path at ``speed_mm_s``, arc output on or dry."""

    speed_mm_s: float
    arc_output: bool = True

    def __post_init__(self) -> None:
        object.__setattr__(self, "speed_mm_s", _speed(self.speed_mm_s, "weld speed"))

    def check(self, limits: SafetyLimits) -> None:
        """The weld speed within the safety limit."""
        limits.check_speed(self.speed_mm_s, "run_weld")


@dataclass(frozen=True)
class Event:
    """A controller event.

    ``kind`` is ``in_position`` (motion ``mid`` done), ``progress`` (weld ``mid`` reached path point
    ``index``, 1-based), ``done`` (weld finished), ``fault`` (motion stopped with error ``code`` at
    point ``index``; arc already off) or ``cycle_request`` (operator asked for job ``job``).
    """

    kind: str
    mid: int = 0
    index: int = 0
    code: int = 0
    job: str = ""


@dataclass
class MotionHandle:
    """A motion the controller accepted. ``wait(timeout_s)`` returns when the controller says done.

    ``progress`` is the last path point reached (welds), ``state`` one of ``running``, ``done``,
    ``fault``, ``aborted``. Updated by the link as events or status replies arrive.
    """

    mid: int
    kind: str
    n_points: int = 0
    progress: int = 0
    state: str = "running"
    fault_code: int = 0
    _waiter: Callable[[MotionHandle, float], None] | None = field(default=None, repr=False)
    _changed: threading.Condition = field(default_factory=threading.Condition, repr=False)

    def wait(self, timeout_s: float) -> None:
        """Block until the motion is done (at most ``timeout_s`` seconds).

        Raises :class:`RobotFault` when the controller reports an error or an abort,
        :class:`MotionTimeout` when the link works but the motion did not finish in time,
        :class:`LinkError` when the link returned nothing.
        """
        if self._waiter is None:
            raise RobotFault(f"motion {self.mid} has no link to wait on")
        self._waiter(self, timeout_s)


class Robot(abc.ABC):
    """A robot controller behind a link. Context manager: I/O in ``open()``, never in ``__init__``.

    Units: joints in controller degrees, poses as 4x4 arrays in mm (``T_base_flange`` with tool0 and
    wobj0 for ``read_pose``; ``T_base_tcp`` with the active tool for motion targets).
    """

    mock: Any = None

    @abc.abstractmethod
    def open(self) -> None:
        """Open the link and the session. Raises LinkError / ProtocolError."""

    @abc.abstractmethod
    def close(self) -> None:
        """Close the link (does not stop a running motion; call abort() for that)."""

    def __enter__(self) -> Robot:
        self.open()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @abc.abstractmethod
    def identify(self) -> dict[str, Any]:
        """Protocol, version, robot name, path buffer capacity, controller boot count."""

    @abc.abstractmethod
    def read_joints(self) -> F64:
        """Controller axes 1-6 (degrees), shape (6,)."""

    @abc.abstractmethod
    def read_pose(self) -> Pose:
        """``T_base_flange`` (4x4, mm) as the controller reports it (tool0, wobj0)."""

    @abc.abstractmethod
    def set_tool(self, T_flange_tcp: ArrayLike) -> None:
        """Set the active tool on the controller: TCP in the flange frame (mm)."""

    @abc.abstractmethod
    def move_joints(self, joints_deg: ArrayLike, speed_mm_s: float = 100.0) -> MotionHandle:
        """Joint move to controller axes (deg). Checked (limits, box, speed) before sending."""

    @abc.abstractmethod
    def move_linear(self, T_base_tcp: ArrayLike, speed_mm_s: float = 100.0) -> MotionHandle:
        """Linear move of the TCP to ``T_base_tcp`` (mm); checked (box, speed, IK) first."""

    @abc.abstractmethod
    def upload_path(self, targets: Sequence[ArrayLike]) -> None:
        """Upload the weld path (``T_base_tcp`` each); every point checked first; never cut."""

    @abc.abstractmethod
    def run_weld(self, speed_mm_s: float, arc_output: bool = True) -> MotionHandle:
        """Run the weld pass over the uploaded path; handle.progress follows the points."""

    @abc.abstractmethod
    def abort(self) -> None:
        """Arc off first, then stop and clear the motion. Works while a motion runs."""

    @abc.abstractmethod
    def status(self) -> dict[str, Any]:
        """Controller status: ``arc_on``, ``moving``, ``error`` (0 none) and more.

        Also ``mid``, ``motion_state``, ``path_index``, ``cycle_request`` (job name or None).
        """

    @abc.abstractmethod
    def poll_event(self, timeout_s: float) -> Event | None:
        """The next controller event, or None when none came within ``timeout_s``."""


# ---- the registry ---------------------------------------------------------------------------

#: Robot URL schemes handled by seamguide itself (module:function, imported lazily).
ROBOT_SCHEMES: dict[str, str] = {"mock": "drivers.mock.mock_controller:open_mock_robot"}


def serial_schemes() -> list[str]:
    """URL schemes pyserial's ``serial_for_url`` knows (its ``protocol_*`` handler modules)."""
    import serial.urlhandler

    mods = pkgutil.iter_modules(serial.urlhandler.__path__)
    return sorted(m.name[len("protocol_"):] for m in mods if m.name.startswith("protocol_"))


def open_robot(url: str, *, limits: SafetyLimits | None = None,
               timeout_s: float = DEFAULT_TIMEOUT_S, **link_options: Any) -> Robot:
    """A :class:`Robot` for ``url`` (not opened yet: use it as a context manager or call open()).

    ``mock://?opts`` builds an in-process mock controller on a pseudo-terminal; any other URL
    (device path or a pyserial URL) is handed to ``serial_for_url`` untouched. ``limits`` default
    to :class:`SafetyLimits` ``()``; ``timeout_s`` bounds each request. ``link_options`` go to
    :class:`~drivers.abb.abb_link.AbbRobot` (``ack_timeout_s``, ``retries``, ``baudrate``, ...).
    Raises :class:`ConfigError` for an unknown scheme (listing the known ones) or mock option.
    """
    if not isinstance(url, str) or not url:
        raise ConfigError(f"robot URL must be a non-empty string, got {url!r}")
    lim = limits if limits is not None else SafetyLimits()
    if "://" in url:
        scheme = url.split("://", 1)[0].lower()
        if scheme in ROBOT_SCHEMES:
            mod, fn = ROBOT_SCHEMES[scheme].split(":")
            factory = getattr(importlib.import_module(mod), fn)
            robot: Robot = factory(url, limits=lim, timeout_s=timeout_s, **link_options)
            return robot
        known = sorted(ROBOT_SCHEMES) + serial_schemes()
        if scheme not in known:
            raise ConfigError(f"robot URL {url!r}: unknown scheme {scheme!r}; known schemes: "
                              f"{', '.join(s + '://' for s in known)} or a device path")
    from drivers.abb.abb_link import AbbRobot

    return AbbRobot(url, limits=lim, timeout_s=timeout_s, **link_options)
