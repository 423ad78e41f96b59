"""The calibration file: ROS camera_info fields plus the hand-eye transform (YAML).

The format is the contract in ../shared/DESIGN.md::

    image_width: 2272
    image_height: 1704
    camera_name: seam_cam
    camera_matrix: {rows: 3, cols: 3, data: [fx, 0, cx, 0, fy, cy, 0, 0, 1]}
    distortion_model: plumb_bob
    distortion_coefficients: {rows: 1, cols: 5, data: [k1, k2, p1, p2, k3]}
    hand_eye:            # T_flange_cam: the camera frame expressed in the flange (tool0) frame
      translation_mm: [x, y, z]
      quaternion_wxyz: [w, x, y, z]

Optional keys written by seamguide: ``camera_pose`` (same shape as ``hand_eye``, for a camera fixed
in the cell: ``T_base_cam``; a file holds ``hand_eye`` or ``camera_pose``, not both: one file per
camera, and a camera is on the flange or fixed), ``metadata`` (a mapping: date, residuals, views
used, identities).
Other keys are kept when read and written back, so files from other tools survive a round trip.
Every validation error is a :class:`CalibrationError` naming the file and the key.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from numpy.typing import NDArray

from controller.errors import CalibrationError, InputError
from controller.geometry.camera_model import CameraModel
from controller.geometry.poses import check_quat_wxyz as _check_quat
from controller.geometry.poses import make_pose, pos_quat_from_pose, quat_wxyz_to_matrix
from controller.jsonio import atomic_write_text

F64 = NDArray[np.float64]


@dataclass
class Calibration:
    """A camera's intrinsics and where it sits: on the flange (hand-eye) or fixed in the cell."""

    camera: CameraModel
    T_flange_cam: F64 | None = None
    T_base_cam: F64 | None = None
    metadata: dict[str, Any] = field(default_factory=dict)
    extra: dict[str, Any] = field(default_factory=dict)


def _fail(path: str | os.PathLike[str], key: str, what: str) -> CalibrationError:
    return CalibrationError(f"calibration file {path}: {key}: {what}", file=str(path), key=key)


def _matrix(doc: dict[str, Any], key: str, rows: int, cols: int,
            path: str | os.PathLike[str]) -> F64:
    node = doc.get(key)
    if node is None:
        raise _fail(path, key, "missing; a calibration file needs it (see docs/calibration.md)")
    if not isinstance(node, dict) or "data" not in node:
        raise _fail(path, key, f"must be a mapping with rows, cols, data, got {node!r}")
    r, c = node.get("rows", rows), node.get("cols", cols)
    data = node["data"]
    if (r, c) != (rows, cols) or not isinstance(data, list) or len(data) != rows * cols:
        n = len(data) if isinstance(data, list) else "no list"
        raise _fail(path, key, f"must be {rows}x{cols} ({rows * cols} numbers), "
                    f"got rows={r} cols={c} and {n} values")
    try:
        arr = np.array(data, dtype=np.float64).reshape(rows, cols)
    except (TypeError, ValueError) as err:
        raise _fail(path, key, f"values must be numbers, got {data!r}") from err
    if not np.all(np.isfinite(arr)):
        raise _fail(path, key, "values must be finite")
    return arr


