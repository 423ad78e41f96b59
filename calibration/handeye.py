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

from collections.abc import Sequence
from dataclasses import dataclass, field
from itertools import combinations
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation
from threadpoolctl import threadpool_limits

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

#: Fewest views for a hand-eye calibration (3 give two motions; more average the noise).
MIN_VIEWS = 5
#: A robot "did not move" when every pose is within these of the first.
STILL_MM, STILL_DEG = 1.0, 0.2
#: The largest rotation between any two views must reach this (degrees).
MIN_ROTATION_DEG = 5.0
#: Two relative rotation axes count as different when at least this far apart (degrees).
MIN_AXIS_SPREAD_DEG = 10.0


@dataclass
class Observation:
    """Board corners seen in one view: (N, 2) px and the matching (N, 3) mm in the board frame."""

    image_points: F64
    object_points: F64


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
            out["hand_eye_std_mm_cam_xyz"] = [round(float(v), 4) for v in self.std_mm]
            out["hand_eye_std_deg_cam_xyz"] = [round(float(v), 5) for v in self.std_deg]
        if self.eye_to_hand:
            out["T_base_cam"] = pose_to_dict(self.X)
            out["T_flange_board"] = pose_to_dict(self.Y)
        else:
            out["T_flange_cam"] = pose_to_dict(self.X)
            out["T_base_board"] = pose_to_dict(self.Y)
        return out


# ---------------------------------------------------------------------------------------------
# The OpenCV boundary
# ---------------------------------------------------------------------------------------------
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


# ---------------------------------------------------------------------------------------------
# Checks
# ---------------------------------------------------------------------------------------------
def check_motions(T_base_flange: Sequence[Pose], names: Sequence[str], *,
                  min_views: int = MIN_VIEWS, min_rotation_deg: float = MIN_ROTATION_DEG,
                  min_axis_spread_deg: float = MIN_AXIS_SPREAD_DEG) -> dict[str, float]:
    """Refuse robot poses from which AX = XB cannot be solved; return the motion statistics.

    Raises :class:`CalibrationError` naming the views when there are fewer than ``min_views``,
    when the robot did not move (all within :data:`STILL_MM` / :data:`STILL_DEG` of the first),
    when no two views differ by ``min_rotation_deg`` of rotation, or when all rotations between
    views are about one axis (closer than ``min_axis_spread_deg``).
    """
    n = len(T_base_flange)
    listed = ", ".join(names)
    if n < min_views:
        raise CalibrationError(f"hand-eye needs at least {min_views} good views, got {n} "
                               f"({listed or 'none'}); take more views", views=list(names))
    d = [pose_error(T_base_flange[0], T) for T in T_base_flange]
    if max(x[0] for x in d) < STILL_MM and max(x[1] for x in d) < STILL_DEG:
        raise CalibrationError(
            f"the robot did not move: views {listed} were all taken within {STILL_MM} mm / "
            f"{STILL_DEG} deg of each other; jog the robot to a different pose for every view",
            views=list(names))
    rel = []
    for i, j in combinations(range(n), 2):
        Ri = np.asarray(T_base_flange[i])[:3, :3]
        Rj = np.asarray(T_base_flange[j])[:3, :3]
        rv = Rotation.from_matrix(Ri.T @ Rj).as_rotvec()
        rel.append((float(np.degrees(np.linalg.norm(rv))), rv, i, j))
    max_rot = max(r[0] for r in rel)
    if max_rot < min_rotation_deg:
        raise CalibrationError(
            f"too little rotation between views {listed}: they differ by at most {max_rot:.2f} "
            f"deg (need {min_rotation_deg} deg, better 20-40 deg); hand-eye is degenerate for "
            f"pure translations: tilt the camera about two different axes between views",
            views=list(names), max_rotation_deg=max_rot)
    axes = [r[1] / np.linalg.norm(r[1]) for r in rel if r[0] >= min_rotation_deg]
    spread = 0.0
    a0 = axes[0]
    for a in axes[1:]:
        ang = float(np.degrees(np.arccos(min(1.0, abs(float(a0 @ a))))))
        spread = max(spread, ang)
    if spread < min_axis_spread_deg:
        raise CalibrationError(
            f"views {listed} rotate only about one axis (axes within {spread:.1f} deg): hand-eye "
            f"is degenerate; tilt the camera about a second, different axis too",
            views=list(names), axis_spread_deg=spread)
    return {"max_rotation_deg": max_rot, "axis_spread_deg": spread}


