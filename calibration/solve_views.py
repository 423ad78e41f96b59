"""Intrinsics + hand-eye from collected views, validated on held-out views, with metadata."""
from __future__ import annotations

import datetime as _dt
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from calibration.calibration_file import Calibration
from calibration.handeye import HandEyeResult, Observation, solve_hand_eye, view_residuals
from calibration.intrinsics import IntrinsicsResult, solve_intrinsics
from calibration.targets import BoardSpec
from calibration.teach_progress import ViewRecord
from controller.errors import CalibrationError
from controller.geometry.poses import Pose

F64 = NDArray[np.float64]


def solve_views(views: Sequence[ViewRecord], board: BoardSpec, image_size: tuple[int, int], *,
                eye_to_hand: bool = False, holdout_every: int = 5, camera_name: str = "seam_cam",
                robot_sigma_mm: float = 0.05, robot_sigma_deg: float = 0.01,
                metadata: dict[str, Any] | None = None, **hand_eye_options: Any
                ) -> tuple[Calibration, dict[str, Any]]:
    """Intrinsics + hand-eye from collected views, validated on held-out views.

    1. Intrinsics from every view with the board (outlier views rejected).
    2. Hand-eye with joint refinement of the intrinsics on every view: bad views named, left out.
    3. Validation: every ``holdout_every``-th good view is held out, the calibration solved again
       without them, and their reprojection error (with their recorded poses) checked against the
       same limit as the solution's own residual.
    4. The calibration of step 2 (all good views) is returned with its metadata.

    ``hand_eye_options`` go to :func:`calibration.handeye.solve_hand_eye` (e.g. ``max_rms_px``,
    ``max_consistency_mm``, ``max_consistency_deg``, ``method``).

    Raises :class:`CalibrationError` when the board is in too few views (naming the views
    without a board), for degenerate robot motion, too many bad views, bad residuals, or a
    failed validation (naming the held-out views).
    """
    if board.orientation_ambiguous:
        raise CalibrationError(
            f"board {board.spec}: a chessboard with {board.cols}+{board.rows} inner corners "
            f"(an even sum) looks the same turned 180 degrees, so views cannot be matched for "
            f"hand-eye; use a board with an odd sum (e.g. 9x6) or a ChArUco board")
    found = [v for v in views if v.detection is not None]
    missing = [v.name for v in views if v.detection is None]
    why = {v.name: v.skip_reason or "no board" for v in views if v.detection is None}
    if len(found) < 5:
        raise CalibrationError(
            f"the board {board.spec} was found in only {len(found)} of {len(views)} views"
            f"{'; not in ' + ', '.join(missing) if missing else ''}; need at least 5: check the "
            f"board spec (inner corners for a chessboard) and that the whole board is in view"
            f"{_first_reasons(why)}", views_without_board=missing, why_no_board=why)
    names = [v.name for v in found]
    intr = solve_intrinsics([v.detection.image_points for v in found if v.detection],
                            [v.detection.object_points for v in found if v.detection],
                            image_size, names=names, camera_name=camera_name)
    obs = [Observation(v.detection.image_points, v.detection.object_points)
           for v in found if v.detection is not None]
    A = [v.T_base_flange for v in found]
    kw: dict[str, Any] = {"eye_to_hand": eye_to_hand, "refine_intrinsics": True,
                          "robot_sigma_mm": robot_sigma_mm, "robot_sigma_deg": robot_sigma_deg,
                          **hand_eye_options}
    he = solve_hand_eye(A, obs, intr.camera, names=names, **kw)
    validation = _validate(he, found, A, obs, intr, holdout_every, kw)
    calib = Calibration(he.camera or intr.camera)
    if eye_to_hand:
        calib.T_base_cam = he.X
    else:
        calib.T_flange_cam = he.X
    report = {
        "board": board.spec,
        "views_total": len(views),
        "views_without_board": missing,
        "why_no_board": why,
        "intrinsics": intr.report(),
        "hand_eye": he.report(),
        "validation": validation,
    }
    calib.metadata = _metadata(he, intr, report, metadata)
    return calib, report


