"""Camera intrinsics from board corners: outlier views, RMS, image coverage, uncertainties.

:func:`solve_intrinsics` wraps ``cv2.calibrateCameraExtended`` (pinhole + plumb_bob, 5
coefficients) and adds what an operator needs to trust the result:

- **Outlier views**: a view whose RMS is over ``max(reject_factor * median, reject_min_px)`` is
  left out and the calibration is solved again, worst first, until none is left or only
  ``min_views`` remain; each rejected view is named with its RMS.
- **RMS**: overall and per view, in px.
- **Coverage**: the image is cut into a grid (default 4 x 4); the report counts corners per cell
  over the accepted views and names the cells that still need views ("top-left", ...).
- **Uncertainty**: one standard deviation of each parameter, from the Jacobian at the solution
  (``calibrateCameraExtended``'s ``stdDeviationsIntrinsics``, i.e. sqrt(diag((J^T J)^-1)) times
  the residual variance; OpenCV docs of calibrateCamera).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from controller.errors import CalibrationError
from controller.geometry.camera_model import CameraModel
from controller.geometry.poses import Pose, pose_from_rvec_tvec

F64 = NDArray[np.float64]

PARAM_NAMES = ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3")

#: Fewest views accepted for an intrinsic calibration.
MIN_VIEWS = 4
#: Corners a coverage cell needs before it counts as covered.
COVERAGE_MIN_CORNERS = 3


@dataclass
class Coverage:
    """Corner counts per cell of a ``rows x cols`` grid over the image, and the empty cells."""

    counts: NDArray[np.int64]
    missing: list[str]

    @property
    def fraction(self) -> float:
        """Fraction of cells holding at least :data:`COVERAGE_MIN_CORNERS` corners."""
        return float(np.mean(self.counts >= COVERAGE_MIN_CORNERS))

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready form."""
        return {"grid_counts": self.counts.tolist(), "fraction_covered": round(self.fraction, 3),
                "needs_views_in": self.missing}


def _cell_name(r: int, c: int, rows: int, cols: int) -> str:
    def part(i: int, n: int, words: tuple[str, str, str]) -> str:
        if n == 1:
            return ""
        f = i / (n - 1)
        return words[0] if f < 0.34 else words[2] if f > 0.66 else words[1]

    v = part(r, rows, ("top", "middle", "bottom"))
    h = part(c, cols, ("left", "centre", "right"))
    return f"{v}-{h} (row {r}, col {c})"


def image_coverage(image_points: Sequence[F64], image_size: tuple[int, int],
                   grid: tuple[int, int] = (4, 4)) -> Coverage:
    """Corner counts per cell over ``grid`` = (rows, cols) cells of a (width, height) image."""
    w, h = image_size
    rows, cols = grid
    counts = np.zeros((rows, cols), dtype=np.int64)
    for pts in image_points:
        p = np.asarray(pts, float).reshape(-1, 2)
        c = np.clip((p[:, 0] / w * cols).astype(int), 0, cols - 1)
        r = np.clip((p[:, 1] / h * rows).astype(int), 0, rows - 1)
        np.add.at(counts, (r, c), 1)
    missing = [_cell_name(r, c, rows, cols) for r in range(rows) for c in range(cols)
               if counts[r, c] < COVERAGE_MIN_CORNERS]
    return Coverage(counts, missing)


@dataclass
class IntrinsicsResult:
    """An intrinsic calibration and its report.

    ``per_view_rms_px`` holds one value per input view (rejected views too, from the last solve
    that included them); ``T_cam_board`` holds the board pose per input view (None if rejected).
    ``std`` maps each of :data:`PARAM_NAMES` to one standard deviation (px or unitless).
    """

    camera: CameraModel
    rms_px: float
    per_view_rms_px: list[float]
    rejected_views: list[dict[str, Any]]
    used_views: list[int]
    coverage: Coverage
    std: dict[str, float]
    T_cam_board: list[Pose | None] = field(default_factory=list)
    names: list[str] = field(default_factory=list)

    def report(self) -> dict[str, Any]:
        """JSON-ready summary: camera, RMS, per-view RMS, rejections, coverage, uncertainties."""
        cam = self.camera
        return {
            "image_size": [cam.width, cam.height],
            "fx": cam.fx, "fy": cam.fy, "cx": cam.cx, "cy": cam.cy,
            "distortion": [float(v) for v in cam.dist],
            "std": {k: float(v) for k, v in self.std.items()},
            "rms_px": float(self.rms_px),
            "per_view_rms_px": {self.names[i]: round(float(v), 4)
                                for i, v in enumerate(self.per_view_rms_px)},
            "views_used": [self.names[i] for i in self.used_views],
            "rejected_views": self.rejected_views,
            "coverage": self.coverage.as_dict(),
        }


