"""Hand-eye from board poses only (a tracker's poses, no corners): board-point distances in mm."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares

from calibration.closed_form import _closed_forms, _consistency
from calibration.handeye_model import _exp
from calibration.handeye_result import HandEyeResult
from controller.errors import CalibrationError
from controller.geometry.poses import Pose, invert, make_pose

F64 = NDArray[np.float64]


def _solve_pose_only(A: list[F64], T_cb: list[F64], nm: list[str], *, eye_to_hand: bool,
                     method: str, refine: bool, loss: str, reject_factor: float,
                     reject_min_mm: float, max_rms_mm: float, max_rejected_fraction: float,
                     min_views: int) -> HandEyeResult:
    """Hand-eye from board poses only (no corners): residuals are board-point distances (mm)."""
    n = len(A)
    closed, motions, X, Y = _closed_forms(A, T_cb, eye_to_hand, method, "")
    # Virtual board points: corners of a 200 mm square and its centre.
    pts = np.array([[-100, -100, 0], [100, -100, 0], [100, 100, 0], [-100, 100, 0], [0, 0, 0]],
                   float)
    used = list(range(n))
    rejected: list[dict[str, Any]] = []

    def per_view_err(X: Pose, Y: Pose) -> F64:
        mm, _ = _consistency(motions, T_cb, X, Y, pts)
        return mm

    while True:
        if refine:
            X0, Y0 = X, Y

            def fun(p: F64, X0: Pose = X0, Y0: Pose = Y0) -> F64:
                Xp = make_pose(X0[:3, :3] @ _exp(p[0:3]), X0[:3, 3] + p[3:6])
                Yp = make_pose(Y0[:3, :3] @ _exp(p[6:9]), Y0[:3, 3] + p[9:12])
                out = []
                for i in used:
                    Yi = invert(motions[i]) @ Xp @ T_cb[i]
                    out.append(((Yi[:3, :3] - Yp[:3, :3]) @ pts.T).T.ravel()
                               + np.tile(Yi[:3, 3] - Yp[:3, 3], len(pts)))
                return np.concatenate(out)

            sol = least_squares(fun, np.zeros(12), loss=loss, f_scale=1.0, x_scale="jac",
                                max_nfev=200)
            p = sol.x
            X = make_pose(X0[:3, :3] @ _exp(p[0:3]), X0[:3, 3] + p[3:6])
            Y = make_pose(Y0[:3, :3] @ _exp(p[6:9]), Y0[:3, 3] + p[9:12])
        err = per_view_err(X, Y)
        med = float(np.median(err[used]))
        limit = max(reject_factor * med, reject_min_mm)
        cand = [i for i in used if err[i] > limit]
        if not cand:
            break
        worst = max(cand, key=lambda i: err[i])
        rejected.append({"view": nm[worst], "rms_mm": round(float(err[worst]), 3),
                         "reason": f"board placed {err[worst]:.2f} mm off (limit {limit:.2f})"})
        used.remove(worst)
        if len(used) < min_views or len(rejected) > max_rejected_fraction * n:
            raise CalibrationError(f"hand-eye refused: too many inconsistent poses "
                                   f"({', '.join(r['view'] for r in rejected)})")
    err = per_view_err(X, Y)
    _, deg = _consistency([motions[i] for i in used], [T_cb[i] for i in used], X, Y, pts)
    resid = float(np.sqrt(np.mean(err[used] ** 2)))
    if resid > max_rms_mm:
        raise CalibrationError(f"hand-eye refused: pose consistency {resid:.2f} mm is above "
                               f"{max_rms_mm} mm", residual_mm=resid)
    return HandEyeResult(
        camera=None, T_flange_cam=None if eye_to_hand else X,
        T_base_board=None if eye_to_hand else Y, residual_px=resid,
        per_view_residual_px={nm[i]: float(err[i]) for i in range(n)},
        rejected_views=rejected, used_views=[nm[i] for i in used], consistency_mm=resid,
        consistency_deg=float(np.sqrt(np.mean(deg ** 2))), eye_to_hand=eye_to_hand,
        T_base_cam=X if eye_to_hand else None, T_flange_board=Y if eye_to_hand else None,
        closed_form=closed, method=method)
