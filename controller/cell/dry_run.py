"""The dry run: one full weld cycle against the mock controller and the simulated camera.

The mock controller runs on a real pseudo-terminal and is driven by the same client as the real
robot; the simulated camera renders the workpiece from the pose the mock robot is actually in
(its flange pose times the cell's *true* hand-eye transform). The job's view poses are "taught" by
inverse kinematics of two views suggested for the scene. Because the simulator knows the truth,
the summary reports the 3D error of the located seam and of the weld path.

``cell="fixed-stereo"`` runs the first published cell instead: two fixed cameras with different
lenses on stands (:mod:`drivers.sim.sim_fixed_cell`), each with its own calibration; their views
are captured together with no robot motion, and the mock robot only welds.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from calibration.calibration_file import Calibration, load_calibration
from controller.cell.cycle import CycleResult, WeldCycle
from controller.cell.job import Job, job_from_dict
from controller.errors import ConfigError, ReachabilityError
from controller.geometry.kinematics import inverse_kinematics, irb2400
from controller.geometry.poses import invert, make_pose, rotation_about
from controller.stereo.seam_curve import arc_length
from controller.stereo.triangulate import PolylineDistance
from drivers.mock.mock_controller import HOME_DEG as MOCK_HOME_DEG

log = logging.getLogger(__name__)

#: The IK branch the view poses are taken near, and the safe pose after a fault: the mock
#: controller's home.
HOME_JOINTS_DEG: tuple[float, ...] = tuple(float(v) for v in MOCK_HOME_DEG)

#: Dry-run scenes beyond the simulator's kinds and presets: ``open_ends`` is the ``tack_open``
#: preset's long straight seam (460-520 mm, both ends leave both images) without the tack welds
#: and spatter, for the cycle with cut ends while the detector does not yet bridge tacks.
EXTRA_SCENES: dict[str, tuple[str, dict[str, Any]]] = {
    "open_ends": ("straight", {"variety": "tack_open", "look": {"tacks": 0, "spatter": 0}})}

#: The simulated cells: one camera on the wrist, or two fixed cameras with different lenses.
CELLS = ("wrist", "fixed-stereo")


@dataclass
class DryRunReport:
    """A dry run's result plus its comparison with the simulator's truth (mm)."""

    result: CycleResult
    scene_kind: str
    seed: int
    difficulty: str
    seam_rms_mm: float | None = None
    seam_max_mm: float | None = None
    path_rms_mm: float | None = None
    path_max_mm: float | None = None
    coverage: float | None = None
    arc_on_after: bool | None = None
    cell: str = "wrist"
    motions_before_weld: int | None = None
    extra: dict[str, Any] = field(default_factory=dict)


#: View 2 is rolled about its optical axis so that the seam runs along the image diagonal. Two
#: views that differ by a rotation about one axis cannot show a wrong hand-eye transform (the
#: reconstruction just shifts); rolling one view lets the quality checks catch a 5 mm hand-eye
#: error in most cases (bench/bench_locate.py), and the diagonal is the image's longest line.
VIEW2_ROLL_DEG = float(np.degrees(np.arctan2(1704.0, 2272.0)))


def view_joints(scene: Any, cell: Any, n: int = 2, near: tuple[float, ...] = HOME_JOINTS_DEG,
                baseline_mm: float = 200.0, roll_deg: float = VIEW2_ROLL_DEG) -> list[np.ndarray]:
    """Controller joints (deg) of ``n`` suggested views of ``scene`` for the cell's camera mount.

    The views are displaced across the seam; view 2 is rolled by ``roll_deg`` about its optical
    axis. Raises :class:`ReachabilityError` when a view cannot be reached.
    """
    from drivers.sim.sim_render import suggest_view_poses

    robot = irb2400()
    out = []
    poses = suggest_view_poses(scene, cell.camera, n=n, baseline_mm=baseline_mm)
    if n >= 2:
        poses[1] = poses[1] @ make_pose(rotation_about([0, 0, 1], np.radians(roll_deg)))
    for i, T_base_cam in enumerate(poses):
        sols = inverse_kinematics(robot, T_base_cam @ invert(cell.T_flange_cam))
        if not sols:
            raise ReachabilityError(f"view {i + 1} of the simulated scene cannot be reached")
        out.append(min(sols, key=lambda j: float(np.max(np.abs(j - np.asarray(near))))))
    return out


def dry_run_job(scene: Any, joints: list[np.ndarray], confirm: bool = False,
                views: list[dict[str, Any]] | None = None,
                timeouts: dict[str, float] | None = None, clip_unseen_ends: bool = False,
                nominal_line: bool = False) -> Job:
    """A job for the simulated scene: the views, the nominal seam region and normal, the gap.

    The gap is stated as a drawing would give it, the scene's gap +-50 % (the detector's scales
    and the widest dark band it takes for the gap follow: docs/job-file.md). ``nominal_line``:
    the job states the seam's nominal line too, the scene's seam (a point every 5 mm or so) as
    a drawing would place it, moved by up to 2 mm along each axis.

    ``views`` replaces the views made from ``joints`` (e.g. fixed cameras' views by name).
    """
    region = scene.nominal_region()
    # A job's nominal region comes from a drawing or a rough teach, not from the truth: shift the
    # centre by a few millimetres and widen the radius accordingly.
    rng = np.random.default_rng(scene.seed)
    centre = np.asarray(region["centre_mm"], dtype=np.float64) + rng.uniform(-5.0, 5.0, 3)
    data: dict[str, Any] = {
        "name": f"dry-run-{scene.kind}",
        "views": views if views is not None else [
            {"name": f"view{i + 1}", "joints_deg": [round(float(v), 4) for v in j]}
            for i, j in enumerate(joints)],
        "seam": {"nominal_centre_mm": [round(float(v), 3) for v in centre],
                 "nominal_radius_mm": float(region["radius_mm"]) + 20.0,
                 "normal": [round(float(v), 6) for v in scene.surface_normal],
                 "clip_unseen_ends": clip_unseen_ends,
                 "gap_mm": [round(0.5 * scene.gap_mm, 3), round(1.5 * scene.gap_mm, 3)]},
        "weld": {"confirm": confirm},
    }
    if nominal_line:
        seam = np.asarray(scene.seam_points_mm, dtype=np.float64)
        step = max(1, len(seam) // max(2, int(arc_length(seam)[-1] / 5.0)))
        pts = np.vstack([seam[::step], seam[-1:]]) + rng.uniform(-2.0, 2.0, 3)
        data["seam"]["nominal_line_mm"] = [[round(float(v), 3) for v in q] for q in pts]
    if timeouts:
        data["timeouts"] = timeouts
    return job_from_dict(data, "<dry-run job>")


def truth_errors(seam_dense_mm: np.ndarray, weld_tcp_mm: np.ndarray, tool_axis: np.ndarray,
                 tool_offset_mm: float, truth_mm: np.ndarray) -> dict[str, float]:
    """3D errors (mm) of the located seam and of the welded torch-tip path against the truth.

    The torch tip stands ``tool_offset_mm`` off the seam on purpose; the path error is measured
    after adding that offset back along each target's torch axis.
    """
    dist = PolylineDistance(truth_mm)
    d_seam = dist(seam_dense_mm)
    d_path = dist(weld_tcp_mm + tool_offset_mm * tool_axis)
    return {"seam_rms_mm": float(np.sqrt(np.mean(d_seam**2))), "seam_max_mm": float(d_seam.max()),
            "path_rms_mm": float(np.sqrt(np.mean(d_path**2))), "path_max_mm": float(d_path.max())}


class SimRig:
    """The simulated cell assembled: scene, cell, calibration, job, mock robot and camera.

    A context manager: entering opens the mock controller (on a real pseudo-terminal, driven by the
    real client) and the simulated camera, which renders from the mock's actual flange pose times
    the cell's *true* hand-eye. Tests use it to inject faults into an otherwise real cycle.
    """

    def __init__(self, *, scene_kind: str = "s_curve", seed: int = 1, difficulty: str = "medium",
                 calibration: str | Path | Calibration | Mapping[str, Any] | None = None,
                 robot_options: str = "", camera_options: str = "", speedup: float = 50.0,
                 confirm: bool = False, n_views: int = 2, cell: str = "wrist",
                 clip_unseen_ends: bool = False, robot_scheme: str = "mock",
                 nominal_line: bool = False) -> None:
        from drivers.sim.sim_cell import default_sim_cell
        from drivers.sim.sim_scene import make_scene

        if cell not in CELLS:
            raise ConfigError(f"unknown simulated cell {cell!r}; known: {', '.join(CELLS)}")
        kind, extra = EXTRA_SCENES.get(scene_kind, (scene_kind, {}))
        self.scene = make_scene(kind, seed, difficulty, **extra)
        self.seed = seed
        self.cell_kind = cell
        self.cell = default_sim_cell()
        self.fixed: Any = None
        # One Calibration (wrist cell), or one per camera name (fixed-stereo cell).
        self.calibration: Any = None
        self.clip_unseen_ends = clip_unseen_ends
        self.nominal_line = nominal_line
        if cell == "fixed-stereo":
            self._fixed_stereo(calibration, confirm)
        elif isinstance(calibration, Mapping):
            raise ConfigError("the wrist-camera dry run takes one calibration, not one per "
                              "camera (that is --cell fixed-stereo)")
        elif isinstance(calibration, Calibration):
            self.calibration = calibration
        elif calibration is not None:
            self.calibration = load_calibration(calibration)
        else:
            self.calibration = Calibration(self.cell.camera, self.cell.T_flange_cam,
                                           metadata={"source": "exact simulated cell"})
        if self.fixed is None:
            self.job = dry_run_job(self.scene, view_joints(self.scene, self.cell, n_views),
                                   confirm, clip_unseen_ends=clip_unseen_ends,
                                   nominal_line=nominal_line)
        # robot_scheme "rapid": the controller is SGSERVER.mod itself, in the RAPID interpreter
        self.robot_url = f"{robot_scheme}://?seed={seed}&time_scale={1.0 / speedup:g}" + (
            f"&{robot_options}" if robot_options else "")
        self.camera_url = f"sim:?seed={seed}" + (f"&{camera_options}" if camera_options else "")
        self.robot: Any = None
        self.camera: Any = None

    def _fixed_stereo(self, calibration: Any, confirm: bool) -> None:
        """The fixed-stereo cell: stands for the scene, exact (or given) calibrations, the job."""
        from drivers.sim.sim_fixed_cell import fixed_stereo_cell

        self.fixed = fixed_stereo_cell(self.scene)
        given = dict(calibration) if isinstance(calibration, Mapping) else {}
        if calibration is not None and not isinstance(calibration, Mapping):
            raise ConfigError("the fixed-stereo dry run takes one calibration per camera "
                              f"({', '.join(self.fixed.cameras)}), e.g. left=cam_left.yaml")
        unknown = sorted(set(given) - set(self.fixed.cameras))
        if unknown:
            raise ConfigError(f"the fixed-stereo cell has no camera {unknown[0]!r} (cameras: "
                              f"{', '.join(self.fixed.cameras)})")
        calibs: dict[str, Calibration] = {}
        for name, cam in self.fixed.cameras.items():
            c = given.get(name)
            calibs[name] = (
                c if isinstance(c, Calibration) else load_calibration(c) if c is not None else
                Calibration(cam, T_base_cam=self.fixed.T_base_cam[name],
                            metadata={"source": "exact simulated fixed-stereo cell"}))
        self.calibration = calibs
        # The simulated cameras render their first frames (with their undistortion maps) in
        # parallel in 10-25 s on the 2-core machine; a real camera delivers in milliseconds.
        self.job = dry_run_job(self.scene, [], confirm, views=[
            {"name": name, "camera": name} for name in self.fixed.cameras],
            timeouts={"capture_s": 120.0}, clip_unseen_ends=self.clip_unseen_ends,
            nominal_line=self.nominal_line)

    def __enter__(self) -> SimRig:
        from drivers.cameras import open_camera
        from drivers.robot import open_robot

        self.robot = open_robot(self.robot_url, limits=self.job.safety_limits())
        self.robot.open()
        if self.fixed is not None:
            from drivers.camera_sync import CameraSet

            self.camera = CameraSet({
                name: open_camera(f"sim:?seed={self.seed + 7 * i}", scene=self.scene,
                                  camera_model=cam,
                                  pose_source=lambda T=self.fixed.T_base_cam[name]: T)
                for i, (name, cam) in enumerate(self.fixed.cameras.items())})
            return self
        mock, he = self.robot.mock, self.cell.T_flange_cam
        self.camera = open_camera(self.camera_url, scene=self.scene, camera_model=self.cell.camera,
                                  pose_source=lambda: mock.flange_pose() @ he)
        return self

    def __exit__(self, *exc: object) -> None:
        if self.camera is not None:
            self.camera.close()
        if self.robot is not None:
            self.robot.close()

    @property
    def mock(self) -> Any:
        """The mock controller behind the link (arc output, executed motions, fault injection)."""
        return self.robot.mock

    def cycle(self, records_root: str | Path | None, **kwargs: Any) -> WeldCycle:
        """A :class:`WeldCycle` of the rig's job (keyword arguments go to WeldCycle)."""
        kwargs.setdefault("safe_joints_deg", HOME_JOINTS_DEG)
        return WeldCycle(kwargs.pop("robot", self.robot), kwargs.pop("camera", self.camera),
                         kwargs.pop("calibration", self.calibration), kwargs.pop("job", self.job),
                         records_root=records_root, **kwargs)

    def report(self, result: CycleResult, cycle: WeldCycle | None = None) -> DryRunReport:
        """Compare a finished cycle with the simulator's truth."""
        rep = DryRunReport(result, self.scene.kind, self.seed, self.scene.difficulty,
                           arc_on_after=bool(self.mock.arc_on), cell=self.cell_kind,
                           motions_before_weld=None if cycle is None else cycle.motions_before_weld)
        if result.seam is not None and result.path is not None:
            weld = result.path.weld_targets
            errs = truth_errors(result.seam.dense_points_mm,
                                np.array([t.T_base_tcp[:3, 3] for t in weld]),
                                np.array([t.T_base_tcp[:3, 2] for t in weld]),
                                result.path.params.tool_offset_mm, self.scene.seam_points_mm)
            rep.seam_rms_mm, rep.seam_max_mm = errs["seam_rms_mm"], errs["seam_max_mm"]
            rep.path_rms_mm, rep.path_max_mm = errs["path_rms_mm"], errs["path_max_mm"]
            rep.coverage = result.seam.quality.get("coverage")
            if cycle is not None and cycle.record is not None:
                cycle.record.note(truth=errs, scene={"kind": self.scene.kind, "seed": self.seed,
                                                     "difficulty": self.scene.difficulty})
        return rep


def run_dry_run(output: str | Path | None = "dry-run", *, scene_kind: str = "s_curve",
                seed: int = 1, difficulty: str = "medium",
                calibration: str | Path | Mapping[str, Any] | None = None,
                robot_options: str = "", camera_options: str = "", speedup: float = 50.0,
                confirm: bool = False, n_views: int = 2, cell: str = "wrist",
                clip_unseen_ends: bool = False, nominal_line: bool = False) -> DryRunReport:
    """Run one cycle in the simulated cell; the record goes under ``output`` (None: no record).

    ``calibration`` is a calibration file to use instead of the cell's exact one (e.g. from a
    simulated teach session). ``robot_options`` / ``camera_options`` are extra URL query options
    (fault injection, e.g. ``drop=0.01&corrupt=0.02``). ``speedup`` runs simulated motion that
    many times faster than real time. ``cell``: ``wrist`` (one camera on the flange, two views)
    or ``fixed-stereo`` (two fixed cameras; ``calibration`` then maps camera names to files).
    ``nominal_line``: the job states the seam's nominal line (:func:`dry_run_job`).
    """
    rig = SimRig(scene_kind=scene_kind, seed=seed, difficulty=difficulty, calibration=calibration,
                 robot_options=robot_options, camera_options=camera_options, speedup=speedup,
                 confirm=confirm, n_views=n_views, cell=cell, clip_unseen_ends=clip_unseen_ends,
                 nominal_line=nominal_line)
    with rig:
        cycle = rig.cycle(output)
        result = cycle.run()
        return rig.report(result, cycle)


def summary_text(rep: DryRunReport) -> str:
    """A short human summary: states and times, seam length, weld points, errors vs truth."""
    r = rep.result
    cell = f"{rep.cell} cell, " if rep.cell != "wrist" else ""
    lines = [f"dry run: {cell}scene {rep.scene_kind} (seed {rep.seed}, {rep.difficulty}) -> "
             f"{r.status.upper()}" + (f": {r.reason}" if r.reason else "")]
    hist = r.state_history
    for (name, t0), nxt in zip(hist, [*hist[1:], None], strict=True):
        dur = "" if nxt is None else f"{nxt[1] - t0:8.3f} s"
        lines.append(f"  {name:<15}{dur}")
    if r.seam is not None:
        lines.append(f"  seam: {r.seam.length_mm:.1f} mm, {len(r.seam.points_mm)} points, "
                     f"coverage {r.seam.quality['coverage']:.1%}")
        ends = r.seam.quality.get("ends", [])
        if any(e["status"] != "seen" for e in ends):
            lines.append("  seam ends: " + "; ".join(
                f"{e['end']} {e['status']}" + (f" ({e['clipped_mm']:.1f} mm cut, "
                                                f"{e.get('border_trimmed_mm', 0.0):.1f} mm at the "
                                                f"image borders; not seen: "
                                                f"{', '.join(e['not_seen'])})"
                                                if e["status"] == "clipped" else "")
                for e in ends))
    if r.path is not None:
        lines.append(f"  weld path: {len(r.path.weld_targets)} weld points + approach/depart, "
                     f"tool offset {r.path.params.tool_offset_mm:.1f} mm")
    if rep.seam_rms_mm is not None:
        lines.append(f"  error vs truth: seam {rep.seam_rms_mm:.3f} mm RMS / "
                     f"{rep.seam_max_mm:.3f} mm max; weld path {rep.path_rms_mm:.3f} mm RMS / "
                     f"{rep.path_max_mm:.3f} mm max")
    if r.capture_skews_s:
        lines.append("  views captured together, trigger skew "
                     + ", ".join(f"{1000 * s:.2f} ms" for s in r.capture_skews_s)
                     + f"; robot motions before the weld: {rep.motions_before_weld}")
    lines.append(f"  arc after the cycle: {'ON' if rep.arc_on_after else 'off'}")
    if r.record_path is not None:
        lines.append(f"  record: {r.record_path}")
    return "\n".join(lines)
