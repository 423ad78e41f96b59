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

import datetime as _dt
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from itertools import combinations
from pathlib import Path
from typing import Any, Protocol, TextIO

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from calibration.calibration_file import Calibration
from calibration.handeye import HandEyeResult, Observation, solve_hand_eye, view_residuals
from calibration.intrinsics import IntrinsicsResult, image_coverage, solve_intrinsics
from calibration.targets import BoardSpec, Detection, detect_board, parse_board_spec
from controller.errors import CalibrationError, InputError, ReachabilityError
from controller.geometry.poses import Pose, make_pose, pose_to_dict, rotation_about

F64 = NDArray[np.float64]

#: Good views the routine asks for before it says "enough".
TARGET_VIEWS = 15
#: Spread of orientations (largest rotation between two views, deg) it asks for.
TARGET_SPREAD_DEG = 30.0
#: Fraction of the 4x4 image cells that must hold corners.
TARGET_COVERAGE = 0.75


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


@dataclass
class ViewRecord:
    """One collected view: its name, robot pose (recorded), detection (None if no board)."""

    name: str
    T_base_flange: Pose
    detection: Detection | None
    joints_deg: F64 | None = None
    image_path: str | None = None


# ---------------------------------------------------------------------------------------------
# Progress
# ---------------------------------------------------------------------------------------------
@dataclass
class Progress:
    """How a collection is going: counts, orientation spread, coverage, and what is missing."""

    good: int
    total: int
    spread_deg: float
    coverage: float
    missing_cells: list[str]
    enough: bool
    target_views: int

    def line(self, width: int = 20) -> str:
        """One status line with a progress bar, for stderr."""
        frac = min(1.0, self.good / self.target_views)
        done = int(round(frac * width))
        bar = "#" * done + "." * (width - done)
        text = (f"[{bar}] {self.good}/{self.target_views} good views ({self.total} taken) | "
                f"orientation spread {self.spread_deg:.0f}/{TARGET_SPREAD_DEG:.0f} deg | "
                f"coverage {100 * self.coverage:.0f}%")
        if self.enough:
            return text + " | ENOUGH good views: confirm 'done' to solve, or add more"
        todo = []
        if self.spread_deg < TARGET_SPREAD_DEG:
            todo.append("tilt the camera more (20-40 deg) about different axes")
        if self.coverage < TARGET_COVERAGE and self.missing_cells:
            words = list(dict.fromkeys(c.split(" (")[0] for c in self.missing_cells))
            todo.append("put the board in the " + ", ".join(words[:4]) + " of the image")
        return text + (" | next: " + "; ".join(todo) if todo else "")


def orientation_spread_deg(poses: Sequence[Pose]) -> float:
    """Largest rotation angle between any two poses (deg); 0 for fewer than two."""
    best = 0.0
    Rs = [np.asarray(T)[:3, :3] for T in poses]
    for a, b in combinations(Rs, 2):
        best = max(best, float(np.degrees(Rotation.from_matrix(a.T @ b).magnitude())))
    return best


def collection_progress(views: Sequence[ViewRecord], image_size: tuple[int, int],
                        target_views: int = TARGET_VIEWS) -> Progress:
    """Progress of a collection of views against the targets of this module."""
    good = [v for v in views if v.detection is not None]
    spread = orientation_spread_deg([v.T_base_flange for v in good])
    cov = image_coverage([v.detection.image_points for v in good if v.detection is not None],
                         image_size)
    enough = (len(good) >= target_views and spread >= TARGET_SPREAD_DEG
              and cov.fraction >= TARGET_COVERAGE)
    return Progress(len(good), len(views), spread, cov.fraction, cov.missing, enough,
                    target_views)


