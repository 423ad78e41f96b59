"""The teach-pose routine and the offline solvers built on the same code.

- :func:`run_teach`: the operator jogs the robot to a pose and confirms (Enter, or any other
  ``confirm`` callable, e.g. a request from the controller); the routine reads the robot's joints
  and flange pose, takes an image, says at once whether the board was found and how the
  collection is going (count, spread of orientations, image coverage, a progress bar) on stderr,
  and says when enough good views are in. With ``auto_n`` it generates well-spread poses around
  the first taught one (checked with the IRB 2400's inverse kinematics and a workspace box) and
  drives the robot there. Then it solves, validates on held-out views and returns the calibration
  with its metadata; the caller saves it (keeping the previous file).
- :func:`calibrate_from_folder`: the same solver from recorded view files (DESIGN.md contract).
- :func:`calibrate_images`: intrinsics only, from a set of images.

The robot and camera are reached through two tiny interfaces (:class:`TeachRobot`,
:class:`TeachCamera`) so that the routine cannot tell the mock from the real thing; the command
line adapts ``open_robot`` / ``open_camera`` objects to them.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any, Protocol, TextIO

import cv2
import numpy as np
from numpy.typing import NDArray

from calibration import teach_poses
from calibration.calibrate_offline import (
    calibrate_from_folder,
    calibrate_images,
    load_view_records,
    read_image,
)
from calibration.calibration_file import Calibration
from calibration.solve_views import solve_views
from calibration.targets import BoardSpec, detect_board_explained
from calibration.teach_poses import explore_poses, rough_calibration, spread_poses
from calibration.teach_progress import (
    TARGET_COVERAGE,
    TARGET_SPREAD_DEG,
    TARGET_VIEWS,
    Progress,
    ViewRecord,
    collection_progress,
    orientation_spread_deg,
)
from controller.errors import CalibrationError
from controller.geometry.poses import Pose, pose_to_dict

F64 = NDArray[np.float64]


class TeachRobot(Protocol):
    """What the routine needs from a robot (mm, degrees, controller axis convention)."""

    def joints_deg(self) -> F64:
        """Current controller joint values (deg)."""

    def flange_pose(self) -> Pose:
        """Current flange (tool0) pose in the base frame (4x4, mm)."""

    def move_joints(self, joints_deg: F64, timeout_s: float) -> None:
        """Move to the joint values and return when the controller says the move is done."""


class TeachCamera(Protocol):
    """What the routine needs from a camera."""

    def grab(self, timeout_s: float = 5.0) -> NDArray[np.uint8]:
        """One frame, greyscale or BGR uint8."""


# ---------------------------------------------------------------------------------------------
# The routine
# ---------------------------------------------------------------------------------------------
def stdin_confirm(prompt_out: TextIO | None = None) -> Callable[[Progress | None], str]:
    """A ``confirm`` callable reading the operator's answer from stdin.

    Enter takes a view; ``d`` (or end of input) solves; ``q`` aborts.
    """
    def confirm(progress: Progress | None) -> str:
        stream = sys.stderr if prompt_out is None else prompt_out
        stream.write("jog the robot, then Enter = take view, d = done/solve, q = abort: ")
        stream.flush()
        line = sys.stdin.readline()
        if line == "":
            return "done"
        word = line.strip().lower()
        return {"": "take", "d": "done", "done": "done", "q": "abort",
                "quit": "abort"}.get(word, "take")
    return confirm


def collect_view(robot: TeachRobot, camera: TeachCamera, board: BoardSpec, name: str,
                 timeout_s: float = 10.0) -> tuple[ViewRecord, NDArray[np.uint8]]:
    """Read the robot's pose, take one image, detect the board."""
    joints = np.asarray(robot.joints_deg(), float)
    T = np.asarray(robot.flange_pose(), float)
    image = camera.grab(timeout_s)
    det, reason = detect_board_explained(image, board)
    return ViewRecord(name, T, det, joints, skip_reason=None if det else reason), image


