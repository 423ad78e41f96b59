"""One weld cycle: drive the robot and camera through the cycle machine's states.

The states are those of :mod:`controller.cell.cycle_machine`.

The cycle orchestrates; the maths is in pure functions (detect, locate, plan). Fallible work is
done *before* the state change that reports it, so a failure leaves the machine in the state where
it happened and then goes to ``fault``. Every blocking call gets the time left in its state. On
``fault`` or ``aborted`` the robot is made safe first: arc off, motion stopped (the robot's
``abort``), then the configured safe pose when the link still works. Nothing is sent to the robot
for welding unless detection, triangulation quality, planning and reach checks all passed.

The robot and camera are the two small interfaces of drivers/ (``Robot``, ``Camera``); the cycle
cannot tell a mock from the real thing.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from calibration.calibration_file import Calibration, calibration_to_dict
from controller.cell.cell_config import DEFAULT_CAMERA
from controller.cell.cycle_machine import CycleState, build_machine
from controller.cell.cycle_record import CycleRecord
from controller.cell.job import Job
from controller.cell.seam_plot import seam_plot_png
from controller.cell.view_cameras import ViewCamera, capture_groups, resolve_view_cameras
from controller.errors import CameraError, CycleAborted, InputError, RobotFault, SeamguideError
from controller.geometry.camera_model import CameraModel
from controller.geometry.kinematics import RobotModel, check_pose_consistency, flange_pose, irb2400
from controller.geometry.poses import pose_to_dict
from controller.path.path_fit import fit_segments
from controller.path.rapid_export import rapid_module
from controller.path.weld_path import WeldPath, plan_weld
from controller.stereo.locate import Seam3D, ViewObservation, locate_seam

log = logging.getLogger(__name__)

#: Joint tolerance (deg) between a commanded view pose and the joints read back after the move.
ARRIVAL_TOLERANCE_DEG = 0.05


class CycleTimeout(RobotFault):
    """A state of the cycle took longer than its configured timeout."""

    exit_code = 17


@dataclass
class CycleResult:
    """What a cycle did: final status, reason, the located seam and path, the record folder."""

    status: str
    reason: str | None = None
    error: SeamguideError | None = None
    seam: Seam3D | None = None
    path: WeldPath | None = None
    record_path: Path | None = None
    state_history: list[tuple[str, float]] = field(default_factory=list)
    camera_poses: list[np.ndarray] = field(default_factory=list)
    capture_skews_s: list[float] = field(default_factory=list)
    detections: list[Any] = field(default_factory=list)
    images: list[np.ndarray] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        """True when the cycle ended ``done``."""
        return self.status == "done"


Detector = Callable[..., Any]
Confirmer = Callable[[WeldPath, float], bool]


def _default_detector() -> Detector:
    from controller.vision.seam_detect import detect_seam

    return detect_seam


class WeldCycle:
    """Runs one cycle of ``job``; construct, then :meth:`run` (blocking) in one thread.

    ``request_abort`` may be called from any other thread at any time.
    """

    state: CycleState
    # Triggers bound by transitions (declared for type checkers; not assigned, so the machine
    # attaches them).
    start: Callable[[], bool]
    arrived: Callable[[], bool]
    captured: Callable[[], bool]
    located: Callable[[], bool]
    planned: Callable[[], bool]
    confirmed: Callable[[], bool]
    welded: Callable[[], bool]
    fault: Callable[[], bool]
    abort: Callable[[], bool]
    reset: Callable[[], bool]

    def __init__(self, robot: Any, camera: Any,
                 calibration: Calibration | Mapping[str, Calibration], job: Job, *,
                 records_root: str | Path | None = None, confirm: Confirmer | None = None,
                 detector: Detector | None = None, robot_model: RobotModel | None = None,
                 safe_joints_deg: tuple[float, ...] | None = None,
                 clock: Callable[[], float] = time.monotonic,
                 on_state: Callable[[str], None] | None = None) -> None:
        self.robot = robot
        # One camera and calibration (a one-camera cell), or both by camera name.
        self.cameras: Mapping[str, Any] = (camera if isinstance(camera, Mapping)
                                           else {DEFAULT_CAMERA: camera})
        self.calibrations: dict[str, Calibration] = (
            dict(calibration) if isinstance(calibration, Mapping)
            else {DEFAULT_CAMERA: calibration})
        self.job = job
        self.model = robot_model or irb2400()
        self.confirm = confirm
        self.detector = detector or _default_detector()
        self.safe_joints_deg = safe_joints_deg
        self.clock = clock
        self.on_state = on_state
        self.records_root = records_root
        self.record: CycleRecord | None = None
        self.result = CycleResult(status="incomplete")
        self._view_index = 0
        self._groups: list[list[int]] = []
        self._group_index = 0
        self._view_cams: list[ViewCamera] = []
        self._motions = 0
        self._joints_read: dict[int, np.ndarray] = {}
        self._state_t0 = clock()
        self._abort = threading.Event()
        self._abort_reason = ""
        self._made_safe = False
        build_machine(self)

    # ------------------------------------------------------------------ machine callbacks
    def more_views(self) -> bool:
        """Condition: views remain to be captured."""
        return self._group_index + 1 < len(self._groups)

    def no_motion_next(self) -> bool:
        """Condition: the next views to capture are fixed cameras' (no motion before them)."""
        nxt = self._group_index + (0 if self.state is CycleState.IDLE else 1)
        if nxt >= len(self._groups):
            return False
        v = self._view_cams[self._groups[nxt][0]]
        return v.fixed and v.joints_deg is None

    def needs_confirmation(self) -> bool:
        """Condition: the job asks the operator to confirm the planned path."""
        return bool(self.job.weld.confirm)

    def after_state_change(self) -> None:
        """Record every state change with its time (record.json and the result)."""
        self._state_t0 = self.clock()
        name = self.state.value
        self.result.state_history.append((name, self._state_t0))
        if self.record is not None:
            self.record.state(name)
        if self.on_state is not None:
            self.on_state(name)
        log.info("cycle state: %s", name)

    # transitions names the enter callbacks after the Enum member's *name* (FAULT, ABORTED), not
    # its value: on_enter_fault was never called, and a fault left the robot as it was.
    def on_enter_FAULT(self) -> None:
        """Entering fault: make the robot safe before anything else."""
        self._make_safe(move_to_safe_pose=True)

    def on_enter_ABORTED(self) -> None:
        """Entering aborted: make the robot safe (arc off, stop); no further motion."""
        self._make_safe(move_to_safe_pose=False)

    # ------------------------------------------------------------------ public
    @property
    def motions_before_weld(self) -> int:
        """Robot motions this cycle commanded before welding (moves to views)."""
        return self._motions

    def request_abort(self, reason: str = "operator abort") -> None:
        """Abort from any thread: the arc goes off and motion stops now; the cycle then ends."""
        self._abort_reason = reason
        self._abort.set()
        try:
            self.robot.abort()
        except SeamguideError as err:
            log.error("abort request could not reach the robot: %s", err)

    def run(self) -> CycleResult:
        """Run the whole cycle; never raises for a cycle failure (see ``result.status``)."""
        if self.records_root is not None:
            self.record = CycleRecord(self.records_root, self.job.name)
            self.result.record_path = self.record.path
            for cam, calib in self.calibrations.items():
                name = "calibration.yaml" if cam == DEFAULT_CAMERA else f"calibration_{cam}.yaml"
                self.record.save_text(name, _yaml(calibration_to_dict(calib)))
        try:
            self._view_cams = resolve_view_cameras(self.job, self.calibrations)
            self._groups = capture_groups(self._view_cams)
            self.result.images = [np.zeros((0, 0), np.uint8)] * len(self.job.views)
            self.result.camera_poses = [np.eye(4)] * len(self.job.views)
            self._check_abort()
            self.start()
            for g, group in enumerate(self._groups):
                self._group_index = g
                if self.state is CycleState.MOVING_TO_VIEW:
                    self._move_to_view(group[0])
                    self.arrived()
                self._capture(group)
                self.captured()
            if self.record is not None:
                self.record.note(robot_motions_before_weld=self._motions)
            seam = self._locate()
            self.located()
            path = self._plan(seam)
            self.planned()
            if self.state is CycleState.CONFIRMING:
                self._confirm(path)
                self.confirmed()
            self._weld(path)
            self.welded()
            self._finish("done", None)
        except CycleAborted as err:
            self._end(CycleState.ABORTED, "aborted", str(err), err)
        except SeamguideError as err:
            if self._abort.is_set():
                self._end(CycleState.ABORTED, "aborted", self._abort_reason, err)
            else:
                self._end(CycleState.FAULT, "fault", str(err), err)
        except Exception as err:  # noqa: BLE001 - a bug must still leave the robot safe
            log.exception("unexpected error in the weld cycle")
            wrapped = SeamguideError(f"internal error: {type(err).__name__}: {err}")
            self._end(CycleState.FAULT, "fault", str(wrapped), wrapped)
        return self.result

    # ------------------------------------------------------------------ steps
    def _remaining(self, limit_s: float) -> float:
        left = limit_s - (self.clock() - self._state_t0)
        if left <= 0:
            raise CycleTimeout(f"state {self.state.value} took longer than its {limit_s:.0f} s "
                               f"timeout", state=self.state.value)
        return left

    def _check_abort(self) -> None:
        if self._abort.is_set():
            raise CycleAborted(self._abort_reason or "aborted")

    def _move_to_view(self, i: int) -> None:
        view = self.job.views[i]
        t = self.job.timeouts.move_s
        self._motions += 1
        handle = self.robot.move_joints(np.asarray(view.joints_deg), speed_mm_s=view.speed_mm_s)
        handle.wait(timeout_s=self._remaining(t))
        self._check_abort()
        joints = np.asarray(self.robot.read_joints(), dtype=np.float64)
        off = float(np.max(np.abs(joints - np.asarray(view.joints_deg))))
        if off > ARRIVAL_TOLERANCE_DEG:
            raise RobotFault(f"view {view.name}: the robot stopped {off:.3f} deg from the taught "
                             f"joints (tolerance {ARRIVAL_TOLERANCE_DEG} deg)", joints_deg=joints)
        reported = self.robot.read_pose()
        check_pose_consistency(self.model, joints, reported)
        self._joints_read[i] = joints

    def _camera_pose(self, i: int) -> np.ndarray:
        """``T_base_cam`` of view ``i``: a fixed camera's calibrated pose, or FK @ hand-eye."""
        vc = self._view_cams[i]
        calib = self.calibrations[vc.camera]
        if vc.fixed:
            assert calib.T_base_cam is not None
            return np.asarray(calib.T_base_cam)
        assert calib.T_flange_cam is not None
        return flange_pose(self.model, self._joints_read[i], check_limits=False) @ \
            calib.T_flange_cam

    def _capture(self, group: list[int]) -> None:
        from controller.vision.image_io import check_image
        from drivers.camera_sync import grab_together

        left = self._remaining(self.job.timeouts.capture_s)
        cams = [self._view_cams[i].camera for i in group]
        if len(group) == 1:
            frames = [self.cameras[cams[0]].grab()]
            skew = None
        else:
            got, skew = grab_together(self.cameras, cams, left)
            frames = [f.image for f in got]
        for i, cam, frame in zip(group, cams, frames, strict=True):
            name = self.job.views[i].name
            try:
                image = check_image(frame, name=f"view {name} from camera {cam}",
                                    camera=self.calibrations[cam].camera)
            except InputError as err:  # a black, saturated or wrong-size frame is a camera fault
                raise CameraError(str(err), view=name, camera=cam) from err
            T_base_cam = self._camera_pose(i)
            self.result.images[i] = image
            self.result.camera_poses[i] = T_base_cam
            if self.record is not None:
                self.record.save_image(f"{name}.png", image)
                self.record.save_json(f"{name}.json", self._view_doc(i, T_base_cam, skew))
        if skew is not None:
            self.result.capture_skews_s.append(skew)
            log.info("views %s captured together, trigger skew %.2f ms",
                     ", ".join(self.job.views[i].name for i in group), 1000 * skew)
            if self.record is not None:
                self.record.note(capture_skew_ms=[round(1000 * s, 3)
                                                  for s in self.result.capture_skews_s])
        self._check_abort()

    def _view_doc(self, i: int, T_base_cam: np.ndarray, skew: float | None) -> dict[str, Any]:
        """The record's view file of view ``i`` (DESIGN.md's contract, plus what was measured)."""
        view, vc = self.job.views[i], self._view_cams[i]
        doc: dict[str, Any] = {"image": f"{view.name}.png"}
        if vc.camera != DEFAULT_CAMERA or len(self.calibrations) > 1:
            doc["camera"] = vc.camera
        if vc.fixed:
            doc["camera_pose"] = pose_to_dict(T_base_cam)
        else:
            doc["joints_deg"] = [round(float(v), 4) for v in self._joints_read[i]]
            doc["camera_pose_computed"] = pose_to_dict(T_base_cam)
        if skew is not None:
            doc["capture_skew_ms"] = round(1000 * skew, 3)
        return doc

    def _locate(self) -> Seam3D:
        from controller.stereo.view_geometry import view_layout_warning
        from controller.vision.seam_detect import detect_seams

        t = self.job.timeouts.locate_s
        cams = [self.calibrations[vc.camera].camera for vc in self._view_cams]
        warning = view_layout_warning(self.result.camera_poses)
        if warning is not None:
            log.warning("job %s: %s", self.job.name, warning)
            if self.record is not None:
                self.record.note(view_layout_warning=warning)
        observations = []
        dets = detect_seams(self.result.images, camera=cams,
                            rois=[self._roi(c, T) for c, T in zip(cams, self.result.camera_poses,
                                                                  strict=True)],
                            detector=self.detector)
        for view, cam, image, T, det in zip(self.job.views, cams, self.result.images,
                                            self.result.camera_poses, dets, strict=True):
            self.result.detections.append(det)
            if self.record is not None:
                self._save_overlay(view.name, image, det)
            observations.append(ViewObservation(cam, T, det.points_px, view.name,
                                                getattr(det, "end_kinds", None)))
            self._remaining(t)
        if self.record is not None:
            self.record.note(detections=[
                {"view": v.name, "confidence": round(float(d.confidence), 3)}
                for v, d in zip(self.job.views, dets, strict=True)])
        seam = locate_seam(observations, self.job.quality, spacing_mm=self.job.seam.spacing_mm,
                           count=self.job.seam.count,
                           nominal_region=(np.asarray(self.job.seam.nominal_centre_mm),
                                           self.job.seam.nominal_radius_mm),
                           clip_unseen_ends=self.job.seam.clip_unseen_ends)
        self.result.seam = seam
        clipped = [e for e in seam.quality.get("ends", []) if e["status"] == "clipped"]
        if clipped:
            note = "; ".join(f"{e['end']} not seen by any view ({'; '.join(e['not_seen'])}): "
                             f"clipped to the nominal region ({e['clipped_mm']:.1f} mm cut)"
                             for e in clipped)
            log.warning("job %s: seam %s", self.job.name, note)
        if self.record is not None:
            self.record.note(seam_ends=seam.quality.get("ends", []))
        self._remaining(t)
        self._check_abort()
        return seam

    def _roi(self, cam: CameraModel, T_base_cam: np.ndarray) -> tuple[int, int, int, int] | None:
        """Bounding box (px) of the job's nominal seam sphere seen by ``cam`` at ``T_base_cam``."""
        c = np.asarray(self.job.seam.nominal_centre_mm)
        r = self.job.seam.nominal_radius_mm
        pts = c + r * np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1)
                                for sz in (-1, 1)], dtype=np.float64)
        uv = cam.project(pts, T_base_cam)
        if np.any(~np.isfinite(uv)):
            return None
        x0, y0 = np.clip(np.floor(uv.min(axis=0)), 0, [cam.width - 1, cam.height - 1])
        x1, y1 = np.clip(np.ceil(uv.max(axis=0)), 0, [cam.width - 1, cam.height - 1])
        if x1 - x0 < 16 or y1 - y0 < 16:
            return None
        return int(x0), int(y0), int(x1), int(y1)

    def _save_overlay(self, name: str, image: np.ndarray, det: Any) -> None:
        try:
            from controller.vision.seam_overlay import draw_overlay
        except ImportError:
            return
        assert self.record is not None
        self.record.save_image(f"{name}_overlay.png", draw_overlay(image, det))

    def _plan(self, seam: Seam3D) -> WeldPath:
        self._remaining(self.job.timeouts.plan_s)
        normal = self.job.seam.normal
        if normal is None:
            from controller.stereo.view_geometry import nominal_normal_from_views

            normal_v = nominal_normal_from_views(self.result.camera_poses)
        else:
            normal_v = np.asarray(normal, dtype=np.float64)
        path = plan_weld(self.model, seam.points_mm, normal_v, self.job.weld_params(),
                         self.job.workspace(),
                         start_joints_deg=np.asarray(self.robot.read_joints()))
        # the controller interpolates lines and circles: send the fewest within the tolerance
        path.segments = fit_segments([t.T_base_tcp for t in path.weld_targets],
                                     self.job.path_tolerance())
        self.result.path = path
        if self.record is not None:
            self._save_seam(seam, path)
        self._remaining(self.job.timeouts.plan_s)
        self._check_abort()
        return path

    def _save_seam(self, seam: Seam3D, path: WeldPath) -> None:
        assert self.record is not None
        self.record.save_json("seam.json", locate_output(seam, path))
        self.record.note(weld_segments=[g.to_dict() for g in path.segments])
        self.record.save_text("weld_path.mod", rapid_module(
            path, arc_output=self.job.weld.arc_output, comment=f"job {self.job.name}"))
        tips = np.array([t.T_base_tcp[:3, 3] for t in path.targets])
        self.record.save_bytes("seam_plot.png", seam_plot_png(seam.points_mm, tips,
                                                              title=f"job {self.job.name}"))

    def _confirm(self, path: WeldPath) -> None:
        if self.confirm is None:
            raise CycleAborted("the job asks for operator confirmation but no operator interface "
                               "is connected; set weld.confirm = false or run from the daemon")
        ok = self.confirm(path, self._remaining(self.job.timeouts.confirm_s))
        self._check_abort()
        if not ok:
            raise CycleAborted("the operator did not confirm the weld path")

    def _weld(self, path: WeldPath) -> None:
        t = self.job.timeouts.weld_s
        self.robot.set_tool(path.params.T_flange_tcp)
        approach = path.targets[0]
        self.robot.move_joints(approach.joints_deg, speed_mm_s=self.job.views[0].speed_mm_s
                               ).wait(timeout_s=self._remaining(t))
        self._check_abort()
        self.robot.upload_path(*path.upload())
        self._check_abort()
        handle = self.robot.run_weld(speed_mm_s=path.params.speed_mm_s)
        handle.wait(timeout_s=self._remaining(t))
        self._check_abort()

    # ------------------------------------------------------------------ ending
    def _make_safe(self, move_to_safe_pose: bool) -> None:
        if self._made_safe:
            return
        self._made_safe = True
        try:
            self.robot.abort()
        except SeamguideError as err:
            log.error("could not make the robot safe over the link: %s", err)
            return
        if move_to_safe_pose and self.safe_joints_deg is not None:
            try:
                self.robot.move_joints(np.asarray(self.safe_joints_deg), speed_mm_s=100.0
                                       ).wait(timeout_s=self.job.timeouts.move_s)
            except SeamguideError as err:
                log.error("could not move to the safe pose: %s", err)

    def _end(self, dest: CycleState, status: str, reason: str, err: SeamguideError) -> None:
        self.result.error = err
        if self.state not in (CycleState.FAULT, CycleState.ABORTED):
            try:
                self.abort() if dest is CycleState.ABORTED else self.fault()
            except Exception:  # noqa: BLE001 - the robot must be made safe regardless
                log.exception("state change to %s failed", dest.value)
                self._make_safe(move_to_safe_pose=False)
        else:
            self._make_safe(move_to_safe_pose=False)
        self._finish(status, reason, error=type(err).__name__, exit_code=err.exit_code,
                     **_jsonable(err.details))

    def _finish(self, status: str, reason: str | None, **details: Any) -> None:
        self.result.status = status
        self.result.reason = reason
        if self.record is not None:
            self.record.finish(status, reason, **details)


def locate_output(seam: Seam3D, path: WeldPath | None) -> dict[str, Any]:
    """The ``seamguide locate`` output contract: seam points (base frame, mm), path, quality."""
    return {"seam_points_mm": [[round(float(v), 4) for v in p] for p in seam.points_mm],
            "weld_path": path.to_json() if path is not None else [],
            "quality": seam.quality}


def _jsonable(d: dict[str, Any]) -> dict[str, Any]:
    out = {}
    for k, v in d.items():
        if isinstance(v, np.ndarray):
            out[k] = v.tolist()
        elif isinstance(v, int | float | str | bool | list | dict) or v is None:
            out[k] = v
        else:
            out[k] = str(v)
    return out


def _yaml(doc: dict[str, Any]) -> str:
    import yaml

    return yaml.safe_dump(doc, sort_keys=False, default_flow_style=None)