# ---------------------------------------------------------------------------------------------
# Solving
# ---------------------------------------------------------------------------------------------
def solve_views(views: Sequence[ViewRecord], board: BoardSpec, image_size: tuple[int, int], *,
                eye_to_hand: bool = False, holdout_every: int = 5, camera_name: str = "seam_cam",
                robot_sigma_mm: float = 0.05, robot_sigma_deg: float = 0.01,
                metadata: dict[str, Any] | None = None, **hand_eye_options: Any
                ) -> tuple[Calibration, dict[str, Any]]:
    """Intrinsics + hand-eye from collected views, validated on held-out views.

    1. Intrinsics from every view with the board (outlier views rejected).
    2. Hand-eye with joint refinement of the intrinsics on every view: bad views named, left out.
    3. Validation: every ``holdout_every``-th good view is held out, the calibration solved again
       without them, and their reprojection error (with their recorded poses) checked against the
       same limit as the solution's own residual.
    4. The calibration of step 2 (all good views) is returned with its metadata.

    ``hand_eye_options`` go to :func:`calibration.handeye.solve_hand_eye` (e.g. ``max_rms_px``,
    ``max_consistency_mm``, ``max_consistency_deg``, ``method``).

    Raises :class:`CalibrationError` when the board is in too few views (naming the views
    without a board), for degenerate robot motion, too many bad views, bad residuals, or a
    failed validation (naming the held-out views).
    """
    if board.orientation_ambiguous:
        raise CalibrationError(
            f"board {board.spec}: a chessboard with {board.cols}+{board.rows} inner corners "
            f"(an even sum) looks the same turned 180 degrees, so views cannot be matched for "
            f"hand-eye; use a board with an odd sum (e.g. 9x6) or a ChArUco board")
    found = [v for v in views if v.detection is not None]
    missing = [v.name for v in views if v.detection is None]
    if len(found) < 5:
        raise CalibrationError(
            f"the board {board.spec} was found in only {len(found)} of {len(views)} views"
            f"{'; not in ' + ', '.join(missing) if missing else ''}; need at least 5: check the "
            f"board spec (inner corners for a chessboard) and that the whole board is in view",
            views_without_board=missing)
    names = [v.name for v in found]
    intr = solve_intrinsics([v.detection.image_points for v in found if v.detection],
                            [v.detection.object_points for v in found if v.detection],
                            image_size, names=names, camera_name=camera_name)
    obs = [Observation(v.detection.image_points, v.detection.object_points)
           for v in found if v.detection is not None]
    A = [v.T_base_flange for v in found]
    kw: dict[str, Any] = {"eye_to_hand": eye_to_hand, "refine_intrinsics": True,
                          "robot_sigma_mm": robot_sigma_mm, "robot_sigma_deg": robot_sigma_deg,
                          **hand_eye_options}
    he = solve_hand_eye(A, obs, intr.camera, names=names, **kw)
    validation = _validate(he, found, A, obs, intr, holdout_every, kw)
    calib = Calibration(he.camera or intr.camera)
    if eye_to_hand:
        calib.T_base_cam = he.X
    else:
        calib.T_flange_cam = he.X
    report = {
        "board": board.spec,
        "views_total": len(views),
        "views_without_board": missing,
        "intrinsics": intr.report(),
        "hand_eye": he.report(),
        "validation": validation,
    }
    calib.metadata = _metadata(he, intr, report, metadata)
    return calib, report


def _validate(he: HandEyeResult, found: Sequence[ViewRecord], A: Sequence[Pose],
              obs: Sequence[Observation], intr: IntrinsicsResult, holdout_every: int,
              kw: dict[str, Any]) -> dict[str, Any]:
    if holdout_every <= 1:
        return {"held_out": [], "note": "validation skipped (holdout_every <= 1)"}
    used = [i for i, v in enumerate(found) if v.name in he.used_views]
    held = used[holdout_every - 1::holdout_every]
    train = [i for i in range(len(found)) if i not in held]
    if len(held) == 0 or len(train) - len(he.rejected_views) < 5:
        return {"held_out": [], "note": "too few views to hold some out"}
    sub = solve_hand_eye([A[i] for i in train], [obs[i] for i in train], intr.camera,
                         names=[found[i].name for i in train], **kw)
    per = {}
    for i in held:
        r = view_residuals(sub, A[i], obs[i])
        per[found[i].name] = float(np.sqrt(np.mean(np.sum(r * r, axis=1))))
    rms = float(np.sqrt(np.mean(np.square(list(per.values())))))
    limit = max(3.0 * sub.residual_px, 1.0)
    if rms > limit:
        listed = ", ".join(f"{k} ({v:.2f} px)" for k, v in per.items())
        raise CalibrationError(
            f"validation failed: held-out views reproject with RMS {rms:.2f} px, more than "
            f"{limit:.2f} px (3x the fit's {sub.residual_px:.2f} px): {listed}. The calibration "
            f"does not predict new views; take more, better spread views", held_out=per)
    dX = _pose_delta(sub.X, he.X)
    return {"held_out": list(per), "held_out_rms_px": round(rms, 4),
            "held_out_per_view_px": {k: round(v, 4) for k, v in per.items()},
            "limit_px": round(limit, 4), "fit_without_them_residual_px": round(sub.residual_px, 4),
            "hand_eye_change_mm_deg": [round(dX[0], 4), round(dX[1], 5)], "passed": True}


