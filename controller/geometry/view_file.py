"""The view file of DESIGN.md: one JSON file per image, saying where the camera or the flange was.

One of three pose keys, besides ``"image"`` (a path relative to the view file's folder)::

    {"image": "view1.png",
     "flange_pose": {"position_mm": [x, y, z], "quaternion_wxyz": [w, x, y, z]}}
    {"image": "view2.png", "joints_deg": [j1, j2, j3, j4, j5, j6]}
    {"image": "fixed_cam.png",
     "camera_pose": {"position_mm": [x, y, z], "quaternion_wxyz": [w, x, y, z]}}

``joints_deg`` are controller axis values (ABB convention, degrees); the flange pose is computed by
:func:`controller.geometry.kinematics.flange_pose`. Poses are in the robot base frame, millimetres.

In a cell with several cameras a view names its camera (``"camera": "left"``), whose calibration
file holds its intrinsics and either ``hand_eye`` (on the flange) or ``camera_pose`` (fixed). A
view of a fixed camera may then omit the pose: it comes from that camera's calibration. Every
problem is an :class:`InputError` naming the file and the key.
"""

from __future__ import annotations

import json
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from controller.errors import InputError, SeamguideError
from controller.geometry.poses import Pose, pose_from_dict

F64 = NDArray[np.float64]

POSE_KEYS = ("flange_pose", "joints_deg", "camera_pose")

#: A camera name: what the cell configuration, job and ``--calibration NAME=FILE`` call it.
CAMERA_NAME = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.-]{0,63}$")


def camera_name_problem(name: object) -> str | None:
    """What is wrong with a camera name (letters, digits, ``_ . -``), or None when it is valid."""
    if isinstance(name, str) and CAMERA_NAME.match(name):
        return None
    return (f"a camera name must be 1-64 letters, digits, '_', '.' or '-' (not starting with '.' "
            f"or '-'), got {name!r}")


def check_camera_name(name: object, what: str) -> str:
    """``name`` if it is a valid camera name, else :class:`InputError` naming ``what``."""
    problem = camera_name_problem(name)
    if problem is not None:
        raise InputError(f"{what}: {problem}")
    assert isinstance(name, str)
    return name


@dataclass(frozen=True)
class View:
    """One view: the image file and the pose it was taken from (base frame, mm).

    At most one of ``joints_deg`` / ``T_base_flange`` / ``T_base_cam`` came from the file; when
    joints were given, ``T_base_flange`` holds their forward kinematics as well. None of them
    only for a view naming its ``camera`` (a fixed camera whose calibration holds its pose).
    """

    path: Path
    image_path: Path
    T_base_flange: Pose | None = None
    joints_deg: F64 | None = None
    T_base_cam: Pose | None = None
    camera: str | None = None

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
    no ``image``, has more than one of ``flange_pose`` / ``joints_deg`` / ``camera_pose`` (or none
    and no ``camera``), a camera name is malformed, or a pose or joint list is malformed.
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
    camera = doc.get("camera")
    if camera is not None and (problem := camera_name_problem(camera)) is not None:
        raise _fail(p, "camera", problem)
    present = [k for k in POSE_KEYS if doc.get(k) is not None]
    if not present and camera is not None:
        return View(p, image_path, camera=camera)
    if len(present) != 1:
        raise _fail(p, "/".join(POSE_KEYS),
                    f"exactly one of them must be given, found {present or 'none'} (a view of "
                    f"a fixed camera may give none and name its \"camera\" instead)")
    key = present[0]
    try:
        if key == "joints_deg":
            from controller.geometry.kinematics import flange_pose, irb2400

            joints = doc[key]
            arr = np.asarray(joints, dtype=np.float64) if isinstance(joints, list) else None
            if arr is None or arr.shape != (6,) or not np.all(np.isfinite(arr)):
                raise _fail(p, key, f"must be 6 finite numbers (controller axes, degrees), "
                            f"got {joints!r}")
            return View(p, image_path, T_base_flange=flange_pose(irb2400(), arr), joints_deg=arr,
                        camera=camera)
        T = pose_from_dict(doc[key], key)
    except InputError as err:
        if str(err).startswith(f"view file {p}"):
            raise
        raise _fail(p, key, str(err)) from err
    except (TypeError, ValueError, SeamguideError) as err:
        raise _fail(p, key, str(err)) from err
    if key == "flange_pose":
        return View(p, image_path, T_base_flange=T, camera=camera)
    return View(p, image_path, T_base_cam=T, camera=camera)


def view_to_dict(image: str, *, T_base_flange: Pose | None = None,
                 joints_deg: F64 | None = None, T_base_cam: Pose | None = None,
                 camera: str | None = None) -> dict[str, Any]:
    """The JSON document of a view file; inverse of :func:`load_view`.

    Give exactly one pose, or none with ``camera`` (a fixed camera whose calibration has its pose).
    """
    from controller.geometry.poses import pose_to_dict

    doc: dict[str, Any] = {"image": image}
    if camera is not None:
        doc["camera"] = check_camera_name(camera, "view camera")
    if joints_deg is not None:
        doc["joints_deg"] = [round(float(v), 6) for v in joints_deg]
    elif T_base_flange is not None:
        doc["flange_pose"] = pose_to_dict(T_base_flange, decimals=6)
    elif T_base_cam is not None:
        doc["camera_pose"] = pose_to_dict(T_base_cam, decimals=6)
    elif camera is None:
        raise InputError("a view needs a pose: give T_base_flange, joints_deg or T_base_cam")
    return doc