def _calibrate(obj: list[F64], img: list[F64], size: tuple[int, int], flags: int,
               K0: F64 | None) -> tuple[float, F64, F64, list[F64], list[F64], F64, F64]:
    objp = [np.asarray(o, np.float32).reshape(-1, 1, 3) for o in obj]
    imgp = [np.asarray(i, np.float32).reshape(-1, 1, 2) for i in img]
    K: Any = None if K0 is None else K0.copy()
    if K is not None:
        flags |= cv2.CALIB_USE_INTRINSIC_GUESS
    crit = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 100, 1e-12)
    try:
        rms, K, dist, rvecs, tvecs, std_in, _std_ex, per_view = cv2.calibrateCameraExtended(
            objp, imgp, size, K, None, flags=flags, criteria=crit)  # type: ignore[call-overload]
    except cv2.error as err:
        raise CalibrationError(f"intrinsic calibration failed in OpenCV: {err}; check that the "
                               f"board spec matches the printed board") from err
    return (float(rms), np.asarray(K, float), np.asarray(dist, float).ravel(),
            list(rvecs), list(tvecs), np.asarray(std_in, float).ravel(),
            np.asarray(per_view, float).ravel())


def solve_intrinsics(image_points: Sequence[F64], object_points: Sequence[F64],
                     image_size: tuple[int, int], *, names: Sequence[str] | None = None,
                     flags: int = 0, reject_factor: float = 3.0, reject_min_px: float = 1.0,
                     min_views: int = MIN_VIEWS, coverage_grid: tuple[int, int] = (4, 4),
                     camera_name: str = "seam_cam") -> IntrinsicsResult:
    """Calibrate a camera from board corners seen in several views.

    ``image_points[i]`` (N_i, 2) px match ``object_points[i]`` (N_i, 3) mm in the board frame;
    ``image_size`` = (width, height) px; ``names`` name the views in the report.

    ``flags`` are OpenCV ``CALIB_*`` flags (e.g. ``cv2.CALIB_FIX_K3``). Outlier views are
    rejected as described in the module docstring. Raises :class:`CalibrationError` when fewer
    than ``min_views`` views are given or remain, when a view has fewer than 6 points, or when
    OpenCV fails.
    """
    n = len(image_points)
    nm = list(names) if names is not None else [f"view{i + 1:02d}" for i in range(n)]
    if len(object_points) != n or len(nm) != n:
        raise CalibrationError(f"solve_intrinsics: {n} image point sets, {len(object_points)} "
                               f"object point sets and {len(nm)} names: they must match")
    if n < min_views:
        raise CalibrationError(
            f"intrinsic calibration needs at least {min_views} views with the board found, got "
            f"{n}{' (' + ', '.join(nm) + ')' if nm else ''}; take more views of the board, "
            f"tilted and spread over the image", views=nm)
    for i in range(n):
        if len(image_points[i]) < 6 or len(image_points[i]) != len(object_points[i]):
            raise CalibrationError(f"view {nm[i]}: {len(image_points[i])} image points for "
                                   f"{len(object_points[i])} object points; need >= 6, equal")
    w, h = int(image_size[0]), int(image_size[1])
    used = list(range(n))
    rejected: list[dict[str, Any]] = []
    per_view_all = np.full(n, np.nan)
    K0 = None
    while True:
        rms, K, dist, rvecs, tvecs, std_in, per_view = _calibrate(
            [object_points[i] for i in used], [image_points[i] for i in used], (w, h), flags, K0)
        per_view_all[used] = per_view
        med = float(np.median(per_view))
        limit = max(reject_factor * med, reject_min_px)
        worst = int(np.argmax(per_view))
        if per_view[worst] <= limit or len(used) <= min_views:
            break
        bad = used[worst]
        rejected.append({"view": nm[bad], "rms_px": round(float(per_view[worst]), 4),
                         "reason": f"reprojection RMS {per_view[worst]:.2f} px > limit "
                                   f"{limit:.2f} px (median {med:.2f} px)"})
        used.remove(bad)
        K0 = K
    dist5 = np.zeros(5)
    dist5[: min(5, dist.size)] = dist[:5]
    camera = CameraModel(w, h, K, dist5, camera_name)
    std = {name: float(std_in[i]) if i < std_in.size else float("nan")
           for i, name in enumerate(PARAM_NAMES)}
    T_cb: list[Pose | None] = [None] * n
    for k, i in enumerate(used):
        T_cb[i] = pose_from_rvec_tvec(rvecs[k], tvecs[k])
    coverage = image_coverage([image_points[i] for i in used], (w, h), coverage_grid)
    return IntrinsicsResult(camera, rms, [float(v) for v in per_view_all], rejected, used,
                            coverage, std, T_cb, nm)
