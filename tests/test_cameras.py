import cv2
import numpy as np
import pytest

from controller.errors import CameraError, ConfigError
from controller.geometry.camera_model import default_camera
from drivers.cameras import CAMERA_SCHEMES, Camera, open_camera
from drivers.sim.sim_render import suggest_view_poses
from drivers.sim.sim_scene import make_scene

CAM = default_camera().scaled(0.25)
SCENE = make_scene("straight", 1, "easy")
POSE = suggest_view_poses(SCENE, CAM)[0]


@pytest.fixture
def image_dir(tmp_path):
    for i in (2, 0, 1):
        img = np.full((80, 100), 40 + 60 * i, np.uint8)
        cv2.imwrite(str(tmp_path / f"frame{i}.png"), img)
    return tmp_path


def _open(kind, image_dir):
    if kind == "sim":
        return open_camera("sim:?seed=1", scene=SCENE, camera_model=CAM, pose_source=lambda: POSE)
    return open_camera(f"files:{image_dir}/*.png")


@pytest.mark.parametrize("kind", ["sim", "files"])
def test_camera_contract(kind, image_dir):
    with _open(kind, image_dir) as cam:
        assert isinstance(cam, Camera)
        frame = cam.grab()
        assert frame.dtype == np.uint8 and frame.ndim in (2, 3) and frame.size > 0
        assert cam.grab().shape == frame.shape
    with pytest.raises(CameraError):
        cam.grab()


def test_files_camera_cycles_in_sorted_order(image_dir):
    cam = open_camera(f"files:{image_dir}/*.png")
    means = [int(cam.grab().mean()) for _ in range(4)]
    assert means == [40, 100, 160, 40]


def test_files_camera_errors(tmp_path):
    with pytest.raises(CameraError, match="no file matches"):
        open_camera(f"files:{tmp_path}/*.png")
    (tmp_path / "bad.png").write_text("not an image")
    cam = open_camera(f"files:{tmp_path}/*.png")
    with pytest.raises(CameraError, match="not a readable image"):
        cam.grab()


def test_sim_camera_is_deterministic_and_follows_the_pose():
    poses = [POSE]
    a = open_camera("sim:?seed=4", scene=SCENE, camera_model=CAM, pose_source=lambda: poses[0])
    b = open_camera("sim:?seed=4", scene=SCENE, camera_model=CAM, pose_source=lambda: poses[0])
    f1, g1 = a.grab(), b.grab()
    assert np.array_equal(f1, g1)
    assert a.last is not None and len(a.last.seam_px) > 10
    poses[0] = POSE.copy()
    poses[0][:3, 3] += POSE[:3, 1] * 40.0
    f2 = a.grab()
    assert np.abs(f2.astype(int) - f1.astype(int)).mean() > 5  # the view moved


def test_sim_camera_builds_its_scene_from_the_url():
    cam = open_camera("sim:?kind=arc&seed=2&difficulty=hard", camera_model=CAM,
                      pose_source=lambda: suggest_view_poses(make_scene("arc", 2, "hard"), CAM)[0])
    assert cam.scene.kind == "arc" and cam.scene.difficulty == "hard"


def test_registry_errors():
    with pytest.raises(ConfigError) as err:
        open_camera("gige:0")
    for scheme in CAMERA_SCHEMES:
        assert f"{scheme}:" in str(err.value)
    with pytest.raises(ConfigError, match="unknown option"):
        open_camera("sim:?sed=3", pose_source=lambda: POSE)
    with pytest.raises(ConfigError, match="pose_source"):
        open_camera("sim:")
    with pytest.raises(ConfigError, match="keyword"):
        open_camera("files:/tmp/*.png", scene=SCENE)
    with pytest.raises(ConfigError, match="unknown scheme"):
        open_camera("no-colon-here")


def test_sim_camera_bad_pose_source_is_a_camera_error():
    cam = open_camera("sim:", scene=SCENE, camera_model=CAM, pose_source=lambda: np.eye(3))
    with pytest.raises(CameraError, match="4x4"):
        cam.grab()

    def broken():
        raise RuntimeError("robot gone")

    cam = open_camera("sim:", scene=SCENE, camera_model=CAM, pose_source=broken)
    with pytest.raises(CameraError, match="robot gone"):
        cam.grab()


def test_opencv_camera_that_does_not_exist(tmp_path):
    with pytest.raises(CameraError, match="cannot open"):
        open_camera(f"opencv:{tmp_path}/no_such_video_device")


def test_constructing_a_camera_opens_nothing(image_dir, tmp_path):
    from drivers.cameras import FilesCamera, OpenCVCamera

    cam = OpenCVCamera(f"opencv:{tmp_path}/no_such_video_device")  # no device touched yet
    with pytest.raises(CameraError, match="no frame"):
        cam.grab()
    with pytest.raises(CameraError, match="cannot open"):
        cam.open()
    files = FilesCamera(f"files:{image_dir}/*.png")
    with pytest.raises(CameraError, match="not open"):
        files.grab()
    with files.open() as opened:
        assert opened.grab().shape == (80, 100)
