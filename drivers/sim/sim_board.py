"""Simulated calibration board: images of a chessboard or ChArUco board with exact ground truth.

:func:`render_board` draws a board through a :class:`~controller.geometry.camera_model.CameraModel`
(distortion included) by casting, for every sub-sample of every pixel, the ray through it onto the
board plane and evaluating the board's printed pattern there exactly (squares, and the ArUco
markers' cells); sub-samples are averaged (anti-aliasing), then optional defocus blur, motion blur
and sensor noise are applied. The true corner pixels come from ``CameraModel.project_cam`` of the
board's corner points, so detection error is measured against an exact answer.

:func:`simulate_session` builds a whole hand-eye session: a board lying in the robot cell (or held
by the robot, eye-to-hand), well-spread camera views checked with the IRB 2400's inverse
kinematics, recorded flange poses with Gaussian pose noise, and optional bad views (a
motion-blurred frame whose recorded pose is off, a board partly out of frame, a frame without the
board). :class:`SimBoardCamera` renders from a robot's current pose, for the teach routine.

What this does not model: lens vignetting and chromatic effects, rolling shutter, specular glare,
board non-flatness and printing scale errors, JPEG artefacts, the detector seeing other objects.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy.interpolate import RectBivariateSpline

from calibration.targets import BoardSpec
from controller.errors import CameraError, InputError, ReachabilityError
from controller.geometry.camera_model import CameraModel
from controller.geometry.poses import Pose, compose, invert, make_pose, rotation_about

F64 = NDArray[np.float64]

#: Spread of simulated views: tilt of the optical axis from the board normal (deg), and the
#: fraction of the image width the board fills at the mean distance.
VIEW_TILT_DEG = (20.0, 50.0)
VIEW_FILL = 0.7

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


# ---------------------------------------------------------------------------------------------
# Sessions
# ---------------------------------------------------------------------------------------------
def default_hand_eye() -> Pose:
    """A plausible wrist camera: 95 mm off the flange axis, 60 mm along it, tilted 12 degrees."""
    R = rotation_about([0, 0, 1], np.radians(90)) @ rotation_about([1, 0, 0], np.radians(-12))
    return make_pose(R, [95.0, -8.0, 60.0])


def default_board_pose(board: BoardSpec) -> Pose:
    """A board lying face up on the table in front of the robot, its centre at (1000, 50, 300) mm.

    The board's z axis points down (into the table), so its printed face looks up.
    """
    w, h = board.size_mm
    centre_b = np.array(board.object_points().mean(axis=0))
    R = rotation_about([1, 0, 0], np.pi) @ rotation_about([0, 0, 1], np.radians(8))
    t = np.array([1000.0, 50.0, 300.0]) - R @ centre_b
    del w, h
    return make_pose(R, t)


def look_at(eye: F64, target: F64, roll_rad: float, up: F64 | None = None) -> Pose:
    """Camera pose (optical frame) at ``eye`` looking at ``target`` (both mm), rolled by an angle.

    With zero roll the camera's y axis (image down) is as close as possible to ``up``'s negative
    (default: base -x, i.e. image "up" points away from the robot).
    """
    z = np.asarray(target, float) - np.asarray(eye, float)
    z /= np.linalg.norm(z)
    upv = np.array([-1.0, 0.0, 0.0]) if up is None else np.asarray(up, float)
    x = np.cross(z, upv)
    if np.linalg.norm(x) < 1e-6:
        x = np.cross(z, [0.0, 1.0, 0.0])
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R = np.column_stack([x, y, z]) @ rotation_about([0, 0, 1], roll_rad)
    return make_pose(R, eye)


@dataclass
class SimView:
    """One simulated view: image, true and recorded flange pose, and what kind of view it is."""

    name: str
    image: NDArray[np.uint8]
    T_base_flange_true: Pose
    T_base_flange: Pose
    T_cam_board: Pose
    kind: str = "good"
    joints_deg: F64 | None = None


@dataclass
class SimSession:
    """A simulated calibration session with its ground truth."""

    camera: CameraModel
    board: BoardSpec
    T_flange_cam: Pose | None
    T_base_board: Pose | None
    views: list[SimView] = field(default_factory=list)
    eye_to_hand: bool = False
    T_base_cam: Pose | None = None
    T_flange_board: Pose | None = None


def perturb(T: Pose, rng: np.random.Generator, sigma_mm: float, sigma_deg: float) -> Pose:
    """``T`` moved by Gaussian noise: per-axis sigma_mm of translation and sigma_deg of rotation."""
    rv = rng.normal(0.0, np.radians(sigma_deg), 3)
    angle = float(np.linalg.norm(rv))
    R = rotation_about(list(rv), angle) if angle > 0 else np.eye(3)
    out = np.asarray(T, float).copy()
    out[:3, :3] = out[:3, :3] @ R
    out[:3, 3] += rng.normal(0.0, sigma_mm, 3)
    return out


def _view_poses(rng: np.random.Generator, n: int, centre: F64, camera: CameraModel,
                board: BoardSpec, start: int = 0) -> list[tuple[F64, F64, float]]:
    """Make n (eye, target, roll) triples spread over azimuth, tilt, distance and image position.

    The azimuth of triple i steps by the golden angle from ``start + i``: a caller that asks for
    one triple at a time passes a running count as ``start``, or every view would come from the
    same side of the board (rotations about one axis only, the hand-eye depth poorly observed).
    """
    w, h = board.size_mm
    fov = 2 * np.arctan(0.5 * camera.width / camera.fx)
    # Distance at which the board fills FILL of the image width.
    base_dist = max(w, h) / VIEW_FILL / (2 * np.tan(fov / 2))
    out = []
    golden = np.pi * (3 - np.sqrt(5))
    for i in range(n):
        az = (start + i) * golden + rng.uniform(-0.2, 0.2)
        tilt = np.radians(rng.uniform(*VIEW_TILT_DEG))
        dist = base_dist * rng.uniform(0.8, 1.2)
        eye = centre + dist * np.array([np.sin(tilt) * np.cos(az), np.sin(tilt) * np.sin(az),
                                        np.cos(tilt)])
        # Aim a little off the board centre so the corners cover the whole image over the views.
        target = centre + np.array([rng.uniform(-0.45, 0.45) * w, rng.uniform(-0.45, 0.45) * h,
                                    0.0])
        roll = np.radians(rng.uniform(-35, 35))
        out.append((eye, target, roll))
    return out


def simulate_session(camera: CameraModel, board: BoardSpec, *, n_views: int = 20, seed: int = 0,
                     T_flange_cam: Pose | None = None, T_base_board: Pose | None = None,
                     pose_noise_mm: float = 0.05, pose_noise_deg: float = 0.01,
                     n_blurred: int = 0, n_out_of_frame: int = 0, n_no_board: int = 0,
                     blurred_pose_error_mm: float = 1.5, blurred_pose_error_deg: float = 0.3,
                     check_reach: bool = True, supersample: int = 2, noise_sigma: float = 1.5,
                     eye_to_hand: bool = False,
                     progress: Callable[[int], None] | None = None) -> SimSession:
    """A complete simulated session of ``n_views`` good views plus the requested bad views.

    Eye-in-hand (default): the board lies on the table at ``T_base_board`` and the camera sits on
    the flange at ``T_flange_cam``. Eye-to-hand: the camera is fixed at a pose looking at the
    robot's work area and the board is held by the flange (``T_flange_board``); every view then
    moves the flange. Recorded flange poses get Gaussian noise (per-axis ``pose_noise_mm``,
    ``pose_noise_deg``). Bad views: ``n_blurred`` frames taken while moving (motion blur, recorded
    pose off by about ``blurred_pose_error_mm`` / ``_deg``), ``n_out_of_frame`` frames with the
    board partly outside the image, ``n_no_board`` frames that miss the board. With
    ``check_reach`` every flange pose is checked with the IRB 2400's inverse kinematics and
    joints are recorded. Raises :class:`ReachabilityError` if poses cannot be found.
    """
    from controller.geometry.kinematics import inverse_kinematics, irb2400

    rng = np.random.default_rng(seed)
    robot = irb2400()
    X = default_hand_eye() if T_flange_cam is None else np.asarray(T_flange_cam, float)
    Y = default_board_pose(board) if T_base_board is None else np.asarray(T_base_board, float)
    sess = SimSession(camera, board, None if eye_to_hand else X, None if eye_to_hand else Y,
                      eye_to_hand=eye_to_hand)
    centre = Y[:3, :3] @ board.object_points().mean(axis=0) + Y[:3, 3]
    T_base_cam: Pose | None = None
    T_flange_board: Pose | None = None
    if eye_to_hand:
        # A fixed camera above and in front; the flange holds the board ~150 mm out along tool z.
        T_base_cam = look_at(np.array([1500.0, -300.0, 1000.0]), np.array([1000.0, 0.0, 650.0]),
                             0.0, up=np.array([0.0, 0.0, 1.0]))
        cb = board.object_points().mean(axis=0)
        # Board face towards the camera: board z (into the board) opposite the flange's z.
        Rfb = rotation_about([1, 0, 0], np.pi)
        T_flange_board = make_pose(Rfb, np.array([0.0, 0.0, 150.0]) - Rfb @ cb)
        sess.T_base_cam, sess.T_flange_board = T_base_cam, T_flange_board

    kinds = (["good"] * n_views + ["blurred"] * n_blurred + ["out_of_frame"] * n_out_of_frame
             + ["no_board"] * n_no_board)
    order = rng.permutation(len(kinds))
    kinds = [kinds[i] for i in order]
    idx = 0
    attempts = 0
    while idx < len(kinds):
        attempts += 1
        if attempts > 50 * len(kinds):
            raise ReachabilityError("simulate_session: could not find reachable view poses; "
                                    "move the board closer to the robot")
        kind = kinds[idx]
        if eye_to_hand:
            T_cam_board = _eye_to_hand_pose(rng, camera, board, sess, kind)
            assert T_base_cam is not None and T_flange_board is not None
            T_base_flange = compose(T_base_cam, T_cam_board, invert(T_flange_board))
        else:
            eye, target, roll = _view_poses(rng, 1, centre, camera, board, attempts)[0]
            if kind == "out_of_frame":
                w, h = board.size_mm
                target = centre + np.array([0.6 * w, 0.1 * h, 0.0]) * rng.choice([-1, 1])
            elif kind == "no_board":
                target = centre + np.array([0.0, 700.0, 0.0])
            T_base_cam = look_at(eye, target, roll)
            T_base_flange = T_base_cam @ invert(X)
            T_cam_board = invert(T_base_cam) @ Y
        joints = None
        if check_reach:
            sols = inverse_kinematics(robot, T_base_flange)
            if not sols:
                continue
            joints = sols[0]
        uv, inside = true_corners(camera, board, T_cam_board)
        if kind in ("good", "blurred") and not inside.all():
            continue
        if kind == "out_of_frame" and not (0.2 < inside.mean() < 0.85):
            continue
        if kind == "no_board" and inside.any():
            continue
        motion = (0.0, 0.0)
        recorded = perturb(T_base_flange, rng, pose_noise_mm, pose_noise_deg)
        if kind == "blurred":
            direction = rng.normal(size=3)
            direction /= np.linalg.norm(direction)
            recorded[:3, 3] += blurred_pose_error_mm * direction
            axis = rng.normal(size=3)
            recorded[:3, :3] = np.asarray(recorded[:3, :3]) @ rotation_about(
                list(axis), float(np.radians(blurred_pose_error_deg)))
            ang = rng.uniform(0, np.pi)
            motion = (6.0 * np.cos(ang), 6.0 * np.sin(ang))
        image = render_board(camera, board, T_cam_board, supersample=supersample,
                             noise_sigma=noise_sigma, motion_blur_px=motion,
                             seed=seed * 1000 + idx)
        name = f"view{idx + 1:02d}"
        sess.views.append(SimView(name, image, T_base_flange, recorded, T_cam_board, kind,
                                  None if joints is None else np.asarray(joints)))
        if progress is not None:
            progress(idx)
        idx += 1
    return sess


def _eye_to_hand_pose(rng: np.random.Generator, camera: CameraModel, board: BoardSpec,
                      sess: SimSession, kind: str) -> Pose:
    """A board pose in the fixed camera's frame for one eye-to-hand view."""
    w, h = board.size_mm
    fov = 2 * np.arctan(0.5 * camera.width / camera.fx)
    dist = max(w, h) / 0.6 / (2 * np.tan(fov / 2)) * rng.uniform(0.85, 1.2)
    cb = board.object_points().mean(axis=0)
    # Board facing the camera (board z along camera z), tilted 12-35 deg, rolled.
    tilt = np.radians(rng.uniform(12, 35))
    az = rng.uniform(0, 2 * np.pi)
    R = rotation_about([np.cos(az), np.sin(az), 0.0], tilt) @ rotation_about(
        [0, 0, 1], rng.uniform(-0.6, 0.6))
    off = np.array([rng.uniform(-0.25, 0.25) * w, rng.uniform(-0.25, 0.25) * h, 0.0])
    if kind == "out_of_frame":
        off = np.array([0.6 * w, 0.1 * h, 0.0]) * rng.choice([-1, 1])
    elif kind == "no_board":
        off = np.array([0.0, 0.0, -10 * dist])
    centre_cam = np.array([0.0, 0.0, dist]) + off
    return make_pose(R, centre_cam - R @ cb)


