"""What the data say about their own noise and about the hand-eye's precision.

**Noise from the residuals** (:func:`estimate_noise`). The joint refinement weighs three kinds
of residual: the corners (px), and each view's correction of its recorded flange pose, in
translation (mm) and rotation (rad), against the robot's pose noise. How noisy each is, is
estimated from the fit itself by variance-component estimation (Foerstner 1979; Koch, Parameter
Estimation, 1999): a group's variance factor is its weighted residual square sum over its
redundancy, ``sum(r^2) / sum(1 - h_ii)`` (``h_ii`` the diagonal of the hat matrix: what the fit
absorbs). Here the factor is taken per view and the median over views is used (scaled by the
median of a chi-square), so that a bad view -- taken while the robot moved -- cannot inflate the
robot's noise and hide itself: it is still many sigmas out, and rejected.

**Leave-one-out** (:func:`leave_one_out`). For every view: the solution without it, by one
Gauss-Newton step from the full solution on the remaining residuals (its own rows and its pose
correction removed), and the view predicted from its recorded robot pose under that solution: RMS
in px and in mm at the board (the pixel error times the corner's depth over the focal length).
The spread of the hand-eye over the leave-one-out solutions is the jackknife's one-sigma,
``sqrt((n-1)/n * sum (x_i - mean)^2)``, which the report sets beside the covariance's.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from calibration.handeye_model import _Problem
from controller.geometry.poses import Pose

F64 = NDArray[np.float64]

#: Bounds of the estimated noise: corners (px per axis), robot (mm, rad per axis).
SIGMA_PX_RANGE = (0.005, 20.0)
SIGMA_MM_RANGE = (0.002, 50.0)
SIGMA_RAD_RANGE = (np.radians(0.0002), np.radians(5.0))


def _chi2_median_over_k(k: F64) -> F64:
    """Median of chi-square(k) / k (Wilson-Hilferty), for k > 0."""
    k = np.maximum(k, 0.5)
    return np.asarray((1.0 - 2.0 / (9.0 * k)) ** 3)


def row_groups(prob: _Problem) -> tuple[F64, F64]:
    """(group, view) of every residual row: group 0 corners, 1 robot rotation, 2 translation."""
    n = prob.n_views
    group = np.concatenate([np.zeros(2 * len(prob.view)), np.ones(3 * n), np.full(3 * n, 2)])
    view = np.concatenate([np.repeat(prob.view, 2), np.repeat(np.arange(n), 3),
                           np.repeat(np.arange(n), 3)])
    return group, view


def hat_diagonal(J: F64, N_inv: F64) -> F64:
    """diag(J N^-1 J^T) row by row, without forming the square matrix."""
    return np.asarray(np.einsum("ij,ij->i", J @ N_inv, J))


def estimate_noise(prob: _Problem, r: F64, J: F64, N_inv: F64, estimate_robot: bool
                   ) -> tuple[float, float, float, dict[str, Any]]:
    """Updated (sigma_px, sigma_mm, sigma_rad) from a solution of ``prob`` (module docstring).

    ``r`` and ``J`` are the whitened residuals and Jacobian there, ``N_inv`` = (J^T J)^-1. The
    robot's sigmas stay as they are unless ``estimate_robot``. Returns the three (px per image
    axis, mm and rad per axis) and the per-group variance factors.
    """
    group, view = row_groups(prob)
    red = 1.0 - hat_diagonal(J, N_inv)
    sig = [prob.sigma_px, prob.sigma_rad, prob.sigma_mm]
    factors = {}
    for g, name in ((0, "corners"), (1, "robot_rotation"), (2, "robot_translation")):
        if g > 0 and not estimate_robot:
            continue
        m = group == g
        ss = np.bincount(view[m].astype(int), r[m] ** 2, prob.n_views)
        rd = np.bincount(view[m].astype(int), red[m], prob.n_views)
        ok = rd > 0.05
        if not np.any(ok):
            continue
        q = ss[ok] / rd[ok]
        f = float(np.median(q) / np.median(_chi2_median_over_k(np.asarray(rd[ok], float))))
        factors[name] = f
        sig[g] = sig[g] * float(np.sqrt(max(f, 1e-6)))
    sigma_px = float(np.clip(sig[0], *SIGMA_PX_RANGE))
    sigma_rad = float(np.clip(sig[1], *SIGMA_RAD_RANGE))
    sigma_mm = float(np.clip(sig[2], *SIGMA_MM_RANGE))
    return sigma_px, sigma_mm, sigma_rad, factors


def hand_eye_std(N_inv: F64, X: Pose) -> tuple[F64, F64]:
    """One sigma of X (translation mm, rotation deg) along the camera's axes.

    ``N_inv`` = (J^T J)^-1 of the whitened problem: X's rotation is its first 3 parameters,
    applied on the right; its translation the next 3, in the flange (or base) frame.
    """
    R = X[:3, :3]
    ct = R.T @ N_inv[3:6, 3:6] @ R
    std_mm = np.sqrt(np.clip(np.diag(ct), 0.0, None))
    std_deg = np.degrees(np.sqrt(np.clip(np.diag(N_inv[0:3, 0:3]), 0.0, None)))
    return std_mm, std_deg


def leave_one_out(prob: _Problem, p: F64, r: F64, J: F64) -> dict[str, Any]:
    """Every view predicted by the solution without it (module docstring).

    Returns ``rms_px`` and ``rms_mm`` (n_views,), and the jackknife one-sigma of X along the
    camera axes (``jackknife_std_mm``, ``jackknife_std_deg``, each (3,)).
    """
    n, ng = prob.n_views, prob.n_global
    group, view = row_groups(prob)
    del group
    N = J.T @ J
    grad = J.T @ r
    X0, _, _, _ = prob.unpack(p)
    rms_px = np.zeros(n)
    rms_mm = np.zeros(n)
    dt = np.zeros((n, 3))
    dr = np.zeros((n, 3))
    for k in range(n):
        rows = view == k
        Jg = J[rows]
        cols = np.ones(p.size, bool)
        cols[ng + 6 * k: ng + 6 * k + 6] = False
        Nk = (N - Jg.T @ Jg)[np.ix_(cols, cols)]
        gk = (grad - Jg.T @ r[rows])[cols]
        q = p.copy()
        q[cols] -= np.linalg.lstsq(Nk, gk, rcond=None)[0]
        q[ng + 6 * k: ng + 6 * k + 6] = 0.0  # the recorded pose, uncorrected
        X, Y, intr, D = prob.unpack(q)
        err = prob.reprojection(X, Y, intr, D)[prob.view == k]
        # Depth of each corner in the camera, for the error in mm at the board.
        T = np.einsum("ij,jk,kl->il", np.linalg.inv(X), prob.motions(D)[k], Y)
        z = (prob.obj[prob.view == k] @ T[:3, 2]) + T[2, 3]
        e_px = np.sqrt(np.sum(err * err, axis=1))
        rms_px[k] = float(np.sqrt(np.mean(e_px ** 2)))
        rms_mm[k] = float(np.sqrt(np.mean((e_px * z / intr[0]) ** 2)))
        dt[k] = X0[:3, :3].T @ (X[:3, 3] - X0[:3, 3])
        dr[k] = Rotation.from_matrix(X0[:3, :3].T @ X[:3, :3]).as_rotvec()
    scale = (n - 1) / n
    jk_mm = np.sqrt(scale * np.sum((dt - dt.mean(axis=0)) ** 2, axis=0))
    jk_deg = np.degrees(np.sqrt(scale * np.sum((dr - dr.mean(axis=0)) ** 2, axis=0)))
    return {"rms_px": rms_px, "rms_mm": rms_mm, "jackknife_std_mm": jk_mm,
            "jackknife_std_deg": jk_deg}
