import json
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml
from shared_data import CHESSBOARD, needs

from calibration.calibration_file import load_calibration
from calibration.export import export_hand_eye, pose_from_easy_handeye
from calibration.targets import parse_board_spec
from controller.cli import main
from controller.errors import CalibrationError
from controller.geometry.camera_model import default_camera
from controller.geometry.poses import pose_error
from drivers.sim.sim_board import simulate_session, write_view_folder

DATA = CHESSBOARD
CAM = default_camera(640, 480)
BOARD = parse_board_spec("chessboard:9x6:20")
SPEC = "chessboard:9x6:20"


@pytest.fixture(scope="module")
def session():
    return simulate_session(CAM, BOARD, n_views=11, seed=21, n_blurred=1)


@pytest.fixture(scope="module")
def folder(tmp_path_factory, session):
    d = tmp_path_factory.mktemp("views")
    write_view_folder(session, d)
    return d


def test_from_folder_writes_calibration(folder, session, tmp_path, capsys):
    out = tmp_path / "c.yaml"
    out.write_text("an older calibration\n")
    he = tmp_path / "he.yaml"
    rc = main(["calibrate", "--from-folder", str(folder), "--board", SPEC, "--output", str(out),
               "--export", f"easy_handeye:{he}", "--holdout-every", "4",
               "--report", str(tmp_path / "r.json")])
    assert rc == 0
    report = json.loads((tmp_path / "r.json").read_text())
    assert report["validation"]["passed"]
    calib = load_calibration(out)
    assert calib.T_flange_cam is not None and calib.T_base_cam is None
    assert pose_error(calib.T_flange_cam, session.T_flange_cam)[0] < 0.5
    blurred = [v.name for v in session.views if v.kind == "blurred"]
    assert [r["view"] for r in report["hand_eye"]["rejected_views"]] == blurred
    assert calib.metadata["views_rejected"][0]["view"] == blurred[0]
    T, on_hand = pose_from_easy_handeye(he.read_text())
    assert on_hand and pose_error(T, calib.T_flange_cam)[0] < 1e-6
    # The file that was there is kept.
    assert (tmp_path / "c.prev.yaml").read_text() == "an older calibration\n"


def test_images_intrinsics_only(folder, tmp_path, capsys):
    out = tmp_path / "i.yaml"
    assert main(["calibrate", "--images", str(folder / "*.png"), "--board", SPEC, "--output",
                 str(out)]) == 0
    doc = yaml.safe_load(out.read_text())
    assert "hand_eye" not in doc and "camera_pose" not in doc
    assert abs(doc["camera_matrix"]["data"][0] / CAM.fx - 1) < 0.003


