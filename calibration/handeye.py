"""Hand-eye calibration (AX = XB): closed-form methods, then a joint robust refinement.

**Eye-in-hand** (camera on the flange): unknowns ``X = T_flange_cam`` and ``Y = T_base_board``
(the board lying in the cell). Every view i with recorded flange pose ``A_i = T_base_flange`` sees
the board at ``T_cam_board_i = X^-1 A_i^-1 Y``.

**Eye-to-hand** (camera fixed in the cell, board held by the robot): unknowns ``X = T_base_cam``
and ``Y = T_flange_board``; ``T_cam_board_i = X^-1 A_i Y``. Both are the same problem with the
motion ``M_i = A_i^-1`` or ``A_i``; the code below is written once for ``T_cam_board_i = X^-1 M_i
Y``.

Steps of :func:`solve_hand_eye`:

1. Degeneracy checks on the robot poses, naming the views: too few views, a robot that did not
   move, too little rotation between views or rotations all about one axis (AX = XB needs two
   rotations about non-parallel axes; Tsai & Lenz 1989).
2. Board pose per view by ``cv2.solvePnP`` (when corners are given).
3. Closed form by OpenCV's ``calibrateHandEye`` (Tsai, Park, Horaud, Andreff, Daniilidis), wrapped
   in :func:`opencv_calibrate_hand_eye` -- the only function that sees OpenCV's
   ``gripper2base`` / ``target2cam`` naming.
4. Joint refinement with ``scipy.optimize.least_squares``: the reprojection error of every board
   corner in every view over X, Y and optionally the intrinsics, with a robust (soft-L1) loss so
   that a bad view cannot pull the solution while it is being found.
5. Bad views: a view whose RMS is over ``max(reject_factor * median, reject_min_px)`` is named,
   left out, and the refinement runs again.
6. Consistency: where each view alone puts the board (``M_i^-1 X T_cam_board_i``, from its own
   PnP) against the joint ``Y``, as the RMS corner distance (mm) and rotation (deg).
7. Refusal: :class:`CalibrationError` naming the worst views when the RMS over the views kept is
   above ``max_rms_px`` or too many views were bad.
"""


from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares
from threadpoolctl import threadpool_limits

from calibration.closed_form import (
    CLOSED_FORM_METHODS,
    _average_pose,
    _closed_forms,
    _pnp,
    closed_form,
    opencv_calibrate_hand_eye,
)
from calibration.handeye_checks import (
    MIN_AXIS_SPREAD_DEG,
    MIN_ROTATION_DEG,
    MIN_VIEWS,
    STILL_DEG,
    STILL_MM,
    check_motions,
)
from calibration.handeye_diagnose import INCONSISTENT_MM, board_spread_mm, diagnose_poses
from calibration.handeye_model import Observation, _camera_from, _intr_vector, _Problem
from calibration.handeye_noise import estimate_noise, hand_eye_std, leave_one_out
from calibration.handeye_pose_only import _solve_pose_only
from calibration.handeye_result import HandEyeResult, view_residuals
from calibration.pose_streams import pair_pose_streams
from controller.errors import CalibrationError
from controller.geometry.camera_model import CameraModel
from controller.geometry.poses import Pose

F64 = NDArray[np.float64]

#: Default refusal limit of the reprojection RMS with the recorded poses, as a fraction of the
#: image diagonal (7.1 px at 2272x1704, 5.7 px at 1920x1200, 2.0 px at 640x480): what a robot
#: whose poses are off by about a millimetre gives at the usual distances.
MAX_RMS_FRACTION = 0.0025
#: Default refusal limits of the pose consistency (RMS of the per-view pose corrections).
MAX_CONSISTENCY_MM, MAX_CONSISTENCY_DEG = 3.0, 0.5

__all__ = ["CLOSED_FORM_METHODS", "MIN_AXIS_SPREAD_DEG", "MIN_ROTATION_DEG", "MIN_VIEWS",
           "STILL_DEG", "STILL_MM", "HandEyeResult", "Observation", "_average_pose",
           "check_motions", "closed_form", "opencv_calibrate_hand_eye", "pair_pose_streams",
           "solve_hand_eye", "view_residuals"]