# ---------------------------------------------------------------------------------------------
# Model
# ---------------------------------------------------------------------------------------------
def _exp(v: F64) -> F64:
    return np.asarray(Rotation.from_rotvec(v).as_matrix())


def _project(P: F64, intr: F64) -> F64:
    """Project (N, 3) camera-frame points with intrinsics (fx, fy, cx, cy, k1, k2, p1, p2, k3)."""
    fx, fy, cx, cy, k1, k2, p1, p2, k3 = intr
    x = P[:, 0] / P[:, 2]
    y = P[:, 1] / P[:, 2]
    r2 = x * x + y * y
    radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    return np.stack([fx * xd + cx, fy * yd + cy], axis=1)


def _intr_vector(camera: CameraModel) -> F64:
    return np.array([camera.fx, camera.fy, camera.cx, camera.cy, *camera.dist])


def _camera_from(camera: CameraModel, intr: F64) -> CameraModel:
    K = np.array([[intr[0], 0.0, intr[2]], [0.0, intr[1], intr[3]], [0.0, 0.0, 1.0]])
    return CameraModel(camera.width, camera.height, K, intr[4:9].copy(), camera.name)


class _Problem:
    """The joint refinement: corners of the views in use, robot pose corrections with a prior.

    Parameters: X and Y (each a rotation vector applied on the right and a translation, 6), the
    intrinsics when refined (9), and per view a correction ``D_i`` of the recorded flange pose
    (``A_i D_i``, 6, in the flange frame). Residuals: every corner's reprojection error over
    ``sigma_px``, and every correction over the robot's pose noise (``sigma_mm``, ``sigma_rad``).
    This is the maximum-likelihood estimate when both the corners and the robot poses are noisy;
    reprojection error alone, with the robot poses taken as exact, was 5-10x less accurate in
    simulation whenever the robot's pose noise dominates (0.05 mm at 400 mm is 0.1-0.4 px).
    """

    def __init__(self, A: list[F64], obs: list[Observation], X0: Pose, Y0: Pose, intr0: F64,
                 refine_intrinsics: bool, eye_to_hand: bool, sigma_px: float, sigma_mm: float,
                 sigma_rad: float) -> None:
        self.A = np.stack(A)
        self.obj = np.concatenate([o.object_points for o in obs])
        self.img = np.concatenate([o.image_points for o in obs])
        self.view = np.concatenate([np.full(len(o.image_points), k) for k, o in enumerate(obs)])
        self.X0, self.Y0, self.intr0 = X0, Y0, intr0
        self.refine_intrinsics = refine_intrinsics
        self.eye_to_hand = eye_to_hand
        self.n_views = len(obs)
        self.n_global = 21 if refine_intrinsics else 12
        self.sigma_px, self.sigma_mm, self.sigma_rad = sigma_px, sigma_mm, sigma_rad

    def unpack(self, p: F64) -> tuple[Pose, Pose, F64, F64]:
        X = make_pose(self.X0[:3, :3] @ _exp(p[0:3]), self.X0[:3, 3] + p[3:6])
        Y = make_pose(self.Y0[:3, :3] @ _exp(p[6:9]), self.Y0[:3, 3] + p[9:12])
        intr = self.intr0 + p[12:21] if self.refine_intrinsics else self.intr0
        D = p[self.n_global:].reshape(self.n_views, 6)
        return X, Y, intr, D

    def x0(self) -> F64:
        return np.zeros(self.n_global + 6 * self.n_views)

    def motions(self, D: F64) -> F64:
        """(n_views, 4, 4) M_i of the corrected flange poses A_i D_i."""
        Rd = Rotation.from_rotvec(D[:, :3]).as_matrix()
        A = self.A.copy()
        A[:, :3, 3] += np.einsum("nij,nj->ni", self.A[:, :3, :3], D[:, 3:])
        A[:, :3, :3] = np.einsum("nij,njk->nik", self.A[:, :3, :3], Rd)
        if self.eye_to_hand:
            return A
        Ainv = np.zeros_like(A)
        Rt = np.transpose(A[:, :3, :3], (0, 2, 1))
        Ainv[:, :3, :3] = Rt
        Ainv[:, :3, 3] = -np.einsum("nij,nj->ni", Rt, A[:, :3, 3])
        Ainv[:, 3, 3] = 1.0
        return Ainv

    def reprojection(self, X: Pose, Y: Pose, intr: F64, D: F64) -> F64:
        """(N, 2) reprojection errors in px."""
        T = np.einsum("ij,njk,kl->nil", invert(X), self.motions(D), Y)[self.view]
        P = np.einsum("nij,nj->ni", T[:, :3, :3], self.obj) + T[:, :3, 3]
        return _project(P, intr) - self.img

    def residuals(self, p: F64) -> F64:
        X, Y, intr, D = self.unpack(p)
        r = self.reprojection(X, Y, intr, D).ravel() / self.sigma_px
        prior = np.concatenate([D[:, :3].ravel() / self.sigma_rad,
                                D[:, 3:].ravel() / self.sigma_mm])
        return np.concatenate([r, prior])

    def jac(self, p: F64) -> F64:
        """Dense Jacobian by grouped forward differences.

        Each view's correction moves only that view's residuals, so one evaluation perturbs the
        same component of every view's correction at once (n_global + 6 evaluations in all).
        """
        f0 = self.residuals(p)
        n_par = p.size
        J = np.zeros((f0.size, n_par))
        steps = np.full(n_par, 1e-7)
        steps[3:6] = steps[9:12] = 1e-6  # translations (mm)
        if self.refine_intrinsics:
            steps[12:16] = 1e-5  # fx fy cx cy (px)
        steps[self.n_global:] = 1e-7
        for c in range(self.n_global):
            q = p.copy()
            q[c] += steps[c]
            J[:, c] = (self.residuals(q) - f0) / steps[c]
        per_view_3 = np.repeat(np.arange(self.n_views), 3)
        row_view = np.concatenate([np.repeat(self.view, 2), per_view_3, per_view_3])
        for c in range(6):
            q = p.copy()
            cols = self.n_global + 6 * np.arange(self.n_views) + c
            q[cols] += steps[cols]
            diff = (self.residuals(q) - f0) / steps[cols][0]
            J[np.arange(f0.size), self.n_global + 6 * row_view + c] = diff
        return J

    def sparsity(self) -> Any:
        from scipy.sparse import lil_matrix

        n_px = 2 * len(self.view)
        J = lil_matrix((n_px + 6 * self.n_views, self.n_global + 6 * self.n_views), dtype=int)
        J[:n_px, : self.n_global] = 1
        rows = np.repeat(np.arange(n_px), 6)
        cols = self.n_global + 6 * np.repeat(self.view, 2).repeat(6) + np.tile(np.arange(6), n_px)
        J[rows, cols] = 1
        for k in range(self.n_views):
            for c in range(3):
                J[n_px + 3 * k + c, self.n_global + 6 * k + c] = 1
                J[n_px + 3 * self.n_views + 3 * k + c, self.n_global + 6 * k + 3 + c] = 1
        return J

    def per_view_rms(self, err: F64) -> F64:
        sq = np.sum(err * err, axis=1)
        return np.asarray(np.sqrt(np.bincount(self.view, sq, self.n_views)
                                  / np.bincount(self.view, minlength=self.n_views)))


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