def write_view_folder(session: SimSession, folder: str | Path, *, use_joints: bool = False,
                      recorded: bool = True) -> list[Path]:
    """Write a session as a view folder (DESIGN.md view files + PNG images); returns the files.

    ``use_joints`` writes ``joints_deg`` (IK of the recorded flange pose, needs reachable views)
    instead of ``flange_pose``; ``recorded`` False writes the true poses instead of the noisy ones.
    """
    from controller.geometry.kinematics import inverse_kinematics, irb2400
    from controller.geometry.view_file import view_to_dict
    from controller.jsonio import atomic_write_text, dumps

    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    files = []
    for v in session.views:
        cv2.imwrite(str(out / f"{v.name}.png"), v.image)
        T = v.T_base_flange if recorded else v.T_base_flange_true
        if use_joints:
            sols = inverse_kinematics(irb2400(), T)
            if not sols:
                raise ReachabilityError(f"view {v.name}: no IK solution for its flange pose")
            ref = v.joints_deg if v.joints_deg is not None else np.zeros(6)
            j = min(sols, key=lambda s: float(np.max(np.abs(s - ref))))
            doc = view_to_dict(f"{v.name}.png", joints_deg=j)
        else:
            doc = view_to_dict(f"{v.name}.png", T_base_flange=T)
        path = out / f"{v.name}.json"
        atomic_write_text(path, dumps(doc))
        files.append(path)
    return files


