"""The job file (TOML): where to look, where the seam should be, how to weld it, what is allowed.

The format is documented in docs/job-file.md; ``examples/demo-job.toml`` is a complete example.
Loading validates everything once (unknown keys, types, ranges, joint limits) and returns a frozen
:class:`Job`; nothing downstream sees raw TOML.
"""

from __future__ import annotations

import os
import tomllib
from collections.abc import Collection
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import tomli_w

from controller.cell.typed_config import from_dict, load_toml
from controller.errors import ConfigError, InputError, SeamguideError
from controller.geometry.kinematics import check_joint_limits, irb2400
from controller.geometry.poses import make_pose, quat_wxyz_to_matrix
from controller.jsonio import atomic_write_text
from controller.path.path_fit import PathTolerance
from controller.path.weld_path import WeldParams, WorkspaceBox
from controller.stereo.locate import QualityLimits
from controller.stereo.seam_curve import arc_length
from controller.vision.seam_scale import check_gap_mm
from drivers.robot_commands import SafetyLimits


@dataclass(frozen=True)
class ViewSpec:
    """A view: the camera that takes it, the taught robot joints (deg), the speed there (mm/s).

    ``camera`` names one of the cell's cameras (None: the cell's only camera). A view of a camera
    on the flange needs ``joints_deg``; a view of a fixed camera needs none (no motion before it).
    """

    name: str
    joints_deg: tuple[float, ...] | None = None
    speed_mm_s: float = 200.0
    camera: str | None = None

    def __post_init__(self) -> None:
        if self.camera is not None:
            from controller.geometry.view_file import camera_name_problem

            problem = camera_name_problem(self.camera)
            if problem is not None:
                raise ConfigError(f"views.{self.name}.camera: {problem}")
        if self.joints_deg is not None:
            try:
                check_joint_limits(irb2400(), self.joints_deg, f"views.{self.name}.joints_deg")
            except SeamguideError as err:
                raise ConfigError(str(err)) from err


@dataclass(frozen=True)
class SeamSpec:
    """Where the seam should be (base frame, mm) and how to sample it."""

    nominal_centre_mm: tuple[float, float, float] = field(
        metadata={"help": "the seam's expected centre in the base frame, mm"})
    nominal_radius_mm: float = 150.0
    normal: tuple[float, float, float] | None = None
    spacing_mm: float = 2.0
    count: int | None = None
    #: Where no view sees an end of the seam (it runs out of the images), weld what the views see
    #: inside the nominal region instead of refusing the seam (default: refuse).
    clip_unseen_ends: bool = False
    #: The narrowest and the widest gap expected between the sheets (mm): with the working
    #: distance, sets the detector's pixel scales (controller.vision.seam_scale), and a dark band
    #: wider than this gap can make is refused, and a darker core narrower than its narrowest
    #: is not taken for the gap beside a shadow. None (not stated): the scales of
    #: DEFAULT_GAP_MM and neither rule.
    gap_mm: tuple[float, float] | None = None
    #: The seam as drawn (base frame, mm): two or more points along it, in order, inside the
    #: nominal sphere. Seen from each view it is the detector's nominal seam: a line
    #: ``line_tolerance_mm`` (mean) or more from it is never welded (it still makes the view
    #: ambiguous). None: no such check.
    nominal_line_mm: tuple[tuple[float, float, float], ...] | None = None
    #: How far (mm) the real seam may lie from ``nominal_line_mm`` (fixture and part tolerance).
    line_tolerance_mm: float = 10.0

    def __post_init__(self) -> None:
        if self.nominal_radius_mm <= 0:
            raise ConfigError(f"seam.nominal_radius_mm must be positive, got "
                              f"{self.nominal_radius_mm}")
        if not 0 < self.line_tolerance_mm <= self.nominal_radius_mm:
            raise ConfigError(f"seam.line_tolerance_mm must be positive and at most "
                              f"seam.nominal_radius_mm ({self.nominal_radius_mm:g}), got "
                              f"{self.line_tolerance_mm:g}")
        if self.nominal_line_mm is not None:
            check_nominal_line(self.nominal_line_mm, self.nominal_centre_mm,
                               self.nominal_radius_mm)
        try:
            if self.gap_mm is not None:
                check_gap_mm(self.gap_mm, "seam.gap_mm")
        except InputError as err:
            raise ConfigError(str(err)) from err
        if self.normal is not None and np.linalg.norm(self.normal) < 1e-9:
            raise ConfigError("seam.normal must be a non-zero vector (out of the part)")


