"""The cell configuration (TOML) of the daemon: robot, cameras, calibrations, jobs, records.

A cell has one camera (``[camera] url`` and ``calibration``, as before) or several cameras by name
(``[cameras.NAME] url, calibration``), each with its own calibration file (a camera on the flange,
``hand_eye``, or fixed in the cell, ``camera_pose``).

Documented in docs/cell-config.md; ``examples/sim-cell.toml`` is a complete cell against the mock
controller and the simulated camera. Relative paths are relative to the configuration file's
folder. Validated once at start-up (and on SIGHUP) by :func:`load_cell_config`; errors name the file
and the key. ``seamguide check-config --config FILE`` runs the same validation and also loads every
job and the calibration.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from calibration.calibration_file import Calibration
from controller.cell.job import Job, load_job
from controller.errors import ConfigError


@dataclass(frozen=True)
class RobotSection:
    """How to reach the controller."""

    url: str = field(metadata={"help": "the robot URL, e.g. /dev/ttyS0 or mock://"})
    timeout_s: float = 5.0
    reconnect_min_s: float = 0.5
    reconnect_max_s: float = 30.0

    def __post_init__(self) -> None:
        if not self.url:
            raise ConfigError("robot.url must not be empty")
        if not 0 < self.reconnect_min_s <= self.reconnect_max_s:
            raise ConfigError("robot.reconnect_min_s must be positive and <= reconnect_max_s")


@dataclass(frozen=True)
class CameraSection:
    """Which camera to open (``opencv:0``, ``files:/path/*.png``, ``sim:``)."""

    url: str = field(metadata={"help": "the camera URL, e.g. opencv:0 or sim:"})


@dataclass(frozen=True)
class CameraEntry:
    """One named camera of the cell: its URL and its calibration file."""

    url: str = field(metadata={"help": "the camera URL, e.g. opencv:0 or sim:"})
    calibration: str = field(metadata={"help": "the camera's calibration file (YAML)"})


#: The name of the camera of a one-camera cell (``[camera]`` and ``calibration``).
DEFAULT_CAMERA = "camera"


@dataclass(frozen=True)
class SimSection:
    """For a simulated cell only: the workpiece the simulated camera renders."""

    scene: str = "s_curve"
    seed: int = 1
    difficulty: str = "medium"


@dataclass(frozen=True)
class RecordsSection:
    """Where cycle records go and how long they are kept."""

    dir: str = "records"
    max_age_days: float = 30.0
    max_total_mb: float = 2000.0


@dataclass(frozen=True)
class ControlSection:
    """The local control socket (owner-only Unix socket); no network listener."""

    socket: str = "seamguide.sock"
    max_line_bytes: int = 4096


@dataclass(frozen=True)
class HttpSection:
    """The operator station (a web page and ``/metrics``); absent: no network listener.

    ``bind`` other than a loopback address needs ``token_file`` (TOML, owner-only, with a
    ``viewer`` and an ``operator`` token); see docs/operator-station.md.
    """

    bind: str = "127.0.0.1"
    port: int = 8080
    token_file: str | None = None
    max_request_bytes: int = 16384

    def __post_init__(self) -> None:
        if not 0 <= self.port <= 65535:
            raise ConfigError(f"http.port must be 0..65535, got {self.port}")
        if not 1024 <= self.max_request_bytes <= 1 << 20:
            raise ConfigError("http.max_request_bytes must be 1024..1048576")


@dataclass(frozen=True)
class CellConfig:
    """The whole cell configuration; paths already resolved against the file's folder."""

    name: str
    robot: RobotSection
    camera: CameraSection | None = None
    calibration: str | None = None
    cameras: dict[str, CameraEntry] = field(default_factory=dict)
    jobs: dict[str, str] = field(default_factory=dict)
    records: RecordsSection = RecordsSection()
    control: ControlSection = ControlSection()
    safe_joints_deg: tuple[float, ...] | None = None
    sim: SimSection | None = None
    log_file: str | None = None
    http: HttpSection | None = None
    path: str = ""

    def camera_entries(self) -> dict[str, CameraEntry]:
        """Every camera by name; a one-camera cell's camera is called :data:`DEFAULT_CAMERA`."""
        if self.cameras:
            return dict(self.cameras)
        assert self.camera is not None and self.calibration is not None
        return {DEFAULT_CAMERA: CameraEntry(self.camera.url, self.calibration)}

    def job(self, name: str) -> Job:
        """Load the job called ``name``; :class:`ConfigError` lists the known jobs."""
        if name not in self.jobs:
            known = ", ".join(sorted(self.jobs)) or "none"
            raise ConfigError(f"unknown job {name!r}; the cell {self.name} knows: {known}",
                              job=name)
        return load_job(self.jobs[name])


def load_cell_config(path: str | os.PathLike[str]) -> CellConfig:
    """Read, validate and resolve a cell configuration file."""
    import tomllib

    from controller.cell.typed_config import from_dict

    p = Path(path).resolve()
    # Validate types with the loader first (it names file and key), then resolve paths.
    try:
        raw = tomllib.loads(p.read_text(encoding="utf-8"))
    except FileNotFoundError as err:
        raise ConfigError(f"cell configuration {path} does not exist", file=str(path)) from err
    except tomllib.TOMLDecodeError as err:
        raise ConfigError(f"{path} is not valid TOML: {err}", file=str(path)) from err
    jobs = raw.get("jobs", {})
    if not isinstance(jobs, dict) or not all(isinstance(v, str) for v in jobs.values()):
        raise ConfigError(f"{p}: jobs: must be a table of name = \"job file\"", file=str(p))
    cameras = _cameras(raw.get("cameras", {}), p)
    raw_rest = {k: v for k, v in raw.items() if k not in ("jobs", "cameras")}
    cfg = from_dict(CellConfig, raw_rest, str(p))
    if cameras and (cfg.camera is not None or cfg.calibration is not None):
        raise ConfigError(f"{p}: give either [camera] and calibration (one camera) or "
                          f"[cameras.NAME] tables (several), not both", file=str(p),
                          key="cameras")
    if not cameras and (cfg.camera is None or cfg.calibration is None):
        missing = "camera" if cfg.camera is None else "calibration"
        raise ConfigError(f"{p}: {missing}: missing; a cell needs [camera] url and calibration, "
                          f"or a [cameras.NAME] table (url, calibration) per camera",
                          file=str(p), key=missing)
    base = p.parent

    def res(s: str) -> str:
        return str((base / s).resolve()) if not os.path.isabs(s) else s

    resolved = CellConfig(
        name=cfg.name, robot=cfg.robot, camera=cfg.camera,
        calibration=res(cfg.calibration) if cfg.calibration is not None else None,
        cameras={k: CameraEntry(c.url, res(c.calibration)) for k, c in cameras.items()},
        jobs={k: res(v) for k, v in jobs.items()},
        records=RecordsSection(res(cfg.records.dir), cfg.records.max_age_days,
                               cfg.records.max_total_mb),
        control=ControlSection(res(cfg.control.socket), cfg.control.max_line_bytes),
        safe_joints_deg=cfg.safe_joints_deg, sim=cfg.sim,
        log_file=res(cfg.log_file) if cfg.log_file else None,
        http=(HttpSection(cfg.http.bind, cfg.http.port,
                          res(cfg.http.token_file) if cfg.http.token_file else None,
                          cfg.http.max_request_bytes) if cfg.http is not None else None),
        path=str(p))
    if cfg.safe_joints_deg is not None:
        from controller.geometry.kinematics import check_joint_limits, irb2400

        try:
            check_joint_limits(irb2400(), cfg.safe_joints_deg, "safe_joints_deg")
        except Exception as err:  # noqa: BLE001 - any refusal is a configuration error here
            raise ConfigError(f"{p}: {err}", file=str(p), key="safe_joints_deg") from err
    if len(resolved.control.socket.encode()) > 100:
        raise ConfigError(f"{p}: control.socket path is too long for a Unix socket (max ~100 "
                          f"bytes): {resolved.control.socket}", file=str(p))
    sim_cams = [k for k, c in resolved.camera_entries().items() if c.url.startswith("sim:")]
    if resolved.sim is None and sim_cams:
        raise ConfigError(f"{p}: camera {sim_cams[0]} is sim: but there is no [sim] section "
                          f"naming the scene", file=str(p), key="sim")
    return resolved


def _cameras(node: Any, p: Path) -> dict[str, CameraEntry]:
    """The ``[cameras.NAME]`` tables, validated (names, keys) by the typed loader."""
    from controller.cell.typed_config import from_dict
    from controller.geometry.view_file import camera_name_problem

    if not isinstance(node, dict):
        raise ConfigError(f"{p}: cameras: must be tables [cameras.NAME] with url and calibration",
                          file=str(p), key="cameras")
    out = {}
    for name, entry in node.items():
        if (problem := camera_name_problem(name)) is not None:
            raise ConfigError(f"{p}: cameras.{name}: {problem}", file=str(p), key=f"cameras.{name}")
        if not isinstance(entry, dict):
            raise ConfigError(f"{p}: cameras.{name}: must be a table with url and calibration",
                              file=str(p), key=f"cameras.{name}")
        out[name] = from_dict(CameraEntry, entry, str(p), f"cameras.{name}")
    return out


def load_calibrations(cfg: CellConfig) -> dict[str, Calibration]:
    """Every camera's calibration by camera name; :class:`CalibrationError` names the file."""
    from calibration.calibration_file import load_calibration

    return {k: load_calibration(e.calibration) for k, e in cfg.camera_entries().items()}


def check_config(path: str | os.PathLike[str]) -> list[str]:
    """Full check: the configuration, every camera's calibration and every job; returns a report.

    Raises :class:`ConfigError` listing every problem of the jobs' views against the cameras
    (each naming the job, the view and the camera), or the calibration's error.
    """
    import numpy as np

    from calibration.calibration_file import load_calibration
    from controller.cell.view_cameras import view_camera_problems
    from controller.geometry.kinematics import flange_pose, irb2400
    from controller.stereo.view_geometry import view_layout_warning

    cfg = load_cell_config(path)
    lines = [f"cell {cfg.name}: configuration {cfg.path} is valid"]
    calibs = {}
    for cam, entry in cfg.camera_entries().items():
        calib = load_calibration(entry.calibration)
        calibs[cam] = calib
        where = ("with hand_eye" if calib.T_flange_cam is not None else
                 "fixed (camera_pose)" if calib.T_base_cam is not None else
                 "WITHOUT hand_eye or camera_pose")
        name = "" if cam == DEFAULT_CAMERA and not cfg.cameras else f"camera {cam}: "
        lines.append(f"{name}calibration {entry.calibration}: {calib.camera.width}x"
                     f"{calib.camera.height}, {where}")
    problems = []
    for name in sorted(cfg.jobs):
        job = cfg.job(name)
        taught = sum(v.joints_deg is not None for v in job.views)
        one = next(iter(calibs)) if len(calibs) == 1 else ""
        fixed = sum(getattr(calibs.get(v.camera or one), "T_base_cam", None) is not None
                    for v in job.views)
        lines.append(f"job {name}: {cfg.jobs[name]}: {len(job.views)} views ({taught} taught"
                     + (f", {fixed} of fixed cameras)" if fixed else ")"))
        found = view_camera_problems(job, calibs)
        untaught = [p for p in found if "has no joints" in p]
        problems += [p for p in found if p not in untaught]
        if found:
            continue
        model = irb2400()
        only = next(iter(calibs)) if len(calibs) == 1 else None
        poses: list[np.ndarray] = []
        for v in job.views:
            c = calibs[v.camera or only or ""]
            if c.T_flange_cam is not None:
                poses.append(flange_pose(model, np.asarray(v.joints_deg)) @ c.T_flange_cam)
            elif c.T_base_cam is not None:
                poses.append(np.asarray(c.T_base_cam))
        warning = view_layout_warning(poses)
        if warning is not None:
            lines.append(f"WARNING job {name}: {warning}")
    if problems:
        raise ConfigError(f"{cfg.path}: " + "; ".join(problems), file=cfg.path,
                          problems=problems)
    return lines
