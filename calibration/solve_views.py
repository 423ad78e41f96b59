"""Intrinsics + hand-eye from collected views, validated on held-out views, with metadata."""
from __future__ import annotations

import datetime as _dt
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from calibration.calibration_file import Calibration
from calibration.handeye import HandEyeResult, Observation, solve_hand_eye, view_residuals
from calibration.intrinsics import IntrinsicsResult, solve_intrinsics
from calibration.targets import BoardSpec
from calibration.teach_progress import ViewRecord
from controller.errors import CalibrationError
from controller.geometry.camera_model import CameraModel
from controller.geometry.poses import Pose

F64 = NDArray[np.float64]


def solve_views(views: Sequence[ViewRecord], board: BoardSpec, image_size: tuple[int, int], *,
                eye_to_hand: bool = False, holdout_every: int = 5, camera_name: str = "seam_cam",
                robot_sigma_mm: float | None = None, robot_sigma_deg: float | None = None,
                intrinsics: CameraModel | None = None, intrinsics_source: str | None = None,
                log: Callable[[str], None] | None = None,
                metadata: dict[str, Any] | None = None, **hand_eye_options: Any
                ) -> tuple[Calibration, dict[str, Any]]:
    """Intrinsics + hand-eye from collected views, validated on held-out views.

    1. Intrinsics from every view with the board (outlier views rejected) -- or, with
       ``intrinsics`` (a camera model from an earlier calibration, e.g. ``--intrinsics FILE``),
       that model, fixed: it must be of the same image size.
    2. Hand-eye with joint refinement of the intrinsics (unless fixed) on every view: bad views
       named, left out; the robot's pose noise estimated unless ``robot_sigma_mm`` / ``_deg``
       are given; every view predicted from a solve without it (leave-one-out).
    3. Validation: every ``holdout_every``-th good view is held out, the calibration solved again
       without them, and their reprojection error (with their recorded poses) checked against the
       same limit as the solution's own residual.
    4. The calibration of step 2 (all good views) is returned with its metadata; the report's
       ``summary`` holds the lines a person reads (also sent to ``log``).

    ``hand_eye_options`` go to :func:`calibration.handeye.solve_hand_eye` (e.g. ``max_rms_px``,
    ``max_consistency_mm``, ``max_consistency_deg``, ``method``).

    Raises :class:`CalibrationError` when the board is in too few views (naming the views
    without a board and why), for degenerate robot motion, too many bad views, bad residuals, a
    failed validation (naming the held-out views), or intrinsics of another image size. Its
    details hold ``report``: what was found up to the refusal (views, reasons, intrinsics).
    """
    say = log or (lambda line: None)
    if board.orientation_ambiguous:
        raise CalibrationError(
            f"board {board.spec}: a chessboard with {board.cols}+{board.rows} inner corners "
            f"(an even sum) looks the same turned 180 degrees, so views cannot be matched for "
            f"hand-eye; use a board with an odd sum (e.g. 9x6) or a ChArUco board")
    found = [v for v in views if v.detection is not None]
    missing = [v.name for v in views if v.detection is None]
    why = {v.name: v.skip_reason or "no board" for v in views if v.detection is None}
    report: dict[str, Any] = {"board": board.spec, "views_total": len(views),
                              "views_without_board": missing, "why_no_board": why}
    if len(found) < 5:
        raise CalibrationError(
            f"the board {board.spec} was found in only {len(found)} of {len(views)} views"
            f"{'; not in ' + ', '.join(missing) if missing else ''}; need at least 5: check the "
            f"board spec (inner corners for a chessboard) and that the whole board is in view"
            f"{_first_reasons(why)}", views_without_board=missing, why_no_board=why,
            report=report, options=["--board with the right inner-corner count", "more views"])
    names = [v.name for v in found]
    if intrinsics is not None:
        if (intrinsics.width, intrinsics.height) != tuple(image_size):
            raise CalibrationError(
                f"--intrinsics {intrinsics_source or ''}: the camera model is for "
                f"{intrinsics.width}x{intrinsics.height} images, these are "
                f"{image_size[0]}x{image_size[1]}; give the calibration of this camera at this "
                f"resolution", report=report)
        camera0 = intrinsics
        report["intrinsics"] = {"fixed": True, "source": intrinsics_source or "given",
                                **_camera_dict(intrinsics)}
        intr = None
    else:
        intr = solve_intrinsics([v.detection.image_points for v in found if v.detection],
                                [v.detection.object_points for v in found if v.detection],
                                image_size, names=names, camera_name=camera_name)
        camera0 = intr.camera
        report["intrinsics"] = {"fixed": False, **intr.report()}
    obs = [Observation(v.detection.image_points, v.detection.object_points)
           for v in found if v.detection is not None]
    A = [v.T_base_flange for v in found]
    kw: dict[str, Any] = {"eye_to_hand": eye_to_hand, "refine_intrinsics": intrinsics is None,
                          "robot_sigma_mm": robot_sigma_mm, "robot_sigma_deg": robot_sigma_deg,
                          **hand_eye_options}
    try:
        he = solve_hand_eye(A, obs, camera0, names=names, progress=say, **kw)
        if holdout_every > 1:
            say(f"validating: every {holdout_every}th view held out, solved again without them")
        validation = _validate(he, found, A, obs, camera0, holdout_every,
                               {**kw, "leave_out": False})
    except CalibrationError as err:
        err.details.setdefault("report", report)
        if intrinsics is None and len(found) < 12:
            err.details.setdefault("options", []).append(
                "--intrinsics FILE (a lens calibrated once: with few views the refined "
                "intrinsics overfit)")
        raise
    cam_out = he.camera or camera0
    calib = Calibration(cam_out)
    if eye_to_hand:
        calib.T_base_cam = he.X
    else:
        calib.T_flange_cam = he.X
    report["intrinsics_written"] = {"refined_with_hand_eye": he.refined_intrinsics,
                                    **_camera_dict(cam_out)}
    report["hand_eye"] = he.report()
    report["validation"] = validation
    report["summary"] = quality_summary(report)
    for line in report["summary"]:
        say(line)
    calib.metadata = _metadata(he, intr, report, metadata)
    return calib, report


