"""The robot's command value objects and the safety limits they are checked against.

One frozen value object per robot instruction (RAPID ``MoveAbsJ``, ``MoveL``, the weld path, the
weld run, ``tooldata``). The constructor rejects a wrong joint count, a non-finite number, a joint
outside its limits; ``check`` runs the safety checks (workspace box, speed, reachability) against
:class:`SafetyLimits` before a byte is encoded. Units: mm, mm/s, controller degrees.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from controller.errors import ConfigError, InputError, SafetyError
from controller.geometry.kinematics import (
    check_joint_limits,
    flange_pose,
    irb2400,
    solve_ik_near,
)
from controller.geometry.poses import check_pose, invert
from controller.geometry.segment_motion import circle_through, segment_poses

F64 = NDArray[np.float64]

#: Largest arc one MoveC may sweep (deg): ABB allows up to 240; the fit uses at most 180.
MAX_SWEEP_DEG = 180.0


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

    def check(self, limits: SafetyLimits, tool: ToolData, near_deg: F64 | None = None) -> F64:
        """Box, speed, and IK reachability (raises ReachabilityError / JointLimitError).

        Returns a solution (controller deg); ``near_deg`` (joints the robot is at or near) only
        speeds the search up: the target is refused exactly when no solution exists.
        """
        limits.check_point(self.T_base_tcp[:3, 3], "move_linear target")
        limits.check_speed(self.speed_mm_s, "move_linear")
        return solve_ik_near(irb2400(), self.T_base_tcp @ invert(tool.T_flange_tcp), near_deg,
                             name="move_linear target")


@dataclass(frozen=True)
class PathTargets:
    """A weld path: TCP poses ``T_base_tcp`` (mm, wobj0), in order; uploaded, never truncated.

    ``circles`` (empty, or one entry per target): the circle point (mm) of the ``MoveC`` that
    reaches the target from the target before it, or None for a ``MoveL``. The first target's
    segment starts wherever the robot is: it may have a circle point only when ``start`` (the
    ``T_base_tcp`` the pass will start from) says where that is, and its circle is checked
    from there (the robot must then be there when the pass starts: the caller's check).
    """

    targets: tuple[F64, ...]
    circles: tuple[F64 | None, ...] = ()
    start: F64 | None = None

    def __post_init__(self) -> None:
        if len(self.targets) == 0:
            raise InputError("upload_path: the path has no points")
        object.__setattr__(self, "targets", tuple(
            check_pose(T, f"path point {i + 1}") for i, T in enumerate(self.targets)))
        if self.start is not None:
            object.__setattr__(self, "start", check_pose(self.start, "path start"))
        if not self.circles:
            object.__setattr__(self, "circles", (None,) * len(self.targets))
        if len(self.circles) != len(self.targets):
            raise InputError(f"upload_path: {len(self.circles)} circle points for "
                             f"{len(self.targets)} path points; give one (or None) per point")
        circles: list[F64 | None] = []
        for i, c in enumerate(self.circles):
            if c is None:
                circles.append(None)
                continue
            v = np.asarray(c, dtype=np.float64)
            if v.shape != (3,) or not np.all(np.isfinite(v)):
                raise InputError(f"upload_path: circle point of path point {i + 1} must be 3 "
                                 f"finite numbers (mm), got {c!r}")
            before = self.targets[i - 1] if i > 0 else self.start
            if before is None:
                raise InputError("upload_path: the first path point is reached from wherever the "
                                 "robot is; it can be the end of a circle only when the path's "
                                 "start is given (else send a MoveL)")
            try:
                circle = circle_through(before[:3, 3], v, self.targets[i][:3, 3])
            except InputError as err:
                raise InputError(f"upload_path: path point {i + 1}: {err}") from err
            if np.degrees(circle.sweep_rad) > MAX_SWEEP_DEG + 1e-6:
                raise InputError(f"upload_path: the circle to path point {i + 1} sweeps "
                                 f"{np.degrees(circle.sweep_rad):.0f} deg, more than "
                                 f"{MAX_SWEEP_DEG:.0f}; split it")
            circles.append(v)
        object.__setattr__(self, "circles", tuple(circles))

    def check(self, limits: SafetyLimits, tool: ToolData, capacity: int,
              near_deg: F64 | None = None) -> F64:
        """Length within ``capacity``, every point in the box and reachable; names the point.

        An arc is checked too: the arc in the box (its end points and every point where a
        coordinate turns, so the bulge between samples cannot slip out), its middle reachable.
        Returns the last point's solution (controller deg); ``near_deg`` (joints near the path's
        start) only seeds the search.
        """
        if len(self.targets) > capacity:
            raise SafetyError(f"the path has {len(self.targets)} points, the controller buffer "
                              f"holds {capacity}; split the weld, nothing was sent",
                              points=len(self.targets), capacity=capacity)
        T_tcp_flange = invert(tool.T_flange_tcp)
        near = near_deg
        if self.start is not None:
            limits.check_point(self.start[:3, 3], "path start")
        for i, (T, via) in enumerate(zip(self.targets, self.circles, strict=True)):
            name = f"path point {i + 1}"
            limits.check_point(T[:3, 3], name)
            if via is not None:
                before = self.targets[i - 1] if i > 0 else self.start
                assert before is not None  # __post_init__ refused a circle with no start
                circle = circle_through(before[:3, 3], via, T[:3, 3])
                for p in circle.point(circle.axis_extreme_fractions()):
                    limits.check_point(p, f"the circle to {name}")
                mid = segment_poses(before, T, [0.5], via, circle)[0] @ T_tcp_flange
                near = solve_ik_near(irb2400(), mid, near, name=f"the circle to {name}")
            near = solve_ik_near(irb2400(), T @ T_tcp_flange, near, name=name)
        assert near is not None  # a path has a point
        return near


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
