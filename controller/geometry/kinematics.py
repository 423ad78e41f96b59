"""ABB IRB 2400 kinematics on Pinocchio: controller joints in degrees <-> flange (tool0) pose in mm.

This module is the one boundary that sees Pinocchio's metres and the IRB 2400's parallel linkage.

**Axis 2/3 coupling.** On the IRB 2400 the upper arm is driven through a parallel linkage, and the
controller's axis-3 angle is the upper arm's angle against the horizontal, not against the lower
arm. The URDF is a serial chain whose joint 3 is relative to link 2, so::

    urdf_q3 = axis3 - axis2          axis3 = urdf_q3 + urdf_q2

(ROS-Industrial's abb_driver applies the same correction when its ``J23_coupled`` parameter is
set.) Everything outside this module speaks controller axes in degrees.

**Joint limits** are the controller's (ABB product specification, IRB 2400): axis 1 +-180, axis 2
-100..+110, axis 3 -60..+65, axis 4 +-200, axis 5 +-120, axis 6 +-400 degrees. The arm has a further
axis 2/3 interaction limit in the controller that is not modelled here; the mock controller and the
reachability check use these box limits only.

**Inverse kinematics** is numerical, as the product's reachability checks need every solution: the
seeds are the eight closed-form branches of the spherical wrist (shoulder front/back, elbow
up/down, wrist flip) plus their +-360 deg turns of axes 4 and 6, each refined by damped least
squares on Pinocchio's frame Jacobian; distinct solutions within limits are returned.
"""

from __future__ import annotations

import functools
import itertools
import math
import threading
from dataclasses import dataclass
from importlib import resources

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from controller.errors import InputError, JointLimitError, PoseMismatchError, ReachabilityError
from controller.geometry.poses import Pose, check_pose, make_pose, pose_error

F64 = NDArray[np.float64]

#: Controller axis limits (degrees), from the IRB 2400 product specification.
IRB2400_LIMITS_DEG: F64 = np.array([
    [-180.0, 180.0], [-100.0, 110.0], [-60.0, 65.0],
    [-200.0, 200.0], [-120.0, 120.0], [-400.0, 400.0]])

# Arm dimensions (mm) used by the closed-form seeds; they must agree with the URDF (a test checks).
_SHOULDER_X, _SHOULDER_Z = 100.0, 615.0
_LOWER_ARM = 705.0
_FOREARM_X, _FOREARM_Z = 755.0, 135.0
_WRIST_TO_FLANGE = 85.0
# tool0 relative to link_6 (URDF fixed joint rpy = 0, pi/2, 0).
_R_LINK6_TOOL0 = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])


@dataclass(frozen=True)
class RobotModel:
    """A Pinocchio model of the arm, built once and passed to the pure functions below."""

    model: pin.Model
    tool0_frame: int
    limits_deg: F64
    name: str = "ABB IRB 2400"


@functools.cache
def irb2400() -> RobotModel:
    """The IRB 2400 model from the URDF shipped in the package (built once per process)."""
    urdf = resources.files("controller.geometry") / "data" / "irb2400.urdf"
    with resources.as_file(urdf) as path:
        model = pin.buildModelFromUrdf(str(path))
    return RobotModel(model=model, tool0_frame=model.getFrameId("tool0"),
                      limits_deg=IRB2400_LIMITS_DEG.copy())


