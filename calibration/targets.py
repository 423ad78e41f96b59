"""Calibration targets: board specs, board geometry in the board frame, and corner detection.

Two kinds of board, written as a ``SPEC`` string on the command line:

- ``chessboard:COLSxROWS:SQUARE_MM`` -- COLS x ROWS *inner* corners (OpenCV's pattern size),
  detected by a cascade of OpenCV's detectors (calibration/chessboard_detect.py: the sector-based
  ``cv2.findChessboardCornersSB``, Duda & Frese 2018, first; every board either OpenCV detector
  finds with its defaults is found).
- ``charuco:COLSxROWS:SQUARE_MM:MARKER_MM:DICT`` -- COLS x ROWS *squares* with ArUco markers of the
  dictionary ``DICT`` (e.g. ``DICT_5X5_100``), detected with ``cv2.aruco.CharucoDetector``.

**Board frame** (mm): z = 0 is the printed plane; x along the columns, y along the rows, so that z
points into the board, away from a camera that sees its printed face (OpenCV's convention). For a
chessboard the origin is the first inner corner; for a ChArUco board it is the outer corner of the
first square (OpenCV's ``CharucoBoard`` frame).

**Chessboard orientation.** OpenCV may return a chessboard's corners in either of two orders
(rotated 180 degrees). For hand-eye calibration the order must be the same physical corner in every
view, so :func:`detect_board` makes it canonical: the square diagonally inward of corner 0 is
black. This is unambiguous only when COLS + ROWS is odd (e.g. 9x6);
:attr:`BoardSpec.orientation_ambiguous` says when it is not, and hand-eye refuses such boards.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from calibration.chessboard_detect import find_chessboard, square_mean
from controller.errors import ConfigError, InputError

F64 = NDArray[np.float64]

_SPEC_HELP = ("use chessboard:COLSxROWS:SQUARE_MM (inner corners, e.g. chessboard:9x6:25) or "
              "charuco:COLSxROWS:SQUARE_MM:MARKER_MM:DICT (squares, e.g. "
              "charuco:8x6:30:22:DICT_5X5_100)")

#: A square smaller than this (mm) is taken for a length given in metres.
MIN_SQUARE_MM = 1.0

#: Fewest ChArUco corners accepted as a detection (fewer cannot give a stable pose).
MIN_CHARUCO_CORNERS = 6


@dataclass(frozen=True)
class BoardSpec:
    """A calibration board: kind, size, square (and marker) length in mm, ArUco dictionary."""

    kind: str
    cols: int
    rows: int
    square_mm: float
    marker_mm: float = 0.0
    dictionary: str = ""

    @property
    def corner_grid(self) -> tuple[int, int]:
        """(columns, rows) of the detectable corner grid (inner corners)."""
        if self.kind == "chessboard":
            return self.cols, self.rows
        return self.cols - 1, self.rows - 1

    @property
    def n_corners(self) -> int:
        """Number of detectable corners on the board."""
        c, r = self.corner_grid
        return c * r

    @property
    def orientation_ambiguous(self) -> bool:
        """True when the corner order cannot be told apart from its 180-degree rotation."""
        return self.kind == "chessboard" and (self.cols + self.rows) % 2 == 0

    @property
    def size_mm(self) -> tuple[float, float]:
        """Printed size of the checkered area (width, height) in mm."""
        if self.kind == "chessboard":
            return (self.cols + 1) * self.square_mm, (self.rows + 1) * self.square_mm
        return self.cols * self.square_mm, self.rows * self.square_mm

    def object_points(self) -> F64:
        """(n_corners, 3) corner positions in the board frame (mm), in corner-id order."""
        c, r = self.corner_grid
        jj, ii = np.mgrid[0:r, 0:c]
        pts = np.zeros((c * r, 3))
        pts[:, 0] = ii.ravel() * self.square_mm
        pts[:, 1] = jj.ravel() * self.square_mm
        if self.kind == "charuco":
            pts[:, :2] += self.square_mm  # OpenCV's ChArUco frame starts at the outer corner
        return pts

    @cached_property
    def charuco_board(self) -> Any:
        """The ``cv2.aruco.CharucoBoard`` of a ChArUco spec (error for a chessboard)."""
        if self.kind != "charuco":
            raise ConfigError(f"{self.spec} is not a ChArUco board")
        dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary))
        return cv2.aruco.CharucoBoard((self.cols, self.rows), self.square_mm, self.marker_mm,
                                      dictionary)

    @property
    def spec(self) -> str:
        """The SPEC string that parses back to this board."""
        base = f"{self.kind}:{self.cols}x{self.rows}:{self.square_mm:g}"
        if self.kind == "charuco":
            return f"{base}:{self.marker_mm:g}:{self.dictionary}"
        return base


def parse_board_spec(spec: str) -> BoardSpec:
    """Parse a board SPEC string (see the module docstring).

    Raises :class:`ConfigError` naming the spec and saying the accepted forms when the kind is
    unknown, a size is not a positive number, the grid is too small, the marker does not fit in a
    square, or the ArUco dictionary is unknown.
    """
    parts = str(spec).strip().split(":")
    kind = parts[0].lower()
    if kind not in ("chessboard", "charuco"):
        raise ConfigError(f"board spec {spec!r}: unknown board kind {parts[0]!r}; {_SPEC_HELP}")
    want = 3 if kind == "chessboard" else 5
    if len(parts) != want:
        raise ConfigError(f"board spec {spec!r}: {kind} needs {want} fields separated by ':', got "
                          f"{len(parts)}; {_SPEC_HELP}")
    m = re.fullmatch(r"(\d+)[xX](\d+)", parts[1])
    if not m:
        raise ConfigError(f"board spec {spec!r}: size {parts[1]!r} must be COLSxROWS; {_SPEC_HELP}")
    cols, rows = int(m.group(1)), int(m.group(2))
    minimum = 2 if kind == "chessboard" else 3
    if cols < minimum or rows < minimum:
        raise ConfigError(f"board spec {spec!r}: a {kind} needs at least {minimum}x{minimum} "
                          f"({'inner corners' if kind == 'chessboard' else 'squares'})")
    try:
        square = float(parts[2])
        marker = float(parts[3]) if kind == "charuco" else 0.0
    except ValueError as err:
        raise ConfigError(f"board spec {spec!r}: square and marker lengths must be numbers in "
                          f"mm; {_SPEC_HELP}") from err
    if not (np.isfinite(square) and square > 0):
        raise ConfigError(f"board spec {spec!r}: square length must be > 0 mm, got {parts[2]}")
    if square < MIN_SQUARE_MM:
        raise ConfigError(f"board spec {spec!r}: a square of {square:g} mm looks like a length in "
                          f"metres; give it in mm (0.025 m = 25 mm): {_SPEC_HELP}")
    dictionary = ""
    if kind == "charuco":
        if not (np.isfinite(marker) and 0 < marker < square):
            raise ConfigError(f"board spec {spec!r}: marker length must be > 0 and smaller than "
                              f"the square ({square:g} mm), got {parts[3]}")
        dictionary = parts[4].upper()
        if not dictionary.startswith("DICT_") or not hasattr(cv2.aruco, dictionary):
            raise ConfigError(f"board spec {spec!r}: unknown ArUco dictionary {parts[4]!r}; use "
                              f"one of OpenCV's, e.g. DICT_4X4_50, DICT_5X5_100, DICT_6X6_250")
    board = BoardSpec(kind, cols, rows, square, marker, dictionary)
    if kind == "charuco":
        n_markers = (cols * rows) // 2
        dict_size = cv2.aruco.getPredefinedDictionary(
            getattr(cv2.aruco, dictionary)).bytesList.shape[0]
        if n_markers > dict_size:
            raise ConfigError(f"board spec {spec!r}: the board needs {n_markers} markers but "
                              f"{dictionary} has {dict_size}; use a larger dictionary")
    return board


@dataclass(frozen=True)
class Detection:
    """Board corners found in one image.

    ``image_points`` (N, 2) px, ``ids`` (N,) corner ids, ``object_points`` (N, 3) mm in the board
    frame, row i of each belonging together.
    """

    image_points: F64
    ids: NDArray[np.int64]
    object_points: F64

    def __len__(self) -> int:
        return len(self.ids)


def _as_grey(image: NDArray[Any]) -> NDArray[np.uint8]:
    img = np.asarray(image)
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    if img.ndim != 2 or img.size == 0:
        raise InputError(f"image must be a greyscale or BGR array, got shape {img.shape}")
    if img.dtype != np.uint8:
        raise InputError(f"image must be 8-bit (uint8), got {img.dtype}")
    return img


def _canonical_chessboard(grey: NDArray[np.uint8], corners: F64, cols: int, rows: int) -> F64:
    """Put chessboard corners in the canonical order (see the module docstring)."""
    g = corners.reshape(rows, cols, 2)
    # A board seen from its printed face keeps its handedness: x (columns) cross y (rows) > 0 in
    # image coordinates (v down). A mirrored order is flipped along the rows first.
    a, b = g[0, 1] - g[0, 0], g[1, 0] - g[0, 0]
    if a[0] * b[1] - a[1] * b[0] < 0:
        g = g[::-1]
    # The square diagonally inward of corner 0 is black by convention; its neighbour is white.
    first = _mean_in(grey, np.array([g[0, 0], g[0, 1], g[1, 0], g[1, 1]]))
    second = _mean_in(grey, np.array([g[0, 1], g[0, 2], g[1, 1], g[1, 2]])) if cols > 2 \
        else _mean_in(grey, np.array([g[1, 0], g[1, 1], g[2, 0], g[2, 1]]))
    if first > second:
        g = g[::-1, ::-1]
    return np.ascontiguousarray(g.reshape(-1, 2))


def _mean_in(grey: NDArray[np.uint8], quad: F64) -> float:
    m = square_mean(grey, quad)
    if m is None:  # a corner square cut by the image border: its centre pixel
        c = np.clip(quad.mean(axis=0), 0, [grey.shape[1] - 1, grey.shape[0] - 1])
        return float(grey[int(round(c[1])), int(round(c[0]))])
    return m


def detect_board(image: NDArray[Any], board: BoardSpec) -> Detection | None:
    """Find the board's corners in an image (greyscale or BGR uint8); None when it is not found.

    Chessboards must be seen whole (every inner corner); ChArUco
    boards may be partly hidden or out of frame and return the corners seen (at least
    :data:`MIN_CHARUCO_CORNERS`). Corner positions are sub-pixel, (u, v) with the origin at the
    centre of the top-left pixel. Raises :class:`InputError` for a non-image array.
    """
    return detect_board_explained(image, board)[0]


def detect_board_explained(image: NDArray[Any], board: BoardSpec) -> tuple[Detection | None, str]:
    """:func:`detect_board` and a one-line reason, for the report and the console.

    The reason names the detector that found the board, or says why no board is accepted (see
    calibration/chessboard_detect.py).
    """
    grey = _as_grey(image)
    if board.kind == "chessboard":
        corners, why, _ = find_chessboard(grey, board.cols, board.rows)
        if corners is None:
            return None, why
        pts = _canonical_chessboard(grey, corners, board.cols, board.rows)
        ids = np.arange(board.n_corners, dtype=np.int64)
        return Detection(pts, ids, board.object_points()), why
    detector = cv2.aruco.CharucoDetector(board.charuco_board)
    ch_corners, ch_ids, _, _ = detector.detectBoard(grey)
    if ch_ids is None or len(ch_ids) < MIN_CHARUCO_CORNERS:
        n = 0 if ch_ids is None else len(ch_ids)
        return None, (f"{n} ChArUco corners found, fewer than {MIN_CHARUCO_CORNERS}: is the board "
                      f"in view and the dictionary {board.dictionary} the printed one?")
    ids = ch_ids.ravel().astype(np.int64)
    order = np.argsort(ids)
    ids = ids[order]
    pts = ch_corners.reshape(-1, 2).astype(np.float64)[order]
    return Detection(pts, ids, board.object_points()[ids]), f"found ({len(ids)} ChArUco corners)"
