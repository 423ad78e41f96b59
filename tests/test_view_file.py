import json

import numpy as np
import pytest

from controller.errors import InputError
from controller.geometry.kinematics import flange_pose, irb2400
from controller.geometry.poses import make_pose, pose_error, rotation_about
from controller.geometry.view_file import load_view, view_to_dict


@pytest.fixture
def folder(tmp_path):
    (tmp_path / "img.png").write_bytes(b"not really a png")
    return tmp_path


def write(folder, doc, name="v.json"):
    p = folder / name
    p.write_text(json.dumps(doc))
    return p


def test_flange_pose_view(folder):
    T = make_pose(rotation_about([0, 1, 0], 0.4), [900, 10, 800])
    v = load_view(write(folder, view_to_dict("img.png", T_base_flange=T)))
    assert v.image_path == folder / "img.png" and v.name == "v"
    assert pose_error(v.T_base_flange, T)[0] < 1e-5 and v.T_base_cam is None


def test_joints_view(folder):
    j = np.array([10, 20, -10, 30, 40, 50.0])
    v = load_view(write(folder, view_to_dict("img.png", joints_deg=j)))
    assert np.allclose(v.joints_deg, j)
    assert pose_error(v.T_base_flange, flange_pose(irb2400(), j))[0] < 1e-9


def test_camera_pose_view(folder):
    T = make_pose(t_mm=[1, 2, 3])
    v = load_view(write(folder, view_to_dict("img.png", T_base_cam=T)))
    assert v.T_base_flange is None and pose_error(v.T_base_cam, T)[0] < 1e-9


def test_image_relative_to_view_folder(folder, monkeypatch, tmp_path_factory):
    monkeypatch.chdir(tmp_path_factory.mktemp("elsewhere"))
    v = load_view(write(folder, {"image": "img.png", "joints_deg": [0, 0, 0, 0, 0, 0]}))
    assert v.image_path.is_file()


@pytest.mark.parametrize("doc, key", [
    ({"joints_deg": [0, 0, 0, 0, 0, 0]}, "image"),
    ({"image": "missing.png", "joints_deg": [0] * 6}, "image"),
    ({"image": "img.png"}, "flange_pose/joints_deg/camera_pose"),
    ({"image": "img.png", "joints_deg": [0] * 6,
      "flange_pose": {"position_mm": [0, 0, 0], "quaternion_wxyz": [1, 0, 0, 0]}},
     "flange_pose/joints_deg/camera_pose"),
    ({"image": "img.png", "joints_deg": [0] * 5}, "joints_deg"),
    ({"image": "img.png", "joints_deg": [0, 0, 0, 0, 0, 999]}, "joints_deg"),
    ({"image": "img.png", "flange_pose": {"position_mm": [0, 0, 0]}}, "flange_pose"),
    ({"image": "img.png",
      "flange_pose": {"position_mm": [0, 0, 0], "quaternion_wxyz": [2, 0, 0, 0]}},
     "flange_pose"),
])
def test_errors_name_file_and_key(folder, doc, key):
    p = write(folder, doc)
    with pytest.raises(InputError) as e:
        load_view(p)
    assert str(p) in str(e.value) and key in str(e.value)


def test_not_json(folder):
    p = folder / "v.json"
    p.write_text("{nope")
    with pytest.raises(InputError, match="not valid JSON"):
        load_view(p)
    with pytest.raises(InputError, match="does not exist"):
        load_view(folder / "none.json")


def test_camera_named_view(folder):
    T = make_pose(t_mm=[1, 2, 3])
    v = load_view(write(folder, view_to_dict("img.png", T_base_cam=T, camera="left")))
    assert v.camera == "left" and pose_error(v.T_base_cam, T)[0] < 1e-9
    # A fixed camera's view may give no pose: its calibration has it.
    v = load_view(write(folder, view_to_dict("img.png", camera="right")))
    assert v.camera == "right" and v.T_base_cam is None and v.T_base_flange is None
    j = np.array([10, 20, -10, 30, 40, 50.0])
    v = load_view(write(folder, view_to_dict("img.png", joints_deg=j, camera="wrist")))
    assert v.camera == "wrist" and v.T_base_flange is not None


@pytest.mark.parametrize("name", ["", "a b", "-x", 7, "x" * 65, "../cam"])
def test_bad_camera_name(folder, name):
    p = write(folder, {"image": "img.png", "camera": name})
    with pytest.raises(InputError) as e:
        load_view(p)
    assert str(p) in str(e.value) and "camera" in str(e.value)
