"""Closed-form hand-eye (OpenCV's five methods) and the per-view board poses they start from.

:func:`opencv_calibrate_hand_eye` is the only function that sees OpenCV's ``gripper2base`` /
``target2cam`` naming; :func:`closed_form` gives (X, Y) by one method.
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from calibration.handeye_model import Observation, _intr_vector, _project
from controller.errors import CalibrationError
from controller.geometry.camera_model import CameraModel
from controller.geometry.poses import Pose, invert, make_pose, pose_error, pose_from_rvec_tvec

F64 = NDArray[np.float64]

CLOSED_FORM_METHODS: dict[str, int] = {
    "tsai": cv2.CALIB_HAND_EYE_TSAI,
    "park": cv2.CALIB_HAND_EYE_PARK,
    "horaud": cv2.CALIB_HAND_EYE_HORAUD,
    "andreff": cv2.CALIB_HAND_EYE_ANDREFF,
    "daniilidis": cv2.CALIB_HAND_EYE_DANIILIDIS,
}


def opencv_calibrate_hand_eye(T_base_flange: Sequence[Pose], T_cam_board: Sequence[Pose],
                              method: str = "park") -> Pose:
    """``T_flange_cam`` from flange poses and board poses by ``cv2.calibrateHandEye``.

    The only place that speaks OpenCV's names: ``gripper2base`` is ``T_base_flange``,
    ``target2cam`` is ``T_cam_board``, and the answer ``cam2gripper`` is ``T_flange_cam``.
    For eye-to-hand, pass ``T_flange_base`` (the inverses) as ``T_base_flange``: the answer is then
    ``T_base_cam`` (OpenCV docs, calibrateHandEye). Translations in mm.
    Raises :class:`CalibrationError` for an unknown method or when OpenCV fails.
    """
    if method not in CLOSED_FORM_METHODS:
        raise CalibrationError(f"unknown hand-eye method {method!r}; use one of "
                               f"{', '.join(CLOSED_FORM_METHODS)}")
    R_gripper2base = [np.asarray(T)[:3, :3] for T in T_base_flange]
    t_gripper2base = [np.asarray(T)[:3, 3].reshape(3, 1) for T in T_base_flange]
    R_target2cam = [np.asarray(T)[:3, :3] for T in T_cam_board]
    t_target2cam = [np.asarray(T)[:3, 3].reshape(3, 1) for T in T_cam_board]
    try:
        R_cam2gripper, t_cam2gripper = cv2.calibrateHandEye(
            R_gripper2base, t_gripper2base, R_target2cam, t_target2cam,
            method=CLOSED_FORM_METHODS[method])
    except cv2.error as err:
        raise CalibrationError(f"hand-eye ({method}) failed in OpenCV: {err}") from err
    R = np.asarray(R_cam2gripper, float)
    t = np.asarray(t_cam2gripper, float).ravel()
    if not (np.all(np.isfinite(R)) and np.all(np.isfinite(t))):
        raise CalibrationError(f"hand-eye ({method}) gave a non-finite result: the motions are "
                               f"degenerate; tilt the camera about two different axes")
    # Re-orthonormalise (Andreff's linear solution is not exactly a rotation).
    U, _, Vt = np.linalg.svd(R)
    R = U @ np.diag([1.0, 1.0, np.linalg.det(U @ Vt)]) @ Vt
    return make_pose(R, t)



def _pnp(camera: CameraModel, ob: Observation, name: str = "view") -> tuple[Pose, float]:
    if len(ob.image_points) < 6 or len(ob.image_points) != len(ob.object_points):
        raise CalibrationError(f"{name}: {len(ob.image_points)} corners for "
                               f"{len(ob.object_points)} board points; need at least 6, matched")
    try:
        ok, rvec, tvec = cv2.solvePnP(ob.object_points.astype(np.float64),
                                      ob.image_points.astype(np.float64), camera.K, camera.dist,
                                      flags=cv2.SOLVEPNP_ITERATIVE)
    except cv2.error as err:
        raise CalibrationError(f"{name}: the board pose cannot be found (solvePnP: {err})") \
            from err
    if not ok:
        raise CalibrationError(f"{name}: the board pose cannot be found (solvePnP failed)")
    rvec, tvec = cv2.solvePnPRefineLM(ob.object_points.astype(np.float64),
                                      ob.image_points.astype(np.float64), camera.K, camera.dist,
                                      rvec, tvec)
    T = pose_from_rvec_tvec(rvec, tvec)
    P = (T[:3, :3] @ ob.object_points.T).T + T[:3, 3]
    r = _project(P, _intr_vector(camera)) - ob.image_points
    return T, float(np.sqrt(np.mean(np.sum(r * r, axis=1))))


def _average_pose(poses: Sequence[Pose]) -> Pose:
    """Chordal L2 mean of rotations, mean of translations."""
    Rs = Rotation.from_matrix(np.stack([np.asarray(T)[:3, :3] for T in poses]))
    return make_pose(Rs.mean().as_matrix(), np.mean([np.asarray(T)[:3, 3] for T in poses], axis=0))


def _consistency(motions: Sequence[F64], T_cb: Sequence[Pose], X: Pose, Y: Pose,
                 pts: F64) -> tuple[F64, F64]:
    """Per view: RMS distance (mm) of the board points placed by this view vs by Y, and deg."""
    mm, deg = [], []
    Py = (Y[:3, :3] @ pts.T).T + Y[:3, 3]
    for M, T in zip(motions, T_cb, strict=True):
        Yi = invert(M) @ X @ T
        Pi = (Yi[:3, :3] @ pts.T).T + Yi[:3, 3]
        mm.append(float(np.sqrt(np.mean(np.sum((Pi - Py) ** 2, axis=1)))))
        deg.append(pose_error(Yi, Y)[1])
    return np.array(mm), np.array(deg)


def _closed_forms(A: list[Pose], T_cb: list[Pose], eye_to_hand: bool, method: str,
                  hint: str) -> tuple[dict[str, Pose], list[Pose], Pose, Pose]:
    """Every closed form that succeeds, the robot motions, and ``method``'s X and the board's Y.

    ``A`` are the robot poses (``T_base_flange``, mm), ``T_cb`` the board in the camera (mm). X is
    the hand-eye of ``method`` (``T_flange_cam``; ``T_base_cam`` eye-to-hand), Y the board pose
    averaged over the views (in the base frame; in the flange eye-to-hand). Raises
    :class:`CalibrationError` (ending with ``hint``) when ``method`` fails.
    """
    motions = A if eye_to_hand else [invert(T) for T in A]
    gripper = [invert(T) for T in A] if eye_to_hand else A
    closed: dict[str, Pose] = {}
    for m in CLOSED_FORM_METHODS:
        try:
            closed[m] = opencv_calibrate_hand_eye(gripper, T_cb, m)
        except CalibrationError:
            continue
    if method not in closed:
        raise CalibrationError(f"the closed-form hand-eye method {method} failed{hint}")
    X = closed[method]
    Y = _average_pose([invert(M) @ X @ T for M, T in zip(motions, T_cb, strict=True)])
    return closed, motions, X, Y


def closed_form(T_base_flange: Sequence[Pose], T_cam_board: Sequence[Pose], *,
                method: str = "park", eye_to_hand: bool = False) -> tuple[Pose, Pose]:
    """(X, Y) by one closed-form method; Y is the average of every view's board pose.

    Eye-in-hand: X = T_flange_cam, Y = T_base_board; eye-to-hand: X = T_base_cam,
    Y = T_flange_board.
    """
    A = [np.asarray(T, float) for T in T_base_flange]
    gripper = [invert(T) for T in A] if eye_to_hand else A
    X = opencv_calibrate_hand_eye(gripper, T_cam_board, method)
    motions = A if eye_to_hand else [invert(T) for T in A]
    Y = _average_pose([invert(M) @ X @ T for M, T in zip(motions, T_cam_board, strict=True)])
    return X, Y