def check_nominal_line(line: tuple[tuple[float, float, float], ...],
                       centre: tuple[float, float, float], radius: float) -> None:
    """Raise :class:`ConfigError` unless the nominal line is one a seam can be.

    ``line`` (base frame, mm): two or more points, all inside the nominal sphere (``centre``,
    ``radius`` mm), and some length.
    """
    pts = np.asarray(line, dtype=np.float64)
    if len(pts) < 2:
        raise ConfigError(f"seam.nominal_line_mm needs two or more points [x, y, z] along the "
                          f"seam (base frame, mm), got {len(pts)}")
    far = np.linalg.norm(pts - np.asarray(centre), axis=1)
    k = int(np.argmax(far))
    if far[k] > radius:
        raise ConfigError(f"seam.nominal_line_mm point {k} lies {far[k]:.1f} mm from "
                          f"seam.nominal_centre_mm, outside seam.nominal_radius_mm "
                          f"({radius:g}): the line must lie in the nominal region")
    if float(arc_length(pts)[-1]) < 1.0:
        raise ConfigError("seam.nominal_line_mm is under 1 mm long: give points along the seam")


@dataclass(frozen=True)
class ToolSpec:
    """The torch as ABB tooldata: TCP in the flange frame (mm, quaternion w, x, y, z)."""

    translation_mm: tuple[float, float, float] = (0.0, 0.0, 350.0)
    quaternion_wxyz: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)

    def pose(self) -> np.ndarray:
        """``T_flange_tcp`` (mm)."""
        from controller.geometry.poses import check_quat_wxyz

        return make_pose(quat_wxyz_to_matrix(check_quat_wxyz(self.quaternion_wxyz,
                                                             "weld.tool.quaternion_wxyz")),
                         self.translation_mm)


@dataclass(frozen=True)
class WeldSpec:
    """Weld parameters (see :class:`controller.path.weld_path.WeldParams`)."""

    speed_mm_s: float = 8.0
    work_angle_deg: float = 0.0
    travel_angle_deg: float = 10.0
    tool_offset_mm: float = 3.0
    approach_mm: float = 50.0
    arc_output: str = "do_arc_on"
    confirm: bool = False
    tool: ToolSpec = ToolSpec()


@dataclass(frozen=True)
class PathSpec:
    """How closely the segments sent to the controller follow the planned path (mm, deg)."""

    tolerance_mm: float = 0.05
    tolerance_deg: float = 0.2
    spin_deg: float = 2.0

    def __post_init__(self) -> None:
        names = {"position_mm": "tolerance_mm", "orientation_deg": "tolerance_deg",
                 "spin_deg": "spin_deg"}
        try:
            self.tolerance()
        except ConfigError as err:
            msg = str(err)
            for fitter_name, key in names.items():
                msg = msg.replace(f"path tolerance {fitter_name}", f"path.{key}")
            raise ConfigError(msg) from err

    def tolerance(self) -> PathTolerance:
        """The fitter's :class:`PathTolerance` (raises :class:`ConfigError` out of range)."""
        return PathTolerance(self.tolerance_mm, self.tolerance_deg, self.spin_deg)


@dataclass(frozen=True)
class LimitsSpec:
    """Safety limits every motion is checked against before it is sent (base frame, mm)."""

    workspace_min_mm: tuple[float, float, float] = (300.0, -900.0, -100.0)
    workspace_max_mm: tuple[float, float, float] = (1600.0, 900.0, 1500.0)
    max_speed_mm_s: float = 250.0

    def __post_init__(self) -> None:
        if any(a >= b for a, b in zip(self.workspace_min_mm, self.workspace_max_mm, strict=True)):
            raise ConfigError("limits.workspace_min_mm must be below workspace_max_mm on every "
                              "axis")
        if self.max_speed_mm_s <= 0:
            raise ConfigError("limits.max_speed_mm_s must be positive")


@dataclass(frozen=True)
class TimeoutsSpec:
    """How long each state of the cycle may take (seconds)."""

    move_s: float = 60.0
    capture_s: float = 10.0
    locate_s: float = 10.0
    plan_s: float = 30.0
    confirm_s: float = 300.0
    weld_s: float = 900.0


