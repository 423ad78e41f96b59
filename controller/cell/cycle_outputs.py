"""What a weld cycle writes into its record besides its states: calibration, overlays, seam, path.

The files are those docs/cycle-record.md lists.
Each function takes the :class:`~controller.cell.cycle_record.CycleRecord` and the data; the
record does the atomic writing.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from calibration.calibration_file import Calibration, calibration_to_dict
from controller.cell.cycle_record import CycleRecord
from controller.cell.guidance import ViewInput, locate_output, nominal_hint
from controller.cell.job import Job
from controller.cell.seam_plot import seam_plot_png
from controller.errors import SeamguideError
from controller.geometry.poses import pose_to_dict
from controller.path.rapid_export import rapid_module
from controller.path.weld_path import WeldPath
from controller.stereo.locate import Seam3D


def save_calibration(record: CycleRecord, calibration: Calibration,
                     name: str = "calibration.yaml") -> None:
    """A calibration the cycle used, as a calibration file (the YAML contract) named ``name``."""
    import yaml

    record.save_text(name, yaml.safe_dump(
        calibration_to_dict(calibration), sort_keys=False, default_flow_style=None))


def save_view(record: CycleRecord, name: str, image: np.ndarray, T_base_cam: np.ndarray, *,
              camera: str | None, joints_deg: np.ndarray | None, skew_s: float | None) -> None:
    """``<view>.png`` as taken and ``<view>.json``, its view file (DESIGN.md's contract).

    The view file names its ``camera`` when given, holds the joints read back (deg) with the
    camera pose computed from them, or, for a fixed camera (``joints_deg`` None), its
    ``camera_pose``; ``capture_skew_ms`` when the view was captured together with others.
    """
    record.save_image(f"{name}.png", image)
    doc: dict[str, Any] = {"image": f"{name}.png"}
    if camera is not None:
        doc["camera"] = camera
    if joints_deg is None:
        doc["camera_pose"] = pose_to_dict(T_base_cam)
    else:
        doc["joints_deg"] = [round(float(v), 4) for v in joints_deg]
        doc["camera_pose_computed"] = pose_to_dict(T_base_cam)
    if skew_s is not None:
        doc["capture_skew_ms"] = round(1000 * skew_s, 3)
    record.save_json(f"{name}.json", doc)


def save_detections(record: CycleRecord, views: Sequence[ViewInput], outcomes: list[Any],
                    nominal_line_mm: Sequence[Sequence[float]] | None = None) -> None:
    """Each view's ``<view>_overlay.png`` and the record's ``detections`` note.

    ``nominal_line_mm``: the job's nominal seam line (base frame, mm), drawn dashed on each
    view's picture where it is in front of the camera.

    ``outcomes``: per view, its detection or the ``SeamguideError`` it was refused with (its
    message written on the picture, an ambiguous refusal's two lines drawn; the note names the
    error's type). The pictures are skipped without cv2.
    """
    _save_overlays(record, views, outcomes, [
        None if nominal_line_mm is None else nominal_hint(v.camera, v.T_base_cam, nominal_line_mm)
        for v in views])
    record.note(detections=[
        {"view": v.name, "refused": type(d).__name__} if isinstance(d, SeamguideError)
        else {"view": v.name, "confidence": round(float(d.confidence), 3)}
        for v, d in zip(views, outcomes, strict=True)])


def _save_overlays(record: CycleRecord, views: Sequence[ViewInput], outcomes: list[Any],
                   nominal_px: Sequence[Any]) -> None:
    try:
        from controller.vision.seam_overlay import outcome_overlay
    except ImportError:
        return
    for view, det, nom in zip(views, outcomes, nominal_px, strict=True):
        record.save_image(f"{view.name}_overlay.png", outcome_overlay(view.image, det, nom))


def save_seam(record: CycleRecord, seam: Seam3D, path: WeldPath, job: Job) -> None:
    """``seam.json`` (locate's contract), the segments (a note), ``weld_path.mod``, the plot."""
    record.save_json("seam.json", locate_output(seam, path))
    record.note(weld_segments=[g.to_dict() for g in path.segments])
    record.save_text("weld_path.mod", rapid_module(
        path, arc_output=job.weld.arc_output, comment=f"job {job.name}"))
    tips = np.array([t.T_base_tcp[:3, 3] for t in path.targets])
    record.save_bytes("seam_plot.png", seam_plot_png(seam.points_mm, tips,
                                                     title=f"job {job.name}"))


def jsonable(d: dict[str, Any]) -> dict[str, Any]:
    """``d`` with arrays as lists and anything else not JSON as its string (error details)."""
    out = {}
    for k, v in d.items():
        if isinstance(v, np.ndarray):
            out[k] = v.tolist()
        elif isinstance(v, int | float | str | bool | list | dict) or v is None:
            out[k] = v
        else:
            out[k] = str(v)
    return out
