"""The cell daemon: waits for cycle requests, runs weld cycles, survives faults, loses nothing.

Requests come from the controller (the RAPID program's operator cycle request, read as a robot
event) and from the local control socket (``seamguide ctl``). One cycle runs at a time, in the main
thread; the control socket is served from another thread, and an abort from it reaches the running
cycle through :meth:`WeldCycle.request_abort` (arc off first).

Start-up order: mark records left ``incomplete`` by a crash as ``interrupted``; connect to the robot
and make it safe (abort: arc off, motion stopped) *before anything else*; open the camera; serve.
A fault in a cycle never ends the daemon: a link fault reconnects the robot with exponential
backoff, a camera fault reopens the camera. SIGTERM aborts a running weld (arc off) and exits;
SIGHUP reloads the configuration between cycles. Under systemd (``Type=notify``) it reports
READY, STATUS and watchdog pings.
"""

from __future__ import annotations

import contextlib
import logging
import signal
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

from calibration.calibration_file import Calibration
from controller.cell.cell_cameras import open_cell_camera
from controller.cell.cell_config import CellConfig, load_calibrations, load_cell_config
from controller.cell.confirmation import OperatorConfirmation
from controller.cell.control_socket import ControlServer
from controller.cell.cycle import WeldCycle
from controller.cell.cycle_record import mark_interrupted, read_record_if_any, rotate_records
from controller.cell.request_queue import RequestQueue
from controller.cell.sd_notify import notify, watchdog_interval_s
from controller.cell.watchdog import Watchdog
from controller.errors import CameraError, ConfigError, LinkError, SeamguideError

log = logging.getLogger(__name__)


#: The job timeout (a ``TimeoutsSpec`` field) that bounds each cycle state, for the watchdog.
STATE_TIMEOUTS = {"moving_to_view": "move_s", "capturing": "capture_s", "locating": "locate_s",
                  "planning": "plan_s", "confirming": "confirm_s", "welding": "weld_s"}


def open_cell_robot(cfg: CellConfig) -> Any:
    """The cell's robot (not yet opened).

    It is opened with the driver's default safety limits; each cycle sets its job's limits
    (box, speed) on it before its first motion (:meth:`WeldCycle.run`). The daemon itself never
    moves the robot outside a cycle.
    """
    from drivers.robot import open_robot

    return open_robot(cfg.robot.url, timeout_s=cfg.robot.timeout_s)


