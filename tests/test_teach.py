import io

import numpy as np
import pytest

from calibration.calibration_file import load_calibration, save_calibration
from calibration.targets import parse_board_spec
from calibration.teach import (
    TARGET_SPREAD_DEG,
    ViewRecord,
    calibrate_from_folder,
    collection_progress,
    explore_poses,
    orientation_spread_deg,
    run_teach,
    solve_views,
)
from controller.errors import CalibrationError
from controller.geometry.camera_model import default_camera
from controller.geometry.kinematics import flange_pose, irb2400, solve_ik
from controller.geometry.poses import invert, make_pose, pose_error, rotation_about
from drivers.sim.sim_board import (
    SimBoardCamera,
    default_board_pose,
    default_hand_eye,
    look_at,
    perturb,
    simulate_session,
    write_view_folder,
)

CAM = default_camera(640, 480)
BOARD = parse_board_spec("chessboard:9x6:20")
X = default_hand_eye()
Y = default_board_pose(BOARD)


class FakeRobot:
    """An in-process robot: FK of its joints, reported with seeded pose noise."""

    def __init__(self, joints, sigma_mm=0.05, sigma_deg=0.01, seed=0):
        self.j = np.asarray(joints, float)
        self.rng = np.random.default_rng(seed)
        self.sigma = (sigma_mm, sigma_deg)
        self.moves = 0

    def true_pose(self):
        return flange_pose(irb2400(), self.j)

    def joints_deg(self):
        return self.j.copy()

    def flange_pose(self):
        return perturb(self.true_pose(), self.rng, *self.sigma)

    def move_joints(self, joints_deg, timeout_s):
        self.j = np.asarray(joints_deg, float)
        self.moves += 1


def first_joints():
    centre = Y[:3, :3] @ BOARD.object_points().mean(axis=0) + Y[:3, 3]
    T_bc = look_at(centre + np.array([0, 0, 330.0]), centre, 0.0)
    return solve_ik(irb2400(), T_bc @ invert(X))


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    d = tmp_path_factory.mktemp("views")
    s = simulate_session(CAM, BOARD, n_views=11, seed=12, n_blurred=1, n_out_of_frame=1)
    write_view_folder(s, d, use_joints=True)
    return d, s


def test_progress_line():
    T0 = np.eye(4)
    views = [ViewRecord(f"v{i}", make_pose(rotation_about([1, 0, 0], np.radians(12 * i))),
                        None) for i in range(3)]
    p = collection_progress(views, (640, 480), target_views=15)
    assert p.good == 0 and p.total == 3 and not p.enough
    line = p.line()
    assert line.startswith("[....................] 0/15 good views (3 taken)")
    assert "tilt the camera more" in line
    assert orientation_spread_deg([T0, make_pose(rotation_about([0, 1, 0], 0.5))]) == \
        pytest.approx(np.degrees(0.5))
    assert TARGET_SPREAD_DEG == 30.0


def test_folder_calibration_and_file_round_trip(folder, tmp_path):
    d, s = folder
    calib, report = calibrate_from_folder(d, "chessboard:9x6:20")
    kinds = {v.name: v.kind for v in s.views}
    rejected = [r["view"] for r in report["hand_eye"]["rejected_views"]]
    assert [kinds[v] for v in rejected] == ["blurred"]
    missing = [kinds[v] for v in report["views_without_board"]]
    assert "out_of_frame" in missing and len(missing) <= 2  # a steep good view may be missed
    d_mm, d_deg = pose_error(calib.T_flange_cam, s.T_flange_cam)
    assert d_mm < 0.4 and d_deg < 0.12  # 640x480, 10 views: the bench shows full-size figures
    assert abs(calib.camera.fx / CAM.fx - 1) < 0.002
    assert report["validation"]["passed"] and report["validation"]["held_out"]
    out = tmp_path / "c.yaml"
    save_calibration(out, calib)
    back = load_calibration(out)
    assert pose_error(back.T_flange_cam, calib.T_flange_cam)[0] < 1e-9
    assert back.metadata["views_rejected"][0]["view"] == rejected[0]
    assert back.metadata["board"] == "chessboard:9x6:20" and "date" in back.metadata


def test_manual_teach_with_operator_script():
    s = simulate_session(CAM, BOARD, n_views=7, seed=6, pose_noise_mm=0, pose_noise_deg=0)
    robot = FakeRobot(s.views[0].joints_deg, seed=1)
    camera = SimBoardCamera(CAM, BOARD, robot.true_pose)
    script = [v.joints_deg for v in s.views]
    answers = []

    def operator(progress):
        answers.append(progress)
        if not script:
            return "done"
        robot.move_joints(script.pop(0), 1.0)  # "jogging" on the pendant
        return "take"

    out = io.StringIO()
    calib, report = run_teach(robot, camera, BOARD, confirm=operator, out=out, target_views=6,
                              holdout_every=0)
    text = out.getvalue()
    assert "view01: board found (54 corners)" in text and "good views" in text
    assert "ENOUGH good views" in text
    assert answers[0] is None and answers[-1].good == 7
    assert pose_error(calib.T_flange_cam, X)[0] < 0.6
    assert calib.metadata["collection"] == "taught"


