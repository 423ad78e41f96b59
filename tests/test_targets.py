
import cv2
import numpy as np
import pytest
from shared_data import CHESSBOARD, needs

from calibration.targets import BoardSpec, detect_board, parse_board_spec
from controller.errors import ConfigError, InputError
from controller.geometry.camera_model import default_camera
from controller.geometry.poses import make_pose, rotation_about
from drivers.sim.sim_board import render_board, true_corners

DATA = CHESSBOARD
CAM = default_camera(640, 480)


def board_pose(board: BoardSpec, roll: float = 0.2, tilt: float = 0.3, dist: float = 330.0):
    c = board.object_points().mean(axis=0)
    R = rotation_about([1, 0, 0], tilt) @ rotation_about([0, 0, 1], roll)
    return make_pose(R, np.array([0, 0, dist]) - R @ c)


def test_parse_chessboard():
    b = parse_board_spec("chessboard:9x6:25")
    assert (b.kind, b.cols, b.rows, b.square_mm) == ("chessboard", 9, 6, 25.0)
    assert b.n_corners == 54 and b.spec == "chessboard:9x6:25"
    pts = b.object_points()
    assert pts.shape == (54, 3)
    assert np.allclose(pts[1] - pts[0], [25, 0, 0]) and np.allclose(pts[9] - pts[0], [0, 25, 0])
    assert not b.orientation_ambiguous
    assert parse_board_spec("chessboard:8x6:20").orientation_ambiguous


def test_parse_charuco():
    b = parse_board_spec("charuco:8x6:25:18:DICT_5X5_100")
    assert b.corner_grid == (7, 5) and b.n_corners == 35
    ref = np.asarray(b.charuco_board.getChessboardCorners())
    assert np.allclose(b.object_points(), ref)
    assert parse_board_spec(b.spec) == b


@pytest.mark.parametrize("spec", [
    "", "circles:4x11:20", "chessboard:9x6", "chessboard:9by6:25", "chessboard:1x6:25",
    "chessboard:9x6:-3", "chessboard:9x6:abc", "charuco:8x6:25:30:DICT_5X5_100",
    "charuco:8x6:25:18:DICT_NOPE", "charuco:8x6:25:18", "charuco:30x30:10:7:DICT_4X4_50"])
def test_bad_specs(spec):
    with pytest.raises(ConfigError) as e:
        parse_board_spec(spec)
    assert repr(spec)[1:-1] in str(e.value) or "board spec" in str(e.value)


@pytest.mark.parametrize("spec", ["chessboard:9x6:20", "charuco:8x6:22:16:DICT_5X5_100"])
@pytest.mark.parametrize("roll", [0.2, 0.2 + np.pi, 1.7])
def test_detect_simulated(spec, roll):
    b = parse_board_spec(spec)
    T = board_pose(b, roll=roll)
    img = render_board(CAM, b, T, seed=3)
    d = detect_board(img, b)
    assert d is not None and len(d) == b.n_corners
    uv, inside = true_corners(CAM, b, T)
    err = np.linalg.norm(d.image_points - uv[d.ids], axis=1)
    # Canonical order (the same physical corner has the same id for any roll) and sub-pixel.
    assert np.sqrt(np.mean(err ** 2)) < 0.15 and err.max() < 0.4
    assert np.allclose(d.object_points, b.object_points()[d.ids])


def test_no_board_is_none():
    b = parse_board_spec("chessboard:9x6:20")
    rng = np.random.default_rng(0)
    assert detect_board(rng.integers(0, 255, (480, 640), dtype=np.uint8), b) is None
    assert detect_board(np.full((480, 640, 3), 128, np.uint8), b) is None


def test_bad_image():
    b = parse_board_spec("chessboard:9x6:20")
    with pytest.raises(InputError):
        detect_board(np.zeros((10, 10), np.float32), b)


def test_charuco_partial_view():
    b = parse_board_spec("charuco:8x6:22:16:DICT_5X5_100")
    T = board_pose(b)
    T[0, 3] += 120  # push the board partly out of the image
    d = detect_board(render_board(CAM, b, T, seed=1), b)
    uv, inside = true_corners(CAM, b, T)
    assert d is not None and 6 <= len(d) < b.n_corners
    assert np.all(inside[d.ids])
    assert np.abs(d.image_points - uv[d.ids]).max() < 0.5


@needs(DATA)
def test_real_chessboard_images():
    b = parse_board_spec("chessboard:9x6:25")
    found = 0
    for p in sorted(DATA.glob("left0*.jpg"))[:5]:
        d = detect_board(cv2.imread(str(p), cv2.IMREAD_GRAYSCALE), b)
        if d is not None:
            found += 1
            g = d.image_points.reshape(6, 9, 2)
            # Handedness of the canonical order: x along columns, y along rows, seen from the front.
            a, c = g[0, 1] - g[0, 0], g[1, 0] - g[0, 0]
            assert a[0] * c[1] - a[1] * c[0] > 0
    assert found == 5