def _pose_delta(a: Pose, b: Pose) -> tuple[float, float]:
    from controller.geometry.poses import pose_error

    return pose_error(a, b)


def _metadata(he: HandEyeResult, intr: IntrinsicsResult, report: dict[str, Any],
              extra: dict[str, Any] | None) -> dict[str, Any]:
    meta: dict[str, Any] = {
        "date": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "tool": "seamguide calibrate",
        "board": report["board"],
        "mode": "eye-to-hand" if he.eye_to_hand else "eye-in-hand",
        "residual_px": round(float(he.residual_px), 4),
        "intrinsics_rms_px": round(float(intr.rms_px), 4),
        "consistency_mm": round(float(he.consistency_mm), 4),
        "consistency_deg": round(float(he.consistency_deg), 5),
        "views_used": list(he.used_views),
        "views_rejected": [{"view": r["view"], "reason": r["reason"]} for r in he.rejected_views],
        "views_without_board": list(report["views_without_board"]),
    }
    if report.get("validation", {}).get("held_out"):
        meta["validation_held_out_rms_px"] = report["validation"]["held_out_rms_px"]
    meta.update(extra or {})
    return _plain(meta)


def _plain(obj: Any) -> Any:
    """Numbers and containers as plain Python types (YAML-safe)."""
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_plain(v) for v in obj]
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return _plain(obj.tolist())
    return obj


def read_image(path: str | Path) -> NDArray[np.uint8]:
    """Read an image file as greyscale uint8; :class:`InputError` naming the file if unreadable."""
    img = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    if img is None:
        raise InputError(f"image {path} cannot be read (missing, or not an image OpenCV reads)",
                         file=str(path))
    return np.asarray(img, np.uint8)


def calibrate_images(paths: Sequence[str | Path], board_spec: str | BoardSpec, *,
                     camera_name: str = "seam_cam") -> tuple[Calibration, dict[str, Any]]:
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
    size: tuple[int, int] | None = None
    for p in sorted(str(x) for x in paths):
        img = read_image(p)
        s = (img.shape[1], img.shape[0])
        if size is not None and s != size:
            raise InputError(f"image {p} is {s[0]}x{s[1]} but the first was {size[0]}x{size[1]}: "
                             f"all images must come from one camera at one resolution", file=p)
        size = s
        d = detect_board(img, board)
        if d is None:
            missing.append(Path(p).name)
        else:
            dets.append(d)
            names.append(Path(p).name)
    assert size is not None
    if len(dets) < 4:
        raise CalibrationError(
            f"the board {board.spec} was found in only {len(dets)} of {len(paths)} images"
            f"{' (not in ' + ', '.join(missing) + ')' if missing else ''}; need at least 4: check "
            f"the board spec (inner corners for a chessboard) and that the whole board is in view",
            images_without_board=missing)
    intr = solve_intrinsics([d.image_points for d in dets], [d.object_points for d in dets],
                            size, names=names, camera_name=camera_name)
    report = {"board": board.spec, "images_total": len(paths), "images_without_board": missing,
              "intrinsics": intr.report()}
    meta = _plain({"date": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
                   "tool": "seamguide calibrate --images", "board": board.spec,
                   "intrinsics_rms_px": round(float(intr.rms_px), 4),
                   "views_used": [names[i] for i in intr.used_views],
                   "views_rejected": intr.rejected_views, "images_without_board": missing})
    return Calibration(intr.camera, metadata=meta), report


