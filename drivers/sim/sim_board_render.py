"""Simulated calibration board images: the printed pattern cast through the camera, exactly.

:func:`render_board` draws a chessboard or ChArUco board through a
:class:`~controller.geometry.camera_model.CameraModel` (distortion included) by casting, for every
sub-sample of every pixel, the ray through it onto the board plane and evaluating the board's
printed pattern there exactly (squares, and the ArUco markers' cells); sub-samples are averaged
(anti-aliasing), then optional defocus blur, motion blur and sensor noise are applied.
:func:`true_corners` gives the exact corner pixels (``CameraModel.project_cam`` of the board's
corner points), so detection error is measured against an exact answer. Sessions of such views
are :mod:`drivers.sim.sim_board`.

What this does not model: lens vignetting and chromatic effects, rolling shutter, specular glare,
board non-flatness and printing scale errors, JPEG artefacts, the detector seeing other objects.
"""

from __future__ import annotations

import functools

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy.interpolate import RectBivariateSpline

from calibration.targets import BoardSpec
from controller.errors import CameraError, InputError
from controller.geometry.camera_model import CameraModel
from controller.geometry.poses import Pose, invert

F64 = NDArray[np.float64]

#: Reflectance of the printed black and white and of the table behind the board (0..1).
BLACK, WHITE, TABLE = 0.08, 0.88, 0.35


