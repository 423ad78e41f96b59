import numpy as np
import pytest

from controller.errors import CalibrationError
from controller.geometry.camera_model import CameraModel, default_camera
from controller.geometry.poses import make_pose, rotation_about


def grid(cam, step=16):
    u, v = np.meshgrid(np.arange(0, cam.width, step, dtype=float),
                       np.arange(0, cam.height, step, dtype=float))
    return np.column_stack([u.ravel(), v.ravel()])


@pytest.mark.parametrize("dist", [
    [0, 0, 0, 0, 0],
    [-0.08, 0.05, 0.0004, -0.0003, 0.0],
    [-0.25, 0.12, 0.001, 0.002, -0.03],
])
def test_project_undistort_backproject_round_trip_whole_image(dist):
    cam = CameraModel(2272, 1704, default_camera().K, np.array(dist))
    uv = grid(cam)
    T_base_cam = make_pose(rotation_about([1, 0.2, 0], 2.8), [1000, 50, 650])
    origin, dirs = cam.pixel_rays(uv, T_base_cam)
    depth = np.linspace(200, 900, len(uv))[:, None]
    points = origin + dirs * depth
    back = cam.project(points, T_base_cam)
    assert np.nanmax(np.abs(back - uv)) < 1e-6
    assert not np.any(np.isnan(back))


def test_project_matches_opencv():
    import cv2

    cam = default_camera()
    rng = np.random.default_rng(3)
    P = np.column_stack([rng.uniform(-100, 100, 50), rng.uniform(-80, 80, 50),
                         rng.uniform(300, 500, 50)])
    ours = cam.project_cam(P)
    theirs, _ = cv2.projectPoints(P, np.zeros(3), np.zeros(3), cam.K, cam.dist)
    assert np.max(np.abs(ours - theirs.reshape(-1, 2))) < 1e-6


def test_points_behind_camera_are_nan():
    cam = default_camera()
    uv = cam.project_cam([[0, 0, -100.0], [0, 0, 100.0]])
    assert np.all(np.isnan(uv[0])) and np.all(np.isfinite(uv[1]))


def test_scaled_camera_keeps_pixel_centres():
    cam = default_camera()
    half = cam.scaled(0.5)
    P = np.array([[10.0, -20.0, 400.0]])
    full_uv = cam.project_cam(P)[0]
    half_uv = half.project_cam(P)[0]
    assert np.allclose(half_uv + 0.5, (full_uv + 0.5) * 0.5, atol=1e-9)


@pytest.mark.parametrize("K", [np.diag([0.0, 100, 1]), np.diag([100.0, -1, 1]), np.eye(2)])
def test_bad_intrinsics_refused(K):
    with pytest.raises(CalibrationError):
        CameraModel(640, 480, K)