class Daemon:
    """The long-running cell process; :meth:`serve` blocks until SIGTERM or :meth:`shutdown`."""

    def __init__(self, config_path: str | Path) -> None:
        self.config_path = Path(config_path)
        self.cfg = load_cell_config(config_path)
        self._lock = threading.Lock()
        #: Cycle requests from the control socket, waiting in order; ``ctl pause`` holds them.
        self.requests = RequestQueue()
        self._stop = threading.Event()
        self._reload = threading.Event()
        self._cycle: WeldCycle | None = None
        self._cycle_state = "idle"
        self._cycle_job: str | None = None
        self.counters = {"cycles_done": 0, "cycles_faulted": 0, "cycles_aborted": 0,
                         "requests_rejected": 0}
        self.last_cycle: dict[str, Any] | None = None
        self.robot: Any = None
        self.camera: Any = None
        self.calibration: dict[str, Calibration] | None = None
        self.robot_state = "disconnected"
        self.reloads = 0
        self.camera_state = "closed"
        self._backoff = self.cfg.robot.reconnect_min_s
        self._server: ControlServer | None = None
        self.ready = threading.Event()
        self._ended = threading.Condition(self._lock)
        self._cycles_ended = 0  # counted once the observers (the station's metrics) saw the end
        #: A weld path waiting for the operator (``ctl confirm`` / ``ctl reject``).
        self.confirmation = OperatorConfirmation(self._stop)
        #: Liveness for systemd's watchdog: serve-loop check-ins and bounded waits.
        self.watchdog = Watchdog()
        self._cycle_timeouts: Any = None
        self._cycle_views: list[str] = []
        #: Called (from the serve thread) with each event: ``("state", {"state": name})`` and
        #: ``("cycle_end", {...last_cycle, "error_kind", "record_doc"})``; the operator
        #: station's metrics listen here. An observer must not block or raise.
        self.observers: list[Callable[[str, dict[str, Any]], None]] = []

    # ------------------------------------------------------------------ control requests
    def handle_request(self, req: dict[str, Any]) -> dict[str, Any]:
        """Answer one control-socket request (thread-safe)."""
        cmd = req.get("cmd")
        if cmd == "status":
            return self.status()
        if cmd == "start":
            job = req.get("job")
            if not isinstance(job, str) or not job:
                return self._reject("start needs a job name: {\"cmd\": \"start\", \"job\": NAME}")
            try:
                self.cfg.job(job)
            except ConfigError as err:
                return self._reject(str(err))
            n = self.requests.put(job, "control socket")
            return {"ok": True, "queued": job, "queue_length": n}
        if cmd in ("confirm", "reject"):
            if not self.confirmation.answer(cmd == "confirm"):
                return self._reject(f"{cmd}: no weld path is waiting for confirmation")
            return {"ok": True, "confirmed": cmd == "confirm"}
        if cmd == "abort":
            dropped = self.requests.clear()
            with self._lock:
                cycle = self._cycle
            self.confirmation.answer(False)  # a path waiting for the operator: that is a no
            if cycle is not None:
                cycle.request_abort("operator abort (control socket)")
            return {"ok": True, "aborted": cycle is not None, "dropped_requests": dropped}
        if cmd in ("pause", "resume"):
            self.requests.set_paused(cmd == "pause")
            return {"ok": True, "paused": cmd == "pause"}
        return self._reject(f"unknown command {cmd!r}; use start, status, abort, pause, "
                            "resume, confirm, reject")

    def _reject(self, why: str) -> dict[str, Any]:
        with self._lock:
            self.counters["requests_rejected"] += 1
        return {"ok": False, "error": why}

    def status(self) -> dict[str, Any]:
        """The status answer: state (``idle`` when waiting), counters, last cycle, devices."""
        with self._lock:
            return {"ok": True, "cell": self.cfg.name, "state": self._cycle_state,
                    "job": self._cycle_job, "paused": self.requests.paused,
                    "robot": self.robot_state, "camera": self.camera_state,
                    "queue_length": len(self.requests), "counters": dict(self.counters),
                    "config_reloads": self.reloads,
                    "awaiting_confirmation": self.confirmation.awaiting,
                    "record": (str(self._cycle.record.path) if self._cycle is not None
                               and self._cycle.record is not None else None),
                    "views": list(self._cycle_views),
                    "last_cycle": self.last_cycle}

    def wait_cycles(self, n: int, timeout_s: float) -> bool:
        """Block until ``n`` cycles have ended and the observers saw it; False on timeout."""
        with self._lock:
            return self._ended.wait_for(lambda: self._cycles_ended >= n, timeout=timeout_s)

    # ------------------------------------------------------------------ life cycle
    def request_stop(self, reason: str = "shutdown") -> None:
        """Stop after making the robot safe: a running weld is aborted (arc off) first."""
        self._stop.set()
        self.confirmation.wake()
        self.requests.wake()
        with self._lock:
            cycle = self._cycle
        if cycle is not None:
            threading.Thread(target=cycle.request_abort, args=(reason,), daemon=True).start()

    def install_signal_handlers(self) -> None:
        """SIGTERM/SIGINT stop safely; SIGHUP reloads the configuration between cycles.

        A handler runs in the main thread, which may hold the daemon's lock at that moment: it
        only sets flags and hands the rest (taking the lock, aborting the cycle) to a thread.
        """
        def stop(name: str) -> None:
            self._stop.set()
            threading.Thread(target=self.request_stop, args=(f"shutdown ({name})",),
                             daemon=True).start()

        signal.signal(signal.SIGTERM, lambda *_: stop("SIGTERM"))
        signal.signal(signal.SIGINT, lambda *_: stop("SIGINT"))
        signal.signal(signal.SIGHUP, lambda *_: self._reload.set())

    def serve(self) -> int:
        """Run until stopped; returns the exit code (0 after a clean stop)."""
        marked = mark_interrupted(self.cfg.records.dir)
        for d in marked:
            log.warning("cycle record %s was left incomplete by a previous run: marked "
                        "interrupted", d)
        self.calibration = load_calibrations(self.cfg)
        self._connect_robot()
        self._server = ControlServer(self.cfg.control.socket, self.handle_request,
                                     self.cfg.control.max_line_bytes)
        self._server.start()
        notify("READY=1")
        notify(f"STATUS=cell {self.cfg.name}: waiting for cycle requests")
        log.info("daemon ready: cell %s, control socket %s", self.cfg.name,
                 self.cfg.control.socket)
        self.ready.set()
        wd = watchdog_interval_s()
        if wd is not None:
            threading.Thread(target=self.watchdog.run, args=(wd, self._stop), name="watchdog",
                             daemon=True).start()
        try:
            while not self._stop.is_set():
                self.watchdog.check_in()
                if self._reload.is_set():
                    self._do_reload()
                if self.robot is None:
                    self._connect_robot()
                    continue
                request = self._next_request()
                if request is not None:
                    self._run_cycle(*request)
        finally:
            self._shutdown()
        return 0

    def _next_request(self) -> tuple[str, str] | None:
        # Wait for a request (woken by start/resume/stop) for at most 0.1 s, then look at the
        # controller's events.
        request = self.requests.next(self._stop, 0.1)
        if request is not None or self._stop.is_set() or self.requests.paused:
            return request
        try:
            event = self.robot.poll_event(timeout_s=0.1)
        except LinkError as err:
            log.error("robot link lost while idle: %s", err)
            self._drop_robot()
            return None
        if event is not None and event.kind == "cycle_request":
            try:
                self.cfg.job(event.job)
            except ConfigError as err:
                log.error("the controller asked for job %r: %s", event.job, err)
                with self._lock:
                    self.counters["requests_rejected"] += 1
                return None
            return event.job, "controller"
        return None

    def _connect_robot(self) -> None:
        """Open the robot link and make the robot safe; back off exponentially on failure."""
        try:
            if self.robot is None:
                robot = open_cell_robot(self.cfg)
                robot.open()
                self.robot = robot
            self.robot.abort()  # make safe before anything else
            log.info("robot link open; robot made safe (arc off, motion stopped)")
            with self._lock:
                self.robot_state = "connected"
            self._backoff = self.cfg.robot.reconnect_min_s
            self._open_camera()
        except LinkError as err:
            with self._lock:
                self.robot_state = f"reconnecting ({err})"
            log.error("robot link: %s; retrying in %.1f s", err, self._backoff)
            self._drop_robot()
            self._busy(self._backoff)
            self._stop.wait(self._backoff)
            self._backoff = min(self._backoff * 2, self.cfg.robot.reconnect_max_s)

    def _open_camera(self) -> None:
        if self.camera is not None or self.robot is None:
            return
        try:
            self.camera = open_cell_camera(self.cfg, self.robot)
            self.camera_state = "open"
        except CameraError as err:
            self.camera_state = f"failed ({err})"
            log.error("camera: %s", err)

    def _drop_robot(self) -> None:
        if self.robot is not None:
            with contextlib.suppress(SeamguideError):
                self.robot.close()
        self.robot = None
        if self.camera is not None:
            with contextlib.suppress(SeamguideError):
                self.camera.close()
        self.camera = None
        self.camera_state = "closed"

    def _run_cycle(self, job_name: str, source: str) -> None:
        try:
            job = self.cfg.job(job_name)
        except ConfigError as err:
            self._reject(str(err))
            return
        self._open_camera()
        if self.camera is None:
            with self._lock:
                self.counters["cycles_faulted"] += 1
                self.last_cycle = {"job": job_name, "status": "fault",
                                   "reason": f"camera unavailable: {self.camera_state}",
                                   "record": None}
            self._notify("cycle_end", {**self.last_cycle, "error_kind": "CameraError",
                                       "record_doc": None})
            self._signal_ended()
            return
        assert self.calibration is not None
        cycle = WeldCycle(self.robot, self.camera, self.calibration, job,
                          records_root=self.cfg.records.dir,
                          safe_joints_deg=self.cfg.safe_joints_deg, on_state=self._on_state,
                          confirm=self.confirmation.ask)
        with self._lock:
            self._cycle = cycle
            self._cycle_job = job_name
            self._cycle_timeouts = job.timeouts
            self._cycle_views = [v.name for v in job.views]
        notify(f"STATUS=cycle of job {job_name} running")
        log.info("cycle of job %s started (requested by %s)", job_name, source)
        try:
            result = cycle.run()
        finally:
            with self._lock:
                self._cycle = None
                self._cycle_state = "idle"
                self._cycle_job = None
            self.watchdog.idle()
        key = {"done": "cycles_done", "aborted": "cycles_aborted"}.get(result.status,
                                                                      "cycles_faulted")
        with self._lock:
            self.counters[key] += 1
            self.last_cycle = {"job": job_name, "status": result.status,
                               "reason": result.reason,
                               "record": str(result.record_path) if result.record_path else None,
                               "views": [v.name for v in job.views]}
        self._notify("cycle_end", {**self.last_cycle,
                                   "error_kind": (type(result.error).__name__
                                                  if result.error is not None else None),
                                   "record_doc": read_record_if_any(result.record_path)})
        self._signal_ended()
        log.info("cycle of job %s ended %s%s", job_name, result.status,
                 f": {result.reason}" if result.reason else "")
        notify(f"STATUS=last cycle {result.status}; waiting for cycle requests")
        if isinstance(result.error, LinkError):
            self._drop_robot()
            with self._lock:
                self.robot_state = "reconnecting"
        elif isinstance(result.error, CameraError):
            with contextlib.suppress(SeamguideError):
                self.camera.close()
            self.camera = None
            self.camera_state = "closed"
        rotate_records(self.cfg.records.dir, self.cfg.records.max_age_days,
                       self.cfg.records.max_total_mb)

    def _on_state(self, name: str) -> None:
        with self._lock:
            limit = getattr(self._cycle_timeouts, STATE_TIMEOUTS.get(name, ""), None)
            self._cycle_state = name
        self._busy(limit if limit is not None else 60.0)
        self._notify("state", {"state": name})

    def _signal_ended(self) -> None:
        # after the observers: a waiter then reads metrics that hold the cycle (a race before)
        with self._lock:
            self._cycles_ended += 1
            self._ended.notify_all()

    def _notify(self, event: str, data: dict[str, Any]) -> None:
        for observer in list(self.observers):
            try:
                observer(event, data)
            except Exception:  # an observer's bug must never stop a cycle
                log.exception("observer of daemon event %s failed", event)

    def _busy(self, seconds: float) -> None:
        """The serve thread enters a wait bounded by ``seconds``: the watchdog keeps pinging."""
        self.watchdog.busy(seconds)

    def _do_reload(self) -> None:
        self._reload.clear()
        try:
            new = load_cell_config(self.config_path)
            calib = load_calibrations(new)
        except SeamguideError as err:
            log.error("SIGHUP: configuration not reloaded, keeping the old one: %s", err)
            return
        devices_changed = (new.robot != self.cfg.robot
                           or new.camera_entries() != self.cfg.camera_entries()
                           or new.sim != self.cfg.sim)
        with self._lock:
            self.cfg = new
            self.calibration = calib
            self.reloads += 1
        if devices_changed:
            self._drop_robot()
        log.info("configuration reloaded from %s", self.config_path)

    def _shutdown(self) -> None:
        notify("STOPPING=1")
        if self.robot is not None:
            try:
                self.robot.abort()
            except SeamguideError as err:
                log.error("could not make the robot safe at shutdown: %s", err)
        self._drop_robot()
        if self._server is not None:
            self._server.stop()
        log.info("daemon stopped")
