"""The shipped examples stay consistent with the simulated cell they describe."""

from pathlib import Path

import numpy as np

from calibration.calibration_file import load_calibration
from controller.cell.cell_config import check_config, load_cell_config
from controller.cell.dry_run import view_joints
from controller.cell.job import load_job
from controller.geometry.poses import pose_error
from drivers.sim.sim_cell import default_sim_cell
from drivers.sim.sim_scene import make_scene

EXAMPLES = Path(__file__).parent.parent / "examples"


def test_sim_calibration_is_the_simulated_cell():
    calib = load_calibration(EXAMPLES / "sim-calibration.yaml")
    cell = default_sim_cell()
    assert np.allclose(calib.camera.K, cell.camera.K)
    assert np.allclose(calib.camera.dist, cell.camera.dist)
    d_mm, d_deg = pose_error(calib.T_flange_cam, cell.T_flange_cam)
    assert d_mm < 1e-9 and d_deg < 1e-9


def test_demo_job_views_look_at_the_sim_cell_scene():
    cfg = load_cell_config(EXAMPLES / "sim-cell.toml")
    scene = make_scene(cfg.sim.scene, cfg.sim.seed, cfg.sim.difficulty)
    expected = view_joints(scene, default_sim_cell())
    job = load_job(EXAMPLES / "demo-job.toml")
    for v, e in zip(job.views, expected, strict=True):
        assert np.max(np.abs(np.asarray(v.joints_deg) - e)) < 1e-3
    centre = np.asarray(job.seam.nominal_centre_mm)
    dist = np.linalg.norm(scene.seam_points_mm - centre, axis=1)
    assert dist.max() < job.seam.nominal_radius_mm


def test_sim_cell_config_checks():
    report = check_config(EXAMPLES / "sim-cell.toml")
    assert any("job demo" in line and "2 taught" in line for line in report)
    assert not any(line.startswith("WARNING") for line in report)


def test_views_rolled_alike_are_warned_about(tmp_path):
    import shutil

    from controller.stereo.view_geometry import roll_difference_deg, view_layout_warning

    cfg = load_cell_config(EXAMPLES / "sim-cell.toml")
    scene = make_scene(cfg.sim.scene, cfg.sim.seed, cfg.sim.difficulty)
    cell = default_sim_cell()
    from controller.geometry.kinematics import flange_pose, irb2400

    def cams(joints):
        return [flange_pose(irb2400(), j) @ cell.T_flange_cam for j in joints]

    rolled = cams(view_joints(scene, cell))
    alike = view_joints(scene, cell, roll_deg=0.0)
    assert abs(roll_difference_deg(*rolled) - 36.87) < 3.0  # seen along the mean axis
    assert roll_difference_deg(*cams(alike)) < 2.0
    assert view_layout_warning(rolled) is None
    assert "would go unnoticed" in view_layout_warning(cams(alike))
    # check-config says so for a job taught that way.
    for name in ("sim-cell.toml", "demo-job.toml", "sim-calibration.yaml"):
        shutil.copy(EXAMPLES / name, tmp_path / name)
    job = tmp_path / "demo-job.toml"
    text = job.read_text()
    old = [line for line in text.splitlines() if line.startswith("joints_deg")]
    for line, j in zip(old, alike, strict=True):
        text = text.replace(line, "joints_deg = [" + ", ".join(f"{v:.4f}" for v in j) + "]")
    job.write_text(text)
    report = check_config(tmp_path / "sim-cell.toml")
    assert any(line.startswith("WARNING job demo") and "roll" in line for line in report)


def test_fixed_stereo_example_is_the_simulated_cell():
    from drivers.sim.sim_fixed_cell import fixed_stereo_cell

    cfg = load_cell_config(EXAMPLES / "fixed-stereo-cell.toml")
    scene = make_scene(cfg.sim.scene, cfg.sim.seed, cfg.sim.difficulty)
    cell = fixed_stereo_cell(scene)
    assert set(cfg.cameras) == set(cell.cameras) == {"left", "right"}
    for name, entry in cfg.cameras.items():
        calib = load_calibration(entry.calibration)
        assert np.allclose(calib.camera.K, cell.cameras[name].K)
        assert np.allclose(calib.camera.dist, cell.cameras[name].dist)
        assert calib.T_flange_cam is None
        d_mm, d_deg = pose_error(calib.T_base_cam, cell.T_base_cam[name])
        assert d_mm < 1e-6 and d_deg < 1e-6
    job = load_job(EXAMPLES / "fixed-stereo-job.toml")
    assert [v.camera for v in job.views] == ["left", "right"]
    dist = np.linalg.norm(scene.seam_points_mm - np.asarray(job.seam.nominal_centre_mm), axis=1)
    assert dist.max() < job.seam.nominal_radius_mm
    report = check_config(EXAMPLES / "fixed-stereo-cell.toml")
    assert any("job fixed-demo" in line and "2 of fixed cameras" in line for line in report)
    assert not any(line.startswith("WARNING") for line in report)


def _fixed_copy(tmp_path, job_text):
    import shutil

    for name in ("fixed-stereo-cell.toml", "cam_left.yaml", "cam_right.yaml",
                 "fixed-stereo-job.toml"):
        shutil.copy(EXAMPLES / name, tmp_path / name)
    job = tmp_path / "fixed-stereo-job.toml"
    job.write_text(job_text(job.read_text()))
    return tmp_path / "fixed-stereo-cell.toml"


def test_check_config_names_job_view_and_camera(tmp_path):
    import pytest

    from controller.errors import ConfigError

    cell = _fixed_copy(tmp_path, lambda t: t.replace('camera = "right"', 'camera = "middle"'))
    with pytest.raises(ConfigError) as info:
        check_config(cell)
    msg = str(info.value)
    assert "job fixed-demo: view right: camera 'middle' is not a camera of this cell" in msg
    assert "cameras: left, right" in msg
    cell = _fixed_copy(tmp_path, lambda t: t.replace('camera = "left"\n', ''))
    with pytest.raises(ConfigError, match="job fixed-demo: view left does not name its camera"):
        check_config(cell)
    cell = _fixed_copy(tmp_path, lambda t: t.replace('camera = "left"', 'camera = "no good"'))
    with pytest.raises(ConfigError, match=r"views.left.camera: a camera name must be"):
        check_config(cell)


def test_cell_config_cameras_errors(tmp_path):
    import pytest

    from controller.errors import ConfigError

    base = (EXAMPLES / "fixed-stereo-cell.toml").read_text()
    bad = {
        "both": base.replace("[cameras.left]", '[camera]\nurl = "sim:"\n\n[cameras.left]'),
        "key": base.replace('calibration = "cam_left.yaml"', 'calib = "cam_left.yaml"'),
        "none": base.split("[cameras.left]")[0] + "[sim]" + base.split("[sim]")[1],
    }
    expect = {"both": "not both", "key": "cameras.left.calib", "none": "camera: missing"}
    for k, text in bad.items():
        p = tmp_path / f"{k}.toml"
        p.write_text(text)
        with pytest.raises(ConfigError, match=expect[k]):
            load_cell_config(p)
