"""Calibrating fixed cameras as a set, and the cross-check that they still agree.

Each fixed camera is calibrated eye-to-hand on its own (:func:`calibration.solve_views.
solve_views` with the board on the flange), from the views it took. The cross-check then uses
views that *every* camera took at the same robot pose: each camera sees the board through its own
intrinsics and its own ``camera_pose``, so each puts the board somewhere in the base frame, and
those places must agree. Disagreement is reported per camera in mm (the board's centre) and deg
(its orientation); over the tolerance it is a :class:`CalibrationError` naming the camera.

Which camera moved: two cameras that disagree cannot say by themselves which one is off. The robot
is the third witness: the calibration of each camera records where the board sat on the flange
(``metadata.board_on_flange``, the eye-to-hand solution's ``T_flange_board``), so the flange pose
of a view predicts where the board is; a camera whose view disagrees with that prediction by more
than the tolerance is the one named. Without that record both cameras are named.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from itertools import combinations
from typing import Any

import cv2
import numpy as np

from calibration.calibration_file import Calibration
from calibration.targets import BoardSpec, Detection
from controller.errors import CalibrationError
from controller.geometry.camera_model import CameraModel
from controller.geometry.poses import (
    Pose,
    pose_from_dict,
    pose_from_rvec_tvec,
    rotation_error_deg,
    transform_points,
)

#: Default tolerance of the cross-check: board centres (mm) and orientations (deg) seen by two
#: cameras. Two cameras each calibrated to 0.1 mm / 0.02 deg, seeing a board 350-450 mm away,
#: disagree by up to about 0.2 mm / 0.04 deg (bench/bench_fixed_pair.py); a camera knocked by 1 mm
#: or 0.2 deg (about 1.5 mm at the board) is well over.
TOLERANCE_MM = 0.4
TOLERANCE_DEG = 0.1


@dataclass(frozen=True)
class SharedView:
    """One robot pose seen by several fixed cameras: the recorded flange pose and each detection."""

    name: str
    T_base_flange: Pose
    detections: Mapping[str, Detection | None]


def board_in_camera(camera: CameraModel, det: Detection, name: str = "view") -> Pose:
    """``T_cam_board`` (mm) from the board's corners by PnP, refined by Levenberg-Marquardt.

    Raises :class:`CalibrationError` naming the view when fewer than 6 corners or PnP fails.
    """
    obj = np.asarray(det.object_points, dtype=np.float64)
    img = np.asarray(det.image_points, dtype=np.float64)
    if len(img) < 6:
        raise CalibrationError(f"{name}: only {len(img)} board corners; need at least 6")
    ok, rvec, tvec = cv2.solvePnP(obj, img, camera.K, camera.dist, flags=cv2.SOLVEPNP_ITERATIVE)
    if not ok:
        raise CalibrationError(f"{name}: the board pose cannot be found (solvePnP failed)")
    rvec, tvec = cv2.solvePnPRefineLM(obj, img, camera.K, camera.dist, rvec, tvec)
    return pose_from_rvec_tvec(rvec, tvec)


def calibrate_fixed_cameras(views: Sequence[SharedView], board: BoardSpec,
                            image_sizes: Mapping[str, tuple[int, int]], **solve_options: Any
                            ) -> tuple[dict[str, Calibration], dict[str, Any]]:
    """Eye-to-hand calibration of every fixed camera, then the cross-check on the same views.

    ``views``: robot poses with the board on the flange, each seen by the cameras named in its
    ``detections`` (None where a camera did not find the board); ``image_sizes``: (width, height)
    per camera. Each camera is solved on its own (``solve_options`` go to ``solve_views``), its
    calibration gets ``metadata.board_on_flange``, and the cameras are cross-checked on the views
    all of them saw. Returns the calibrations by camera name and a report; raises
    :class:`CalibrationError` (naming the camera) when a solve or the cross-check fails.
    """
    from calibration.solve_views import solve_views
    from calibration.teach_progress import ViewRecord

    calibs: dict[str, Calibration] = {}
    report: dict[str, Any] = {"cameras": {}}
    for cam_name, size in image_sizes.items():
        records = [ViewRecord(v.name, v.T_base_flange, v.detections.get(cam_name))
                   for v in views]
        try:
            calib, rep = solve_views(records, board, size, eye_to_hand=True,
                                     camera_name=cam_name, **solve_options)
        except CalibrationError as err:
            raise CalibrationError(f"camera {cam_name}: {err}", camera=cam_name) from err
        Y = rep["hand_eye"].get("T_flange_board")
        if Y is not None:
            calib.metadata["board_on_flange"] = Y
        calibs[cam_name] = calib
        report["cameras"][cam_name] = rep
    report["cross_check"] = cross_check(calibs, views, board)
    return calibs, report


def _board_in_base(calib: Calibration, det: Detection, view: str, cam: str) -> Pose:
    if calib.T_base_cam is None:
        raise CalibrationError(f"camera {cam}: its calibration has no camera_pose; the "
                               f"cross-check is for fixed cameras", camera=cam)
    return np.asarray(calib.T_base_cam) @ board_in_camera(calib.camera, det, f"{view} ({cam})")


def _difference(Ta: Pose, Tb: Pose, centre: np.ndarray) -> tuple[float, float]:
    pa = transform_points(Ta, centre[None])[0]
    pb = transform_points(Tb, centre[None])[0]
    return float(np.linalg.norm(pa - pb)), rotation_error_deg(Ta, Tb)


def cross_check(calibs: Mapping[str, Calibration], views: Sequence[SharedView],
                board: BoardSpec, tolerance_mm: float = TOLERANCE_MM,
                tolerance_deg: float = TOLERANCE_DEG) -> dict[str, Any]:
    """Do fixed cameras agree on where the board is? (base frame; mm at the board's centre, deg).

    Uses the views in which at least two of the cameras found the board. Returns a report: per
    view and pair the disagreement, the worst per pair, and per camera the disagreement with the
    robot's prediction where its calibration records ``board_on_flange``. Raises
    :class:`CalibrationError` naming the camera that moved (or both cameras of the pair, when the
    robot cannot tell) when a pair disagrees by more than ``tolerance_mm`` or ``tolerance_deg``,
    and when no view was seen by two cameras.
    """
    centre = board.object_points().mean(axis=0)
    per_view: dict[str, dict[str, list[float]]] = {}
    robot: dict[str, list[tuple[float, float]]] = {k: [] for k in calibs}
    worst: dict[tuple[str, str], tuple[float, float, str]] = {}
    for v in views:
        seen = {k: _board_in_base(calibs[k], d, v.name, k) for k, d in v.detections.items()
                if d is not None and k in calibs}
        for k, T in seen.items():
            Y = calibs[k].metadata.get("board_on_flange")
            if Y is not None:
                T_pred = np.asarray(v.T_base_flange) @ pose_from_dict(Y, "board_on_flange")
                robot[k].append(_difference(T, T_pred, centre))
        for a, b in combinations(sorted(seen), 2):
            mm, deg = _difference(seen[a], seen[b], centre)
            per_view.setdefault(v.name, {})[f"{a}-{b}"] = [round(mm, 4), round(deg, 5)]
            if (a, b) not in worst or mm / tolerance_mm + deg / tolerance_deg > \
                    worst[(a, b)][0] / tolerance_mm + worst[(a, b)][1] / tolerance_deg:
                worst[(a, b)] = (mm, deg, v.name)
    if not worst:
        raise CalibrationError("cross-check: no view was seen by two of the cameras "
                               f"({', '.join(sorted(calibs))}); take views with the board in "
                               f"every camera's image at the same robot pose")
    robot_median = {k: [float(np.median([m for m, _ in r])), float(np.median([d for _, d in r]))]
                    for k, r in robot.items() if r}
    report: dict[str, Any] = {
        "tolerance_mm_deg": [tolerance_mm, tolerance_deg],
        "views": per_view,
        "worst": {f"{a}-{b}": {"mm": round(w[0], 4), "deg": round(w[1], 5), "view": w[2]}
                  for (a, b), w in worst.items()},
        "robot_vs_camera_median_mm_deg": {k: [round(v[0], 4), round(v[1], 5)]
                                          for k, v in robot_median.items()},
    }
    bad = [(a, b, w) for (a, b), w in worst.items()
           if w[0] > tolerance_mm or w[1] > tolerance_deg]
    if bad:
        a, b, (mm, deg, view) = bad[0]
        moved = [k for k in (a, b) if k in robot_median and
                 (robot_median[k][0] > tolerance_mm or robot_median[k][1] > tolerance_deg)]
        if len(moved) == 1:
            k = moved[0]
            other = b if k == a else a
            blame = (f"camera {k} has moved since it was calibrated: the robot puts the board "
                     f"{robot_median[k][0]:.2f} mm / {robot_median[k][1]:.3f} deg from where "
                     f"camera {k} sees it"
                     + (f" (camera {other}: {robot_median[other][0]:.2f} mm / "
                        f"{robot_median[other][1]:.3f} deg)" if other in robot_median else "")
                     + f"; recalibrate camera {k}")
            named = [k]
        else:
            blame = (f"cameras {a} and {b}: the robot cannot tell which one moved; check both "
                     f"mounts and recalibrate")
            named = [a, b]
        raise CalibrationError(
            f"cross-check of the fixed cameras failed: cameras {a} and {b} see the board of "
            f"{view} {mm:.2f} mm / {deg:.3f} deg apart (tolerance {tolerance_mm} mm / "
            f"{tolerance_deg} deg); {blame}", camera=named[0] if len(named) == 1 else named,
            cross_check=report)
    return report


def shared_views_from_sessions(names: Sequence[str], flange_poses: Sequence[Pose],
                               detections: Mapping[str, Sequence[Detection | None]]
                               ) -> list[SharedView]:
    """Zip per-camera detection lists (same order as ``names``) into :class:`SharedView` s."""
    return [SharedView(n, np.asarray(T), {k: d[i] for k, d in detections.items()})
            for i, (n, T) in enumerate(zip(names, flange_poses, strict=True))]


__all__ = ["TOLERANCE_DEG", "TOLERANCE_MM", "SharedView", "board_in_camera",
           "calibrate_fixed_cameras", "cross_check", "shared_views_from_sessions"]