@dataclass(frozen=True)
class Job:
    """A weld job: views, nominal seam, weld parameters, limits, quality limits, timeouts."""

    name: str
    views: list[ViewSpec]
    seam: SeamSpec
    weld: WeldSpec = WeldSpec()
    path: PathSpec = PathSpec()
    limits: LimitsSpec = LimitsSpec()
    quality: QualityLimits = QualityLimits()
    timeouts: TimeoutsSpec = TimeoutsSpec()

    def __post_init__(self) -> None:
        names = [v.name for v in self.views]
        if len(set(names)) != len(names):
            raise ConfigError(f"views: names must be unique, got {names}")
        for v in self.views:
            if v.speed_mm_s > self.limits.max_speed_mm_s:
                raise ConfigError(f"views.{v.name}.speed_mm_s = {v.speed_mm_s} is over "
                                  f"limits.max_speed_mm_s = {self.limits.max_speed_mm_s}")
        if self.weld.speed_mm_s > self.limits.max_speed_mm_s:
            raise ConfigError("weld.speed_mm_s is over limits.max_speed_mm_s")

    def require_taught(self, fixed_cameras: Collection[str] = ()) -> None:
        """Raise :class:`ConfigError` unless >= 2 views and every view needing joints has them.

        Views of the cameras in ``fixed_cameras`` (cameras fixed in the cell) need no joints.
        """
        if len(self.views) < 2:
            raise ConfigError(f"job {self.name}: needs at least two views, has "
                              f"{len(self.views)}; teach them with `seamguide teach-view`")
        for v in self.views:
            if v.joints_deg is None and v.camera not in fixed_cameras:
                raise ConfigError(f"job {self.name}: view {v.name} has not been taught; jog the "
                                  f"robot there and run `seamguide teach-view JOB {v.name}`")

    def weld_params(self) -> WeldParams:
        """The planner's parameters for this job."""
        w = self.weld
        return WeldParams(speed_mm_s=w.speed_mm_s, work_angle_deg=w.work_angle_deg,
                          travel_angle_deg=w.travel_angle_deg, tool_offset_mm=w.tool_offset_mm,
                          approach_mm=w.approach_mm, spacing_mm=self.seam.spacing_mm,
                          count=self.seam.count, T_flange_tcp=w.tool.pose())

    def path_tolerance(self) -> PathTolerance:
        """How closely the segments sent to the controller follow the planned path."""
        return self.path.tolerance()

    def workspace(self) -> WorkspaceBox:
        """The workspace box of the limits."""
        return WorkspaceBox(self.limits.workspace_min_mm, self.limits.workspace_max_mm)

    def safety_limits(self) -> SafetyLimits:
        """The robot's safety limits for this job: the TCP box (base frame, mm) and max speed."""
        lim = self.limits
        return SafetyLimits(workspace_min_mm=lim.workspace_min_mm,
                            workspace_max_mm=lim.workspace_max_mm,
                            max_speed_mm_s=lim.max_speed_mm_s)


def load_job(path: str | os.PathLike[str]) -> Job:
    """Read and validate a job file; :class:`ConfigError` names the file and key."""
    return load_toml(Job, path)


def job_from_dict(data: dict[str, Any], path: str = "<job>") -> Job:
    """Validate an already parsed job document."""
    return from_dict(Job, data, path)


def teach_view(path: str | os.PathLike[str], name: str, joints_deg: np.ndarray,
               speed_mm_s: float | None = None) -> Job:
    """Store ``joints_deg`` (controller axes, deg) as view ``name`` in the job file.

    The view is replaced if it exists, appended otherwise. The file is validated before and after
    and rewritten atomically (comments in the file are not kept). Returns the updated job.
    """
    p = Path(path)
    load_job(p)
    data = tomllib.loads(p.read_text(encoding="utf-8"))
    views = data.setdefault("views", [])
    entry = next((v for v in views if v.get("name") == name), None)
    if entry is None:
        entry = {"name": name}
        views.append(entry)
    entry["joints_deg"] = [round(float(v), 4) for v in joints_deg]
    if speed_mm_s is not None:
        entry["speed_mm_s"] = float(speed_mm_s)
    job = job_from_dict(data, str(p))
    atomic_write_text(p, tomli_w.dumps(data))
    return job