class SimBoardCamera:
    """A simulated camera that renders the board from a robot's current flange pose.

    Eye-in-hand: ``T_base_cam = T_base_flange @ T_flange_cam`` and the board lies at
    ``T_base_board``. Eye-to-hand (``T_base_cam`` given): the camera is fixed and the board rides
    on the flange at ``T_flange_board``. ``pose_of`` is a callable returning the robot's true
    flange pose (mm); frames are rendered at the given image size.
    """

    def __init__(self, camera: CameraModel, board: BoardSpec, pose_of: Callable[[], Pose], *,
                 T_flange_cam: Pose | None = None, T_base_board: Pose | None = None,
                 T_base_cam: Pose | None = None, T_flange_board: Pose | None = None,
                 noise_sigma: float = 1.5, supersample: int = 2, seed: int = 0,
                 name: str = "sim-board") -> None:
        self.model = camera
        self.board = board
        self._pose_of = pose_of
        self.eye_to_hand = T_base_cam is not None
        self.T_flange_cam = default_hand_eye() if T_flange_cam is None else T_flange_cam
        self.T_base_board = default_board_pose(board) if T_base_board is None else T_base_board
        self.T_base_cam = T_base_cam
        self.T_flange_board = T_flange_board
        self.noise_sigma = noise_sigma
        self.supersample = supersample
        self.name = name
        self._count = seed * 100000

    def T_cam_board(self) -> Pose:
        """The board in the camera frame at the robot's current pose."""
        T_bf = self._pose_of()
        if self.eye_to_hand:
            assert self.T_base_cam is not None and self.T_flange_board is not None
            return compose(invert(self.T_base_cam), T_bf, self.T_flange_board)
        return compose(invert(T_bf @ self.T_flange_cam), self.T_base_board)

    def grab(self, timeout_s: float = 5.0) -> NDArray[np.uint8]:
        """Render one frame (greyscale uint8) at the robot's current pose."""
        self._count += 1
        return render_board(self.model, self.board, self.T_cam_board(),
                            supersample=self.supersample, noise_sigma=self.noise_sigma,
                            seed=self._count)

    def identity(self) -> dict[str, Any]:
        """What the calibration metadata records about this camera."""
        return {"kind": "simulated board camera", "name": self.name,
                "size": [self.model.width, self.model.height]}

    def close(self) -> None:
        """Nothing to release."""
