"""Cameras behind one small interface, opened by URL through an explicit registry.

``open_camera(url, **kwargs)`` returns a :class:`Camera` whose ``grab()`` gives one uint8 frame
(greyscale (H, W) or BGR (H, W, 3), as OpenCV reads them). Schemes:

- ``sim:?kind=arc&seed=3&difficulty=medium`` renders the simulated workpiece
  (:mod:`drivers.sim.sim_render`) from the pose given by ``pose_source()`` at each grab. Keyword
  arguments: ``pose_source`` (callable returning ``T_base_cam``, required), ``scene`` (a
  :class:`~drivers.sim.sim_scene.Scene`; when absent one is made from ``kind``/``seed``/
  ``difficulty`` in the URL), ``camera_model`` (default ``default_camera()``). URL options:
  ``kind``, ``seed``, ``difficulty``, ``ss`` (supersampling). Frame n uses noise seed
  ``seed + n``: the same URL and poses give the same frames.
- ``files:/path/*.png`` cycles through the sorted files matching the pattern.
- ``opencv:0`` a real camera through ``cv2.VideoCapture`` (index or device path or stream URL).

Constructing a camera only checks its URL (an unknown scheme or option is a :class:`ConfigError`
listing the known ones); ``open()`` acquires the device or files, as pyserial's ``Serial`` does
with ``do_not_open``. ``open_camera`` does both. A camera that cannot be opened or does not
deliver a frame raises :class:`CameraError`.

What the simulated camera does not model: exposure control, frame timing, dropped frames.
"""

from __future__ import annotations

import glob
import importlib
from collections.abc import Callable
from pathlib import Path
from types import TracebackType
from typing import Any
from urllib.parse import parse_qsl

import cv2
import numpy as np
from numpy.typing import NDArray

from controller.errors import CameraError, ConfigError


class Camera:
    """One camera: ``open()`` it, ``grab()`` frames, ``close()`` it; a context manager."""

    url: str = ""

    def open(self) -> Camera:
        """Acquire the device (or files); returns self. Raises :class:`CameraError`."""
        return self

    def grab(self) -> NDArray[np.uint8]:
        """One frame, uint8 greyscale (H, W) or BGR (H, W, 3); raises :class:`CameraError`."""
        raise NotImplementedError

    def close(self) -> None:
        """Release the camera; grabbing afterwards raises :class:`CameraError`."""

    def __enter__(self) -> Camera:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()


def _split(url: str, scheme: str) -> tuple[str, dict[str, str]]:
    rest = url[len(scheme) + 1:]
    path, _, query = rest.partition("?")
    return path, dict(parse_qsl(query, keep_blank_values=True))


class SimCamera(Camera):
    """Renders the simulated workpiece from ``pose_source()`` at each grab (see module doc)."""

    OPTIONS = ("kind", "seed", "difficulty", "ss")

    def __init__(self, url: str, *, pose_source: Callable[[], NDArray[np.float64]] | None = None,
                 scene: Any = None, camera_model: Any = None) -> None:
        from controller.geometry.camera_model import default_camera
        from drivers.sim.sim_scene import make_scene

        self.url = url
        _, opts = _split(url, "sim")
        unknown = set(opts) - set(self.OPTIONS)
        if unknown:
            raise ConfigError(f"camera {url}: unknown option(s) {sorted(unknown)}; known: "
                              f"{', '.join(self.OPTIONS)}")
        if pose_source is None or not callable(pose_source):
            raise ConfigError(f"camera {url}: a sim: camera needs pose_source, a callable "
                              "returning the camera pose T_base_cam (4x4, mm)")
        try:
            self._seed = int(opts.get("seed", "0"))
            self._ss = int(opts.get("ss", "1"))
        except ValueError as err:
            raise ConfigError(f"camera {url}: seed and ss must be integers") from err
        self.scene = scene if scene is not None else make_scene(
            opts.get("kind", "straight"), self._seed, opts.get("difficulty", "medium"))
        self.camera_model = camera_model if camera_model is not None else default_camera()
        self._pose_source = pose_source
        self._frames = 0
        self._closed = False
        #: Ground truth of the last frame (a drivers.sim.sim_render.Rendered), for tests and dry
        #: runs.
        self.last: Any = None

    def grab(self) -> NDArray[np.uint8]:
        """Render one frame from the current pose; raises :class:`CameraError` when closed."""
        from drivers.sim.sim_render import render

        if self._closed:
            raise CameraError(f"camera {self.url}: grab after close")
        try:
            T = np.asarray(self._pose_source(), dtype=np.float64)
        except Exception as err:  # the pose source is user code: report it as a camera fault
            raise CameraError(f"camera {self.url}: pose_source failed: {err}") from err
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            raise CameraError(f"camera {self.url}: pose_source returned {T.shape}, not a finite "
                              "4x4 pose T_base_cam")
        self.last = render(self.scene, self.camera_model, T, seed=self._seed + self._frames,
                           ss=self._ss)
        self._frames += 1
        return np.asarray(self.last.image)

    def close(self) -> None:
        """Mark closed (nothing to release)."""
        self._closed = True


