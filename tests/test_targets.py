
import cv2
import numpy as np
import pytest
from shared_data import CHESSBOARD, needs

from calibration.chessboard_detect import RING_MIN_FRACTION, ring_fraction
from calibration.targets import BoardSpec, detect_board, detect_board_explained, parse_board_spec
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
    # Small images: every detector setting runs on an image without a board (a few seconds here).
    assert detect_board(rng.integers(0, 255, (240, 320), dtype=np.uint8), b) is None
    assert detect_board(np.full((240, 320, 3), 128, np.uint8), b) is None


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


def test_squares_given_instead_of_inner_corners():
    """A 9x6 board (10x7 squares) given as 10x7, or as 8x5: no board, and the message says which
    size is in the image and that COLSxROWS counts inner corners."""
    b = parse_board_spec("chessboard:9x6:20")
    img = render_board(CAM, b, board_pose(b), seed=2)
    for spec in ("chessboard:10x7:20", "chessboard:8x5:20"):
        d, why = detect_board_explained(img, parse_board_spec(spec))
        assert d is None
        assert "INNER corners" in why and "but a 9x6 one is" in why, why


def test_ring_check_tells_a_board_from_its_edge():
    """The squares around a true grid alternate; around a grid whose outer row is the board's
    edge (what a board given in squares can produce) half of them are the white margin."""
    b = parse_board_spec("chessboard:9x6:20")
    T = board_pose(b, tilt=0.2)
    img = render_board(CAM, b, T, seed=4)
    uv, _ = true_corners(CAM, b, T)
    assert ring_fraction(img, uv, 9, 6) > 0.95
    # The 11x8 grid of the checkered area's corners, its outer row on the board's edge.
    edge = parse_board_spec("chessboard:11x8:20")
    T_edge = T @ make_pose(np.eye(3), [-20.0, -20.0, 0.0])
    uv_edge, inside = true_corners(CAM, edge, T_edge)
    assert inside.all()
    assert ring_fraction(img, uv_edge, 11, 8) < RING_MIN_FRACTION


def test_cascade_falls_back_when_the_first_detector_misses(monkeypatch):
    """The normalised SB detector missing a board (as it did on ten real 28x17 views) is not the
    end: the next settings find it, and the reason names the one that did."""
    import calibration.chessboard_detect as cd

    b = parse_board_spec("chessboard:9x6:20")
    T = board_pose(b)
    img = render_board(CAM, b, T, seed=5)
    monkeypatch.setattr(cd, "CASCADE", [("SB normalised", lambda g, p: None), *cd.CASCADE[1:]])
    d, why = detect_board_explained(img, b)
    assert d is not None and why == "found (SB)"
    uv, _ = true_corners(CAM, b, T)
    assert np.sqrt(np.mean(np.sum((d.image_points - uv) ** 2, axis=1))) < 0.15


def steep_28x17_views(n, seed, width=960, height=None):
    """``n`` rendered views of a 28x17 board (20 mm squares) tilted 40-60 deg from its normal,
    whole in the image, with varied light, blur and noise; a list of (camera, board, image,
    T_cam_board). The camera is the 2272x1704 one scaled to ``width`` (4:3), or with ``height``
    :func:`default_camera` of that size (the same 44 deg horizontal field)."""
    from controller.geometry.poses import invert
    from drivers.sim.sim_board import default_board_pose, look_at

    cam = (default_camera(2272, 1704).scaled(width / 2272) if height is None
           else default_camera(width, height))
    b = parse_board_spec("chessboard:28x17:20")
    Y = default_board_pose(b)
    centre = Y[:3, :3] @ b.object_points().mean(axis=0) + Y[:3, 3]
    rng = np.random.default_rng(seed)
    w, h = b.size_mm
    dist0 = max(w, h) / 0.7 * cam.fx / cam.width
    out = []
    while len(out) < n:
        az, tilt = rng.uniform(0, 2 * np.pi), np.radians(rng.uniform(40, 60))
        eye = centre + dist0 * rng.uniform(0.8, 1.2) * np.array(
            [np.sin(tilt) * np.cos(az), np.sin(tilt) * np.sin(az), np.cos(tilt)])
        target = centre + np.array([rng.uniform(-0.2, 0.2) * w, rng.uniform(-0.2, 0.2) * h, 0])
        T = invert(look_at(eye, target, np.radians(rng.uniform(-35, 35)))) @ Y
        if not true_corners(cam, b, T)[1].all():
            continue
        img = render_board(cam, b, T, seed=len(out), blur_sigma_px=rng.uniform(0, 1.2),
                           illumination=rng.uniform(0.35, 1.1), gain_dark=rng.uniform(0, 0.3),
                           noise_sigma=rng.uniform(1, 3))
        out.append((cam, b, img, T))
    return out


def test_steep_28x17_board_found_wherever_opencv_finds_it():
    """bench/bench_calibration_noise.py --steep runs this on 1920x1200 images and more views; here
    three views at 960 px (the first view of seed 1, which no detector finds, is skipped: a
    failing search costs half a minute here and shows nothing about this property)."""
    opencv_found = 0
    for cam, b, img, T in steep_28x17_views(4, seed=1)[1:]:
        classic = cv2.findChessboardCorners(img, (28, 17))[0]
        sb = cv2.findChessboardCornersSB(img, (28, 17))[0]
        d, why = detect_board_explained(img, b)
        if classic or sb:
            opencv_found += 1
            assert d is not None, why
        if d is not None:
            uv, _ = true_corners(cam, b, T)
            assert np.sqrt(np.mean(np.sum((d.image_points - uv) ** 2, axis=1))) < 0.2
    assert opencv_found == 3


def test_square_size_in_metres_refused():
    with pytest.raises(ConfigError, match="metres"):
        parse_board_spec("chessboard:9x6:0.025")
