"""The ``Robot`` interface the controller sees, its motion handles and its events.

Implemented by :class:`drivers.abb.abb_robot.AbbRobot` (the real controller and the mock alike);
built by :func:`drivers.robot.open_robot`. Units: joints in controller degrees, poses 4x4 in mm.
"""

from __future__ import annotations

import abc
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from controller.errors import RobotFault
from controller.geometry.poses import Pose
from drivers.robot_commands import SafetyLimits

F64 = NDArray[np.float64]

#: Default timeout (s) of one request/reply exchange, retries included.
DEFAULT_TIMEOUT_S = 5.0


class MotionTimeout(RobotFault):
    """The link answered, but the robot did not report the end of the motion within the timeout.

    Distinct from :class:`LinkError` (the link returned nothing). The motion may still be running:
    call ``abort()``.
    """


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
    #: What every motion command is checked against before a byte is sent (workspace box of the
    #: TCP, speed). A weld cycle sets its job's limits here before its first motion.
    limits: SafetyLimits

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
    def upload_path(self, targets: Sequence[ArrayLike],
                    circle_points_mm: Sequence[ArrayLike | None] | None = None,
                    start: ArrayLike | None = None) -> None:
        """Upload the weld path (``T_base_tcp`` each); every point checked first; never cut.

        The robot reaches each point by a ``MoveL``, or by a ``MoveC`` from the point before
        when ``circle_points_mm`` (one entry per point, None for a MoveL) gives its circle point.
        The first point's segment starts where the robot is when the pass starts; it may be a
        circle only when ``start`` (``T_base_tcp``) says where that is, and ``run_weld`` then
        refuses unless the robot got there by a completed ``move_linear``.
        """

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
