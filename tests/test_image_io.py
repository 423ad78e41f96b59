import cv2
import numpy as np
import pytest

from controller.errors import InputError
from controller.geometry.camera_model import default_camera
from controller.vision.image_io import check_image, load_image


def _write(path, img):
    assert cv2.imwrite(str(path), img)
    return path


def _texture(h=200, w=300):
    rng = np.random.default_rng(0)
    return rng.integers(30, 220, (h, w), dtype=np.uint8)


def test_good_image_loads_grey_and_colour(tmp_path):
    g = load_image(_write(tmp_path / "g.png", _texture()))
    assert g.dtype == np.uint8 and g.shape == (200, 300)
    bgr = cv2.merge([_texture()] * 3)
    c = load_image(_write(tmp_path / "c.png", bgr))
    assert c.shape == (200, 300, 3)
    bgra = cv2.merge([_texture()] * 4)
    assert load_image(_write(tmp_path / "a.png", bgra)).shape == (200, 300, 3)


def test_missing_file_and_directory(tmp_path):
    with pytest.raises(InputError, match="no such file") as err:
        load_image(tmp_path / "nope.png")
    assert "nope.png" in str(err.value)
    with pytest.raises(InputError, match="directory"):
        load_image(tmp_path)


@pytest.mark.parametrize("content", [b"", b"hello, not an image\n", b"\x89PNG\r\n\x1a\n broken"])
def test_non_image_file(tmp_path, content):
    p = tmp_path / "view1.png"
    p.write_bytes(content)
    with pytest.raises(InputError, match="not an image") as err:
        load_image(p)
    assert str(p) in str(err.value) and err.value.details["file"] == str(p)


def test_black_image(tmp_path):
    img = np.random.default_rng(1).integers(0, 6, (200, 300), dtype=np.uint8)
    with pytest.raises(InputError, match="black.*lens cap"):
        load_image(_write(tmp_path / "black.png", img))


def test_saturated_image(tmp_path):
    img = np.full((200, 300), 255, np.uint8)
    img[:50] = 100
    with pytest.raises(InputError, match="saturated.*exposure"):
        load_image(_write(tmp_path / "sat.png", img))


def test_tiny_image(tmp_path):
    with pytest.raises(InputError, match="too small"):
        load_image(_write(tmp_path / "tiny.png", _texture(40, 300)))


def test_wrong_size_against_calibration(tmp_path):
    cam = default_camera(400, 300)
    p = _write(tmp_path / "img.png", _texture(200, 300))
    with pytest.raises(InputError, match="300x200 px but the calibration is for 400x300"):
        load_image(p, camera=cam)
    assert load_image(_write(tmp_path / "ok.png", _texture(300, 400)), camera=cam).shape == (300,
                                                                                          400)


def test_sixteen_bit_and_float_images(tmp_path):
    img16 = (_texture().astype(np.uint16) * 256)
    with pytest.raises(InputError, match="8-bit"):
        load_image(_write(tmp_path / "deep.png", img16))
    with pytest.raises(InputError, match="8-bit"):
        check_image(np.zeros((100, 100), np.float32))
    with pytest.raises(InputError, match="shape"):
        check_image(np.zeros((100, 100, 2), np.uint8))
