"""The cell's cameras, opened from the cell configuration (one camera, or several by name).

Real cameras open by URL (:func:`drivers.cameras.open_camera`); ``sim:`` cameras are wired to the
simulated workpiece of the ``[sim]`` section and to the mock robot where they ride on the flange.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from calibration.calibration_file import Calibration
from controller.cell.cell_config import CellConfig, load_calibrations
from controller.errors import ConfigError, SeamguideError
from controller.geometry.poses import Pose


def open_cell_camera(cfg: CellConfig, robot: Any) -> Any:
    """The cell's camera, or its cameras by name (a ``CameraSet``) when it lists several.

    A ``sim:`` camera renders the simulated workpiece: a one-camera cell's from the mock robot's
    actual flange pose times the simulated cell's true hand-eye (``robot.url = "mock://..."``);
    a named camera from its calibration (a fixed camera from its ``camera_pose``, a flange camera
    from the mock's flange pose times its ``hand_eye``), with the calibration's intrinsics.
    Raises :class:`ConfigError` / :class:`CameraError`.
    """
    from drivers.cameras import open_camera

    if not cfg.cameras:
        assert cfg.camera is not None
        if not cfg.camera.url.startswith("sim:"):
            return open_camera(cfg.camera.url)
        from drivers.sim.sim_cell import default_sim_cell

        cell = default_sim_cell()
        he = cell.T_flange_cam
        mock = _sim_mock(cfg, robot)
        return open_camera(cfg.camera.url, scene=_sim_scene(cfg), camera_model=cell.camera,
                           pose_source=lambda: np.asarray(mock.flange_pose() @ he))
    from drivers.camera_sync import CameraSet

    calibs = load_calibrations(cfg)
    opened: dict[str, Any] = {}
    try:
        for name, entry in cfg.cameras.items():
            if not entry.url.startswith("sim:"):
                opened[name] = open_camera(entry.url)
                continue
            c = calibs[name]
            opened[name] = open_camera(entry.url, scene=_sim_scene(cfg), camera_model=c.camera,
                                       pose_source=_sim_pose_source(cfg, robot, c))
    except SeamguideError:
        CameraSet(opened).close()
        raise
    return CameraSet(opened)


def _sim_pose_source(cfg: CellConfig, robot: Any, calib: Calibration) -> Callable[[], Pose]:
    """Where a simulated named camera is: fixed (its camera_pose) or on the mock's flange."""
    if calib.T_base_cam is not None:
        T = np.asarray(calib.T_base_cam)
        return lambda: T
    mock, he = _sim_mock(cfg, robot), np.asarray(calib.T_flange_cam)
    return lambda: np.asarray(mock.flange_pose() @ he)


def _sim_mock(cfg: CellConfig, robot: Any) -> Any:
    if getattr(robot, "mock", None) is None:
        raise ConfigError(f"{cfg.path}: a sim: camera (a simulated camera) renders the mock "
                          f"robot's workpiece: robot.url must be mock://")
    return robot.mock


def _sim_scene(cfg: CellConfig) -> Any:
    from drivers.sim.sim_scene import make_scene

    assert cfg.sim is not None
    return make_scene(cfg.sim.scene, cfg.sim.seed, cfg.sim.difficulty)