def _pose(node: Any, key: str, path: str | os.PathLike[str]) -> F64:
    if not isinstance(node, dict):
        raise _fail(path, key, "must be a mapping with translation_mm and quaternion_wxyz")
    for sub in ("translation_mm", "quaternion_wxyz"):
        if sub not in node:
            raise _fail(path, f"{key}.{sub}", "missing")
    t = node["translation_mm"]
    try:
        tv = np.array(t, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise _fail(path, f"{key}.translation_mm", f"must be 3 numbers, got {t!r}") from err
    if tv.shape != (3,) or not np.all(np.isfinite(tv)):
        raise _fail(path, f"{key}.translation_mm", f"must be 3 finite numbers (mm), got {t!r}")
    try:
        q = _check_quat(node["quaternion_wxyz"], f"{key}.quaternion_wxyz")
    except InputError as err:
        raise _fail(path, f"{key}.quaternion_wxyz", str(err)) from err
    return make_pose(quat_wxyz_to_matrix(q), tv)


def calibration_from_dict(doc: Any, path: str | os.PathLike[str] = "<memory>") -> Calibration:
    """Validate a parsed calibration document and build a :class:`Calibration`."""
    if not isinstance(doc, dict):
        raise CalibrationError(f"calibration file {path}: must be a YAML mapping of the "
                               f"camera_info fields, got {type(doc).__name__}", file=str(path))
    size = []
    for key in ("image_width", "image_height"):
        v = doc.get(key)
        if v is None:
            raise _fail(path, key, "missing")
        if not isinstance(v, int) or isinstance(v, bool) or v <= 0:
            raise _fail(path, key, f"must be a positive whole number of pixels, got {v!r}")
        size.append(v)
    K = _matrix(doc, "camera_matrix", 3, 3, path)
    if K[0, 0] <= 0 or K[1, 1] <= 0:
        raise _fail(path, "camera_matrix", f"focal lengths must be positive, got fx={K[0, 0]} "
                    f"fy={K[1, 1]}")
    if not np.allclose(K[2], [0, 0, 1]) or K[1, 0] != 0:
        raise _fail(path, "camera_matrix", "must be [fx, s, cx, 0, fy, cy, 0, 0, 1]")
    model = doc.get("distortion_model", "plumb_bob")
    if model != "plumb_bob":
        raise _fail(path, "distortion_model", f"only plumb_bob is supported, got {model!r}")
    node = doc.get("distortion_coefficients")
    if node is None:
        raise _fail(path, "distortion_coefficients", "missing (use five zeros for none)")
    ncoef = len(node.get("data", [])) if isinstance(node, dict) else 0
    if ncoef not in (4, 5):
        raise _fail(path, "distortion_coefficients", f"plumb_bob needs 5 values (k1 k2 p1 p2 "
                    f"k3), got {ncoef}")
    dist = _matrix(doc, "distortion_coefficients", 1, ncoef, path).ravel()
    camera = CameraModel(size[0], size[1], K, dist, str(doc.get("camera_name", "seam_cam")))
    T_fc = _pose(doc["hand_eye"], "hand_eye", path) if doc.get("hand_eye") is not None else None
    T_bc = (_pose(doc["camera_pose"], "camera_pose", path)
            if doc.get("camera_pose") is not None else None)
    if T_fc is not None and T_bc is not None:
        raise _fail(path, "hand_eye/camera_pose", "a calibration file is of one camera, on the "
                    "flange (hand_eye) or fixed in the cell (camera_pose), not both; keep the "
                    "one that matches how the camera is mounted")
    meta = doc.get("metadata", {})
    if not isinstance(meta, dict):
        raise _fail(path, "metadata", "must be a mapping")
    known = {"image_width", "image_height", "camera_name", "camera_matrix", "distortion_model",
             "distortion_coefficients", "hand_eye", "camera_pose", "metadata",
             "rectification_matrix", "projection_matrix"}
    extra = {k: v for k, v in doc.items() if k not in known}
    return Calibration(camera, T_fc, T_bc, meta, extra)


def load_calibration(path: str | os.PathLike[str]) -> Calibration:
    """Read and validate a calibration file; :class:`CalibrationError` names the file and key."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError as err:
        raise CalibrationError(f"calibration file {p} does not exist; run `seamguide calibrate` "
                               f"or pass the right --calibration path", file=str(p)) from err
    except (OSError, UnicodeDecodeError) as err:
        raise CalibrationError(f"calibration file {p} cannot be read: {err}", file=str(p)) from err
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError as err:
        raise CalibrationError(f"calibration file {p} is not valid YAML: {err}",
                               file=str(p)) from err
    return calibration_from_dict(doc, p)


def _pose_node(T: F64) -> dict[str, list[float]]:
    t, q = pos_quat_from_pose(T)
    return {"translation_mm": [float(v) for v in t], "quaternion_wxyz": [float(v) for v in q]}


def calibration_to_dict(calib: Calibration) -> dict[str, Any]:
    """The YAML document of a calibration (full float precision)."""
    cam = calib.camera
    doc: dict[str, Any] = {
        "image_width": int(cam.width),
        "image_height": int(cam.height),
        "camera_name": cam.name,
        "camera_matrix": {"rows": 3, "cols": 3, "data": [float(v) for v in cam.K.ravel()]},
        "distortion_model": "plumb_bob",
        "distortion_coefficients": {"rows": 1, "cols": 5,
                                    "data": [float(v) for v in cam.dist.ravel()]},
    }
    if calib.T_flange_cam is not None:
        doc["hand_eye"] = _pose_node(calib.T_flange_cam)
    if calib.T_base_cam is not None:
        doc["camera_pose"] = _pose_node(calib.T_base_cam)
    if calib.metadata:
        doc["metadata"] = calib.metadata
    doc.update(calib.extra)
    return doc


def save_calibration(path: str | os.PathLike[str], calib: Calibration,
                     keep_previous: bool = True) -> Path | None:
    """Write a calibration file atomically; an existing file is kept as ``<name>.prev.yaml``.

    Returns the path of the kept previous file, if any.
    """
    p = Path(path)
    prev = None
    if keep_previous and p.exists():
        prev = p.with_name(p.stem + ".prev" + p.suffix)
        prev.write_bytes(p.read_bytes())
    text = yaml.safe_dump(calibration_to_dict(calib), sort_keys=False, default_flow_style=None)
    atomic_write_text(p, text)
    return prev
