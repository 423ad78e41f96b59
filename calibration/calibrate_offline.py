"""The offline solvers: a recorded folder of view files, or intrinsics only from images."""
from __future__ import annotations

import datetime as _dt
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from calibration.calibration_file import Calibration
from calibration.intrinsics import solve_intrinsics
from calibration.solve_views import _first_reasons, _plain, solve_views
from calibration.targets import BoardSpec, Detection, detect_board_explained, parse_board_spec
from calibration.teach_progress import ViewRecord
from controller.errors import CalibrationError, InputError

F64 = NDArray[np.float64]


def read_image(path: str | Path) -> NDArray[np.uint8]:
    """Read an image file as greyscale uint8; :class:`InputError` naming the file if unreadable."""
    img = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    if img is None:
        raise InputError(f"image {path} cannot be read (missing, or not an image OpenCV reads)",
                         file=str(path))
    return np.asarray(img, np.uint8)


def calibrate_images(paths: Sequence[str | Path], board_spec: str | BoardSpec, *,
                     camera_name: str = "seam_cam", log: Callable[[str], None] | None = None
                     ) -> tuple[Calibration, dict[str, Any]]:
    """Intrinsics only from images of a board; a :class:`Calibration` without hand-eye.

    Raises :class:`InputError` for no images, unreadable images or images of different sizes,
    and :class:`CalibrationError` when the board is in too few of them (naming those without).
    """
    board = parse_board_spec(board_spec) if isinstance(board_spec, str) else board_spec
    if not paths:
        raise InputError("no images given; pass --images 'folder/*.png' (quoted glob)")
    dets: list[Detection] = []
    names: list[str] = []
    missing: list[str] = []
    why: dict[str, str] = {}
    size: tuple[int, int] | None = None
    for p in sorted(str(x) for x in paths):
        img = read_image(p)
        s = (img.shape[1], img.shape[0])
        if size is not None and s != size:
            raise InputError(f"image {p} is {s[0]}x{s[1]} but the first was {size[0]}x{size[1]}: "
                             f"all images must come from one camera at one resolution", file=p)
        size = s
        d, reason = detect_board_explained(img, board)
        if d is None:
            missing.append(Path(p).name)
            why[Path(p).name] = reason
            if log is not None:
                log(f"{Path(p).name}: NOT USED: {reason}")
        else:
            dets.append(d)
            names.append(Path(p).name)
    assert size is not None
    if len(dets) < 4:
        raise CalibrationError(
            f"the board {board.spec} was found in only {len(dets)} of {len(paths)} images"
            f"{' (not in ' + ', '.join(missing) + ')' if missing else ''}; need at least 4: check "
            f"the board spec (inner corners for a chessboard) and that the whole board is in view"
            f"{_first_reasons(why)}", images_without_board=missing, why_no_board=why)
    intr = solve_intrinsics([d.image_points for d in dets], [d.object_points for d in dets],
                            size, names=names, camera_name=camera_name)
    report = {"board": board.spec, "images_total": len(paths), "images_without_board": missing,
              "why_no_board": why, "intrinsics": intr.report()}
    meta = _plain({"date": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
                   "tool": "seamguide calibrate --images", "board": board.spec,
                   "intrinsics_rms_px": round(float(intr.rms_px), 4),
                   "views_used": [names[i] for i in intr.used_views],
                   "views_rejected": intr.rejected_views, "images_without_board": missing})
    return Calibration(intr.camera, metadata=meta), report


def load_view_records(folder: str | Path, board: BoardSpec,
                      log: Callable[[str], None] | None = None
                      ) -> tuple[list[ViewRecord], tuple[int, int]]:
    """Read every ``*.json`` view file in ``folder`` (sorted), its image, and detect the board.

    ``log`` (e.g. a line to stderr) gets one line per view: the board found, or why not.

    Raises :class:`InputError` when the folder has no view files, a view file is malformed (naming
    it and the key), a view gives ``camera_pose`` (hand-eye needs the robot's flange pose or
    joints), or the images differ in size.
    """
    from controller.geometry.view_file import load_view

    files = sorted(Path(folder).glob("*.json"))
    if not files:
        raise InputError(f"folder {folder} holds no view files (*.json); each image needs one "
                         f"with \"image\" and \"flange_pose\" or \"joints_deg\" "
                         f"(docs/calibration.md)", folder=str(folder))
    records: list[ViewRecord] = []
    size: tuple[int, int] | None = None
    for f in files:
        view = load_view(f)
        if view.T_base_flange is None:
            raise InputError(f"view file {f}: camera_pose: hand-eye calibration needs the robot's "
                             f"flange_pose or joints_deg for every view, not a camera pose",
                             file=str(f), key="camera_pose")
        img = read_image(view.image_path)
        s = (img.shape[1], img.shape[0])
        if size is not None and s != size:
            raise InputError(f"view file {f}: image {view.image_path} is {s[0]}x{s[1]}, the "
                             f"others {size[0]}x{size[1]}", file=str(f), key="image")
        size = s
        det, reason = detect_board_explained(img, board)
        if log is not None:
            log(f"{view.name}: {'board ' + reason if det is not None else 'NOT USED: ' + reason}"
                f" [{len(records) + 1}/{len(files)}]")
        records.append(ViewRecord(view.name, view.T_base_flange, det, view.joints_deg,
                                  str(view.image_path), None if det is not None else reason))
    assert size is not None
    return records, size


def calibrate_from_folder(folder: str | Path, board_spec: str | BoardSpec,
                          eye_to_hand: bool = False, **kwargs: Any
                          ) -> tuple[Calibration, dict[str, Any]]:
    """Intrinsics and hand-eye from a folder of view files (see :func:`solve_views`).

    Eye-in-hand writes ``T_flange_cam`` (the ``hand_eye`` key); eye-to-hand writes
    ``T_base_cam`` (the ``camera_pose`` key). ``kwargs`` go to :func:`solve_views`.
    """
    board = parse_board_spec(board_spec) if isinstance(board_spec, str) else board_spec
    records, size = load_view_records(folder, board, kwargs.get("log"))
    meta = {"source": f"folder {Path(folder).resolve()}"}
    meta.update(kwargs.pop("metadata", {}) or {})
    return solve_views(records, board, size, eye_to_hand=eye_to_hand, metadata=meta, **kwargs)