def test_abort_saves_nothing(tmp_path):
    robot = FakeRobot(first_joints())
    camera = SimBoardCamera(CAM, BOARD, robot.true_pose)
    with pytest.raises(CalibrationError, match="aborted"):
        run_teach(robot, camera, BOARD, confirm=lambda p: "abort", out=io.StringIO())
    with pytest.raises(CalibrationError, match="no views"):
        run_teach(robot, camera, BOARD, confirm=lambda p: "done", out=io.StringIO())


def test_robot_that_did_not_move_is_refused():
    robot = FakeRobot(first_joints(), sigma_mm=0.0, sigma_deg=0.0)
    camera = SimBoardCamera(CAM, BOARD, robot.true_pose)
    n = iter(range(5))
    with pytest.raises(CalibrationError, match="robot did not move"):
        run_teach(robot, camera, BOARD, confirm=lambda p: "take" if next(n, None) is not None
                  else "done", out=io.StringIO())


def test_explore_poses_reachable_and_small():
    j0 = first_joints()
    T0 = flange_pose(irb2400(), j0)
    poses = explore_poses(T0, j0, pivot_mm=350)
    assert len(poses) == 6
    for j in poses:
        assert 5 < pose_error(T0, flange_pose(irb2400(), j))[1] < 17


@pytest.mark.slow
def test_automatic_teach_noisy_robot(tmp_path):
    robot = FakeRobot(first_joints(), seed=3)
    camera = SimBoardCamera(CAM, BOARD, robot.true_pose)
    out = io.StringIO()
    calib, report = run_teach(robot, camera, BOARD, auto_n=10, out=out, save_dir=tmp_path,
                              holdout_every=0)
    assert robot.moves == 6 + 10 + 1  # explore, spread, back to the first pose
    assert len(list(tmp_path.glob("*.json"))) == 17
    assert len(report["views_without_board"]) <= 2
    d_mm, d_deg = pose_error(calib.T_flange_cam, X)
    assert d_mm < 0.35 and d_deg < 0.05
    assert calib.metadata["collection"] == "automatic"
    # The recorded folder solves again offline to the same answer.
    again, _ = calibrate_from_folder(tmp_path, BOARD)
    assert pose_error(again.T_flange_cam, calib.T_flange_cam)[0] < 1e-3


def test_solve_views_needs_the_board():
    views = [ViewRecord(f"v{i}", np.eye(4), None) for i in range(6)]
    with pytest.raises(CalibrationError, match="found in only 0 of 6 views; not in v0, v1"):
        solve_views(views, BOARD, (640, 480))


def test_ambiguous_chessboard_refused():
    with pytest.raises(CalibrationError, match="odd sum"):
        solve_views([], parse_board_spec("chessboard:8x6:20"), (640, 480))


@pytest.mark.slow
def test_eye_to_hand_folder_writes_camera_pose(tmp_path):
    s = simulate_session(CAM, BOARD, n_views=8, seed=2, eye_to_hand=True)
    write_view_folder(s, tmp_path)
    calib, report = calibrate_from_folder(tmp_path, BOARD, eye_to_hand=True, holdout_every=0)
    assert calib.T_flange_cam is None and calib.T_base_cam is not None
    d_mm, d_deg = pose_error(calib.T_base_cam, s.T_base_cam)
    assert d_mm < 1.0 and d_deg < 0.1
    assert report["hand_eye"]["mode"] == "eye-to-hand"
    out = tmp_path / "fixed.yaml"
    save_calibration(out, calib)
    assert load_calibration(out).T_base_cam is not None
    # The fixed camera's pose, ready for the view files of `seamguide locate`.
    import json

    from calibration.export import export_hand_eye
    from controller.geometry.poses import pose_from_dict

    doc = json.loads(export_hand_eye(calib, "view_camera_pose"))
    assert pose_error(pose_from_dict(doc["camera_pose"]), calib.T_base_cam)[0] < 1e-5


def test_charuco_folder(tmp_path):
    board = parse_board_spec("charuco:8x6:22:16:DICT_5X5_100")
    s = simulate_session(CAM, board, n_views=8, seed=5, n_out_of_frame=1)
    write_view_folder(s, tmp_path)
    calib, report = calibrate_from_folder(tmp_path, board, holdout_every=0)
    # The partial ChArUco view is detected (partial boards are fine data) and kept.
    partial = [v.name for v in s.views if v.kind == "out_of_frame"]
    assert report["views_without_board"] == [] and partial[0] in report["hand_eye"]["views_used"]
    assert pose_error(calib.T_flange_cam, s.T_flange_cam)[0] < 0.6