def solve_hand_eye(T_base_flange_list: Sequence[Pose],
                   observations: Sequence[Observation] | Sequence[Pose],
                   camera: CameraModel | None = None, *, names: Sequence[str] | None = None,
                   eye_to_hand: bool = False, method: str = "park", refine: bool = True,
                   refine_intrinsics: bool = False, robot_sigma_mm: float | None = None,
                   robot_sigma_deg: float | None = None, loss: str = "soft_l1",
                   reject_factor: float = 4.0, reject_min_px: float = 1.0,
                   reject_min_sigma: float = 6.0, max_rms_px: float | None = None,
                   max_consistency_mm: float = MAX_CONSISTENCY_MM,
                   max_consistency_deg: float = MAX_CONSISTENCY_DEG,
                   max_rejected_fraction: float = 0.34, min_views: int = MIN_VIEWS,
                   min_rotation_deg: float = MIN_ROTATION_DEG, leave_out: bool = True,
                   progress: Callable[[str], None] | None = None) -> HandEyeResult:
    """Solve hand-eye from flange poses and board observations (see the module docstring).

    ``T_base_flange_list``: recorded flange poses (mm). ``observations``: per view either an
    :class:`Observation` (corners; needs ``camera``) or a 4x4 ``T_cam_board`` (board pose only;
    then residuals are distances in mm of points on a 200 mm square on the board, and intrinsics
    cannot be refined). ``robot_sigma_mm`` / ``_deg``: the robot's pose noise (per axis), the
    prior of the per-view pose corrections; None (the default) estimates both from the residuals
    (calibration/handeye_noise.py), as it always does the corner noise. A view is bad when its
    pose correction exceeds ``max(reject_factor * median, reject_min_sigma)`` sigmas, or its
    reprojection RMS (with its correction) exceeds ``max(reject_factor * median,
    reject_min_px)``. ``leave_out``: predict every view from a solve without it (the report's
    leave-one-out table and the jackknife one-sigma). ``progress`` gets a line per step.

    ``residual_px`` is the reprojection RMS of the views kept *with their recorded poses* (what
    the calibration will see in use); ``consistency_mm`` / ``_deg`` the RMS of the pose corrections
    (how well robot poses and images agree). ``max_rms_px`` None is :data:`MAX_RMS_FRACTION` of
    the image diagonal.

    Raises :class:`CalibrationError` naming the views for degenerate input (too few views, robot
    still, too little rotation), for input that fits only once a usual mistake is undone (units,
    quaternion order, inverted poses: the message names it), for too many bad views, and for a
    result above ``max_rms_px``, ``max_consistency_mm`` or ``max_consistency_deg``; its details
    hold ``options``, the command-line options that would change the outcome.
    """
    # One BLAS thread: the matrices here are a few hundred wide; threads only add contention
    # (on a 2-core machine shared with other jobs a 132x132 pinv took a second with them).
    with threadpool_limits(limits=1, user_api="blas"):
        return _solve(T_base_flange_list, observations, camera, names=names,
                      eye_to_hand=eye_to_hand, method=method, refine=refine,
                      refine_intrinsics=refine_intrinsics, robot_sigma_mm=robot_sigma_mm,
                      robot_sigma_deg=robot_sigma_deg, loss=loss, reject_factor=reject_factor,
                      reject_min_px=reject_min_px, reject_min_sigma=reject_min_sigma,
                      max_rms_px=max_rms_px, max_consistency_mm=max_consistency_mm,
                      max_consistency_deg=max_consistency_deg,
                      max_rejected_fraction=max_rejected_fraction, min_views=min_views,
                      min_rotation_deg=min_rotation_deg, leave_out=leave_out, progress=progress)


