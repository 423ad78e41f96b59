"""Calibrating a fixed pair of cameras (eye-to-hand each) and the cross-check that they agree."""

import numpy as np
import pytest

from calibration.fixed_pair import (
    calibrate_fixed_cameras,
    cross_check,
    shared_views_from_sessions,
)
from calibration.targets import detect_board, parse_board_spec
from controller.errors import CalibrationError
from controller.geometry.poses import make_pose, pose_error, rotation_about
from drivers.sim.sim_fixed_cell import fixed_stereo_cell
from drivers.sim.sim_fixed_pair import simulate_pair_session
from drivers.sim.sim_scene import make_scene

pytestmark = pytest.mark.slow

BOARD = parse_board_spec("chessboard:9x6:20")


def shared(sess):
    dets = {k: [detect_board(im, BOARD) for im in ims] for k, ims in sess.images.items()}
    return shared_views_from_sessions(sess.names, sess.T_base_flange, dets)


@pytest.fixture(scope="module")
def pair():
    """The fixed-stereo cell's two cameras at 0.3 x their resolution (fast), calibrated."""
    cell = fixed_stereo_cell(make_scene("s_curve", 1, "medium"))
    cams = {k: c.scaled(0.3) for k, c in cell.cameras.items()}
    sess = simulate_pair_session(cams, cell.T_base_cam, BOARD, n_views=12, seed=1)
    calibs, report = calibrate_fixed_cameras(
        shared(sess), BOARD, {k: (c.width, c.height) for k, c in cams.items()}, holdout_every=0)
    return cell, cams, calibs, report


def test_each_camera_pose_recovered(pair):
    cell, _, calibs, report = pair
    for name, calib in calibs.items():
        d_mm, d_deg = pose_error(calib.T_base_cam, cell.T_base_cam[name])
        # At 0.3 x resolution; full resolution is in bench/bench_fixed_pair.py (README).
        assert d_mm < 0.5 and d_deg < 0.1, (name, d_mm, d_deg)
        assert calib.T_flange_cam is None and "board_on_flange" in calib.metadata
    worst = report["cross_check"]["worst"]["left-right"]
    assert worst["mm"] < 0.4 and worst["deg"] < 0.1


@pytest.mark.parametrize("knock, what", [
    (make_pose(t_mm=[1.0, 0.0, 0.0]), "1 mm"),
    (make_pose(rotation_about([0, 1, 0], np.radians(0.2))), "0.2 deg"),
])
def test_cross_check_names_the_knocked_camera(pair, knock, what):
    cell, cams, calibs, _ = pair
    moved = dict(cell.T_base_cam)
    moved["right"] = moved["right"] @ knock
    views = shared(simulate_pair_session(cams, moved, BOARD, n_views=3, seed=51))
    with pytest.raises(CalibrationError, match="camera right has moved") as info:
        cross_check(calibs, views, BOARD)
    assert info.value.details["camera"] == "right", what
    # The same check on views of the cameras where they were calibrated passes.
    ok = cross_check(calibs, shared(simulate_pair_session(cams, cell.T_base_cam, BOARD,
                                                          n_views=3, seed=51)), BOARD)
    assert ok["worst"]["left-right"]["mm"] < 0.4


def test_cross_check_without_the_robot_names_both(pair):
    cell, cams, calibs, _ = pair
    bare = {k: type(c)(c.camera, T_base_cam=c.T_base_cam) for k, c in calibs.items()}
    moved = dict(cell.T_base_cam)
    moved["left"] = moved["left"] @ make_pose(t_mm=[0.0, 1.5, 0.0])
    views = shared(simulate_pair_session(cams, moved, BOARD, n_views=2, seed=52))
    with pytest.raises(CalibrationError, match="cannot tell which one moved") as info:
        cross_check(bare, views, BOARD)
    assert info.value.details["camera"] == ["left", "right"]


def test_cross_check_needs_shared_views(pair):
    _, cams, calibs, _ = pair
    with pytest.raises(CalibrationError, match="no view was seen by two"):
        cross_check(calibs, [], BOARD)
    mixed = {"left": type(calibs["left"])(calibs["left"].camera, T_flange_cam=np.eye(4)),
             "right": calibs["right"]}
    sess = simulate_pair_session(cams, {k: c.T_base_cam for k, c in calibs.items()}, BOARD,
                                 n_views=1, seed=3)
    with pytest.raises(CalibrationError, match="camera left: its calibration has no camera_pose"):
        cross_check(mixed, shared(sess), BOARD)