@needs(DATA)
def test_images_real_opencv_set(tmp_path, capsys):
    out = tmp_path / "left.yaml"
    assert main(["calibrate", "--images", str(DATA / "left*.jpg"), "--board",
                 "chessboard:9x6:25", "--output", str(out)]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["intrinsics"]["rms_px"] < 0.25 and report["images_without_board"] == []
    assert load_calibration(out).camera.width == 640


def test_images_without_board_error_nothing_saved(tmp_path, capsys):
    for i in range(5):
        cv2.imwrite(str(tmp_path / f"blank{i}.png"), np.full((480, 640), 128, np.uint8))
    out = tmp_path / "c.yaml"
    rc = main(["calibrate", "--images", str(tmp_path / "*.png"), "--board", SPEC, "--output",
               str(out)])
    err = capsys.readouterr().err
    assert rc == CalibrationError.exit_code and not out.exists()
    assert "found in only 0 of 5 images" in err and "blank0.png" in err


def _copy_views(src: Path, dst: Path, names):
    dst.mkdir()
    for n in names:
        (dst / f"{n}.png").write_bytes((src / f"{n}.png").read_bytes())
        (dst / f"{n}.json").write_text((src / f"{n}.json").read_text())


def test_too_few_views_nothing_saved(folder, tmp_path, capsys):
    few = tmp_path / "few"
    _copy_views(folder, few, ["view01", "view02", "view03"])
    out = tmp_path / "c.yaml"
    rc = main(["calibrate", "--from-folder", str(few), "--board", SPEC, "--output", str(out)])
    assert rc == CalibrationError.exit_code and not out.exists()
    assert "need at least 5" in capsys.readouterr().err


def test_robot_still_and_translation_only_nothing_saved(folder, tmp_path, capsys):
    # Same recorded pose for every view (a robot that did not move / a link that froze).
    still = tmp_path / "still"
    names = [f"view{i:02d}" for i in range(1, 8)]
    _copy_views(folder, still, names)
    first = json.loads((still / "view01.json").read_text())["flange_pose"]
    for n in names:
        doc = json.loads((still / f"{n}.json").read_text())
        doc["flange_pose"] = first
        (still / f"{n}.json").write_text(json.dumps(doc))
    out = tmp_path / "c.yaml"
    rc = main(["calibrate", "--from-folder", str(still), "--board", SPEC, "--output", str(out)])
    assert rc == CalibrationError.exit_code and not out.exists()
    assert "robot did not move: views view01, view02" in capsys.readouterr().err
    # Translations only: degenerate for hand-eye.
    for k, n in enumerate(names):
        doc = json.loads((still / f"{n}.json").read_text())
        doc["flange_pose"]["position_mm"] = [first["position_mm"][0] + 15 * k,
                                             first["position_mm"][1] - 10 * k,
                                             first["position_mm"][2] + 5 * k]
        (still / f"{n}.json").write_text(json.dumps(doc))
    rc = main(["calibrate", "--from-folder", str(still), "--board", SPEC, "--output", str(out)])
    assert rc == CalibrationError.exit_code and not out.exists()
    assert "too little rotation between views" in capsys.readouterr().err


def test_bad_arguments(tmp_path, capsys):
    out = str(tmp_path / "c.yaml")
    assert main(["calibrate", "--images", "/nonexistent/*.png", "--board", SPEC,
                 "--output", out]) == 2
    assert main(["calibrate", "--images", "x", "--board", "chessboard:9x6", "--output", out]) == 2
    assert main(["calibrate", "--port", "mock://", "--board", SPEC, "--output", out]) == 2
    assert main(["calibrate", "--from-folder", str(tmp_path), "--board", SPEC,
                 "--output", out]) == 3  # no view files
    err = capsys.readouterr().err
    assert "matches no file" in err and "needs --camera" in err and "no view files" in err


def test_export_formats():
    from calibration.calibration_file import Calibration
    from controller.geometry.poses import make_pose, rotation_about

    calib = Calibration(CAM, make_pose(rotation_about([1, 2, 3], 0.4), [95.0, -8.0, 60.0]))
    tf = export_hand_eye(calib, "tf").split()
    assert tf[-2:] == ["tool0", "camera_optical_frame"] and len(tf) == 9
    assert abs(float(tf[0]) * 1000 - calib.T_flange_cam[0, 3]) < 1e-3
    m = json.loads(export_hand_eye(calib, "matrix"))
    assert np.allclose(m["T_flange_cam"], calib.T_flange_cam, atol=1e-6)
    abb = export_hand_eye(calib, "abb_tooldata")
    assert abb.startswith("[[95.000,-8.000,60.000],[") and abb.count(",") == 6
    with pytest.raises(CalibrationError, match="fixed in the cell"):
        export_hand_eye(calib, "view_camera_pose")
    with pytest.raises(CalibrationError, match="intrinsics only"):
        export_hand_eye(Calibration(CAM), "tf")


@pytest.mark.slow
def test_teach_cli_mock_robot_auto(tmp_path, capsys):
    """The whole routine from the command line: mock robot on a pty, simulated board camera."""
    from controller.geometry.kinematics import irb2400, solve_ik
    from controller.geometry.poses import invert
    from drivers.sim.sim_board import default_board_pose, default_hand_eye, look_at

    Y = default_board_pose(BOARD)
    centre = Y[:3, :3] @ BOARD.object_points().mean(axis=0) + Y[:3, 3]
    j0 = solve_ik(irb2400(), look_at(centre + np.array([0, 0, 330.0]), centre, 0.0)
                  @ invert(default_hand_eye()))
    # The joints the docs give for this first pose.
    assert np.allclose(j0, [2.9564, 34.4874, 45.5124, 0.7370, 56.4743, 2.4848], atol=1e-3)
    out = tmp_path / "c.yaml"
    rc = main(["calibrate", "--port", "mock://", "--camera", "simboard:?width=640",
               "--board", SPEC, "--output", str(out), "--auto", "6",
               "--first-joints", ",".join(f"{v:.4f}" for v in j0),
               "--save-views", str(tmp_path / "views")])
    captured = capsys.readouterr()
    assert rc == 0, captured.err
    calib = load_calibration(out)
    assert pose_error(calib.T_flange_cam, default_hand_eye())[0] < 0.3
    assert calib.metadata["robot_and_camera"]["robot"]["robot"] == "IRB2400"
    assert "good views" in captured.err and "solved:" in captured.err


def test_intrinsics_fixed_summary_and_a_skipped_view_says_why(folder, session, tmp_path, capsys):
    """--intrinsics FILE: the camera model is used as it is and the report says so; a view
    without a board is named on stderr with the reason; the quality summary is printed."""
    from calibration.calibration_file import Calibration, save_calibration

    views = tmp_path / "views"
    _copy_views(folder, views, [v.name for v in session.views])
    cv2.imwrite(str(views / "view99.png"), np.full((480, 640), 90, np.uint8))
    (views / "view99.json").write_text((views / "view01.json").read_text().replace(
        "view01.png", "view99.png"))
    lens = tmp_path / "lens.yaml"
    save_calibration(lens, Calibration(CAM))
    out = tmp_path / "c.yaml"
    rc = main(["calibrate", "--from-folder", str(views), "--board", SPEC, "--output", str(out),
               "--intrinsics", str(lens), "--holdout-every", "0",
               "--report", str(tmp_path / "r.json")])
    assert rc == 0
    err = capsys.readouterr().err
    assert "view99: NOT USED: no 9x6 chessboard found" in err
    assert "leave-one-out prediction" in err and "noise: corners" in err
    assert f"intrinsics written: fx {CAM.fx:.2f}" in err and f"fixed, from {lens}" in err
    report = json.loads((tmp_path / "r.json").read_text())
    assert report["intrinsics"]["fixed"] and report["intrinsics"]["source"] == str(lens)
    assert not report["hand_eye"]["refined_intrinsics"]
    assert report["intrinsics_written"]["fx"] == round(CAM.fx, 4)
    assert "view99" in report["why_no_board"]
    assert np.allclose(load_calibration(out).camera.K, CAM.K)
    # Intrinsics of another image size are refused, naming both sizes.
    big = tmp_path / "big.yaml"
    save_calibration(big, Calibration(default_camera(1280, 960)))
    rc = main(["calibrate", "--from-folder", str(folder), "--board", SPEC, "--output",
               str(tmp_path / "x.yaml"), "--intrinsics", str(big)])
    assert rc == CalibrationError.exit_code and "for 1280x960 images" in capsys.readouterr().err


def test_refusal_writes_a_report_with_the_options(folder, tmp_path, capsys):
    out = tmp_path / "c.yaml"
    rc = main(["calibrate", "--from-folder", str(folder), "--board", SPEC, "--output", str(out),
               "--max-rms-px", "0.05", "--holdout-every", "0",
               "--report", str(tmp_path / "r.json")])
    assert rc == CalibrationError.exit_code and not out.exists()
    report = json.loads((tmp_path / "r.json").read_text())
    assert report["status"] == "refused" and "hand-eye refused" in report["error"]
    assert any(o.startswith("--max-rms-px") for o in report["options"])
    assert report["intrinsics"]["fx"] > 0 and report["views_total"] == 12
    assert "would change the outcome: --max-rms-px" in capsys.readouterr().err
