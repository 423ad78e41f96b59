"""Loading and checking one camera image, with errors that say what is wrong and what to do.

:func:`load_image` reads a file with OpenCV and runs :func:`check_image`: a file that is missing or
is not an image, a 16-bit or float image, an image that is too small, black (lens cap, no light)
or mostly saturated (over-exposed), or whose size does not match the calibration, raises an
:class:`~controller.errors.InputError` naming the file and the remedy. Images come back as numpy
uint8, greyscale (H, W) or BGR (H, W, 3), as OpenCV reads them (an alpha channel is dropped).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from controller.errors import InputError
from controller.geometry.camera_model import CameraModel

#: Smallest accepted side (px): below this no seam can be told from noise.
MIN_SIDE_PX = 64
#: An image whose 99th percentile grey level is below this is black.
BLACK_P99 = 12
#: An image with more than this fraction of pixels at >= 250 is saturated.
SATURATED_FRACTION = 0.5


def load_image(path: str | os.PathLike[str], *, camera: CameraModel | None = None
               ) -> NDArray[np.uint8]:
    """Read the image at ``path`` and check it (see :func:`check_image`); uint8 grey or BGR.

    Raises :class:`InputError` naming the file when it is missing, unreadable, not an image, or
    fails a check.
    """
    p = Path(path)
    if not p.exists():
        raise InputError(f"image {p}: no such file; check the path", file=str(p))
    if not p.is_file():
        raise InputError(f"image {p}: is a directory, not an image file", file=str(p))
    try:
        data = np.fromfile(str(p), dtype=np.uint8)
    except OSError as err:
        raise InputError(f"image {p}: cannot be read ({err}); check its permissions",
                         file=str(p)) from err
    img = cv2.imdecode(data, cv2.IMREAD_UNCHANGED) if data.size else None
    if img is None:
        raise InputError(f"image {p}: not an image OpenCV can decode (PNG, JPEG, TIFF, BMP...); "
                         "give the camera's image file", file=str(p))
    return check_image(img, name=str(p), camera=camera)


def check_image(img: NDArray[Any], *, name: str = "image",
                camera: CameraModel | None = None) -> NDArray[np.uint8]:
    """Check an image array and return it as uint8 greyscale (H, W) or BGR (H, W, 3).

    ``camera``: when given, the image must be ``camera.width x camera.height``. Raises
    :class:`InputError` (naming ``name``) for a non-8-bit image, a wrong shape, a side below
    :data:`MIN_SIDE_PX`, a black image, a saturated image or a size that does not match.
    """
    arr = np.asarray(img)
    if arr.dtype != np.uint8:
        raise InputError(f"{name}: {arr.dtype} pixels; seamguide takes 8-bit images: save the "
                         "camera image as 8-bit PNG or JPEG", file=name, dtype=str(arr.dtype))
    if arr.ndim == 3 and arr.shape[2] == 4:
        arr = np.asarray(cv2.cvtColor(arr, cv2.COLOR_BGRA2BGR), np.uint8)
    elif arr.ndim == 3 and arr.shape[2] == 1:
        arr = arr[:, :, 0]
    if not (arr.ndim == 2 or (arr.ndim == 3 and arr.shape[2] == 3)):
        raise InputError(f"{name}: shape {arr.shape} is not a greyscale or colour image",
                         file=name, shape=list(arr.shape))
    h, w = arr.shape[:2]
    if min(h, w) < MIN_SIDE_PX:
        raise InputError(f"{name}: {w}x{h} px is too small (at least {MIN_SIDE_PX} px each way); "
                         "give the full camera image, not a thumbnail", file=name, size=[w, h])
    if camera is not None and (w, h) != (camera.width, camera.height):
        raise InputError(f"{name}: {w}x{h} px but the calibration is for "
                         f"{camera.width}x{camera.height} px; use this camera's calibration, or "
                         "the unscaled image it was calibrated with", file=name, size=[w, h],
                         calibration_size=[camera.width, camera.height])
    grey = arr if arr.ndim == 2 else cv2.cvtColor(arr, cv2.COLOR_BGR2GRAY)
    sample = grey[:: max(1, h // 400), :: max(1, w // 400)]
    p99 = float(np.percentile(sample, 99))
    if p99 < BLACK_P99:
        raise InputError(f"{name}: the image is black (99 % of pixels below grey {p99:.0f}); "
                         "check the lens cap, the lighting and the exposure time", file=name,
                         p99=p99)
    sat = float(np.mean(sample >= 250))
    if sat > SATURATED_FRACTION:
        raise InputError(f"{name}: {100 * sat:.0f} % of the image is saturated; reduce the "
                         "exposure time or the gain, or move the light so it does not glare",
                         file=name, saturated_fraction=sat)
    return arr