def _check_joint_vector(joints_deg: ArrayLike, name: str) -> F64:
    try:
        j = np.asarray(joints_deg, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise InputError(f"{name} must be 6 joint values in degrees, got {joints_deg!r}") from err
    if j.shape != (6,):
        raise InputError(f"{name} must be exactly 6 joint values in degrees (axes 1-6), "
                         f"got {j.size}: {joints_deg!r}")
    if not np.all(np.isfinite(j)):
        raise InputError(f"{name} must be finite numbers, got {joints_deg!r}")
    return j


def check_joint_limits(robot: RobotModel, joints_deg: ArrayLike, name: str = "joints_deg") -> F64:
    """Validate 6 controller joint values (deg) against the limits; return them as an array.

    Raises :class:`InputError` for a wrong count or non-finite values and :class:`JointLimitError`
    naming the first axis outside its limits.
    """
    j = _check_joint_vector(joints_deg, name)
    lo, hi = robot.limits_deg[:, 0], robot.limits_deg[:, 1]
    bad = np.flatnonzero((j < lo - 1e-9) | (j > hi + 1e-9))
    if bad.size:
        i = int(bad[0])
        raise JointLimitError(
            f"{name}: axis {i + 1} = {j[i]:.4f} deg is outside its limits "
            f"[{lo[i]:.0f}, {hi[i]:.0f}] deg of the {robot.name}",
            axis=i + 1, value_deg=float(j[i]), limits_deg=[float(lo[i]), float(hi[i])])
    return j


def within_limits(robot: RobotModel, joints_deg: ArrayLike) -> bool:
    """True when all six controller joint values (deg) are inside the limits."""
    j = np.asarray(joints_deg, dtype=np.float64)
    return bool(np.all(j >= robot.limits_deg[:, 0] - 1e-9) and np.all(j <= robot.limits_deg[:, 1]
                                                                       + 1e-9))


def controller_to_urdf(joints_deg: ArrayLike) -> F64:
    """Controller axes (deg) to URDF joint positions (rad), applying the axis 2/3 coupling."""
    q = np.radians(np.asarray(joints_deg, dtype=np.float64))
    q[2] = q[2] - q[1]
    return q


def urdf_to_controller(q_rad: ArrayLike) -> F64:
    """URDF joint positions (rad) to controller axes (deg), undoing the axis 2/3 coupling."""
    q = np.asarray(q_rad, dtype=np.float64).copy()
    q[2] = q[2] + q[1]
    return np.degrees(q)


def se3_to_pose(M: pin.SE3) -> Pose:
    """Pinocchio ``SE3`` (metres) to a 4x4 pose in mm."""
    return make_pose(np.array(M.rotation), np.array(M.translation) * 1000.0)


def pose_to_se3(T: ArrayLike) -> pin.SE3:
    """4x4 pose in mm to a Pinocchio ``SE3`` in metres."""
    A = np.asarray(T, dtype=np.float64)
    return pin.SE3(A[:3, :3].copy(), A[:3, 3] / 1000.0)


def _fk_urdf(robot: RobotModel, q: F64) -> pin.SE3:
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, q)
    return data.oMf[robot.tool0_frame].copy()


def flange_pose(robot: RobotModel, joints_deg: ArrayLike, check_limits: bool = True) -> Pose:
    """Forward kinematics: ``T_base_flange`` (mm) for controller joint values in degrees.

    Raises :class:`JointLimitError` for joints outside limits unless ``check_limits`` is False
    (used when reading back what a controller reports, which is never refused).
    """
    j = check_joint_limits(robot, joints_deg) if check_limits else _check_joint_vector(
        joints_deg, "joints_deg")
    return se3_to_pose(_fk_urdf(robot, controller_to_urdf(j)))


def _closed_form_seeds(T_base_flange: Pose) -> list[F64]:
    """Closed-form URDF joint branches (rad) of the spherical-wrist arm; may be out of limits."""
    R = T_base_flange[:3, :3]
    wc = T_base_flange[:3, 3] - _WRIST_TO_FLANGE * R[:, 2]  # tool0 z = link_6 x
    L = math.hypot(_FOREARM_X, _FOREARM_Z)
    phi = math.atan2(_FOREARM_X, _FOREARM_Z)
    seeds: list[F64] = []
    q1a = math.atan2(wc[1], wc[0])
    rho = math.hypot(wc[0], wc[1])
    for q1, r in ((q1a, rho), (q1a + math.pi, -rho)):
        dr, dz = r - _SHOULDER_X, wc[2] - _SHOULDER_Z
        c = (dr * dr + dz * dz - _LOWER_ARM**2 - L * L) / (2 * _LOWER_ARM * L)
        if abs(c) > 1.0 + 1e-12:
            continue
        base = math.acos(max(-1.0, min(1.0, c)))
        for q3 in (base - phi, -base - phi):
            a = _FOREARM_X * math.cos(q3) + _FOREARM_Z * math.sin(q3)
            b = _LOWER_ARM - _FOREARM_X * math.sin(q3) + _FOREARM_Z * math.cos(q3)
            q2 = math.atan2(b * dr - a * dz, a * dr + b * dz)
            q123 = np.array([q1, q2, q3, 0.0, 0.0, 0.0])
            R03 = _fk_rotation_to_link3(q123)
            R36 = R03.T @ R @ _R_LINK6_TOOL0.T
            # R36 = Rx(q4) Ry(q5) Rx(q6)
            q5 = math.acos(max(-1.0, min(1.0, R36[0, 0])))
            if abs(math.sin(q5)) < 1e-9:
                q4, q6 = 0.0, math.atan2(-R36[1, 2], R36[1, 1])
                wrists = [(q4, q5, q6)]
            else:
                q4 = math.atan2(R36[1, 0], -R36[2, 0])
                q6 = math.atan2(R36[0, 1], R36[0, 2])
                wrists = [(q4, q5, q6), (q4 + math.pi, -q5, q6 + math.pi)]
            for w4, w5, w6 in wrists:
                seeds.append(np.array([q1, q2, q3, w4, w5, w6]))
    return seeds