def _solve(T_base_flange_list: Sequence[Pose],
           observations: Sequence[Observation] | Sequence[Pose], camera: CameraModel | None, *,
           names: Sequence[str] | None, eye_to_hand: bool, method: str, refine: bool,
           refine_intrinsics: bool, robot_sigma_mm: float | None,
           robot_sigma_deg: float | None, loss: str, reject_factor: float,
           reject_min_px: float, reject_min_sigma: float, max_rms_px: float | None,
           max_consistency_mm: float, max_consistency_deg: float,
           max_rejected_fraction: float, min_views: int, min_rotation_deg: float,
           leave_out: bool, progress: Callable[[str], None] | None) -> HandEyeResult:
    """:func:`solve_hand_eye`'s work, under one BLAS thread."""
    n = len(T_base_flange_list)
    nm = list(names) if names is not None else [f"view{i + 1:02d}" for i in range(n)]
    if len(observations) != n or len(nm) != n:
        raise CalibrationError(f"solve_hand_eye: {n} flange poses, {len(observations)} "
                               f"observations and {len(nm)} names: they must match")
    A = [np.asarray(T, float) for T in T_base_flange_list]
    check_motions(A, nm, min_views=min_views, min_rotation_deg=min_rotation_deg)
    pose_only = n > 0 and not isinstance(observations[0], Observation)
    if pose_only:
        return _solve_pose_only(A, [np.asarray(o, float) for o in observations], nm,
                                eye_to_hand=eye_to_hand, method=method, refine=refine,
                                loss=loss, reject_factor=reject_factor,
                                reject_min_mm=reject_min_px,
                                max_rms_mm=3.0 if max_rms_px is None else max_rms_px,
                                max_rejected_fraction=max_rejected_fraction, min_views=min_views)
    if camera is None:
        raise CalibrationError("solve_hand_eye: corner observations need the camera intrinsics")
    obs = [o for o in observations if isinstance(o, Observation)]
    pnp = [_pnp(camera, o, nm[i]) for i, o in enumerate(obs)]
    T_cb = [p[0] for p in pnp]
    closed, motions, X, Y = _closed_forms(A, T_cb, eye_to_hand, method,
                                          f"; the views {', '.join(nm)} may be degenerate")
    say = progress or (lambda line: None)
    spread = board_spread_mm(A, T_cb, eye_to_hand)
    if spread > INCONSISTENT_MM:
        hint = diagnose_poses(A, T_cb, eye_to_hand)
        if hint is not None:
            raise CalibrationError(f"hand-eye refused: {hint}", board_spread_mm=spread,
                                   options=["fix the view files or --board as said, then rerun"])
    if max_rms_px is None:
        max_rms_px = MAX_RMS_FRACTION * float(np.hypot(camera.width, camera.height))
    intr = _intr_vector(camera)
    estimate = robot_sigma_mm is None or robot_sigma_deg is None
    sigma_mm = 0.05 if robot_sigma_mm is None else float(robot_sigma_mm)
    sigma_rad = float(np.radians(0.01 if robot_sigma_deg is None else robot_sigma_deg))
    # Corner noise per image axis, to start: the pooled PnP residual (a 2D RMS).
    sigma_px = max(0.02, float(np.sqrt(np.mean([q[1] ** 2 for q in pnp])))) / np.sqrt(2.0)
    say(f"closed forms done ({len(closed)} methods); refining {n} views"
        + (", estimating the robot's pose noise" if estimate else ""))
    used = list(range(n))
    rejected: list[dict[str, Any]] = []
    corr_mm, corr_deg, corr_sigma, fit_rms = (np.zeros(n) for _ in range(4))
    noise_info: dict[str, Any] = {}
    t0 = time.monotonic()
    noise_pending = refine

    def assess(prob: _Problem, X: Pose, Y: Pose, intr: F64, D: F64
               ) -> tuple[int, F64, float, float]:
        """Per view pose correction and fit; the worst view, the scores and the two limits."""
        fit = prob.per_view_rms(prob.reprojection(X, Y, intr, D))
        for k, i in enumerate(used):
            corr_deg[i] = float(np.degrees(np.linalg.norm(D[k, :3])))
            corr_mm[i] = float(np.linalg.norm(D[k, 3:]))
            corr_sigma[i] = float(np.sqrt(np.sum((D[k, :3] / prob.sigma_rad) ** 2)
                                          + np.sum((D[k, 3:] / prob.sigma_mm) ** 2)))
            fit_rms[i] = fit[k]
        lim_s = max(reject_factor * float(np.median(corr_sigma[used])), reject_min_sigma)
        lim_px = max(reject_factor * float(np.median(fit_rms[used])), reject_min_px)
        score = np.maximum(corr_sigma / lim_s, fit_rms / lim_px)
        return max(used, key=lambda i: score[i]), score, lim_s, lim_px

    while True:
        prob = _Problem([A[i] for i in used], [obs[i] for i in used], X, Y, intr,
                        refine_intrinsics and refine, eye_to_hand, sigma_px, sigma_mm, sigma_rad)
        p = prob.x0()
        if refine:
            p = _refine(prob, p, loss)
        X, Y, intr, D = prob.unpack(p)
        worst, score, lim_s, lim_px = assess(prob, X, Y, intr, D)
        if refine and score[worst] <= 1.0 and noise_pending:
            # The noise is estimated once the bad views are out (with them in, a robot that is
            # fine elsewhere looks noisy and the bad views hide in the noise), then the views
            # are judged again with it.
            noise_pending = False
            for it in range(6):
                J = prob.jac(p)
                N_inv = np.asarray(np.linalg.pinv(J.T @ J), float)
                s_px, s_mm, s_rad, factors = estimate_noise(prob, prob.residuals(p), J, N_inv,
                                                            estimate)
                change = max(abs(np.log(s_px / prob.sigma_px)),
                             abs(np.log(s_mm / prob.sigma_mm)),
                             abs(np.log(s_rad / prob.sigma_rad)))
                prob.sigma_px, prob.sigma_mm, prob.sigma_rad = s_px, s_mm, s_rad
                noise_info = {"iterations": it + 1, "variance_factors": factors}
                say(f"  noise pass {it + 1}: corners {s_px:.3f} px, robot {s_mm:.3f} mm / "
                    f"{np.degrees(s_rad):.4f} deg ({len(used)} views, "
                    f"{time.monotonic() - t0:.0f} s)")
                p = _refine(prob, p, loss)
                if change < 0.05:
                    break
            sigma_px, sigma_mm, sigma_rad = prob.sigma_px, prob.sigma_mm, prob.sigma_rad
            X, Y, intr, D = prob.unpack(p)
            worst, score, lim_s, lim_px = assess(prob, X, Y, intr, D)
        if not refine or score[worst] <= 1.0:
            break
        if fit_rms[worst] > lim_px:
            why = (f"its corners do not fit the board (RMS {fit_rms[worst]:.2f} px > "
                   f"{lim_px:.2f} px): blur, a misdetection or a wrong board spec")
        else:
            why = (f"its recorded robot pose is {corr_mm[worst]:.2f} mm / {corr_deg[worst]:.3f} "
                   f"deg away from where its image puts it ({corr_sigma[worst]:.0f} sigma > "
                   f"{lim_s:.0f}): the robot was moving during the exposure (motion blur) or the "
                   f"pose is wrong")
        rejected.append({"view": nm[worst], "pose_error_mm": round(corr_mm[worst], 3),
                         "pose_error_deg": round(corr_deg[worst], 4),
                         "fit_rms_px": round(float(fit_rms[worst]), 3), "reason": why})
        say(f"  {nm[worst]} left out: {why}")
        used.remove(worst)
        if len(used) < min_views or len(rejected) > max_rejected_fraction * n:
            listed = ", ".join(r["view"] for r in rejected)
            raise CalibrationError(
                f"hand-eye refused: too many bad views ({listed}); {len(used)} of {n} views are "
                f"left. Retake the views named, holding the robot still, with the whole board in "
                f"the image", rejected_views=rejected,
                options=["retake the views named", "--robot-sigma-mm / --robot-sigma-deg larger "
                         "than the estimate if the robot is known to be that inaccurate"])
        check_motions([A[i] for i in used], [nm[i] for i in used], min_views=min_views,
                      min_rotation_deg=min_rotation_deg)
    std_mm = std_deg = None
    loo: dict[str, Any] = {}
    if refine:
        J = prob.jac(p)
        std_mm, std_deg = hand_eye_std(np.asarray(np.linalg.pinv(J.T @ J), float), X)
        if leave_out:
            say(f"leave-one-out predictions of {len(used)} views")
            loo = leave_one_out(prob, p, prob.residuals(p), J)
    cam_out = _camera_from(camera, intr) if refine_intrinsics and refine else camera
    # Residuals with the recorded (uncorrected) poses, every view.
    full = _Problem(A, obs, X, Y, intr, False, eye_to_hand, sigma_px, sigma_mm, sigma_rad)
    per_view = full.per_view_rms(full.reprojection(X, Y, intr, np.zeros((n, 6))))
    resid = float(np.sqrt(np.mean(per_view[used] ** 2)))
    c_mm = float(np.sqrt(np.mean(corr_mm[used] ** 2)))
    c_deg = float(np.sqrt(np.mean(corr_deg[used] ** 2)))
    if resid > max_rms_px or c_mm > max_consistency_mm or c_deg > max_consistency_deg:
        worst_views = sorted(used, key=lambda i: -per_view[i])[:3]
        listed = ", ".join(f"{nm[i]} ({per_view[i]:.2f} px, {corr_mm[i]:.2f} mm, "
                           f"{corr_deg[i]:.3f} deg)" for i in worst_views)
        hint = diagnose_poses(A, T_cb, eye_to_hand)
        options = [f"--max-rms-px {1.05 * resid:.2f}" if resid > max_rms_px else "",
                   f"--max-consistency {max(max_consistency_mm, 1.05 * c_mm):.2f} "
                   f"{max(max_consistency_deg, 1.05 * c_deg):.3f}"
                   if c_mm > max_consistency_mm or c_deg > max_consistency_deg else "",
                   "retake or remove the worst views named"]
        raise CalibrationError(
            f"hand-eye refused: reprojection RMS {resid:.2f} px (limit {max_rms_px:.2f}), pose "
            f"consistency {c_mm:.3f} mm / {c_deg:.4f} deg (limits {max_consistency_mm} mm / "
            f"{max_consistency_deg} deg); worst views: {listed}. "
            + (f"Likely cause: {hint}. " if hint else "Check the board spec, the robot's "
               "tool0 setting, and retake those views. ")
            + f"Would pass with: {'; '.join(o for o in options if o)}",
            residual_px=resid, consistency_mm=c_mm, consistency_deg=c_deg,
            worst_views=[nm[i] for i in worst_views], options=[o for o in options if o],
            robot_sigma_mm=sigma_mm, robot_sigma_deg=float(np.degrees(sigma_rad)))
    noise = {"corner_sigma_px": sigma_px, "robot_sigma_mm": sigma_mm,
             "robot_sigma_deg": float(np.degrees(sigma_rad)),
             "robot_noise": "estimated from the residuals" if estimate else "given", **noise_info}
    return HandEyeResult(
        camera=cam_out,
        T_flange_cam=None if eye_to_hand else X, T_base_board=None if eye_to_hand else Y,
        residual_px=resid, per_view_residual_px={nm[i]: float(per_view[i]) for i in range(n)},
        rejected_views=rejected, used_views=[nm[i] for i in used],
        consistency_mm=c_mm, consistency_deg=c_deg,
        eye_to_hand=eye_to_hand, T_base_cam=X if eye_to_hand else None,
        T_flange_board=Y if eye_to_hand else None, closed_form=closed, method=method,
        refined_intrinsics=bool(refine_intrinsics and refine),
        per_view_pose_correction={nm[i]: (float(corr_mm[i]), float(corr_deg[i]))
                                  for i in used}, std_mm=std_mm, std_deg=std_deg, noise=noise,
        leave_one_out={nm[i]: (float(loo["rms_px"][k]), float(loo["rms_mm"][k]))
                       for k, i in enumerate(used)} if loo else {},
        jackknife_std_mm=loo.get("jackknife_std_mm"),
        jackknife_std_deg=loo.get("jackknife_std_deg"), max_rms_px=max_rms_px)


def _refine(prob: _Problem, p: F64, loss: str) -> F64:
    """One robust least-squares solve of ``prob`` from ``p``."""
    sol = least_squares(prob.residuals, p, jac=prob.jac, loss=loss, f_scale=3.0,
                        method="trf", x_scale="jac", tr_solver="exact", max_nfev=100)
    return np.asarray(sol.x)


