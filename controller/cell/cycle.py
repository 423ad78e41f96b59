"""One weld cycle: drive the robot and camera through the states of ``cell.cycle_machine``.

The cycle orchestrates; the maths is in pure functions (detect, locate, plan). Fallible work is
done *before* the state change that reports it, so a failure leaves the machine in the state where
it happened and then goes to ``fault``. Every blocking call gets the time left in its state. On
``fault`` or ``aborted`` the robot is made safe first: arc off, motion stopped (the robot's
``abort``), then the safe pose when the link still works. Nothing is sent to the robot for welding
unless detection, quality, planning and reach checks all passed; the arc is on over the seam only.
"""

from __future__ import annotations

import functools
import logging
import threading
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from calibration.calibration_file import Calibration
from controller.cell.cell_config import DEFAULT_CAMERA
from controller.cell.cycle_machine import CycleState, build_machine
from controller.cell.cycle_outputs import (
    jsonable,
    save_calibration,
    save_detections,
    save_seam,
    save_view,
)
from controller.cell.cycle_record import CycleRecord
from controller.cell.cycle_result import CycleResult, CycleTimeout
from controller.cell.guidance import (
    Detector,
    GuidanceSettings,
    Located,
    ViewInput,
    locate_views,
    plan_path,
    settings_from_job,
)
from controller.cell.job import Job
from controller.cell.view_cameras import ViewCamera, capture_groups, resolve_view_cameras
from controller.errors import CameraError, CycleAborted, InputError, RobotFault, SeamguideError
from controller.geometry.kinematics import RobotModel, check_pose_consistency, flange_pose, irb2400
from controller.path.weld_path import WeldPath

log = logging.getLogger(__name__)

#: Joint tolerance (deg) between a commanded view pose and the joints read back after the move.
ARRIVAL_TOLERANCE_DEG = 0.05

Confirmer = Callable[[WeldPath, float], bool]


def _default_detector() -> Detector:
    from controller.vision.seam_detect import detect_seam

    return detect_seam


class WeldCycle:
    """Runs one cycle of ``job``: construct, :meth:`run` (blocking); abort from any thread."""

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
        self._joints_now: np.ndarray | None = None  # read after the last (view) motion
        self._state_t0 = clock()
        self._abort = threading.Event()
        self._abort_reason = ""
        self._made_safe = False
        build_machine(self)

    # ------------------------------------------------------------------ machine callbacks
    @functools.cached_property
    def settings(self) -> GuidanceSettings:
        """The pipeline settings of the job (read when the cycle first locates)."""
        return settings_from_job(self.job)
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
                save_calibration(self.record, calib, name)
        # Every motion of the cycle (views, weld path and its arcs, safe pose): the job's limits.
        self.robot.limits = self.job.safety_limits()
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
            located = self._locate()
            self.located()
            path = self._plan(located)
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
        self._joints_now = joints

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
                vc = self._view_cams[i]
                save_view(self.record, name, image, T_base_cam, skew_s=skew,
                          camera=cam if cam != DEFAULT_CAMERA or len(self.calibrations) > 1
                          else None, joints_deg=None if vc.fixed else self._joints_read[i])
        if skew is not None:
            self.result.capture_skews_s.append(skew)
            log.info("views %s captured together, trigger skew %.2f ms",
                     ", ".join(self.job.views[i].name for i in group), 1000 * skew)
            if self.record is not None:
                self.record.note(capture_skew_ms=[round(1000 * s, 3)
                                                  for s in self.result.capture_skews_s])
        self._check_abort()

    def _views(self) -> list[ViewInput]:
        """The captured views for the guidance pipeline, each with its own camera's model."""
        return [ViewInput(view.name, image, self.calibrations[vc.camera].camera, T)
                for view, vc, image, T in zip(self.job.views, self._view_cams, self.result.images,
                                              self.result.camera_poses, strict=True)]

    def _locate(self) -> Located:
        t = self.job.timeouts.locate_s
        views = self._views()

        def detected(dets: list[Any]) -> None:
            # A view refused: its error stands in its place (the others' pictures are kept too).
            if not any(isinstance(d, SeamguideError) for d in dets):
                self.result.detections.extend(dets)
            if self.record is not None:
                save_detections(self.record, views, dets, self.settings.nominal_line_mm)

        located = locate_views(views, self.settings, detector=self.detector,
                               on_detections=detected, check=lambda: self._remaining(t),
                               note=self.record.note if self.record is not None else None)
        self.result.seam = located.seam
        self._remaining(t)
        self._check_abort()
        return located

    def _plan(self, located: Located) -> WeldPath:
        self._remaining(self.job.timeouts.plan_s)
        # from the joints read at the last view (nothing moved since); read if no view moved
        start = self._joints_now if self._joints_now is not None else self.robot.read_joints()
        path = plan_path(located, self.settings, self.model, start_joints_deg=start)
        self.result.path = path
        if self.record is not None:
            save_seam(self.record, located.seam, path, self.job)
        self._remaining(self.job.timeouts.plan_s)
        self._check_abort()
        return path

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
        # Arc on over the seam only: reach its first point and leave for the depart dry.
        speed = path.params.speed_mm_s
        self.robot.move_linear(path.start, speed_mm_s=speed).wait(timeout_s=self._remaining(t))
        self._check_abort()
        self.robot.upload_path(*path.upload(), start=path.start)
        self._check_abort()
        self.robot.run_weld(speed_mm_s=speed).wait(timeout_s=self._remaining(t))
        self._check_abort()
        self.robot.move_linear(path.targets[-1].T_base_tcp, speed_mm_s=speed
                               ).wait(timeout_s=self._remaining(t))

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
                     **jsonable(err.details))

    def _finish(self, status: str, reason: str | None, **details: Any) -> None:
        self.result.status = status
        self.result.reason = reason
        if self.record is not None:
            self.record.finish(status, reason, **details)
