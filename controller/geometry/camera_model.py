"""Pinhole camera with OpenCV's plumb_bob distortion (k1, k2, p1, p2, k3).

Frames: ``cam`` is the OpenCV optical frame (x right, y down, z along the optical axis), in mm.
Pixels are (u, v) = (column, row) with the origin at the centre of the top-left pixel, as OpenCV.

Projection is written in numpy rather than calling ``cv2.projectPoints`` so that it is vectorised,
float64 throughout and differentiable by hand; undistortion is a Newton iteration on the same model
because ``cv2.undistortPoints`` stops after a fixed 5 iterations and leaves up to ~0.1 px of error
at the corners of a strongly distorted lens.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from controller.errors import CalibrationError
from controller.geometry.poses import invert, transform_points

F64 = NDArray[np.float64]


@dataclass(frozen=True)
class CameraModel:
    """Intrinsics of one camera: image size (px), camera matrix K (px), plumb_bob distortion."""

    width: int
    height: int
    K: F64
    dist: F64 = field(default_factory=lambda: np.zeros(5))
    name: str = "seam_cam"

    def __post_init__(self) -> None:
        K = np.asarray(self.K, dtype=np.float64)
        dist = np.zeros(5)
        d = np.asarray(self.dist, dtype=np.float64).ravel()
        if d.size > 5:
            raise CalibrationError(f"camera {self.name}: plumb_bob takes 5 distortion "
                                   f"coefficients, got {d.size}")
        dist[: d.size] = d
        object.__setattr__(self, "K", K)
        object.__setattr__(self, "dist", dist)
        if K.shape != (3, 3) or not np.all(np.isfinite(K)):
            raise CalibrationError(f"camera {self.name}: camera_matrix must be 3x3 finite")
        if K[0, 0] <= 0 or K[1, 1] <= 0:
            raise CalibrationError(f"camera {self.name}: focal lengths must be positive, "
                                   f"got fx={K[0, 0]}, fy={K[1, 1]}")
        if self.width <= 0 or self.height <= 0:
            raise CalibrationError(f"camera {self.name}: image size must be positive, "
                                   f"got {self.width}x{self.height}")

    @property
    def fx(self) -> float:
        """Focal length along u (px)."""
        return float(self.K[0, 0])

    @property
    def fy(self) -> float:
        """Focal length along v (px)."""
        return float(self.K[1, 1])

    @property
    def cx(self) -> float:
        """Principal point u (px)."""
        return float(self.K[0, 2])

    @property
    def cy(self) -> float:
        """Principal point v (px)."""
        return float(self.K[1, 2])

    def scaled(self, factor: float) -> CameraModel:
        """The same lens on an image resized by ``factor`` (pixel-centre convention kept)."""
        K = self.K.copy()
        K[0, 0] *= factor
        K[1, 1] *= factor
        K[0, 1] *= factor
        # Pixel centres: u' + 0.5 = factor * (u + 0.5).
        K[0, 2] = factor * (K[0, 2] + 0.5) - 0.5
        K[1, 2] = factor * (K[1, 2] + 0.5) - 0.5
        return CameraModel(round(self.width * factor), round(self.height * factor), K,
                           self.dist.copy(), self.name)

    # ------------------------------------------------------------------ normalised <-> pixels
    def distort_normalized(self, xy: ArrayLike) -> F64:
        """Apply plumb_bob distortion to (N, 2) normalised image coordinates (x/z, y/z)."""
        k1, k2, p1, p2, k3 = self.dist
        p = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        x, y = p[:, 0], p[:, 1]
        r2 = x * x + y * y
        radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
        xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
        yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
        return np.stack([xd, yd], axis=1)

    def normalized_to_pixels(self, xy: ArrayLike) -> F64:
        """(N, 2) normalised undistorted coordinates to (N, 2) pixels, distortion applied."""
        d = self.distort_normalized(xy)
        K = self.K
        u = K[0, 0] * d[:, 0] + K[0, 1] * d[:, 1] + K[0, 2]
        v = K[1, 1] * d[:, 1] + K[1, 2]
        return np.stack([u, v], axis=1)

    def pixels_to_normalized(self, uv: ArrayLike, iterations: int = 20) -> F64:
        """(N, 2) pixels to normalised undistorted coordinates by Newton iteration.

        Converges to ~1e-12 for any lens whose distortion is monotonic over the image, which a
        valid calibration is; points where it does not converge come back as NaN.
        """
        K = self.K
        p = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
        yd = (p[:, 1] - K[1, 2]) / K[1, 1]
        xd = (p[:, 0] - K[0, 2] - K[0, 1] * yd) / K[0, 0]
        target = np.stack([xd, yd], axis=1)
        if not np.any(self.dist):
            return target
        k1, k2, p1, p2, k3 = self.dist
        est = target.copy()
        for _ in range(iterations):
            x, y = est[:, 0], est[:, 1]
            r2 = x * x + y * y
            radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
            dradial = k1 + r2 * (2 * k2 + 3 * k3 * r2)  # d radial / d r2
            res = self.distort_normalized(est) - target
            j11 = radial + 2 * x * x * dradial + 2 * p1 * y + 6 * p2 * x
            j12 = 2 * x * y * dradial + 2 * p1 * x + 2 * p2 * y
            j21 = 2 * x * y * dradial + 2 * p1 * x + 2 * p2 * y
            j22 = radial + 2 * y * y * dradial + 6 * p1 * y + 2 * p2 * x
            det = j11 * j22 - j12 * j21
            dx = (j22 * res[:, 0] - j12 * res[:, 1]) / det
            dy = (-j21 * res[:, 0] + j11 * res[:, 1]) / det
            est[:, 0] -= dx
            est[:, 1] -= dy
            if np.nanmax(np.abs(res)) < 1e-15:
                break
        bad = np.linalg.norm(self.distort_normalized(est) - target, axis=1) > 1e-9
        est[bad] = np.nan
        return est

    # ------------------------------------------------------------------ 3D <-> pixels
    def project_cam(self, points_cam: ArrayLike) -> F64:
        """Project (N, 3) points in the camera frame (mm) to (N, 2) pixels; NaN behind the lens."""
        P = np.asarray(points_cam, dtype=np.float64).reshape(-1, 3)
        z = P[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            xy = P[:, :2] / z[:, None]
        uv = self.normalized_to_pixels(xy)
        uv[z <= 1e-9] = np.nan
        return uv

    def project(self, points_base: ArrayLike, T_base_cam: ArrayLike) -> F64:
        """Project (N, 3) points in the base frame (mm) seen from ``T_base_cam`` to pixels."""
        return self.project_cam(transform_points(invert(T_base_cam), points_base))

    def pixel_rays_cam(self, uv: ArrayLike) -> F64:
        """Unit ray directions (N, 3) in the camera frame through the given pixels."""
        xy = self.pixels_to_normalized(uv)
        d = np.column_stack([xy, np.ones(len(xy))])
        return d / np.linalg.norm(d, axis=1, keepdims=True)

    def pixel_rays(self, uv: ArrayLike, T_base_cam: ArrayLike) -> tuple[F64, F64]:
        """Rays through pixels in the base frame: (origin (3,) mm, unit directions (N, 3))."""
        T = np.asarray(T_base_cam, dtype=np.float64)
        return T[:3, 3].copy(), self.pixel_rays_cam(uv) @ T[:3, :3].T

    def in_image(self, uv: ArrayLike, margin_px: float = 0.0) -> NDArray[np.bool_]:
        """Mask of pixels inside the image, at least ``margin_px`` from its border."""
        p = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
        return ((p[:, 0] >= -0.5 + margin_px) & (p[:, 0] <= self.width - 0.5 - margin_px)
                & (p[:, 1] >= -0.5 + margin_px) & (p[:, 1] <= self.height - 0.5 - margin_px))


def default_camera(width: int = 2272, height: int = 1704) -> CameraModel:
    """A plausible seam camera: the published 2272x1704 sensor with a ~16 mm lens.

    Used by the simulator and the dry run when no calibration is given; mild barrel distortion so
    that distortion handling is always exercised.
    """
    f = 1.25 * width  # 44 deg horizontal field: about 280 mm wide at 350 mm
    K = np.array([[f, 0.0, (width - 1) / 2 + 3.2], [0.0, f, (height - 1) / 2 - 2.1], [0, 0, 1]])
    return CameraModel(width, height, K, np.array([-0.08, 0.05, 0.0004, -0.0003, 0.0]))
