"""Simulated calibration board: sessions of board images with exact ground truth.

The images are rendered by :mod:`drivers.sim.sim_board_render` (:func:`render_board`, exact
corners from :func:`true_corners`; both importable from here too).

:func:`simulate_session` builds a whole hand-eye session: a board lying in the robot cell (or held
by the robot, eye-to-hand), well-spread camera views checked with the IRB 2400's inverse
kinematics, recorded flange poses with Gaussian pose noise, and optional bad views (a
motion-blurred frame whose recorded pose is off, a board partly out of frame, a frame without the
board). :class:`SimBoardCamera` renders from a robot's current pose, for the teach routine.

What this does not model: lens vignetting and chromatic effects, rolling shutter, specular glare,
board non-flatness and printing scale errors, JPEG artefacts, the detector seeing other objects.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from calibration.targets import BoardSpec
from controller.errors import ReachabilityError
from controller.geometry.camera_model import CameraModel
from controller.geometry.poses import Pose, compose, invert, make_pose, rotation_about
from drivers.sim.sim_board_render import render_board, true_corners

F64 = NDArray[np.float64]

#: Spread of simulated views: tilt of the optical axis from the board normal (deg), and the
#: fraction of the image width the board fills at the mean distance.
VIEW_TILT_DEG = (20.0, 50.0)
VIEW_FILL = 0.7

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