def solve_hand_eye(T_base_flange_list: Sequence[Pose],
                   observations: Sequence[Observation] | Sequence[Pose],
                   camera: CameraModel | None = None, *, names: Sequence[str] | None = None,
                   eye_to_hand: bool = False, method: str = "park", refine: bool = True,
                   refine_intrinsics: bool = False, robot_sigma_mm: float = 0.05,
                   robot_sigma_deg: float = 0.01, loss: str = "soft_l1",
                   reject_factor: float = 4.0, reject_min_px: float = 1.0,
                   reject_min_sigma: float = 6.0, max_rms_px: float = 3.0,
                   max_consistency_mm: float = 0.5, max_consistency_deg: float = 0.1,
                   max_rejected_fraction: float = 0.34, min_views: int = MIN_VIEWS,
                   min_rotation_deg: float = MIN_ROTATION_DEG) -> HandEyeResult:
    """Solve hand-eye from flange poses and board observations (see the module docstring).

    ``T_base_flange_list``: recorded flange poses (mm). ``observations``: per view either an
    :class:`Observation` (corners; needs ``camera``) or a 4x4 ``T_cam_board`` (board pose only;
    then residuals are distances in mm of points on a 200 mm square on the board, and intrinsics
    cannot be refined). ``robot_sigma_mm`` / ``_deg``: the robot's pose noise (per axis), the
    prior of the per-view pose corrections. A view is bad when its pose correction exceeds
    ``max(reject_factor * median, reject_min_sigma)`` sigmas, or its reprojection RMS (with its
    correction) exceeds ``max(reject_factor * median, reject_min_px)``.

    ``residual_px`` is the reprojection RMS of the views kept *with their recorded poses* (what
    the calibration will see in use); ``consistency_mm`` / ``_deg`` the RMS of the pose corrections
    (how well robot poses and images agree).

    Raises :class:`CalibrationError` naming the views for degenerate input (too few views, robot
    still, too little rotation), for too many bad views, and for a result above ``max_rms_px``,
    ``max_consistency_mm`` or ``max_consistency_deg``.
    """
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
                                reject_min_mm=reject_min_px, max_rms_mm=max_rms_px,
                                max_rejected_fraction=max_rejected_fraction, min_views=min_views)
    if camera is None:
        raise CalibrationError("solve_hand_eye: corner observations need the camera intrinsics")
    obs = [o for o in observations if isinstance(o, Observation)]
    pnp = [_pnp(camera, o, nm[i]) for i, o in enumerate(obs)]
    T_cb = [p[0] for p in pnp]
    closed, motions, X, Y = _closed_forms(A, T_cb, eye_to_hand, method,
                                          f"; the views {', '.join(nm)} may be degenerate")
    intr = _intr_vector(camera)
    # Corner noise: the pooled PnP residual (PnP fits 6 of 2N numbers per view).
    sigma_px = max(0.02, float(np.sqrt(np.mean([p[1] ** 2 for p in pnp]))))
    sigma_rad = np.radians(robot_sigma_deg)
    used = list(range(n))
    rejected: list[dict[str, Any]] = []
    corr_mm = np.zeros(n)
    corr_deg = np.zeros(n)
    corr_sigma = np.zeros(n)
    fit_rms = np.zeros(n)
    while True:
        prob = _Problem([A[i] for i in used], [obs[i] for i in used], X, Y, intr,
                        refine_intrinsics and refine, eye_to_hand, sigma_px, robot_sigma_mm,
                        sigma_rad)
        p = prob.x0()
        if refine:
            # One BLAS thread: the SVDs here are ~2000 x 150; threads only add contention (a
            # 2-core machine shared with other jobs ran this 10x slower with the default).
            with threadpool_limits(limits=1, user_api="blas"):
                sol = least_squares(prob.residuals, p, jac=prob.jac, loss=loss, f_scale=3.0,
                                    method="trf", x_scale="jac", tr_solver="exact",
                                    max_nfev=100)
            p = sol.x
        X, Y, intr_new, D = prob.unpack(p)
        intr = intr_new
        fit = prob.per_view_rms(prob.reprojection(X, Y, intr, D))
        for k, i in enumerate(used):
            corr_deg[i] = float(np.degrees(np.linalg.norm(D[k, :3])))
            corr_mm[i] = float(np.linalg.norm(D[k, 3:]))
            corr_sigma[i] = float(np.sqrt(np.sum((D[k, :3] / sigma_rad) ** 2)
                                          + np.sum((D[k, 3:] / robot_sigma_mm) ** 2)))
            fit_rms[i] = fit[k]
        lim_s = max(reject_factor * float(np.median(corr_sigma[used])), reject_min_sigma)
        lim_px = max(reject_factor * float(np.median(fit_rms[used])), reject_min_px)
        score = np.maximum(corr_sigma / lim_s, fit_rms / lim_px)
        worst = max(used, key=lambda i: score[i])
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
        used.remove(worst)
        if len(used) < min_views or len(rejected) > max_rejected_fraction * n:
            listed = ", ".join(r["view"] for r in rejected)
            raise CalibrationError(
                f"hand-eye refused: too many bad views ({listed}); {len(used)} of {n} views are "
                f"left. Retake the views named, holding the robot still, with the whole board in "
                f"the image", rejected_views=rejected)
        check_motions([A[i] for i in used], [nm[i] for i in used], min_views=min_views,
                      min_rotation_deg=min_rotation_deg)
    std_mm = std_deg = None
    if refine:
        std_mm, std_deg = _hand_eye_std(prob, p, X)
    cam_out = _camera_from(camera, intr) if refine_intrinsics and refine else camera
    # Residuals with the recorded (uncorrected) poses, every view.
    full = _Problem(A, obs, X, Y, intr, False, eye_to_hand, sigma_px, robot_sigma_mm, sigma_rad)
    per_view = full.per_view_rms(full.reprojection(X, Y, intr, np.zeros((n, 6))))
    resid = float(np.sqrt(np.mean(per_view[used] ** 2)))
    c_mm = float(np.sqrt(np.mean(corr_mm[used] ** 2)))
    c_deg = float(np.sqrt(np.mean(corr_deg[used] ** 2)))
    if resid > max_rms_px or c_mm > max_consistency_mm or c_deg > max_consistency_deg:
        worst_views = sorted(used, key=lambda i: -per_view[i])[:3]
        listed = ", ".join(f"{nm[i]} ({per_view[i]:.2f} px, {corr_mm[i]:.2f} mm, "
                           f"{corr_deg[i]:.3f} deg)" for i in worst_views)
        raise CalibrationError(
            f"hand-eye refused: reprojection RMS {resid:.2f} px (limit {max_rms_px}), pose "
            f"consistency {c_mm:.3f} mm / {c_deg:.4f} deg (limits {max_consistency_mm} mm / "
            f"{max_consistency_deg} deg); worst views: {listed}. Check the board spec, the robot's "
            f"tool0 setting, and retake those views", residual_px=resid, consistency_mm=c_mm,
            consistency_deg=c_deg)
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
                                  for i in used}, std_mm=std_mm, std_deg=std_deg)


