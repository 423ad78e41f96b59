"""A simulated calibration session of fixed cameras: the robot shows a board to all of them at once.

The board rides on the flange (a bracket beside the torch, printed face away from the flange, so
that with the torch pointing down the face looks up at cameras on stands). At every robot pose
each fixed camera takes an image; the recorded flange pose gets the robot's Gaussian pose noise.
The cameras render from the poses given, so a check session with one camera *knocked* (its true
pose moved after calibration) is simulated by passing the moved pose.

What it does not model: the robot or the bracket hiding part of the board, the cameras' frames
being taken at slightly different times (the robot holds still), and everything
:mod:`drivers.sim.sim_board` does not model.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from calibration.targets import BoardSpec
from controller.errors import ReachabilityError
from controller.geometry.camera_model import CameraModel
from controller.geometry.poses import Pose, invert, make_pose, rotation_about, transform_points
from drivers.sim.sim_board import perturb, render_board, true_corners

F64 = NDArray[np.float64]


def default_flange_board(board: BoardSpec) -> Pose:
    """``T_flange_board``: the board's centre 150 mm beside the flange axis and 100 mm along it.

    Board axes parallel to the flange's: board z (into the board) along the torch, so the printed
    face looks back past the flange.
    """
    cb = board.object_points().mean(axis=0)
    return make_pose(np.eye(3), np.array([0.0, 150.0, 100.0]) - cb)


@dataclass
class PairSession:
    """One session: per robot pose a recorded flange pose and an image from every camera."""

    cameras: dict[str, CameraModel]
    T_base_cam: dict[str, Pose]
    board: BoardSpec
    T_flange_board: Pose
    names: list[str] = field(default_factory=list)
    T_base_flange_true: list[Pose] = field(default_factory=list)
    T_base_flange: list[Pose] = field(default_factory=list)
    images: dict[str, list[NDArray[np.uint8]]] = field(default_factory=dict)


def common_target(T_base_cam: dict[str, Pose]) -> F64:
    """The point (base frame, mm) nearest to every camera's optical axis (least squares)."""
    A = np.zeros((3, 3))
    b = np.zeros(3)
    for T in T_base_cam.values():
        z = np.asarray(T)[:3, 2]
        P = np.eye(3) - np.outer(z, z)
        A += P
        b += P @ np.asarray(T)[:3, 3]
    return np.asarray(np.linalg.solve(A, b))


def simulate_pair_session(cameras: dict[str, CameraModel], T_base_cam: dict[str, Pose],
                          board: BoardSpec, *, n_views: int = 16, seed: int = 0,
                          T_flange_board: Pose | None = None, pose_noise_mm: float = 0.05,
                          pose_noise_deg: float = 0.01, noise_sigma: float = 1.5,
                          supersample: int = 2, tilt_deg: tuple[float, float] = (10.0, 35.0),
                          ) -> PairSession:
    """``n_views`` robot poses at which every camera sees the whole board, with their images.

    The board's centre is placed within +-30 mm of the point the cameras look at, its face
    tilted ``tilt_deg`` from facing straight up in a random direction and turned up to +-60 deg
    about its normal (the rotations an eye-to-hand calibration needs); every flange pose is
    checked with the IRB 2400's inverse kinematics. Raises :class:`ReachabilityError` when no
    such poses are found.
    """
    from controller.geometry.kinematics import inverse_kinematics, irb2400

    rng = np.random.default_rng(seed)
    robot = irb2400()
    Y = default_flange_board(board) if T_flange_board is None else np.asarray(T_flange_board)
    sess = PairSession(dict(cameras), dict(T_base_cam), board, Y,
                       images={k: [] for k in cameras})
    target = common_target(T_base_cam)
    cb = board.object_points().mean(axis=0)
    attempts = 0
    while len(sess.names) < n_views:
        attempts += 1
        if attempts > 200 * n_views:
            raise ReachabilityError("simulate_pair_session: no robot pose shows the whole board "
                                    "to every camera; check the cameras' poses")
        az = rng.uniform(0, 2 * np.pi)
        tilt = np.radians(rng.uniform(*tilt_deg))
        R = (rotation_about([1, 0, 0], np.pi) @ rotation_about([np.cos(az), np.sin(az), 0], tilt)
             @ rotation_about([0, 0, 1], np.radians(rng.uniform(-60, 60))))
        centre = target + rng.uniform(-30, 30, 3)
        T_base_board = make_pose(R, centre - R @ cb)
        if not all(true_corners(cam, board, invert(T_base_cam[k]) @ T_base_board)[1].all()
                   for k, cam in cameras.items()):
            continue
        T_bf = T_base_board @ invert(Y)
        if not inverse_kinematics(robot, T_bf):
            continue
        i = len(sess.names)
        sess.names.append(f"view{i + 1:02d}")
        sess.T_base_flange_true.append(T_bf)
        sess.T_base_flange.append(perturb(T_bf, rng, pose_noise_mm, pose_noise_deg))
        for j, (k, cam) in enumerate(cameras.items()):
            sess.images[k].append(render_board(
                cam, board, invert(T_base_cam[k]) @ T_base_board, supersample=supersample,
                noise_sigma=noise_sigma, seed=seed * 10000 + 100 * i + j))
    return sess


def board_centre_mm(sess: PairSession, i: int) -> F64:
    """Where the board's centre truly was at view ``i`` (base frame, mm), for checks."""
    cb = sess.board.object_points().mean(axis=0)
    return transform_points(sess.T_base_flange_true[i] @ sess.T_flange_board, cb[None])[0]
