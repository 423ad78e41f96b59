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
