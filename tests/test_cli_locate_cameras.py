"""`seamguide locate` with a calibration per camera (fixed pair, mixed) and as a measuring tool."""

import json

import cv2
import numpy as np
import pytest

from calibration.calibration_file import Calibration, save_calibration
from controller.cli import main
from controller.cli.cycle import parse_calibration_args
from controller.errors import InputError
from controller.geometry.view_file import view_to_dict
from controller.stereo.triangulate import PolylineDistance
from drivers.sim.sim_fixed_cell import fixed_stereo_cell
from drivers.sim.sim_render import render
from drivers.sim.sim_scene import make_scene

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def fixed_pair(tmp_path_factory):
    """Two fixed cameras with different lenses, each with its own calibration file."""
    d = tmp_path_factory.mktemp("fixed")
    scene = make_scene("s_curve", 3, "medium")
    cell = fixed_stereo_cell(scene)
    views = []
    for name, cam in cell.cameras.items():
        T = cell.T_base_cam[name]
        save_calibration(d / f"cam_{name}.yaml", Calibration(cam, T_base_cam=T))
        cv2.imwrite(str(d / f"{name}.png"), render(scene, cam, T, seed=3).image)
        (d / f"{name}.json").write_text(json.dumps(view_to_dict(f"{name}.png", camera=name)))
        views.append(str(d / f"{name}.json"))
    return d, views, scene


def test_two_calibrations_by_camera_name(fixed_pair):
    d, views, scene = fixed_pair
    out = d / "seam.json"
    assert main(["locate", "--calibration", f"left={d / 'cam_left.yaml'}",
                 "--calibration", f"right={d / 'cam_right.yaml'}", "--view", views[0],
                 "--view", views[1], "--no-path", "--output", str(out)]) == 0
    pts = np.array(json.loads(out.read_text())["seam_points_mm"])
    err = PolylineDistance(scene.seam_points_mm)(pts)
    assert np.sqrt(np.mean(err**2)) < 0.05 and err.max() < 0.2


def test_one_calibration_cannot_serve_two_lenses(fixed_pair, capsys):
    d, views, _ = fixed_pair
    # The left camera's file for both views: the right image is 2048x1536, not 2272x1704.
    code = main(["locate", "--calibration", str(d / "cam_left.yaml"), "--view", views[0],
                 "--view", views[1], "--no-path"])
    assert code != 0
    assert "right.png" in capsys.readouterr().err
    code = main(["locate", "--calibration", f"left={d / 'cam_left.yaml'}", "--view", views[0],
                 "--view", views[1], "--no-path"])
    assert code == 3
    assert "camera 'right'" in capsys.readouterr().err


def test_unplannable_path_still_writes_the_seam(fixed_pair, tmp_path, capsys):
    d, views, scene = fixed_pair
    job = tmp_path / "job.toml"
    c = np.round(scene.centre_mm, 1).tolist()
    job.write_text(f'name = "boxed"\nviews = []\n[seam]\nnominal_centre_mm = {c}\n'
                   f'nominal_radius_mm = 200.0\n[limits]\nworkspace_min_mm = [300.0, -900.0, '
                   f'{c[2] + 400}]\nworkspace_max_mm = [1600.0, 900.0, 1500.0]\n')
    out = tmp_path / "seam.json"
    code = main(["locate", "--calibration", f"left={d / 'cam_left.yaml'}", "--calibration",
                 f"right={d / 'cam_right.yaml'}", "--view", views[0], "--view", views[1],
                 "--job", str(job), "--output", str(out)])
    doc = json.loads(out.read_text())
    assert code == doc["weld_path_error"]["exit_code"] and code not in (0, 1)
    assert doc["weld_path"] is None and len(doc["seam_points_mm"]) > 10
    assert doc["quality"]["coverage"] > 0.9 and doc["weld_path_error"]["reason"]
    assert "no weld path" in capsys.readouterr().err


def test_parse_calibration_args(tmp_path):
    assert parse_calibration_args(["c.yaml"]) == {None: "c.yaml"}
    assert parse_calibration_args(["l=a.yaml", "r=b.yaml"]) == {"l": "a.yaml", "r": "b.yaml"}
    odd = tmp_path / "x=y.yaml"
    odd.write_text("")
    assert parse_calibration_args([str(odd)]) == {None: str(odd)}
    for bad in (["l=a", "l=b"], ["a.yaml", "b.yaml"], ["a.yaml", "l=b"], ["a b=c.yaml"]):
        with pytest.raises(InputError, match="--calibration"):
            parse_calibration_args(bad)