def _camera_dict(cam: CameraModel) -> dict[str, Any]:
    return {"image_size": [cam.width, cam.height], "fx": round(float(cam.fx), 4),
            "fy": round(float(cam.fy), 4), "cx": round(float(cam.cx), 4),
            "cy": round(float(cam.cy), 4), "distortion": [round(float(v), 6) for v in cam.dist]}


def quality_summary(report: dict[str, Any]) -> list[str]:
    """The lines a person reads after a successful solve (from a :func:`solve_views` report)."""
    he = report["hand_eye"]
    lines = [f"views: {len(he['views_used'])} used, {len(he['rejected_views'])} left out"
             + "".join(f" ({r['view']})" for r in he["rejected_views"])
             + f", {len(report['views_without_board'])} without a board"]
    noise = he.get("noise", {})
    if noise:
        lines.append(f"noise: corners {noise['corner_sigma_px']:.3f} px, robot "
                     f"{noise['robot_sigma_mm']:.3f} mm / {noise['robot_sigma_deg']:.4f} deg per "
                     f"axis ({noise['robot_noise']})")
    lines.append(f"reprojection with the recorded poses {he['residual_px']:.2f} px (limit "
                 f"{he.get('max_rms_px', 0):.2f}), pose consistency {he['consistency_mm']:.3f} mm"
                 f" / {he['consistency_deg']:.4f} deg")
    loo = he.get("leave_one_out")
    if loo:
        lines.append(f"leave-one-out prediction {loo['rms_px']:.2f} px RMS, "
                     f"{loo['rms_mm_at_board']:.3f} mm at the board; worst views "
                     + ", ".join(f"{v} ({loo['per_view_px_mm'][v][0]:.2f} px)"
                                 for v in loo["worst_views"]))
    if "hand_eye_std_mm_cam_xyz" in he:
        s, d = he["hand_eye_std_mm_cam_xyz"], he["hand_eye_std_deg_cam_xyz"]
        lines.append(f"hand-eye one sigma (camera x, y, z): {s[0]:.3f}, {s[1]:.3f}, {s[2]:.3f} mm;"
                     f" {d[0]:.4f}, {d[1]:.4f}, {d[2]:.4f} deg")
    w = report["intrinsics_written"]
    lines.append(f"intrinsics written: fx {w['fx']:.2f} fy {w['fy']:.2f} cx {w['cx']:.2f} cy "
                 f"{w['cy']:.2f} ("
                 + ("fixed, from " + str(report["intrinsics"].get("source"))
                    if report["intrinsics"].get("fixed") else "refined with the hand-eye") + ")")
    return lines


def _validate(he: HandEyeResult, found: Sequence[ViewRecord], A: Sequence[Pose],
              obs: Sequence[Observation], camera: CameraModel, holdout_every: int,
              kw: dict[str, Any]) -> dict[str, Any]:
    if holdout_every <= 1:
        return {"held_out": [], "note": "validation skipped (holdout_every <= 1)"}
    used = [i for i, v in enumerate(found) if v.name in he.used_views]
    held = used[holdout_every - 1::holdout_every]
    train = [i for i in range(len(found)) if i not in held]
    if len(held) == 0 or len(train) - len(he.rejected_views) < 5:
        return {"held_out": [], "note": "too few views to hold some out"}
    sub = solve_hand_eye([A[i] for i in train], [obs[i] for i in train], camera,
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


def _metadata(he: HandEyeResult, intr: IntrinsicsResult | None, report: dict[str, Any],
              extra: dict[str, Any] | None) -> dict[str, Any]:
    meta: dict[str, Any] = {
        "date": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "tool": "seamguide calibrate",
        "board": report["board"],
        "mode": "eye-to-hand" if he.eye_to_hand else "eye-in-hand",
        "residual_px": round(float(he.residual_px), 4),
        "intrinsics": (f"fixed, from {report['intrinsics'].get('source')}" if intr is None
                       else "refined with the hand-eye"),
        "consistency_mm": round(float(he.consistency_mm), 4),
        "consistency_deg": round(float(he.consistency_deg), 5),
        "views_used": list(he.used_views),
        "views_rejected": [{"view": r["view"], "reason": r["reason"]} for r in he.rejected_views],
        "views_without_board": list(report["views_without_board"]),
    }
    if intr is not None:
        meta["intrinsics_rms_px"] = round(float(intr.rms_px), 4)
    if he.noise:
        meta["robot_sigma_mm_deg"] = [round(he.noise["robot_sigma_mm"], 4),
                                      round(he.noise["robot_sigma_deg"], 5)]
    if he.leave_one_out:
        meta["leave_one_out_rms_px"] = report["hand_eye"]["leave_one_out"]["rms_px"]
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