def _hand_eye_std(prob: _Problem, p: F64, X: Pose) -> tuple[F64, F64]:
    """One sigma of X (translation mm, rotation deg) along the camera axes from the Jacobian.

    The covariance is ``(J^T J)^-1`` of the whitened residuals (a Cramer-Rao-like bound: what
    the corner noise and the robot's pose noise leave of the hand-eye with these views). The
    corner sigma of the problem is a 2D RMS; per image axis it is that over sqrt(2).
    """
    J = prob.jac(p)
    J[: 2 * len(prob.view)] *= np.sqrt(2.0)
    cov = np.linalg.pinv(J.T @ J)
    R = X[:3, :3]
    ct = R.T @ cov[3:6, 3:6] @ R  # translation is added in the flange frame
    std_mm = np.sqrt(np.clip(np.diag(ct), 0.0, None))
    std_deg = np.degrees(np.sqrt(np.clip(np.diag(cov[0:3, 0:3]), 0.0, None)))  # right-applied
    return std_mm, std_deg


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


def view_residuals(result: HandEyeResult, T_base_flange: Pose, observation: Observation) -> F64:
    """Reprojection errors (N, 2) px of one view (e.g. held out) under a solved calibration."""
    if result.camera is None:
        raise CalibrationError("view_residuals needs a corner-based hand-eye result")
    A = np.asarray(T_base_flange, float)
    M = A if result.eye_to_hand else invert(A)
    T = invert(result.X) @ M @ result.Y
    P = (T[:3, :3] @ observation.object_points.T).T + T[:3, 3]
    return _project(P, _intr_vector(result.camera)) - observation.image_points