def load_view_records(folder: str | Path, board: BoardSpec) -> tuple[list[ViewRecord],
                                                                     tuple[int, int]]:
    """Read every ``*.json`` view file in ``folder`` (sorted), its image, and detect the board.

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
    records = []
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
        records.append(ViewRecord(view.name, view.T_base_flange, detect_board(img, board),
                                  view.joints_deg, str(view.image_path)))
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
    records, size = load_view_records(folder, board)
    meta = {"source": f"folder {Path(folder).resolve()}"}
    meta.update(kwargs.pop("metadata", {}) or {})
    return solve_views(records, board, size, eye_to_hand=eye_to_hand, metadata=meta, **kwargs)


# ---------------------------------------------------------------------------------------------
# Automatic poses
# ---------------------------------------------------------------------------------------------
def _reachable(T: Pose, joints_near: F64, lo: F64, hi: F64) -> F64 | None:
    """Joints (deg) reaching flange pose ``T`` nearest ``joints_near``, or None (IK, box)."""
    from controller.geometry.kinematics import inverse_kinematics, irb2400

    if np.any(T[:3, 3] < lo) or np.any(T[:3, 3] > hi):
        return None
    sols = inverse_kinematics(irb2400(), T)
    if not sols:
        return None
    return min(sols, key=lambda j: float(np.max(np.abs(j - joints_near))))


def _box(T_first: Pose, workspace_min_mm: F64 | None, workspace_max_mm: F64 | None
         ) -> tuple[F64, F64]:
    p = np.asarray(T_first, float)[:3, 3]
    lo = p - 400.0 if workspace_min_mm is None else np.asarray(workspace_min_mm, float)
    hi = p + 400.0 if workspace_max_mm is None else np.asarray(workspace_max_mm, float)
    return lo, hi


def explore_poses(T_first: Pose, joints_first: F64, *, pivot_mm: float = 350.0,
                  tilt_deg: float = 8.0, workspace_min_mm: F64 | None = None,
                  workspace_max_mm: F64 | None = None) -> list[F64]:
    """Small first moves (joints, deg) that keep the board in view.

    The flange is tilted by ``tilt_deg`` about its x and y axes (both signs) and rolled about
    z, around a pivot ``pivot_mm`` along its z axis. Views from these give a rough calibration
    to aim with.
    Unreachable candidates (IK, workspace box, default first pose +- 400 mm) are skipped.
    """
    lo, hi = _box(T_first, workspace_min_mm, workspace_max_mm)
    pivot = make_pose(np.eye(3), [0.0, 0.0, pivot_mm])
    T_bp = np.asarray(T_first, float) @ pivot
    out = []
    t = float(np.radians(tilt_deg))
    for axis, ang in (([1.0, 0, 0], t), ([1.0, 0, 0], -t), ([0, 1.0, 0], t), ([0, 1.0, 0], -t),
                      ([0, 0, 1.0], 2 * t), ([1.0, 1.0, 0], t)):
        T = T_bp @ make_pose(rotation_about(axis, ang)) @ np.linalg.inv(pivot)
        j = _reachable(T, joints_first, lo, hi)
        if j is not None:
            out.append(j)
    return out


#: Automatic views: the board fills this fraction of the image width at the mean distance, and the
#: camera axis is tilted from the board normal by this range (deg). From the refinement's
#: covariance on simulated sessions (20 views, the stated noise): 0.55 and 15-40 deg left the
#: hand-eye at 0.099 mm / 0.021 deg RMS (predicted), 0.7 and 20-50 deg at 0.058 mm / 0.015 deg;
#: the depth along the optical axis is what steeper, nearer views pin down.
AUTO_FILL = 0.7
AUTO_TILT_DEG = (20.0, 50.0)


def spread_poses(T_flange_cam: Pose, board_centre_mm: F64, board_normal: F64,
                 distance_mm: float, joints_near: F64, n: int, *,
                 tilt_deg: tuple[float, float] = AUTO_TILT_DEG, roll_deg: float = 35.0,
                 offset_mm: float = 0.0, workspace_min_mm: F64 | None = None,
                 workspace_max_mm: F64 | None = None, T_first: Pose | None = None,
                 seed: int = 0, camera: Any = None, board_points_base: F64 | None = None
                 ) -> list[F64]:
    """``n`` joint targets (deg) whose camera looks at the board from well-spread directions.

    The camera sits ``distance_mm`` (x 0.85-1.15) from ``board_centre_mm`` (base frame), its axis
    tilted from the board's outward normal ``board_normal`` by ``tilt_deg`` at azimuths spread by
    the golden angle, rolled up to ``roll_deg``, aimed up to ``offset_mm`` off the centre so
    the corners cover the image. Flange poses = camera pose x ``T_flange_cam``^-1 (a rough
    hand-eye is enough), each checked with IK and the workspace box; with ``camera`` and
    ``board_points_base`` (N, 3) also that every point lands inside the image (5 % margin). Raises
    :class:`ReachabilityError` when fewer than ``n`` are found.
    """
    rng = np.random.default_rng(seed)
    ref = np.asarray(T_first if T_first is not None else np.eye(4), float)
    lo, hi = _box(ref, workspace_min_mm, workspace_max_mm)
    nz = np.asarray(board_normal, float) / np.linalg.norm(board_normal)
    ex = np.cross(nz, [0.0, 0.0, 1.0]) if abs(nz[2]) < 0.9 else np.cross(nz, [1.0, 0.0, 0.0])
    ex /= np.linalg.norm(ex)
    ey = np.cross(nz, ex)
    golden = np.pi * (3 - np.sqrt(5))
    out: list[F64] = []
    tries = 0
    X_inv = np.linalg.inv(np.asarray(T_flange_cam, float))
    centre = np.asarray(board_centre_mm, float)
    while len(out) < n and tries < 60 * n:
        tries += 1
        az = len(out) * golden + rng.uniform(-0.3, 0.3)
        tilt = np.radians(rng.uniform(*tilt_deg))
        d = distance_mm * rng.uniform(0.85, 1.15)
        direction = np.cos(tilt) * nz + np.sin(tilt) * (np.cos(az) * ex + np.sin(az) * ey)
        eye = centre + d * direction
        target = centre + rng.uniform(-offset_mm, offset_mm) * ex \
            + rng.uniform(-offset_mm, offset_mm) * ey
        z = target - eye
        z /= np.linalg.norm(z)
        x = np.cross(z, ey)
        x /= np.linalg.norm(x)
        y = np.cross(z, x)
        roll = float(np.radians(rng.uniform(-roll_deg, roll_deg)))
        T_cam = make_pose(np.column_stack([x, y, z]) @ rotation_about([0, 0, 1.0], roll), eye)
        if camera is not None and board_points_base is not None:
            uv = camera.project(board_points_base, T_cam)
            mu, mv = 0.05 * camera.width, 0.05 * camera.height
            if not (np.all(np.isfinite(uv)) and uv[:, 0].min() > mu and uv[:, 1].min() > mv
                    and uv[:, 0].max() < camera.width - mu
                    and uv[:, 1].max() < camera.height - mv):
                continue
        j = _reachable(T_cam @ X_inv, joints_near, lo, hi)
        if j is not None:
            out.append(j)
    if len(out) < n:
        raise ReachabilityError(
            f"automatic mode found only {len(out)} of {n} reachable poses looking at the board "
            f"within the workspace box; teach a first pose nearer the middle of the reach, "
            f"widen --workspace, or ask for fewer (--auto)")
    return out


def rough_calibration(views: Sequence[ViewRecord], board: BoardSpec,
                      image_size: tuple[int, int], eye_to_hand: bool = False
                      ) -> tuple[Pose, Pose, Any]:
    """A rough (X, Y, camera) from a few views, to aim the automatic poses.

    Intrinsics with only k1 (other distortion fixed at 0), closed-form hand-eye, no refinement,
    loose checks.
    """
    good = [v for v in views if v.detection is not None]
    if len(good) < 4:
        raise CalibrationError(
            f"automatic mode: the board was found in only {len(good)} of the {len(views)} "
            f"exploring views ({', '.join(v.name for v in views if v.detection is None)} without "
            f"it); start from a pose where the board is in the middle of the image, about "
            f"--pivot-mm away")
    flags = (cv2.CALIB_FIX_K2 | cv2.CALIB_FIX_K3 | cv2.CALIB_ZERO_TANGENT_DIST
             | cv2.CALIB_FIX_ASPECT_RATIO)
    intr = solve_intrinsics([v.detection.image_points for v in good if v.detection],
                            [v.detection.object_points for v in good if v.detection],
                            image_size, names=[v.name for v in good], flags=flags)
    obs = [Observation(v.detection.image_points, v.detection.object_points)
           for v in good if v.detection is not None]
    he = solve_hand_eye([v.T_base_flange for v in good], obs, intr.camera,
                        names=[v.name for v in good], eye_to_hand=eye_to_hand, refine=False,
                        min_views=4, min_rotation_deg=3.0, max_rms_px=1e9,
                        max_consistency_mm=1e9, max_consistency_deg=1e9)
    return he.X, he.Y, intr.camera


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
    return ViewRecord(name, T, detect_board(image, board), joints), image


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
                 else "NO BOARD: not used (is the whole board in the image?)")
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
        d0 = max(w, h) / AUTO_FILL * cam0.fx / cam0.width
        targets = spread_poses(X, centre, normal, d0, first.joints_deg, auto_n,
                               offset_mm=0.3 * min(w, h), tilt_deg=AUTO_TILT_DEG,
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


__all__ = ["ViewRecord", "Progress", "TeachRobot", "TeachCamera", "run_teach", "solve_views",
           "calibrate_from_folder", "calibrate_images", "explore_poses", "spread_poses",
           "rough_calibration", "collection_progress",
           "load_view_records", "read_image"]