def _fk_rotation_to_link3(q: F64) -> F64:
    c1, s1 = math.cos(q[0]), math.sin(q[0])
    a = q[1] + q[2]
    c, s = math.cos(a), math.sin(a)
    Rz = np.array([[c1, -s1, 0.0], [s1, c1, 0.0], [0.0, 0.0, 1.0]])
    Ry = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
    return Rz @ Ry


def _wrap_pi(a: float) -> float:
    return (a + math.pi) % (2 * math.pi) - math.pi


_DATA = threading.local()


def _data(robot: RobotModel) -> pin.Data:
    """Pinocchio work data for ``robot``, one per thread (the mock's thread solves IK too)."""
    cache = getattr(_DATA, "by_model", None)
    if cache is None:
        cache = _DATA.by_model = {}
    d = cache.get(id(robot.model))
    if d is None:
        d = cache[id(robot.model)] = robot.model.createData()
    return d


def _refine_dls(robot: RobotModel, q0: F64, target: pin.SE3, iterations: int = 50,
                damping: float = 1e-6, tol: float = 1e-12) -> tuple[F64, float]:
    """Damped least squares on the tool0 frame error (log6, local frame); returns (q, error)."""
    model = robot.model
    data = _data(robot)
    q = q0.copy()
    err = math.inf
    for _ in range(iterations):
        pin.framesForwardKinematics(model, data, q)
        dM = data.oMf[robot.tool0_frame].actInv(target)
        e = pin.log6(dM).vector
        err = float(np.linalg.norm(e))
        if err < tol:
            break
        J = pin.computeFrameJacobian(model, data, q, robot.tool0_frame, pin.LOCAL)
        Jlog = pin.Jlog6(dM)
        Jt = Jlog @ J
        dq = np.linalg.solve(Jt.T @ Jt + damping * np.eye(6), Jt.T @ e)
        q = q + dq
    return q, err


def inverse_kinematics(robot: RobotModel, T_base_flange: ArrayLike, *,
                       tol_mm: float = 1e-6) -> list[F64]:
    """Every distinct controller-joint solution (deg) within limits that reaches ``T_base_flange``.

    The pose is the flange (tool0) in the base frame, mm. Solutions are sorted by distance from
    all-zero joints. An empty list means the pose is out of reach or outside the joint limits; use
    :func:`solve_ik` for an error that says so.
    """
    T = check_pose(T_base_flange, "T_base_flange")
    target = pose_to_se3(T)
    found: list[F64] = []
    for seed in _closed_form_seeds(T):
        q, err = _refine_dls(robot, seed, target)
        if err > 1e-9:
            continue
        q = np.array([_wrap_pi(a) for a in q])
        base = urdf_to_controller(q)
        # whole turns of axes 4 and 6 do not move the flange: one FK check for all variants
        if pose_error(flange_pose(robot, base, check_limits=False), T)[0] > tol_mm:
            continue
        # Axes 4 and 6 can turn more than one revolution: add every +-360 deg variant.
        for d4, d6 in itertools.product((-360.0, 0.0, 360.0), (-720.0, -360.0, 0.0, 360.0, 720.0)):
            cand = base + np.array([0.0, 0.0, 0.0, d4, 0.0, d6])
            if not within_limits(robot, cand):
                continue
            if all(np.max(np.abs(cand - f)) > 1e-6 for f in found):
                found.append(cand)
    found.sort(key=lambda j: float(np.linalg.norm(j)))
    return found


