"""Camera poses of views: FK of the robot times the hand-eye transform, or a fixed camera's pose."""

from __future__ import annotations

import numpy as np

from calibration.calibration_file import Calibration
from controller.errors import CalibrationError
from controller.poses import Pose
from controller.view_file import View


def camera_pose(view: View, calib: Calibration) -> Pose:
    """``T_base_cam`` of a view (mm): ``T_base_flange @ T_flange_cam``, or the pose given directly.

    A view with a flange pose or joints needs the calibration's ``hand_eye``; a view of a camera
    fixed in the cell carries ``camera_pose`` itself. Raises :class:`CalibrationError` when the
    hand-eye transform is needed and missing.
    """
    if view.T_base_cam is not None:
        return np.asarray(view.T_base_cam, dtype=np.float64)
    if calib.T_flange_cam is None:
        raise CalibrationError(
            f"view {view.path} gives the robot's pose, so the calibration must hold the hand-eye "
            f"transform (hand_eye); calibrate it with `seamguide calibrate --from-folder`, or give "
            f"camera_pose in the view file for a camera fixed in the cell")
    assert view.T_base_flange is not None
    return np.asarray(view.T_base_flange, dtype=np.float64) @ calib.T_flange_cam


def nominal_normal_from_views(T_base_cams: list[Pose]) -> np.ndarray:
    """Unit vector pointing from the part toward the cameras: minus their mean optical axis."""
    z = -np.mean([np.asarray(T)[:3, 2] for T in T_base_cams], axis=0)
    return z / np.linalg.norm(z)
