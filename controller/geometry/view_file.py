"""The view file of DESIGN.md: one JSON file per image, saying where the camera or the flange was.

One of three pose keys, besides ``"image"`` (a path relative to the view file's folder)::

    {"image": "view1.png",
     "flange_pose": {"position_mm": [x, y, z], "quaternion_wxyz": [w, x, y, z]}}
    {"image": "view2.png", "joints_deg": [j1, j2, j3, j4, j5, j6]}
    {"image": "fixed_cam.png",
     "camera_pose": {"position_mm": [x, y, z], "quaternion_wxyz": [w, x, y, z]}}

``joints_deg`` are controller axis values (ABB convention, degrees); the flange pose is computed by
:func:`controller.geometry.kinematics.flange_pose`. Poses are in the robot base frame, millimetres.
Every problem is an :class:`InputError` naming the file and the key.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from controller.errors import InputError, SeamguideError
from controller.geometry.poses import Pose, pose_from_dict

F64 = NDArray[np.float64]

POSE_KEYS = ("flange_pose", "joints_deg", "camera_pose")


@dataclass(frozen=True)
class View:
    """One view: the image file and the pose it was taken from (base frame, mm).

    Exactly one of ``joints_deg`` / ``T_base_flange`` / ``T_base_cam`` came from the file; when
    joints were given, ``T_base_flange`` holds their forward kinematics as well.
    """

    path: Path
    image_path: Path
    T_base_flange: Pose | None = None
    joints_deg: F64 | None = None
    T_base_cam: Pose | None = None

    @property
    def name(self) -> str:
        """The view's name for reports: the view file's stem."""
        return self.path.stem


def _fail(path: Path, key: str, what: str) -> InputError:
    return InputError(f"view file {path}: {key}: {what}", file=str(path), key=key)


def load_view(path: str | os.PathLike[str]) -> View:
    """Read one view file (DESIGN.md contract) and return a :class:`View`.

    The image path is resolved relative to the view file's folder (absolute paths are kept). The
    image file itself must exist. ``joints_deg`` are checked against the IRB 2400's joint limits
    and turned into ``T_base_flange`` by forward kinematics.

    Raises :class:`InputError` naming the file and key when the file is missing, is not JSON, has
    no ``image``, has none or more than one of ``flange_pose`` / ``joints_deg`` / ``camera_pose``,
    or a pose or joint list is malformed.
    """
    p = Path(path)
    try:
        doc: Any = json.loads(p.read_text(encoding="utf-8"))
    except FileNotFoundError as err:
        raise InputError(f"view file {p} does not exist", file=str(p)) from err
    except (OSError, UnicodeDecodeError) as err:
        raise InputError(f"view file {p} cannot be read: {err}", file=str(p)) from err
    except json.JSONDecodeError as err:
        raise InputError(f"view file {p} is not valid JSON: {err}", file=str(p)) from err
    if not isinstance(doc, dict):
        raise InputError(f"view file {p}: must be a JSON object with \"image\" and a pose",
                         file=str(p))
    image = doc.get("image")
    if not isinstance(image, str) or not image:
        raise _fail(p, "image", f"missing or not a file name, got {image!r}")
    image_path = Path(image)
    if not image_path.is_absolute():
        image_path = p.parent / image_path
    if not image_path.is_file():
        raise _fail(p, "image", f"{image_path} does not exist (paths are relative to the view "
                    f"file's folder)")
    present = [k for k in POSE_KEYS if doc.get(k) is not None]
    if len(present) != 1:
        raise _fail(p, "/".join(POSE_KEYS),
                    f"exactly one of them must be given, found {present or 'none'}")
    key = present[0]
    try:
        if key == "joints_deg":
            from controller.geometry.kinematics import flange_pose, irb2400

            joints = doc[key]
            arr = np.asarray(joints, dtype=np.float64) if isinstance(joints, list) else None
            if arr is None or arr.shape != (6,) or not np.all(np.isfinite(arr)):
                raise _fail(p, key, f"must be 6 finite numbers (controller axes, degrees), "
                            f"got {joints!r}")
            return View(p, image_path, T_base_flange=flange_pose(irb2400(), arr), joints_deg=arr)
        T = pose_from_dict(doc[key], key)
    except InputError as err:
        if str(err).startswith(f"view file {p}"):
            raise
        raise _fail(p, key, str(err)) from err
    except (TypeError, ValueError, SeamguideError) as err:
        raise _fail(p, key, str(err)) from err
    if key == "flange_pose":
        return View(p, image_path, T_base_flange=T)
    return View(p, image_path, T_base_cam=T)


def view_to_dict(image: str, *, T_base_flange: Pose | None = None,
                 joints_deg: F64 | None = None, T_base_cam: Pose | None = None) -> dict[str, Any]:
    """The JSON document of a view file (give exactly one pose); inverse of :func:`load_view`."""
    from controller.geometry.poses import pose_to_dict

    doc: dict[str, Any] = {"image": image}
    if joints_deg is not None:
        doc["joints_deg"] = [round(float(v), 6) for v in joints_deg]
    elif T_base_flange is not None:
        doc["flange_pose"] = pose_to_dict(T_base_flange, decimals=6)
    elif T_base_cam is not None:
        doc["camera_pose"] = pose_to_dict(T_base_cam, decimals=6)
    else:
        raise InputError("a view needs a pose: give T_base_flange, joints_deg or T_base_cam")
    return doc
