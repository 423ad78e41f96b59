import numpy as np
import pytest
import yaml

from calibration.calibration_file import Calibration, load_calibration, save_calibration
from controller.errors import CalibrationError
from controller.geometry.camera_model import default_camera
from controller.geometry.poses import make_pose, pose_error, rotation_about


@pytest.fixture
def calib():
    return Calibration(default_camera(), make_pose(rotation_about([0, 0, 1], 0.3), [10, 20, 150]),
                       metadata={"date": "2026-11-22"})


def test_round_trip(tmp_path, calib):
    p = tmp_path / "c.yaml"
    save_calibration(p, calib)
    back = load_calibration(p)
    assert np.allclose(back.camera.K, calib.camera.K)
    assert np.allclose(back.camera.dist, calib.camera.dist)
    assert (back.camera.width, back.camera.height) == (calib.camera.width, calib.camera.height)
    assert pose_error(back.T_flange_cam, calib.T_flange_cam)[0] < 1e-12
    assert back.metadata["date"] == "2026-11-22"
    doc = yaml.safe_load(p.read_text())
    assert doc["camera_matrix"]["rows"] == 3 and len(doc["camera_matrix"]["data"]) == 9
    assert doc["distortion_model"] == "plumb_bob"
    assert set(doc["hand_eye"]) == {"translation_mm", "quaternion_wxyz"}


def test_previous_file_kept(tmp_path, calib):
    p = tmp_path / "c.yaml"
    save_calibration(p, calib)
    first = p.read_text()
    calib.metadata["date"] = "2026-11-23"
    prev = save_calibration(p, calib)
    assert prev is not None and prev.read_text() == first


def test_unknown_keys_survive(tmp_path, calib):
    p = tmp_path / "c.yaml"
    save_calibration(p, calib)
    doc = yaml.safe_load(p.read_text())
    doc["site"] = "cell 3"
    p.write_text(yaml.safe_dump(doc))
    back = load_calibration(p)
    save_calibration(p, back)
    assert yaml.safe_load(p.read_text())["site"] == "cell 3"


def _broken(tmp_path, calib, mutate):
    p = tmp_path / "c.yaml"
    save_calibration(p, calib)
    doc = yaml.safe_load(p.read_text())
    mutate(doc)
    p.write_text(yaml.safe_dump(doc))
    return p


@pytest.mark.parametrize("mutate,key", [
    (lambda d: d.pop("camera_matrix"), "camera_matrix"),
    (lambda d: d.pop("image_width"), "image_width"),
    (lambda d: d["camera_matrix"].update(data=[1, 2, 3]), "camera_matrix"),
    (lambda d: d["camera_matrix"]["data"].__setitem__(0, -5.0), "camera_matrix"),
    (lambda d: d["distortion_coefficients"].update(data=[0.1]), "distortion_coefficients"),
    (lambda d: d["hand_eye"].update(quaternion_wxyz=[1, 1, 1, 1]), "hand_eye.quaternion_wxyz"),
    (lambda d: d["hand_eye"].pop("translation_mm"), "hand_eye.translation_mm"),
    (lambda d: d.update(distortion_model="fisheye"), "distortion_model"),
    (lambda d: d.update(image_height=0), "image_height"),
    (lambda d: d.update(camera_pose=d["hand_eye"]), "hand_eye/camera_pose"),
    # the bottom row of K must be 0 0 1, and K[1, 0] zero (a transposed matrix is caught)
    (lambda d: d["camera_matrix"]["data"].__setitem__(8, 2.0), "camera_matrix"),
    (lambda d: d["camera_matrix"]["data"].__setitem__(6, 0.5), "camera_matrix"),
    (lambda d: d["camera_matrix"]["data"].__setitem__(7, 0.5), "camera_matrix"),
    (lambda d: d["camera_matrix"]["data"].__setitem__(3, 0.5), "camera_matrix"),
    (lambda d: d["hand_eye"]["translation_mm"].__setitem__(1, float("nan")),
     "hand_eye.translation_mm"),
    (lambda d: d["hand_eye"]["translation_mm"].__setitem__(2, float("inf")),
     "hand_eye.translation_mm"),
    (lambda d: d["hand_eye"]["translation_mm"].__setitem__(0, "a"), "hand_eye.translation_mm"),
    (lambda d: d["hand_eye"]["translation_mm"].__setitem__(0, None), "hand_eye.translation_mm"),
    (lambda d: d["camera_matrix"]["data"].__setitem__(4, 0.0), "camera_matrix"),  # fy = 0
    (lambda d: d["camera_matrix"].pop("data"), "camera_matrix"),
    (lambda d: d["camera_matrix"]["data"].__setitem__(2, "a"), "camera_matrix"),
    (lambda d: d["camera_matrix"]["data"].__setitem__(2, None), "camera_matrix"),
    (lambda d: d["camera_matrix"].update(rows=2), "camera_matrix"),
    (lambda d: d.update(image_width=True), "image_width"),
    (lambda d: d.update(image_width=12.5), "image_width"),
])
def test_invalid_file_names_key_and_file(tmp_path, calib, mutate, key):
    p = _broken(tmp_path, calib, mutate)
    with pytest.raises(CalibrationError) as info:
        load_calibration(p)
    assert f"{key}:" in str(info.value) and str(p) in str(info.value)


def test_missing_and_non_yaml_files(tmp_path):
    with pytest.raises(CalibrationError, match="does not exist"):
        load_calibration(tmp_path / "nope.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_text("image_width: [unclosed")
    with pytest.raises(CalibrationError, match="not valid YAML"):
        load_calibration(bad)
    bad.write_text("- just\n- a list\n")
    with pytest.raises(CalibrationError, match="mapping"):
        load_calibration(bad)


def test_four_distortion_coefficients_are_plumb_bob_without_k3(tmp_path, calib):
    p = _broken(tmp_path, calib, lambda d: d["distortion_coefficients"].update(
        cols=4, data=[0.01, -0.02, 0.0, 0.0]))
    assert np.allclose(load_calibration(p).camera.dist[:4], [0.01, -0.02, 0.0, 0.0])
