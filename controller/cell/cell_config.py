"""The cell configuration (TOML) of the daemon: robot, camera, calibration, jobs, records, control.

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
    camera: CameraSection
    calibration: str = field(metadata={"help": "the calibration file (YAML)"})
    jobs: dict[str, str] = field(default_factory=dict)
    records: RecordsSection = RecordsSection()
    control: ControlSection = ControlSection()
    safe_joints_deg: tuple[float, ...] | None = None
    sim: SimSection | None = None
    log_file: str | None = None
    http: HttpSection | None = None
    path: str = ""

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
    raw_wo_jobs = {k: v for k, v in raw.items() if k != "jobs"}
    cfg = from_dict(CellConfig, raw_wo_jobs, str(p))
    base = p.parent

    def res(s: str) -> str:
        return str((base / s).resolve()) if not os.path.isabs(s) else s

    resolved = CellConfig(
        name=cfg.name, robot=cfg.robot, camera=cfg.camera, calibration=res(cfg.calibration),
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
    if resolved.sim is None and (resolved.camera.url.startswith("sim:")):
        raise ConfigError(f"{p}: camera.url is sim: but there is no [sim] section naming the "
                          f"scene", file=str(p), key="sim")
    return resolved


def check_config(path: str | os.PathLike[str]) -> list[str]:
    """Full check: the configuration, every job and the calibration; returns a report."""
    import numpy as np

    from calibration.calibration_file import load_calibration
    from controller.geometry.kinematics import flange_pose, irb2400
    from controller.stereo.view_geometry import view_layout_warning

    cfg = load_cell_config(path)
    lines = [f"cell {cfg.name}: configuration {cfg.path} is valid"]
    calib = load_calibration(cfg.calibration)
    he = "with hand_eye" if calib.T_flange_cam is not None else "WITHOUT hand_eye"
    lines.append(f"calibration {cfg.calibration}: {calib.camera.width}x{calib.camera.height}, {he}")
    for name in sorted(cfg.jobs):
        job = cfg.job(name)
        taught = sum(v.joints_deg is not None for v in job.views)
        lines.append(f"job {name}: {cfg.jobs[name]}: {len(job.views)} views ({taught} taught)")
        if calib.T_flange_cam is not None and taught == len(job.views) >= 2:
            model = irb2400()
            poses = [flange_pose(model, np.asarray(v.joints_deg)) @ calib.T_flange_cam
                     for v in job.views]
            warning = view_layout_warning(poses)
            if warning is not None:
                lines.append(f"WARNING job {name}: {warning}")
    return lines
