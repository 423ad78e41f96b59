"""Camera poses of views: FK of the robot times the hand-eye transform, or a fixed camera's pose.

A cell may have several cameras, each with its own calibration (intrinsics plus ``hand_eye`` for a
camera on the flange, or ``camera_pose`` for a fixed one). :func:`calibration_for_view` picks a
view's calibration by the camera the view names; :func:`camera_pose` gives the view's
``T_base_cam``. Both take anything with the calibration's attributes (``camera``,
``T_flange_cam``, ``T_base_cam``), so this module does not depend on the calibration package.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, TypeVar

import numpy as np

from controller.errors import CalibrationError, InputError
from controller.geometry.poses import Pose, pose_error
from controller.geometry.view_file import View

#: A view's own ``camera_pose`` and its camera's calibrated pose may differ by this much (mm, deg)
#: (the 6 decimals of a view file); more means one of them is stale.
POSE_AGREEMENT_MM = 0.01
POSE_AGREEMENT_DEG = 0.001


C = TypeVar("C")


def calibration_for_view(view: View, calibrations: Mapping[str | None, C]) -> C:
    """The calibration of the camera that took ``view``.

    ``calibrations`` maps camera names to calibrations; the key ``None`` is one calibration given
    without a name, which applies to every view (one camera, as before cameras had names). A view
    naming its ``camera`` gets that camera's calibration; a view naming none gets the only
    calibration there is. Raises :class:`InputError` naming the view and the camera otherwise.
    """
    if not calibrations:
        raise InputError("no calibration given; pass --calibration FILE (or NAME=FILE per camera)")
    named = sorted(k for k in calibrations if k is not None)
    if view.camera is not None:
        if view.camera in calibrations:
            return calibrations[view.camera]
        if not named:
            return calibrations[None]
        raise InputError(f"view {view.path} was taken by camera {view.camera!r}, which has no "
                         f"calibration (calibrated cameras: {', '.join(named)}); pass "
                         f"--calibration {view.camera}=FILE", view=str(view.path),
                         camera=view.camera)
    if len(calibrations) == 1:
        return next(iter(calibrations.values()))
    raise InputError(f"view {view.path} does not say which camera took it, and there are "
                     f"calibrations for {', '.join(named)}: add \"camera\": \"NAME\" to the view "
                     f"file", view=str(view.path))


def camera_pose(view: View, calib: Any) -> Pose:
    """``T_base_cam`` of a view (mm): ``T_base_flange @ T_flange_cam``, or the fixed camera's pose.

    ``calib`` is the view's camera calibration (its ``T_flange_cam`` and ``T_base_cam``, mm). A
    view with a flange pose or joints needs the calibration's ``hand_eye``; a fixed camera's pose
    comes from the view's own ``camera_pose`` or from the calibration's ``camera_pose``. Raises
    :class:`CalibrationError` when the transform needed is missing, when a flange pose is given
    for a fixed camera, or when the view's and the calibration's camera poses disagree (one of
    them is stale).
    """
    T_fc, T_bc = calib.T_flange_cam, calib.T_base_cam
    who = f" of camera {view.camera!r}" if view.camera else ""
    if view.T_base_cam is not None:
        T = np.asarray(view.T_base_cam, dtype=np.float64)
        if T_bc is not None:
            d_mm, d_deg = pose_error(T, T_bc)
            if d_mm > POSE_AGREEMENT_MM or d_deg > POSE_AGREEMENT_DEG:
                raise CalibrationError(
                    f"view {view.path} gives a camera_pose {d_mm:.3f} mm / {d_deg:.4f} deg away "
                    f"from the calibration{who}'s camera_pose: one of them is stale; remove "
                    f"camera_pose from the view file to use the calibration's", view=str(view.path))
        return T
    if view.T_base_flange is None:
        if T_bc is None:
            raise CalibrationError(
                f"view {view.path} gives no pose, so the calibration{who} must hold the fixed "
                f"camera's pose (camera_pose); calibrate it with `seamguide calibrate "
                f"--eye-to-hand`, or give the pose in the view file", view=str(view.path))
        return np.asarray(T_bc, dtype=np.float64)
    if T_fc is None:
        fixed = ("; the calibration is of a fixed camera (camera_pose): such a view needs no robot "
                 "pose" if T_bc is not None else "")
        raise CalibrationError(
            f"view {view.path} gives the robot's pose, so the calibration{who} must hold the "
            f"hand-eye transform (hand_eye); calibrate it with `seamguide calibrate "
            f"--from-folder`, or give camera_pose in the view file for a camera fixed in the "
            f"cell{fixed}", view=str(view.path))
    return np.asarray(view.T_base_flange, dtype=np.float64) @ np.asarray(T_fc, dtype=np.float64)


def nominal_normal_from_views(T_base_cams: list[Pose]) -> np.ndarray:
    """Unit vector pointing from the part toward the cameras: minus their mean optical axis."""
    z = -np.mean([np.asarray(T)[:3, 2] for T in T_base_cams], axis=0)
    return z / np.linalg.norm(z)


#: Views whose rolls about the viewing direction differ by less than this (deg) cannot show a
#: wrong hand-eye transform: see the README's stereo section ("Gross calibration errors").
MIN_ROLL_DIFFERENCE_DEG = 15.0


def roll_difference_deg(T_base_cam_a: Pose, T_base_cam_b: Pose) -> float:
    """Angle (deg, 0-180) between two cameras' image x axes seen along their mean optical axis.

    Two views displaced across the seam by tilting about it have a roll difference near 0; the
    suggested layout rolls view 2 by about 37 deg.
    """
    za, zb = np.asarray(T_base_cam_a)[:3, 2], np.asarray(T_base_cam_b)[:3, 2]
    z = za + zb
    z = z / np.linalg.norm(z)
    xs = []
    for T in (T_base_cam_a, T_base_cam_b):
        x = np.asarray(T)[:3, 0]
        x = x - (x @ z) * z
        xs.append(x / np.linalg.norm(x))
    return float(np.degrees(np.arccos(np.clip(xs[0] @ xs[1], -1.0, 1.0))))


def view_layout_warning(T_base_cams: list[Pose],
                        min_roll_deg: float = MIN_ROLL_DIFFERENCE_DEG) -> str | None:
    """A warning when no two views differ in roll by ``min_roll_deg`` (deg), else None.

    Views rolled alike differ (nearly) by a rotation about one axis, and a wrong hand-eye
    transform then only moves the located seam rigidly: the quality checks caught 2 % of 5 mm
    hand-eye errors with such views against 88 % with view 2 rolled 37 deg (bench_locate.py).
    """
    diffs = [roll_difference_deg(a, b) for i, a in enumerate(T_base_cams)
             for b in T_base_cams[i + 1:]]
    if not diffs or max(diffs) >= min_roll_deg:
        return None
    return (f"the views differ in roll about the viewing direction by at most {max(diffs):.1f} "
            f"deg (< {min_roll_deg:.0f}): a wrong hand-eye calibration would go unnoticed; "
            "teach view 2 rolled by 30-45 deg about the camera axis")