class FilesCamera(Camera):
    """Cycles through the sorted image files matching a glob pattern: ``files:/dir/*.png``."""

    def __init__(self, url: str) -> None:
        self.url = url
        pattern, opts = _split(url, "files")
        if opts:
            raise ConfigError(f"camera {url}: files: takes no options, got {sorted(opts)}")
        self._pattern = pattern
        self.files: list[str] = []
        self._i = 0
        self._closed = True

    def open(self) -> FilesCamera:
        """List the matching files; raises :class:`CameraError` when none match."""
        self.files = sorted(glob.glob(self._pattern))
        if not self.files:
            raise CameraError(f"camera {self.url}: no file matches {self._pattern!r}; check the "
                              "folder and the pattern (e.g. files:/data/views/*.png)")
        self._i = 0
        self._closed = False
        return self

    def grab(self) -> NDArray[np.uint8]:
        """The next file's image (after the last, the first again)."""
        if self._closed:
            raise CameraError(f"camera {self.url}: not open (open() it, or use open_camera)")
        path = self.files[self._i % len(self.files)]
        self._i += 1
        img = cv2.imread(path, cv2.IMREAD_UNCHANGED) if Path(path).is_file() else None
        if img is None:
            raise CameraError(f"camera {self.url}: {path} is not a readable image")
        if img.dtype != np.uint8:
            raise CameraError(f"camera {self.url}: {path} has {img.dtype} pixels; give 8-bit "
                              "images")
        if img.ndim == 3 and img.shape[2] == 4:
            img = cv2.cvtColor(img, cv2.COLOR_BGRA2BGR)
        return np.asarray(img, dtype=np.uint8)

    def close(self) -> None:
        """Mark closed."""
        self._closed = True


class OpenCVCamera(Camera):
    """A real camera through ``cv2.VideoCapture``: ``opencv:0`` or ``opencv:/dev/video2``."""

    def __init__(self, url: str) -> None:
        self.url = url
        target, opts = _split(url, "opencv")
        if opts:
            raise ConfigError(f"camera {url}: opencv: takes no options, got {sorted(opts)}")
        self._source: int | str = int(target) if target.isdigit() else target
        self._cap: cv2.VideoCapture | None = None

    def open(self) -> OpenCVCamera:
        """Open the capture device; raises :class:`CameraError` when it cannot be opened."""
        cap = cv2.VideoCapture(self._source)
        if not cap.isOpened():
            cap.release()
            raise CameraError(f"camera {self.url}: cannot open {self._source!r}; check that the "
                              "camera is connected and not used by another program")
        self._cap = cap
        return self

    def grab(self) -> NDArray[np.uint8]:
        """Read one frame; raises :class:`CameraError` when the camera delivers none."""
        ok, frame = self._cap.read() if self._cap is not None else (False, None)
        if not ok or frame is None:
            raise CameraError(f"camera {self.url}: no frame delivered")
        return np.asarray(frame, dtype=np.uint8)

    def close(self) -> None:
        """Release the capture device."""
        if self._cap is not None:
            self._cap.release()
            self._cap = None


#: The explicit registry: URL scheme -> "module:class", imported when used.
CAMERA_SCHEMES: dict[str, str] = {
    "sim": "drivers.cameras:SimCamera",
    "files": "drivers.cameras:FilesCamera",
    "opencv": "drivers.cameras:OpenCVCamera",
}


def open_camera(url: str, **kwargs: Any) -> Camera:
    """Construct and open the camera named by ``url`` (``sim:...``, ``files:...``, ``opencv:...``).

    Keyword arguments go to the camera class (only ``sim:`` takes any). Raises
    :class:`ConfigError` for an unknown scheme (listing the known ones) or option, and
    :class:`CameraError` when the camera cannot be opened.
    """
    scheme, sep, _ = url.partition(":")
    if not sep or scheme not in CAMERA_SCHEMES:
        raise ConfigError(f"camera URL {url!r}: unknown scheme {scheme!r}; known: "
                          + ", ".join(f"{s}:" for s in CAMERA_SCHEMES))
    module, _, cls = CAMERA_SCHEMES[scheme].partition(":")
    factory = getattr(importlib.import_module(module), cls)
    if kwargs and scheme != "sim":
        raise ConfigError(f"camera URL {url!r}: {scheme}: takes no keyword arguments, got "
                          f"{sorted(kwargs)}")
    camera: Camera = factory(url, **kwargs)
    return camera.open()
