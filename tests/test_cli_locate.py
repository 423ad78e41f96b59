"""`seamguide locate` on rendered views written as view files (the DESIGN.md contracts)."""

import json

import cv2
import numpy as np
import pytest

from calibration.calibration_file import Calibration, save_calibration
from controller.cell.dry_run import view_joints
from controller.cli import main
from controller.geometry.kinematics import flange_pose, irb2400
from controller.geometry.view_file import view_to_dict
from controller.stereo.triangulate import PolylineDistance
from drivers.sim.sim_cell import default_sim_cell
from drivers.sim.sim_render import render
from drivers.sim.sim_scene import make_scene

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def views(tmp_path_factory):
    d = tmp_path_factory.mktemp("locate")
    cell = default_sim_cell()
    scene = make_scene("arc", 4, "medium")
    robot = irb2400()
    save_calibration(d / "calib.yaml", Calibration(cell.camera, cell.T_flange_cam))
    paths = []
    for i, j in enumerate(view_joints(scene, cell)):
        T_base_cam = flange_pose(robot, j) @ cell.T_flange_cam
        cv2.imwrite(str(d / f"v{i + 1}.png"), render(scene, cell.camera, T_base_cam, seed=4).image)
        doc = (view_to_dict(f"v{i + 1}.png", joints_deg=j) if i == 0 else
               view_to_dict(f"v{i + 1}.png", T_base_flange=flange_pose(robot, j)))
        (d / f"v{i + 1}.json").write_text(json.dumps(doc))
        paths.append(str(d / f"v{i + 1}.json"))
    return d, paths, scene


def test_locate_output_contract_and_accuracy(views, capsys):
    d, paths, scene = views
    out = d / "seam.json"
    assert main(["locate", "--calibration", str(d / "calib.yaml"), "--view", paths[0],
                 "--view", paths[1], "--output", str(out), "--overlay-dir", str(d)]) == 0
    doc = json.loads(out.read_text())
    assert set(doc) == {"seam_points_mm", "weld_path", "quality"}
    pts = np.array(doc["seam_points_mm"])
    err = PolylineDistance(scene.seam_points_mm)(pts)
    assert np.sqrt(np.mean(err**2)) < 0.15 and err.max() < 0.5
    kinds = [t["kind"] for t in doc["weld_path"]]
    assert kinds[0] == "approach" and kinds[-1] == "depart" and kinds.count("weld") == len(pts)
    assert (d / "v1_overlay.png").is_file()


def test_locate_count_and_bad_inputs(views, capsys, tmp_path):
    d, paths, _ = views
    assert main(["locate", "--calibration", str(d / "calib.yaml"), "--view", paths[0],
                 "--view", paths[1], "--count", "15", "--no-path"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert len(doc["seam_points_mm"]) == 15 and doc["weld_path"] == []
    assert main(["locate", "--calibration", str(d / "calib.yaml"), "--view", paths[0]]) == 3
    assert "at least two views" in capsys.readouterr().err
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"image": "v1.png"}))
    assert main(["locate", "--calibration", str(d / "calib.yaml"), "--view", paths[0],
                 "--view", str(bad)]) == 3
    assert "bad.json" in capsys.readouterr().err


def test_locate_keeps_every_views_overlay_when_one_is_refused(views, capsys, tmp_path):
    d, paths, _ = views
    blank = tmp_path / "blank.png"  # view 2 sees bare metal: refused, view 1 still found
    cv2.imwrite(str(blank), np.full_like(cv2.imread(str(d / "v2.png")), 120))
    doc = json.loads((d / "v2.json").read_text())
    doc["image"] = str(blank)
    (tmp_path / "v2.json").write_text(json.dumps(doc))
    out_dir = tmp_path / "overlays"
    out_dir.mkdir()
    assert main(["locate", "--calibration", str(d / "calib.yaml"), "--view", paths[0],
                 "--view", str(tmp_path / "v2.json"), "--overlay-dir", str(out_dir)]) == 9
    assert "v2: no weld seam found" in capsys.readouterr().err
    assert sorted(p.name for p in out_dir.iterdir()) == ["v1_overlay.png", "v2_overlay.png"]
    # view 1's picture has its seam in green, view 2's its refusal in red text
    v1, v2 = (cv2.imread(str(out_dir / f"v{i}_overlay.png")).astype(int) for i in (1, 2))
    assert ((v1[:, :, 1] > 200) & (v1[:, :, 0] < 80) & (v1[:, :, 2] < 80)).sum() > 200
    assert ((v2[:, :, 2] > 200) & (v2[:, :, 1] < 90) & (v2[:, :, 0] < 90)).sum() > 200