def ik_from(robot: RobotModel, T_base_flange: ArrayLike, seed_deg: ArrayLike) -> F64 | None:
    """The IK solution (controller deg) reached from ``seed_deg`` by damped least squares.

    For a pose near the one ``seed_deg`` reaches (the next point of a path), this is the solution
    that continues the seed's branch, in a few iterations instead of a full solution set. None when
    it does not converge to ``T_base_flange`` (flange in the base frame, mm) or lands outside the
    joint limits: then only :func:`inverse_kinematics` can say whether the pose is reachable.
    The pose is not validated (a path planner's inner loop): pass a proper rigid transform.
    """
    T = np.asarray(T_base_flange, dtype=np.float64)
    if T.shape != (4, 4):
        raise InputError(f"T_base_flange must be a 4x4 pose, got shape {T.shape}")
    seed = _check_joint_vector(seed_deg, "seed_deg")
    model, data, frame = robot.model, _data(robot), robot.tool0_frame
    target = pose_to_se3(T)
    q = controller_to_urdf(seed)
    # Newton steps on the log6 error (a nearby pose: no damping needed; a singular Jacobian
    # or no convergence is a failure, and the caller solves the full set). The bound is that of
    # inverse_kinematics (log6 error 1e-9: ~1e-6 mm / 1e-9 rad).
    for _ in range(12):
        pin.framesForwardKinematics(model, data, q)
        dM = data.oMf[frame].actInv(target)
        e = pin.log6(dM).vector
        if math.sqrt(float(e @ e)) < 1e-9:
            j = urdf_to_controller(q)
            lo, hi = robot.limits_deg[:, 0], robot.limits_deg[:, 1]
            return j if bool(((j >= lo - 1e-9) & (j <= hi + 1e-9)).all()) else None
        Jt = pin.Jlog6(dM) @ pin.computeFrameJacobian(model, data, q, frame, pin.LOCAL)
        try:
            q = q + np.linalg.solve(Jt, e)
        except np.linalg.LinAlgError:
            return None
    return None


def solve_ik(robot: RobotModel, T_base_flange: ArrayLike, near_deg: ArrayLike | None = None,
             name: str = "target") -> F64:
    """The IK solution (deg) closest to ``near_deg`` (default all-zero joints).

    Raises :class:`ReachabilityError` naming ``name`` and its position when no solution is within
    the joint limits.
    """
    sols = inverse_kinematics(robot, T_base_flange)
    if not sols:
        p = np.asarray(T_base_flange)[:3, 3]
        raise ReachabilityError(
            f"{name} at ({p[0]:.1f}, {p[1]:.1f}, {p[2]:.1f}) mm is out of reach of the "
            f"{robot.name} within its joint limits; move the part or the view pose",
            position_mm=[float(v) for v in p])
    ref = np.zeros(6) if near_deg is None else np.asarray(near_deg, dtype=np.float64)
    return min(sols, key=lambda j: float(np.max(np.abs(j - ref))))


def solve_ik_near(robot: RobotModel, T_base_flange: ArrayLike, near_deg: ArrayLike | None,
                  name: str = "target", max_step_deg: float = 30.0) -> F64:
    """:func:`solve_ik` for a pose next to the one ``near_deg`` reaches (a path's next point).

    The solution continuing ``near_deg``'s branch (:func:`ik_from`, a few Newton steps) when it
    lands within ``max_step_deg`` of ``near_deg`` on every axis, else the full solution set's
    nearest. A pose is refused (:class:`ReachabilityError`) exactly when :func:`solve_ik` refuses
    it: continuity only returns a solution that exists within the limits.
    """
    if near_deg is not None:
        j = ik_from(robot, T_base_flange, near_deg)
        if j is not None and float(np.max(np.abs(j - np.asarray(near_deg)))) <= max_step_deg:
            return j
    return solve_ik(robot, T_base_flange, near_deg=near_deg, name=name)


def check_pose_consistency(robot: RobotModel, joints_deg: ArrayLike, T_reported: ArrayLike,
                           tol_mm: float = 0.5, tol_deg: float = 0.1) -> tuple[float, float]:
    """Compare FK of the reported joints with the controller's reported flange pose.

    Returns (position error mm, rotation error deg). Raises :class:`PoseMismatchError` when they
    disagree by more than the tolerances: a wrong robot model, a tool other than tool0 active on
    the controller, or a wrong axis 2/3 coupling.
    """
    T_fk = flange_pose(robot, joints_deg, check_limits=False)
    d_mm, d_deg = pose_error(T_fk, check_pose(T_reported, "reported pose"))
    if d_mm > tol_mm or d_deg > tol_deg:
        raise PoseMismatchError(
            f"the controller's pose differs from forward kinematics of its joints by {d_mm:.3f} mm "
            f"/ {d_deg:.3f} deg (limits {tol_mm} mm / {tol_deg} deg): check that tool0 and wobj0 "
            f"are active on the controller and that the robot model is the {robot.name}",
            position_error_mm=d_mm, rotation_error_deg=d_deg)
    return d_mm, d_deg