# ---------------------------------------------------------------------------------------------
# Pose streams (a tracker or camera pipeline that gives board poses at its own rate)
# ---------------------------------------------------------------------------------------------
def _angular_speed(slerp: Any, t: F64, h: float) -> F64:
    return np.asarray((slerp(t + h) * slerp(t - h).inv()).magnitude() / (2 * h))


def pair_pose_streams(t_robot_s: F64, T_base_flange: Sequence[Pose], t_cam_s: F64,
                      T_cam_board: Sequence[Pose], n: int = 40, *,
                      max_offset_s: float = 1.0) -> tuple[list[Pose], list[Pose], float, float]:
    """Pair a robot pose stream with a board pose stream sampled at other instants.

    The unknown time offset is found by correlating the angular speeds of the two streams (the
    same rigid motion seen from two frames has the same angular speed): ``t_cam = t_robot +
    offset``, searched within +-``max_offset_s`` at 1 ms. Then ``n`` board samples are taken, the
    stillest of each of ``n`` equal time bins (least harm from a residual offset), with the robot
    pose interpolated at their instants (linear position, slerp rotation).

    Returns (T_base_flange list, T_cam_board list, offset_s, correlation). Raises
    :class:`CalibrationError` when the streams do not overlap or do not correlate (< 0.5).
    """
    from scipy.spatial.transform import Slerp

    tr = np.asarray(t_robot_s, float)
    tc = np.asarray(t_cam_s, float)
    Rr = Rotation.from_matrix(np.stack([np.asarray(T)[:3, :3] for T in T_base_flange]))
    Rc = Rotation.from_matrix(np.stack([np.asarray(T)[:3, :3] for T in T_cam_board]))
    pr = np.stack([np.asarray(T)[:3, 3] for T in T_base_flange])
    sr, sc = Slerp(tr, Rr), Slerp(tc, Rc)
    lo = max(tr[0], tc[0]) + max_offset_s + 0.5
    hi = min(tr[-1], tc[-1]) - max_offset_s - 0.5
    if hi - lo < 2.0:
        raise CalibrationError("the robot and board pose streams overlap by less than 2 s")
    grid = np.arange(lo, hi, 0.01)
    ref = _angular_speed(sr, grid, 0.2)
    # The board stream's speed once on a 1 ms grid; each offset is then an interpolation.
    fine = np.arange(lo - max_offset_s, hi + max_offset_s, 0.001)
    fine_speed = _angular_speed(sc, fine, 0.2)
    best = (-1.0, 0.0)
    for off in np.arange(-max_offset_s, max_offset_s, 0.001):
        c = float(np.corrcoef(ref, np.interp(grid + off, fine, fine_speed))[0, 1])
        if c > best[0]:
            best = (c, float(off))
    corr, off = best
    if not corr >= 0.5:
        raise CalibrationError(f"the pose streams' angular speeds do not correlate (best "
                               f"{corr:.2f}): are they of the same motion?")
    idx = np.arange(1, len(tc) - 1)
    idx = idx[(tc[idx] - off > tr[0]) & (tc[idx] - off < tr[-1])]
    bins = np.linspace(tc[idx[0]], tc[idx[-1]], n + 1)
    A: list[Pose] = []
    B: list[Pose] = []
    for k in range(n):
        inb = idx[(tc[idx] >= bins[k]) & (tc[idx] < bins[k + 1])]
        if not len(inb):
            continue
        i = int(inb[np.argmin(_angular_speed(sc, tc[inb], 0.05))])
        t = tc[i] - off
        A.append(make_pose(sr([t]).as_matrix()[0], [np.interp(t, tr, pr[:, j]) for j in range(3)]))
        B.append(np.asarray(T_cam_board[i], float))
    return A, B, off, corr
