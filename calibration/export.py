"""The hand-eye result in the formats other tools use (and back from easy_handeye).

Every format holds the camera's optical frame (OpenCV: x right, y down, z forward) expressed in
the flange (tool0) frame for eye-in-hand (``T_flange_cam``), or in the robot base frame for a
fixed camera (``T_base_cam``). Formats:

- ``easy_handeye`` -- the YAML file of the ROS package easy_handeye (its
  ``HandeyeCalibration.to_dict``): ``parameters`` (``eye_on_hand``, ``robot_base_frame``,
  ``robot_effector_frame``, ``tracking_base_frame``, ...) and ``transformation`` with ``x, y, z``
  in **metres** and the quaternion ``qx, qy, qz, qw`` (**scalar last**, ROS order).
- ``tf`` -- the arguments of ROS ``static_transform_publisher``:
  ``x y z qx qy qz qw parent child``, metres, scalar last.
- ``matrix`` -- the 4x4 homogeneous matrix, translation in **mm**, as JSON (``T_flange_cam`` or
  ``T_base_cam``).
- ``abb_tooldata`` -- the camera frame as RAPID ``tooldata``'s ``tframe`` (pose): ``[[x, y, z],
  [q1, q2, q3, q4]]`` in **mm**, scalar first, as ABB writes it; eye-in-hand only.
- ``view_camera_pose`` -- for a fixed camera: the ``camera_pose`` entry of a view file
  (DESIGN.md), ``{"camera_pose": {"position_mm": [...], "quaternion_wxyz": [...]}}``, to put in
  the view files given to ``seamguide locate``.

Quaternions are converted from the product's w, x, y, z only here, at this boundary.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import yaml

from calibration.calibration_file import Calibration
from controller.errors import CalibrationError, ConfigError
from controller.geometry.poses import Pose, pos_quat_from_pose, pose_from_pos_quat

FORMATS = ("easy_handeye", "tf", "matrix", "abb_tooldata", "view_camera_pose")


def _mounting(calib: Calibration) -> tuple[Pose, bool]:
    if calib.T_flange_cam is not None:
        return calib.T_flange_cam, True
    if calib.T_base_cam is not None:
        return calib.T_base_cam, False
    raise CalibrationError("the calibration holds intrinsics only (no hand_eye or camera_pose): "
                           "nothing to export; run `seamguide calibrate` with robot poses")


def export_hand_eye(calib: Calibration, fmt: str, *, base_frame: str = "base_link",
                    effector_frame: str = "tool0", camera_frame: str = "camera_optical_frame",
                    marker_frame: str = "calibration_board") -> str:
    """The calibration's camera mounting as text in format ``fmt`` (one of :data:`FORMATS`).

    Raises :class:`ConfigError` for an unknown format, :class:`CalibrationError` when the
    calibration has no mounting (or ``abb_tooldata`` is asked of a fixed camera).
    """
    if fmt not in FORMATS:
        raise ConfigError(f"unknown export format {fmt!r}; use one of {', '.join(FORMATS)}")
    T, on_hand = _mounting(calib)
    p_mm, q = pos_quat_from_pose(T)
    p_m = p_mm / 1000.0
    parent = effector_frame if on_hand else base_frame
    if fmt == "easy_handeye":
        doc: dict[str, Any] = {
            "parameters": {"eye_on_hand": on_hand, "robot_base_frame": base_frame,
                           "robot_effector_frame": effector_frame,
                           "tracking_base_frame": camera_frame,
                           "tracking_marker_frame": marker_frame,
                           "namespace": "seamguide_" + ("eye_on_hand" if on_hand else
                                                        "eye_on_base") + "/"},
            "transformation": {"x": float(p_m[0]), "y": float(p_m[1]), "z": float(p_m[2]),
                               "qx": float(q[1]), "qy": float(q[2]), "qz": float(q[3]),
                               "qw": float(q[0])},
        }
        return str(yaml.safe_dump(doc, default_flow_style=False, sort_keys=False))
    if fmt == "tf":
        nums = [*p_m, q[1], q[2], q[3], q[0]]
        return " ".join(f"{float(v):.9f}" for v in nums) + f" {parent} {camera_frame}\n"
    if fmt == "matrix":
        import json

        key = "T_flange_cam" if on_hand else "T_base_cam"
        return json.dumps({key: np.round(T, 9).tolist(), "unit": "mm"}, indent=2) + "\n"
    if fmt == "view_camera_pose":
        import json

        from controller.geometry.poses import pose_to_dict

        if on_hand:
            raise CalibrationError("view_camera_pose is for a camera fixed in the cell; this "
                                   "calibration is of a camera on the flange (hand_eye)")
        return json.dumps({"camera_pose": pose_to_dict(T)}) + "\n"
    if not on_hand:
        raise CalibrationError("abb_tooldata describes a camera on the flange; this calibration "
                               "is of a fixed camera (camera_pose)")
    return (f"[[{p_mm[0]:.3f},{p_mm[1]:.3f},{p_mm[2]:.3f}],"
            f"[{q[0]:.6f},{q[1]:.6f},{q[2]:.6f},{q[3]:.6f}]]\n")


def pose_from_easy_handeye(text: str) -> tuple[Pose, bool]:
    """(T in mm, eye_on_hand) from an easy_handeye YAML file's text.

    Raises :class:`CalibrationError` when the text lacks ``transformation`` with x, y, z, qx, qy,
    qz, qw.
    """
    try:
        doc = yaml.safe_load(text)
        tr = doc["transformation"]
        p = [float(tr[k]) * 1000.0 for k in ("x", "y", "z")]
        q = [float(tr[k]) for k in ("qw", "qx", "qy", "qz")]
        on_hand = bool(doc.get("parameters", {}).get("eye_on_hand", True))
    except (yaml.YAMLError, KeyError, TypeError, ValueError, AttributeError) as err:
        raise CalibrationError(f"not an easy_handeye calibration (needs transformation: x, y, z, "
                               f"qx, qy, qz, qw): {err}") from err
    return pose_from_pos_quat(p, q, "easy_handeye transformation"), on_hand