def _validate(he: HandEyeResult, found: Sequence[ViewRecord], A: Sequence[Pose],
              obs: Sequence[Observation], intr: IntrinsicsResult, holdout_every: int,
              kw: dict[str, Any]) -> dict[str, Any]:
    if holdout_every <= 1:
        return {"held_out": [], "note": "validation skipped (holdout_every <= 1)"}
    used = [i for i, v in enumerate(found) if v.name in he.used_views]
    held = used[holdout_every - 1::holdout_every]
    train = [i for i in range(len(found)) if i not in held]
    if len(held) == 0 or len(train) - len(he.rejected_views) < 5:
        return {"held_out": [], "note": "too few views to hold some out"}
    sub = solve_hand_eye([A[i] for i in train], [obs[i] for i in train], intr.camera,
                         names=[found[i].name for i in train], **kw)
    per = {}
    for i in held:
        r = view_residuals(sub, A[i], obs[i])
        per[found[i].name] = float(np.sqrt(np.mean(np.sum(r * r, axis=1))))
    rms = float(np.sqrt(np.mean(np.square(list(per.values())))))
    limit = max(3.0 * sub.residual_px, 1.0)
    if rms > limit:
        listed = ", ".join(f"{k} ({v:.2f} px)" for k, v in per.items())
        raise CalibrationError(
            f"validation failed: held-out views reproject with RMS {rms:.2f} px, more than "
            f"{limit:.2f} px (3x the fit's {sub.residual_px:.2f} px): {listed}. The calibration "
            f"does not predict new views; take more, better spread views", held_out=per)
    dX = _pose_delta(sub.X, he.X)
    return {"held_out": list(per), "held_out_rms_px": round(rms, 4),
            "held_out_per_view_px": {k: round(v, 4) for k, v in per.items()},
            "limit_px": round(limit, 4), "fit_without_them_residual_px": round(sub.residual_px, 4),
            "hand_eye_change_mm_deg": [round(dX[0], 4), round(dX[1], 5)], "passed": True}


def _pose_delta(a: Pose, b: Pose) -> tuple[float, float]:
    from controller.geometry.poses import pose_error

    return pose_error(a, b)


def _metadata(he: HandEyeResult, intr: IntrinsicsResult, report: dict[str, Any],
              extra: dict[str, Any] | None) -> dict[str, Any]:
    meta: dict[str, Any] = {
        "date": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "tool": "seamguide calibrate",
        "board": report["board"],
        "mode": "eye-to-hand" if he.eye_to_hand else "eye-in-hand",
        "residual_px": round(float(he.residual_px), 4),
        "intrinsics_rms_px": round(float(intr.rms_px), 4),
        "consistency_mm": round(float(he.consistency_mm), 4),
        "consistency_deg": round(float(he.consistency_deg), 5),
        "views_used": list(he.used_views),
        "views_rejected": [{"view": r["view"], "reason": r["reason"]} for r in he.rejected_views],
        "views_without_board": list(report["views_without_board"]),
    }
    if report.get("validation", {}).get("held_out"):
        meta["validation_held_out_rms_px"] = report["validation"]["held_out_rms_px"]
    meta.update(extra or {})
    return _plain(meta)


def _plain(obj: Any) -> Any:
    """Numbers and containers as plain Python types (YAML-safe)."""
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_plain(v) for v in obj]
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return _plain(obj.tolist())
    return obj


def _first_reasons(why: dict[str, str], n: int = 2) -> str:
    """'; NAME: reason' for the first ``n`` distinct reasons a board was not used."""
    seen: dict[str, str] = {}
    for name, reason in why.items():
        seen.setdefault(reason, name)
    return "".join(f"; {name}: {reason}" for reason, name in list(seen.items())[:n])
