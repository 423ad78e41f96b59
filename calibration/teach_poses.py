"""Automatic teach poses: small exploring moves, well-spread views of the board, a rough solve."""
from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from calibration.handeye import Observation, solve_hand_eye
from calibration.intrinsics import solve_intrinsics
from calibration.targets import BoardSpec
from calibration.teach_progress import ViewRecord
from controller.errors import CalibrationError, ReachabilityError
from controller.geometry.poses import Pose, make_pose, rotation_about

F64 = NDArray[np.float64]


def _reachable(T: Pose, joints_near: F64, lo: F64, hi: F64) -> F64 | None:
    """Joints (deg) reaching flange pose ``T`` nearest ``joints_near``, or None (IK, box)."""
    from controller.geometry.kinematics import inverse_kinematics, irb2400

    if np.any(T[:3, 3] < lo) or np.any(T[:3, 3] > hi):
        return None
    sols = inverse_kinematics(irb2400(), T)
    if not sols:
        return None
    return min(sols, key=lambda j: float(np.max(np.abs(j - joints_near))))


def _box(T_first: Pose, workspace_min_mm: F64 | None, workspace_max_mm: F64 | None
         ) -> tuple[F64, F64]:
    p = np.asarray(T_first, float)[:3, 3]
    lo = p - 400.0 if workspace_min_mm is None else np.asarray(workspace_min_mm, float)
    hi = p + 400.0 if workspace_max_mm is None else np.asarray(workspace_max_mm, float)
    return lo, hi


def explore_poses(T_first: Pose, joints_first: F64, *, pivot_mm: float = 350.0,
                  tilt_deg: float = 8.0, workspace_min_mm: F64 | None = None,
                  workspace_max_mm: F64 | None = None) -> list[F64]:
    """Small first moves (joints, deg) that keep the board in view.

    The flange is tilted by ``tilt_deg`` about its x and y axes (both signs) and rolled about
    z, around a pivot ``pivot_mm`` along its z axis. Views from these give a rough calibration
    to aim with.
    Unreachable candidates (IK, workspace box, default first pose +- 400 mm) are skipped.
    """
    lo, hi = _box(T_first, workspace_min_mm, workspace_max_mm)
    pivot = make_pose(np.eye(3), [0.0, 0.0, pivot_mm])
    T_bp = np.asarray(T_first, float) @ pivot
    out = []
    t = float(np.radians(tilt_deg))
    for axis, ang in (([1.0, 0, 0], t), ([1.0, 0, 0], -t), ([0, 1.0, 0], t), ([0, 1.0, 0], -t),
                      ([0, 0, 1.0], 2 * t), ([1.0, 1.0, 0], t)):
        T = T_bp @ make_pose(rotation_about(axis, ang)) @ np.linalg.inv(pivot)
        j = _reachable(T, joints_first, lo, hi)
        if j is not None:
            out.append(j)
    return out


#: Automatic views: the board fills this fraction of the image width at the mean distance, and the
#: camera axis is tilted from the board normal by this range (deg). From the refinement's
#: covariance on simulated sessions (20 views, the stated noise): 0.55 and 15-40 deg left the
#: hand-eye at 0.099 mm / 0.021 deg RMS (predicted), 0.7 and 20-50 deg at 0.058 mm / 0.015 deg;
#: the depth along the optical axis is what steeper, nearer views pin down.
AUTO_FILL = 0.7
AUTO_TILT_DEG = (20.0, 50.0)


