"""Weld path planning: torch poses along the located seam, tool offset, approach/depart, reach.

Frames: all targets are ``T_base_tcp`` (the torch tip frame in the robot base, mm). The tool
(``T_flange_tcp``) has z along the torch axis pointing into the work, as ABB tooldata does.

Seam frame at each point: x along the travel direction (the seam tangent), z into the part (minus
the surface normal made perpendicular to the tangent), y = z x x. The torch axis is the seam z
tilted by the work angle about x (sideways) and by the travel angle about y (positive = push, the
tip leading). The tool offset moves every weld target back along the torch axis, so the torch tip
stands ``tool_offset_mm`` off the seam: the published cell used a tool 3 mm longer than the real
one for the same reason, so that a small error cannot drive the torch into the part.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.signal import savgol_filter

from controller.errors import ConfigError, ReachabilityError
from controller.geometry.kinematics import RobotModel, ik_from, inverse_kinematics
from controller.geometry.poses import invert, make_pose, pose_to_dict, rotation_about

F64 = NDArray[np.float64]


#: Largest axis step (deg) between two consecutive targets that the continuity solution may take
#: before the full solution set is solved instead (the nearest solution of the set is then used).
CONTINUITY_STEP_DEG = 10.0


def default_torch() -> F64:
    """A straight 350 mm torch along the flange z axis: ``T_flange_tcp`` (mm)."""
    return make_pose(np.eye(3), [0.0, 0.0, 350.0])


@dataclass(frozen=True)
class WeldParams:
    """How to weld the seam: speed (mm/s), torch angles (deg), offsets (mm), tool."""

    speed_mm_s: float = 8.0
    work_angle_deg: float = 0.0
    travel_angle_deg: float = 10.0
    tool_offset_mm: float = 3.0
    approach_mm: float = 50.0
    spacing_mm: float | None = 2.0
    count: int | None = None
    T_flange_tcp: F64 = field(default_factory=default_torch)
    max_joint_step_deg: float = 60.0

    def __post_init__(self) -> None:
        checks = [
            (0 < self.speed_mm_s <= 100, "speed_mm_s", "in (0, 100] mm/s"),
            (abs(self.work_angle_deg) <= 45, "work_angle_deg", "within +-45 deg"),
            (abs(self.travel_angle_deg) <= 45, "travel_angle_deg", "within +-45 deg"),
            (0 <= self.tool_offset_mm <= 50, "tool_offset_mm", "in [0, 50] mm"),
            (0 <= self.approach_mm <= 300, "approach_mm", "in [0, 300] mm"),
        ]
        for ok, name, rng in checks:
            if not ok:
                raise ConfigError(f"weld parameter {name} = {getattr(self, name)} must be {rng}")


@dataclass(frozen=True)
class WorkspaceBox:
    """The box (base frame, mm) every torch target must stay inside."""

    min_mm: tuple[float, float, float] = (300.0, -900.0, -100.0)
    max_mm: tuple[float, float, float] = (1600.0, 900.0, 1500.0)

    def contains(self, p: F64) -> bool:
        """True when point ``p`` (mm, base frame) is inside the box (boundary included)."""
        return bool(np.all(p >= np.asarray(self.min_mm)) and np.all(p <= np.asarray(self.max_mm)))


@dataclass
class WeldTarget:
    """One torch target: kind ('approach', 'weld', 'depart'), pose, joints, arc state."""

    kind: str
    T_base_tcp: F64
    joints_deg: F64
    arc: bool

    def to_dict(self, index: int) -> dict[str, Any]:
        """JSON form: index, kind, position_mm, quaternion_wxyz, joints_deg, arc."""
        d: dict[str, Any] = {"index": index, "kind": self.kind}
        d.update(pose_to_dict(self.T_base_tcp, 4))
        d["joints_deg"] = [round(float(v), 4) for v in self.joints_deg]
        d["arc"] = self.arc
        return d


@dataclass
class WeldPath:
    """The planned path: targets in order, and the parameters that made it."""

    targets: list[WeldTarget]
    params: WeldParams
    #: The weld targets as MoveL / MoveC segments (:func:`controller.path.path_fit.fit_segments`),
    #: when fitted; empty: every target is sent.
    segments: list[Any] = field(default_factory=list)

    @property
    def weld_targets(self) -> list[WeldTarget]:
        """Only the targets welded with the arc on."""
        return [t for t in self.targets if t.kind == "weld"]

    def to_json(self) -> list[dict[str, Any]]:
        """The ``weld_path`` list of the locate output contract."""
        return [t.to_dict(i) for i, t in enumerate(self.targets)]

    def upload(self) -> tuple[list[F64], list[F64 | None]]:
        """What the weld pass runs, arc on: TCP poses from the first weld target to the last.

        The pass starts at the first weld target (:attr:`start`: the cycle reaches it dry from
        the approach, so it is not sent again), then runs to the fitted segments' ends (a MoveC
        where a segment has a circle point, the first one from :attr:`start`), or to every
        other weld target when none were fitted. The depart is not in it: the arc goes off at
        the last weld target and the cycle departs dry.
        """
        weld = self.weld_targets
        if not self.segments:
            rest = weld[1:] or weld  # a one-point weld: that point, where the torch already is
            return [t.T_base_tcp for t in rest], [None] * len(rest)
        return [s.T_end for s in self.segments], [s.via_mm for s in self.segments]

    @property
    def start(self) -> F64:
        """``T_base_tcp`` where the weld pass starts (the first weld target), mm."""
        return self.weld_targets[0].T_base_tcp


#: Span (mm) of the local cubic fitted to the seam points for each tangent (Savitzky-Golay). The
#: located points scatter by ~0.01 mm; central differences over 4 mm turn that into 0.18 deg RMS of
#: torch wobble against the true tangent on the dry run's S-curve; a cubic over 24 mm halves it
#: (0.09 deg RMS, 0.15 deg at most away from the ends) and, being exact for cubics, turns a
#: 60 mm-radius circle's tangent by under 0.04 deg.
TANGENT_SPAN_MM = 24.0


def tangents(points: F64) -> F64:
    """Unit tangents (N, 3) of an ordered polyline (mm, about evenly spaced).

    The derivative of a local cubic over :data:`TANGENT_SPAN_MM` (polynomial fits at the ends);
    central differences when the seam has too few points for that.
    """
    step = float(np.mean(np.linalg.norm(np.diff(points, axis=0), axis=1)))
    window = 2 * int(round(TANGENT_SPAN_MM / max(step, 1e-9) / 2.0)) + 1
    if window < 5 or len(points) < window:
        t = np.gradient(points, axis=0)
    else:
        t = savgol_filter(points, window, 3, deriv=1, axis=0, mode="interp")
    return np.asarray(t / np.linalg.norm(t, axis=1, keepdims=True), dtype=np.float64)


def seam_normals(points: F64, nominal_normal: F64) -> F64:
    """Per-point surface normals: ``nominal_normal`` made perpendicular to the local tangent.

    ``nominal_normal`` comes from the job, or when it has none from the cameras' viewing direction
    (the sheets face the cameras); either way it points out of the part.
    """
    n0 = np.asarray(nominal_normal, dtype=np.float64)
    n0 = n0 / np.linalg.norm(n0)
    t = tangents(points)
    n = n0[None, :] - np.einsum("ij,j->i", t, n0)[:, None] * t
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    if np.any(norm < 0.2):
        raise ConfigError("the nominal surface normal runs along the seam: give the normal of the "
                          "sheets (out of the part) in the job")
    return n / norm


def torch_poses(points: F64, normals: F64, params: WeldParams) -> list[F64]:
    """``T_base_tcp`` at each seam point with the torch angles and tool offset applied."""
    t = tangents(points)
    z = -np.asarray(normals, dtype=np.float64)
    y = np.cross(z, t)
    y /= np.linalg.norm(y, axis=1, keepdims=True)
    x = np.cross(y, z)
    R_seam = np.stack([x, y, z], axis=2)  # columns x, y, z
    tilt = (rotation_about([0, 1, 0], np.radians(params.travel_angle_deg))
            @ rotation_about([1, 0, 0], np.radians(params.work_angle_deg)))
    out = []
    for p, Rs in zip(points, R_seam, strict=True):
        R = Rs @ tilt
        out.append(make_pose(R, p - params.tool_offset_mm * R[:, 2]))
    return out


def plan_weld(robot: RobotModel, seam_points_mm: F64, nominal_normal: F64,
              params: WeldParams = WeldParams(), workspace: WorkspaceBox = WorkspaceBox(),
              start_joints_deg: F64 | None = None) -> WeldPath:
    """Plan the weld over resampled seam points (base frame, mm, ordered, no tool offset).

    Every target is checked against the workspace box and by inverse kinematics against the joint
    limits; the IK solution nearest the previous target is kept (found by continuity from the
    previous target's joints, the full solution set only for the first target or when continuity
    fails: not converged, outside the limits, or an axis step over
    :data:`CONTINUITY_STEP_DEG`), and a jump of more than
    ``params.max_joint_step_deg`` between consecutive weld targets (a wrist flip mid-seam) is
    refused. Raises :class:`ReachabilityError` naming the first bad target.
    """
    pts = np.asarray(seam_points_mm, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) < 2:
        raise ConfigError(f"a weld needs at least 2 seam points (N, 3), got shape {pts.shape}")
    normals = seam_normals(pts, nominal_normal)
    weld = torch_poses(pts, normals, params)
    approach = weld[0].copy()
    approach[:3, 3] -= params.approach_mm * weld[0][:3, 2]
    depart = weld[-1].copy()
    depart[:3, 3] -= params.approach_mm * weld[-1][:3, 2]
    plan = [("approach", approach, False)] + [("weld", T, True) for T in weld]
    plan.append(("depart", depart, False))
    T_tcp_flange = invert(params.T_flange_tcp)
    prev = None if start_joints_deg is None else np.asarray(start_joints_deg, dtype=np.float64)
    targets: list[WeldTarget] = []
    for i, (kind, T, arc) in enumerate(plan):
        p = T[:3, 3]
        where = f"{kind} target {i} at ({p[0]:.1f}, {p[1]:.1f}, {p[2]:.1f}) mm"
        if not workspace.contains(p):
            raise ReachabilityError(f"{where} is outside the workspace box {workspace.min_mm} .. "
                                    f"{workspace.max_mm} mm", index=i, position_mm=p.tolist())
        T_flange = T @ T_tcp_flange
        ref = prev if prev is not None else np.zeros(6)
        # Continuity: from the previous target's joints, Newton steps land on the same branch in
        # a few iterations. The full solution set is solved for the first target, and
        # whenever that fails (no convergence, outside the limits, or a jump that is not a small
        # step), so the choice and the refusals are those of the full set.
        best = None
        if prev is not None and targets:
            # along the seam, seeded where the last step leads (one Newton step fewer)
            seed = prev
            if kind == "weld" and len(targets) >= 2 and targets[-2].kind == "weld":
                seed = 2.0 * prev - targets[-2].joints_deg
            best = ik_from(robot, T_flange, seed)
        if best is None or float(np.max(np.abs(best - ref))) > CONTINUITY_STEP_DEG:
            sols = inverse_kinematics(robot, T_flange)
            if not sols:
                raise ReachabilityError(f"{where} cannot be reached by the {robot.name} within "
                                        f"its joint limits with this torch orientation; change "
                                        f"the work or travel angle or move the part", index=i,
                                        position_mm=p.tolist())
            best = min(sols, key=lambda j: float(np.max(np.abs(j - ref))))
        step = float(np.max(np.abs(best - ref)))
        if prev is not None and kind == "weld" and targets and targets[-1].kind == "weld" \
                and step > params.max_joint_step_deg:
            raise ReachabilityError(f"{where}: the robot would have to turn an axis by {step:.0f} "
                                    f"deg between two weld points (a wrist or arm flip mid-seam);"
                                    f" change the torch angles or the part position", index=i,
                                    position_mm=p.tolist())
        targets.append(WeldTarget(kind, T, best, arc))
        prev = best
    return WeldPath(targets, params)
