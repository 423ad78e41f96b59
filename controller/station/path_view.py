"""The planned torch path drawn on a recorded image, for the operator deciding on a weld.

Reads from a record folder: the view's image and view file, ``calibration.yaml`` (the camera model)
and ``seam.json`` (``weld_path`` positions in the base frame, mm). The path is projected with the
camera pose the cycle computed for that view (``camera_pose_computed``, base frame) or, if absent,
forward kinematics of the view's joints times the hand-eye. Weld points are drawn in red, approach
and depart moves in yellow, the detected seam overlay is not redrawn (it has its own file).
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np

from controller.errors import InputError


def _camera_pose(folder: Path, view_json: dict, view_path: Path) -> np.ndarray:
    from controller.geometry.poses import pose_from_dict

    computed = view_json.get("camera_pose_computed")
    if isinstance(computed, dict):
        return pose_from_dict(computed, f"{view_path}: camera_pose_computed")
    from calibration.calibration_file import load_calibration
    from controller.geometry.view_file import load_view
    from controller.stereo.view_geometry import camera_pose

    return camera_pose(load_view(view_path), load_calibration(folder / "calibration.yaml"))


def path_overlay_png(folder: Path, view: str, max_width: int = 1400) -> bytes:
    """PNG bytes: view ``view`` of the record in ``folder`` with the planned path drawn on it.

    Raises :class:`InputError` when the record has no such view, no image or no planned path.
    """
    from calibration.calibration_file import load_calibration

    view_path = folder / f"{view}.json"
    seam_path = folder / "seam.json"
    if not view_path.is_file():
        raise InputError(f"record {folder.name} has no view {view!r}")
    if not seam_path.is_file():
        raise InputError(f"record {folder.name} has no planned path yet")
    view_json = json.loads(view_path.read_text(encoding="utf-8"))
    image = cv2.imread(str(folder / str(view_json.get("image", ""))), cv2.IMREAD_COLOR)
    if image is None:
        raise InputError(f"record {folder.name}: the image of view {view} cannot be read")
    weld_path = json.loads(seam_path.read_text(encoding="utf-8")).get("weld_path") or []
    if not weld_path:
        raise InputError(f"record {folder.name} has no planned path (weld_path is empty)")
    cam = load_calibration(folder / "calibration.yaml").camera
    T_base_cam = _camera_pose(folder, view_json, view_path)
    pts = np.array([p["position_mm"] for p in weld_path], float)
    uv = cam.project(pts, T_base_cam)
    scale = min(1.0, max_width / image.shape[1])
    small = cv2.resize(image, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
    thick = max(2, round(3 * scale * image.shape[1] / 1400))
    for a, b, pa, pb in zip(uv[:-1], uv[1:], weld_path[:-1], weld_path[1:], strict=True):
        if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
            continue
        colour = (0, 0, 255) if pa.get("arc") and pb.get("arc") else (0, 220, 255)
        p0 = tuple(int(x) for x in np.round(a * scale))
        p1 = tuple(int(x) for x in np.round(b * scale))
        cv2.line(small, p0, p1, colour, thick, cv2.LINE_AA)
    ok, buf = cv2.imencode(".png", small)
    if not ok:
        raise InputError(f"record {folder.name}: cannot encode the path overlay")
    return bytes(buf)