def spread_poses(T_flange_cam: Pose, board_centre_mm: F64, board_normal: F64,
                 distance_mm: float, joints_near: F64, n: int, *,
                 tilt_deg: tuple[float, float] = AUTO_TILT_DEG, roll_deg: float = 35.0,
                 offset_mm: float = 0.0, workspace_min_mm: F64 | None = None,
                 workspace_max_mm: F64 | None = None, T_first: Pose | None = None,
                 seed: int = 0, camera: Any = None, board_points_base: F64 | None = None
                 ) -> list[F64]:
    """``n`` joint targets (deg) whose camera looks at the board from well-spread directions.

    The camera sits ``distance_mm`` (x 0.85-1.15) from ``board_centre_mm`` (base frame), its axis
    tilted from the board's outward normal ``board_normal`` by ``tilt_deg`` at azimuths spread by
    the golden angle, rolled up to ``roll_deg``, aimed up to ``offset_mm`` off the centre so
    the corners cover the image. Flange poses = camera pose x ``T_flange_cam``^-1 (a rough
    hand-eye is enough), each checked with IK and the workspace box; with ``camera`` and
    ``board_points_base`` (N, 3) also that every point lands inside the image (5 % margin). Raises
    :class:`ReachabilityError` when fewer than ``n`` are found.
    """
    rng = np.random.default_rng(seed)
    ref = np.asarray(T_first if T_first is not None else np.eye(4), float)
    lo, hi = _box(ref, workspace_min_mm, workspace_max_mm)
    nz = np.asarray(board_normal, float) / np.linalg.norm(board_normal)
    ex = np.cross(nz, [0.0, 0.0, 1.0]) if abs(nz[2]) < 0.9 else np.cross(nz, [1.0, 0.0, 0.0])
    ex /= np.linalg.norm(ex)
    ey = np.cross(nz, ex)
    golden = np.pi * (3 - np.sqrt(5))
    out: list[F64] = []
    tries = 0
    X_inv = np.linalg.inv(np.asarray(T_flange_cam, float))
    centre = np.asarray(board_centre_mm, float)
    while len(out) < n and tries < 60 * n:
        tries += 1
        az = len(out) * golden + rng.uniform(-0.3, 0.3)
        tilt = np.radians(rng.uniform(*tilt_deg))
        d = distance_mm * rng.uniform(0.85, 1.15)
        direction = np.cos(tilt) * nz + np.sin(tilt) * (np.cos(az) * ex + np.sin(az) * ey)
        eye = centre + d * direction
        target = centre + rng.uniform(-offset_mm, offset_mm) * ex \
            + rng.uniform(-offset_mm, offset_mm) * ey
        z = target - eye
        z /= np.linalg.norm(z)
        x = np.cross(z, ey)
        x /= np.linalg.norm(x)
        y = np.cross(z, x)
        roll = float(np.radians(rng.uniform(-roll_deg, roll_deg)))
        T_cam = make_pose(np.column_stack([x, y, z]) @ rotation_about([0, 0, 1.0], roll), eye)
        if camera is not None and board_points_base is not None:
            uv = camera.project(board_points_base, T_cam)
            mu, mv = 0.05 * camera.width, 0.05 * camera.height
            if not (np.all(np.isfinite(uv)) and uv[:, 0].min() > mu and uv[:, 1].min() > mv
                    and uv[:, 0].max() < camera.width - mu
                    and uv[:, 1].max() < camera.height - mv):
                continue
        j = _reachable(T_cam @ X_inv, joints_near, lo, hi)
        if j is not None:
            out.append(j)
    if len(out) < n:
        raise ReachabilityError(
            f"automatic mode found only {len(out)} of {n} reachable poses looking at the board "
            f"within the workspace box; teach a first pose nearer the middle of the reach, "
            f"widen --workspace, or ask for fewer (--auto)")
    return out


def rough_calibration(views: Sequence[ViewRecord], board: BoardSpec,
                      image_size: tuple[int, int], eye_to_hand: bool = False
                      ) -> tuple[Pose, Pose, Any]:
    """A rough (X, Y, camera) from a few views, to aim the automatic poses.

    Intrinsics with only k1 (other distortion fixed at 0), closed-form hand-eye, no refinement,
    loose checks.
    """
    good = [v for v in views if v.detection is not None]
    if len(good) < 4:
        raise CalibrationError(
            f"automatic mode: the board was found in only {len(good)} of the {len(views)} "
            f"exploring views ({', '.join(v.name for v in views if v.detection is None)} without "
            f"it); start from a pose where the board is in the middle of the image, about "
            f"--pivot-mm away")
    flags = (cv2.CALIB_FIX_K2 | cv2.CALIB_FIX_K3 | cv2.CALIB_ZERO_TANGENT_DIST
             | cv2.CALIB_FIX_ASPECT_RATIO)
    intr = solve_intrinsics([v.detection.image_points for v in good if v.detection],
                            [v.detection.object_points for v in good if v.detection],
                            image_size, names=[v.name for v in good], flags=flags)
    obs = [Observation(v.detection.image_points, v.detection.object_points)
           for v in good if v.detection is not None]
    he = solve_hand_eye([v.T_base_flange for v in good], obs, intr.camera,
                        names=[v.name for v in good], eye_to_hand=eye_to_hand, refine=False,
                        min_views=4, min_rotation_deg=3.0, max_rms_px=1e9,
                        max_consistency_mm=1e9, max_consistency_deg=1e9)
    return he.X, he.Y, intr.camera

