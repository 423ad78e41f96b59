"""A solved hand-eye calibration, its report, and the residuals of a view under it."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from calibration.handeye_model import Observation, _intr_vector, _project
from controller.errors import CalibrationError
from controller.geometry.camera_model import CameraModel
from controller.geometry.poses import Pose, invert

F64 = NDArray[np.float64]


@dataclass
class HandEyeResult:
    """A solved hand-eye calibration and its report.

    Eye-in-hand fills ``T_flange_cam`` and ``T_base_board``; eye-to-hand fills ``T_base_cam`` and
    ``T_flange_board``. Residuals are reprojection errors in px (or, for pose-only input, board
    point distances in mm), over the views kept; ``per_view_residual_px`` maps every view name
    (rejected ones too) to its RMS under the final solution.
    """

    camera: CameraModel | None
    T_flange_cam: Pose | None
    T_base_board: Pose | None
    residual_px: float
    per_view_residual_px: dict[str, float]
    rejected_views: list[dict[str, Any]]
    used_views: list[str]
    consistency_mm: float
    consistency_deg: float
    eye_to_hand: bool = False
    T_base_cam: Pose | None = None
    T_flange_board: Pose | None = None
    closed_form: dict[str, Pose] = field(default_factory=dict)
    method: str = "park"
    refined_intrinsics: bool = False
    per_view_pose_correction: dict[str, tuple[float, float]] = field(default_factory=dict)
    #: One standard deviation of X's translation (mm) and rotation (deg) along the camera's x, y, z
    #: axes, from the joint refinement's Jacobian with the stated noise (corner noise from the
    #: residuals, the robot's pose noise); None without corners or refinement.
    std_mm: F64 | None = None
    std_deg: F64 | None = None
    #: The noise the refinement weighed with: corners (px per axis), robot (mm, deg per axis),
    #: and whether the robot's was estimated from the residuals or given.
    noise: dict[str, Any] = field(default_factory=dict)
    #: Per view used: (px, mm at the board) RMS of its corners predicted from its recorded robot
    #: pose by the solution without it.
    leave_one_out: dict[str, tuple[float, float]] = field(default_factory=dict)
    #: One sigma of X along the camera axes from the spread of the leave-one-out solutions.
    jackknife_std_mm: F64 | None = None
    jackknife_std_deg: F64 | None = None
    #: The refusal limit of ``residual_px`` that was applied (px).
    max_rms_px: float | None = None

    @property
    def X(self) -> Pose:
        """The camera mounting solved for: T_flange_cam, or T_base_cam for eye-to-hand."""
        X = self.T_base_cam if self.eye_to_hand else self.T_flange_cam
        assert X is not None
        return X

    @property
    def Y(self) -> Pose:
        """The board pose solved for: T_base_board, or T_flange_board for eye-to-hand."""
        Y = self.T_flange_board if self.eye_to_hand else self.T_base_board
        assert Y is not None
        return Y

    def report(self) -> dict[str, Any]:
        """JSON-ready summary of the solution and its quality."""
        from controller.geometry.poses import pose_to_dict

        out: dict[str, Any] = {
            "mode": "eye-to-hand" if self.eye_to_hand else "eye-in-hand",
            "closed_form_method": self.method,
            "refined_intrinsics": self.refined_intrinsics,
            "residual_px": round(float(self.residual_px), 4),
            "per_view_residual_px": {k: round(float(v), 4)
                                     for k, v in self.per_view_residual_px.items()},
            "views_used": list(self.used_views),
            "rejected_views": self.rejected_views,
            "consistency_mm": round(float(self.consistency_mm), 4),
            "consistency_deg": round(float(self.consistency_deg), 5),
            "per_view_pose_correction_mm_deg": {
                k: [round(v[0], 4), round(v[1], 5)]
                for k, v in self.per_view_pose_correction.items()},
        }
        if self.std_mm is not None and self.std_deg is not None:
            std_mm, std_deg = self.std_mm, self.std_deg
            if self.jackknife_std_mm is not None and self.jackknife_std_deg is not None:
                out["hand_eye_std_model_mm_cam_xyz"] = _r(self.std_mm, 4)
                out["hand_eye_std_model_deg_cam_xyz"] = _r(self.std_deg, 5)
                out["hand_eye_std_jackknife_mm_cam_xyz"] = _r(self.jackknife_std_mm, 4)
                out["hand_eye_std_jackknife_deg_cam_xyz"] = _r(self.jackknife_std_deg, 5)
                # The larger of the two per axis: the jackknife also sees what the noise model
                # does not (a robot's systematic pose errors).
                std_mm = np.maximum(self.std_mm, self.jackknife_std_mm)
                std_deg = np.maximum(self.std_deg, self.jackknife_std_deg)
            out["hand_eye_std_mm_cam_xyz"] = _r(std_mm, 4)
            out["hand_eye_std_deg_cam_xyz"] = _r(std_deg, 5)
        if self.noise:
            out["noise"] = {k: round(v, 5) if isinstance(v, float) else v
                            for k, v in self.noise.items()}
        if self.leave_one_out:
            px = np.array([v[0] for v in self.leave_one_out.values()])
            mm = np.array([v[1] for v in self.leave_one_out.values()])
            worst = sorted(self.leave_one_out, key=lambda k: -self.leave_one_out[k][0])[:3]
            out["leave_one_out"] = {
                "rms_px": round(float(np.sqrt(np.mean(px ** 2))), 4),
                "rms_mm_at_board": round(float(np.sqrt(np.mean(mm ** 2))), 4),
                "worst_views": worst,
                "per_view_px_mm": {k: [round(v[0], 4), round(v[1], 4)]
                                   for k, v in self.leave_one_out.items()}}
        if self.max_rms_px is not None:
            out["max_rms_px"] = round(float(self.max_rms_px), 3)
        if self.eye_to_hand:
            out["T_base_cam"] = pose_to_dict(self.X)
            out["T_flange_board"] = pose_to_dict(self.Y)
        else:
            out["T_flange_cam"] = pose_to_dict(self.X)
            out["T_base_board"] = pose_to_dict(self.Y)
        return out


def view_residuals(result: HandEyeResult, T_base_flange: Pose, observation: Observation) -> F64:
    """Reprojection errors (N, 2) px of one view (e.g. held out) under a solved calibration."""
    if result.camera is None:
        raise CalibrationError("view_residuals needs a corner-based hand-eye result")
    A = np.asarray(T_base_flange, float)
    M = A if result.eye_to_hand else invert(A)
    T = invert(result.X) @ M @ result.Y
    P = (T[:3, :3] @ observation.object_points.T).T + T[:3, 3]
    return _project(P, _intr_vector(result.camera)) - observation.image_points


def _r(v: F64, nd: int) -> list[float]:
    return [round(float(x), nd) for x in v]