def run_teach(robot: TeachRobot, camera: TeachCamera, board: BoardSpec, *,
              confirm: Callable[[Progress | None], str] | None = None, auto_n: int | None = None,
              eye_to_hand: bool = False, target_views: int = TARGET_VIEWS,
              out: TextIO | None = None, save_dir: str | Path | None = None,
              move_timeout_s: float = 60.0, pivot_mm: float = 350.0,
              workspace_min_mm: F64 | None = None, workspace_max_mm: F64 | None = None,
              identity: dict[str, Any] | None = None, seed: int = 0,
              **solve_kwargs: Any) -> tuple[Calibration, dict[str, Any]]:
    """Collect views from ``robot`` and ``camera`` and solve (see the module docstring).

    Manual mode (``auto_n`` None): ``confirm(progress)`` returns ``"take"``, ``"done"`` or
    ``"abort"``. Automatic mode: the first view is taken where the robot stands (it must see the
    board), then ``auto_n`` generated poses are visited. With ``save_dir`` every image and a
    view file (DESIGN.md contract) are written there, so the session can be solved again with
    ``calibrate_from_folder``. Raises :class:`CalibrationError` when aborted (nothing is
    returned, nothing saved) or when the solve fails.
    """
    from controller.geometry.view_file import view_to_dict

    out = sys.stderr if out is None else out
    views: list[ViewRecord] = []
    size: tuple[int, int] | None = None
    folder = Path(save_dir) if save_dir is not None else None
    if folder is not None:
        folder.mkdir(parents=True, exist_ok=True)

    def take() -> ViewRecord:
        nonlocal size
        name = f"view{len(views) + 1:02d}"
        rec, image = collect_view(robot, camera, board, name)
        size = (image.shape[1], image.shape[0])
        views.append(rec)
        if folder is not None:
            cv2.imwrite(str(folder / f"{name}.png"), image)
            from controller.jsonio import atomic_write_text, dumps

            # The flange pose the solve uses (the controller's), so that the folder solves again
            # to the same answer; the joints go along for the record.
            doc = view_to_dict(f"{name}.png", T_base_flange=rec.T_base_flange)
            if rec.joints_deg is not None:
                doc["recorded_joints_deg"] = [round(float(v), 6) for v in rec.joints_deg]
            atomic_write_text(folder / f"{name}.json", dumps(doc))
        found = (f"board found ({len(rec.detection)} corners)" if rec.detection is not None
                 else f"NO BOARD: not used: {rec.skip_reason}")
        out.write(f"{name}: {found}\n")
        out.write(collection_progress(views, size, target_views).line() + "\n")
        out.flush()
        return rec

    if auto_n is None:
        ask = confirm or stdin_confirm(out)
        progress: Progress | None = None
        while True:
            answer = ask(progress)
            if answer == "abort":
                raise CalibrationError("calibration aborted by the operator; nothing was saved")
            if answer == "done":
                break
            take()
            assert size is not None
            progress = collection_progress(views, size, target_views)
    else:
        first = take()
        if first.detection is None:
            raise CalibrationError("automatic mode: the board is not in the first image; jog the "
                                   "robot so that the camera sees the whole board, then start")
        assert first.joints_deg is not None and size is not None
        box: dict[str, Any] = {"workspace_min_mm": workspace_min_mm,
                               "workspace_max_mm": workspace_max_mm}
        for j in explore_poses(first.T_base_flange, first.joints_deg, pivot_mm=pivot_mm, **box):
            robot.move_joints(j, move_timeout_s)
            take()
        X, Y, cam0 = rough_calibration(views, board, size, eye_to_hand)
        if eye_to_hand:
            raise CalibrationError("automatic mode is for eye-in-hand; teach eye-to-hand views "
                                   "by hand (the board on the flange in front of the camera)")
        obj = board.object_points()
        centre = Y[:3, :3] @ obj.mean(axis=0) + Y[:3, 3]
        normal = -Y[:3, 2]  # board z points into the board; the printed face looks along -z
        w, h = board.size_mm
        # The board filling about 70 % of the image width at the mean distance: nearer views
        # locate the camera better (at 55 % the hand-eye's predicted sigma was 1.4x larger).
        d0 = max(w, h) / teach_poses.AUTO_FILL * cam0.fx / cam0.width
        targets = spread_poses(X, centre, normal, d0, first.joints_deg, auto_n,
                               offset_mm=0.3 * min(w, h), tilt_deg=teach_poses.AUTO_TILT_DEG,
                               T_first=first.T_base_flange,
                               seed=seed, camera=cam0,
                               board_points_base=obj @ Y[:3, :3].T + Y[:3, 3], **box)
        for j in targets:
            robot.move_joints(j, move_timeout_s)
            take()
        robot.move_joints(first.joints_deg, move_timeout_s)
    if size is None:
        raise CalibrationError("no views were taken; nothing was saved")
    meta = {"robot_and_camera": identity or {}, "collection": "automatic" if auto_n else "taught"}
    out.write("solving...\n")
    solve_kwargs.setdefault("log", lambda line: out.write(line + "\n") if line else None)
    calib, report = solve_views(views, board, size, eye_to_hand=eye_to_hand, metadata=meta,
                                **solve_kwargs)
    he = report["hand_eye"]
    out.write(f"solved: residual {he['residual_px']:.3f} px, consistency "
              f"{he['consistency_mm']:.3f} mm / {he['consistency_deg']:.4f} deg, "
              f"{len(he['views_used'])} views used, rejected: "
              f"{', '.join(r['view'] for r in he['rejected_views']) or 'none'}\n")
    return calib, report


def hand_eye_pose_dict(calib: Calibration) -> dict[str, Any]:
    """The solved mounting as ``{"position_mm", "quaternion_wxyz"}`` (for reports)."""
    T = calib.T_base_cam if calib.T_flange_cam is None else calib.T_flange_cam
    if T is None:
        return {}
    return pose_to_dict(T)


__all__ = ["TARGET_COVERAGE", "TARGET_SPREAD_DEG", "TARGET_VIEWS", "ViewRecord", "Progress",
           "TeachRobot", "TeachCamera", "run_teach", "solve_views", "calibrate_from_folder",
           "calibrate_images", "explore_poses", "spread_poses", "rough_calibration",
           "collection_progress", "orientation_spread_deg", "load_view_records", "read_image"]