# ---------------------------------------------------------------------------------------------
# Board pattern
# ---------------------------------------------------------------------------------------------
@functools.cache
def _charuco_tables(board: BoardSpec) -> tuple[NDArray[np.int64], NDArray[np.uint8]]:
    """(rows, cols) marker index per square (-1 = none) and (n, cells, cells) marker bits."""
    cb = board.charuco_board
    dictionary = cb.getDictionary()
    cells = dictionary.markerSize + 2
    ids = np.asarray(cb.getIds()).ravel()
    corners = np.asarray(cb.getObjPoints(), dtype=np.float64)
    table = -np.ones((board.rows, board.cols), dtype=np.int64)
    bits = np.zeros((len(ids), cells, cells), dtype=np.uint8)
    for k, (mid, quad) in enumerate(zip(ids, corners, strict=True)):
        centre = quad[:, :2].mean(axis=0)
        col, row = int(centre[0] // board.square_mm), int(centre[1] // board.square_mm)
        table[row, col] = k
        img = cv2.aruco.generateImageMarker(dictionary, int(mid), cells, borderBits=1)
        bits[k] = (img > 127).astype(np.uint8)
    return table, bits


def board_reflectance(board: BoardSpec, x: F64, y: F64) -> F64:
    """Printed reflectance (0..1) at board-frame points (x, y) in mm; the table outside the board.

    Chessboard: the square diagonally inward of the first inner corner is black, a white margin of
    one square surrounds the checkered area. ChArUco: OpenCV's layout (first square black,
    markers in the white squares), a white margin of half a square.
    """
    s = board.square_mm
    out = np.full(x.shape, TABLE)
    if board.kind == "chessboard":
        a = np.floor(x / s).astype(np.int64) + 1
        b = np.floor(y / s).astype(np.int64) + 1
        on_paper = (x >= -2 * s) & (x < (board.cols + 1) * s) & (y >= -2 * s) & \
            (y < (board.rows + 1) * s)
        checkered = (a >= 0) & (a <= board.cols) & (b >= 0) & (b <= board.rows)
        out[on_paper] = WHITE
        black = checkered & ((a + b) % 2 == 0)
        out[black] = BLACK
        return out
    a = np.floor(x / s).astype(np.int64)
    b = np.floor(y / s).astype(np.int64)
    on_paper = (x >= -0.5 * s) & (x < (board.cols + 0.5) * s) & (y >= -0.5 * s) & \
        (y < (board.rows + 0.5) * s)
    checkered = (a >= 0) & (a < board.cols) & (b >= 0) & (b < board.rows)
    out[on_paper] = WHITE
    out[checkered & ((a + b) % 2 == 0)] = BLACK
    table, bits = _charuco_tables(board)
    idx = np.where(checkered, table[np.clip(b, 0, board.rows - 1), np.clip(a, 0, board.cols - 1)],
                   -1)
    has = idx >= 0
    if np.any(has):
        cells = bits.shape[1]
        m = board.marker_mm
        off = (s - m) / 2
        lx = (x[has] - a[has] * s - off) / m
        ly = (y[has] - b[has] * s - off) / m
        inside = (lx >= 0) & (lx < 1) & (ly >= 0) & (ly < 1)
        cx = np.clip((lx * cells).astype(np.int64), 0, cells - 1)
        cy = np.clip((ly * cells).astype(np.int64), 0, cells - 1)
        val = np.where(bits[idx[has], cy, cx] > 0, WHITE, BLACK)
        sub = out[has]
        sub[inside] = val[inside]
        out[has] = sub
    return out


# ---------------------------------------------------------------------------------------------
# Rendering
# ---------------------------------------------------------------------------------------------
@functools.lru_cache(maxsize=4)
def _ray_grid(width: int, height: int, K: tuple[float, ...], dist: tuple[float, ...],
              supersample: int) -> tuple[F64, F64]:
    """Normalised undistorted (x, y) for every sub-sample, each (H*s, W*s).

    The Newton undistortion runs on a grid every 8 px and a bicubic spline fills in: the lens map
    is smooth, and the spline's error is below 1e-9 (about 1e-6 px, checked in the tests).
    """
    cam = CameraModel(width, height, np.array(K).reshape(3, 3), np.array(dist))
    step = 8
    gu = np.arange(-step, width + 2 * step, step, dtype=np.float64)
    gv = np.arange(-step, height + 2 * step, step, dtype=np.float64)
    uu, vv = np.meshgrid(gu, gv)
    xy = cam.pixels_to_normalized(np.stack([uu.ravel(), vv.ravel()], axis=1))
    if np.any(~np.isfinite(xy)):
        raise CameraError("simulated camera: the lens distortion is not invertible over the image")
    sx = RectBivariateSpline(gv, gu, xy[:, 0].reshape(uu.shape), kx=3, ky=3)
    sy = RectBivariateSpline(gv, gu, xy[:, 1].reshape(uu.shape), kx=3, ky=3)
    u = (np.arange(width * supersample) + 0.5) / supersample - 0.5
    v = (np.arange(height * supersample) + 0.5) / supersample - 0.5
    return sx(v, u), sy(v, u)


def _linear_kernel(vector_px: tuple[float, float], supersample: int = 8) -> NDArray[np.float32]:
    """A normalised motion-blur kernel: a line of the given (du, dv) length in px."""
    du, dv = vector_px
    length = float(np.hypot(du, dv))
    half = int(np.ceil(length / 2)) + 1
    size = 2 * half + 1
    k = np.zeros((size * supersample, size * supersample), np.float32)
    n = max(2, int(length * supersample * 2))
    for t in np.linspace(-0.5, 0.5, n):
        x = (half + t * du + 0.5) * supersample
        y = (half + t * dv + 0.5) * supersample
        k[min(int(y), k.shape[0] - 1), min(int(x), k.shape[1] - 1)] += 1
    small = np.asarray(cv2.resize(k, (size, size), interpolation=cv2.INTER_AREA), np.float32)
    return small / small.sum()


def render_board(camera: CameraModel, board: BoardSpec, T_cam_board: Pose, *,
                 supersample: int = 2, noise_sigma: float = 1.5, blur_sigma_px: float = 0.0,
                 motion_blur_px: tuple[float, float] = (0.0, 0.0), seed: int = 0,
                 illumination: float = 1.0, gain_dark: float = 0.0) -> NDArray[np.uint8]:
    """A greyscale uint8 image (camera.height, camera.width) of the board at ``T_cam_board``.

    ``T_cam_board`` is the board frame in the camera's optical frame (mm). ``supersample`` s
    casts s x s rays per pixel and averages them; ``noise_sigma`` is Gaussian sensor noise in grey
    levels; ``blur_sigma_px`` a Gaussian defocus; ``motion_blur_px`` the (du, dv) streak of a
    moving camera. Deterministic for a given ``seed``. Raises :class:`InputError` for a
    supersample factor below 1.
    """
    if supersample < 1:
        raise InputError(f"supersample must be >= 1, got {supersample}")
    s = int(supersample)
    gx, gy = _ray_grid(camera.width, camera.height, tuple(camera.K.ravel()),
                       tuple(camera.dist.ravel()), s)
    T = invert(T_cam_board)  # T_board_cam
    R, o = T[:3, :3], T[:3, 3]
    H, W = gx.shape
    acc = np.empty((H, W), dtype=np.float32)
    chunk = 512
    for r0 in range(0, H, chunk):
        x = gx[r0:r0 + chunk]
        y = gy[r0:r0 + chunk]
        dz = R[2, 0] * x + R[2, 1] * y + R[2, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            lam = -o[2] / dz
        valid = np.isfinite(lam) & (lam > 0)
        lam = np.where(valid, lam, 0.0)
        bx = o[0] + lam * (R[0, 0] * x + R[0, 1] * y + R[0, 2])
        by = o[1] + lam * (R[1, 0] * x + R[1, 1] * y + R[1, 2])
        val = board_reflectance(board, bx, by)
        val[~valid] = TABLE
        acc[r0:r0 + chunk] = val
    img = acc.reshape(camera.height, s, camera.width, s).mean(axis=(1, 3))
    # Mild illumination gradient so that the detector's normalisation is exercised.
    vv, uu = np.mgrid[0:camera.height, 0:camera.width].astype(np.float32)
    shade = 1.0 - 0.15 * ((uu / camera.width - 0.3) ** 2 + (vv / camera.height - 0.4) ** 2)
    img = 255.0 * (gain_dark + illumination * img * shade)
    if motion_blur_px != (0.0, 0.0):
        img = cv2.filter2D(img, -1, _linear_kernel(motion_blur_px), borderType=cv2.BORDER_REFLECT)
    if blur_sigma_px > 0:
        img = cv2.GaussianBlur(img, (0, 0), blur_sigma_px)
    if noise_sigma > 0:
        rng = np.random.default_rng(seed)
        img = img + rng.normal(0.0, noise_sigma, img.shape).astype(np.float32)
    return np.clip(np.round(img), 0, 255).astype(np.uint8)


def true_corners(camera: CameraModel, board: BoardSpec, T_cam_board: Pose) -> tuple[F64, NDArray[
        np.bool_]]:
    """Exact corner pixels (n_corners, 2) and a mask of those inside the image and in front."""
    from controller.geometry.poses import transform_points

    uv = camera.project_cam(transform_points(T_cam_board, board.object_points()))
    inside = np.isfinite(uv).all(axis=1)
    inside &= (uv[:, 0] >= 0) & (uv[:, 0] <= camera.width - 1)
    inside &= (uv[:, 1] >= 0) & (uv[:, 1] <= camera.height - 1)
    return uv, inside
