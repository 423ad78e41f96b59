import numpy as np
import pytest

from calibration.targets import parse_board_spec
from controller.geometry.camera_model import default_camera
from controller.geometry.kinematics import flange_pose, irb2400
from controller.geometry.poses import invert, make_pose, pose_error
from drivers.sim.sim_board import SimBoardCamera, simulate_session, write_view_folder
from drivers.sim.sim_board_render import (
    BLACK,
    TABLE,
    WHITE,
    _linear_kernel,
    _ray_grid,
    board_reflectance,
    render_board,
    true_corners,
)

CAM = default_camera(640, 480)
BOARD = parse_board_spec("chessboard:9x6:20")


def test_ray_grid_matches_newton_undistortion():
    gx, gy = _ray_grid(CAM.width, CAM.height, tuple(CAM.K.ravel()), tuple(CAM.dist), 2)
    rng = np.random.default_rng(1)
    r = rng.integers(0, gx.shape[0], 200)
    c = rng.integers(0, gx.shape[1], 200)
    uv = np.stack([(c + 0.5) / 2 - 0.5, (r + 0.5) / 2 - 0.5], axis=1)
    ref = CAM.pixels_to_normalized(uv)
    err_px = np.abs(np.stack([gx[r, c], gy[r, c]], axis=1) - ref) * CAM.fx
    assert err_px.max() < 1e-4


def test_board_pattern_convention():
    s = BOARD.square_mm
    # The square diagonally inward of corner 0 is black, its neighbours white; margin white.
    x = np.array([0.5 * s, 1.5 * s, 0.5 * s, -0.5 * s, -1.5 * s, -5 * s])
    y = np.array([0.5 * s, 0.5 * s, 1.5 * s, 0.5 * s, 0.5 * s, 0.0])
    assert board_reflectance(BOARD, x, y).tolist() == [BLACK, WHITE, WHITE, WHITE, WHITE, TABLE]


def test_render_deterministic_and_seeded():
    T = make_pose(np.eye(3), [-90.0, -50.0, 330.0])
    a = render_board(CAM, BOARD, T, seed=4)
    b = render_board(CAM, BOARD, T, seed=4)
    c = render_board(CAM, BOARD, T, seed=5)
    assert a.shape == (480, 640) and a.dtype == np.uint8
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    clean = render_board(CAM, BOARD, T, noise_sigma=0)
    blurred = render_board(CAM, BOARD, T, noise_sigma=0, motion_blur_px=(8.0, 0.0))
    # Motion blur lowers the contrast along rows but keeps the mean level.
    assert abs(clean.mean() - blurred.mean()) < 1.0
    assert np.abs(np.diff(blurred.astype(float), axis=1)).mean() < \
        np.abs(np.diff(clean.astype(float), axis=1)).mean()


def test_linear_kernel_normalised():
    k = _linear_kernel((5.0, 3.0))
    assert abs(k.sum() - 1) < 1e-6 and k.min() >= 0


def test_session_ground_truth():
    s = simulate_session(CAM, BOARD, n_views=4, seed=2, n_blurred=1, n_out_of_frame=1,
                         n_no_board=1)
    kinds = sorted(v.kind for v in s.views)
    assert kinds == ["blurred", "good", "good", "good", "good", "no_board", "out_of_frame"]
    robot = irb2400()
    for v in s.views:
        # Truth chain: T_cam_board = (T_base_flange X)^-1 Y, and IK joints reach the true pose.
        T = invert(v.T_base_flange_true @ s.T_flange_cam) @ s.T_base_board
        assert pose_error(T, v.T_cam_board)[0] < 1e-9
        assert pose_error(flange_pose(robot, v.joints_deg), v.T_base_flange_true)[0] < 1e-6
        d_mm, d_deg = pose_error(v.T_base_flange, v.T_base_flange_true)
        if v.kind == "blurred":
            assert d_mm > 0.7
        else:
            assert d_mm < 0.5 and d_deg < 0.1
        uv, inside = true_corners(CAM, BOARD, v.T_cam_board)
        assert inside.all() == (v.kind in ("good", "blurred"))


def test_eye_to_hand_session():
    s = simulate_session(CAM, BOARD, n_views=3, seed=1, eye_to_hand=True)
    for v in s.views:
        T = invert(s.T_base_cam) @ v.T_base_flange_true @ s.T_flange_board
        assert pose_error(T, v.T_cam_board)[0] < 1e-9


def test_sim_camera_renders_at_robot_pose():
    s = simulate_session(CAM, BOARD, n_views=1, seed=3, pose_noise_mm=0, pose_noise_deg=0,
                         noise_sigma=0)
    v = s.views[0]
    cam = SimBoardCamera(CAM, BOARD, lambda: v.T_base_flange_true, noise_sigma=0)
    assert pose_error(cam.T_cam_board(), v.T_cam_board)[0] < 1e-9
    assert np.array_equal(cam.grab(), v.image)


def test_write_view_folder(tmp_path):
    from controller.geometry.view_file import load_view

    s = simulate_session(CAM, BOARD, n_views=2, seed=3)
    files = write_view_folder(s, tmp_path, use_joints=True)
    for f, v in zip(files, s.views, strict=True):
        view = load_view(f)
        assert view.image_path.exists()
        assert pose_error(view.T_base_flange, v.T_base_flange)[0] < 1e-3


@pytest.mark.parametrize("bad", [0, -1])
def test_bad_supersample(bad):
    from controller.errors import InputError

    with pytest.raises(InputError):
        render_board(CAM, BOARD, make_pose(t_mm=[0, 0, 300]), supersample=bad)
