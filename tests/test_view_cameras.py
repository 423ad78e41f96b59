"""Which camera takes which view of a job, and which views are captured together."""

import numpy as np
import pytest

from calibration.calibration_file import Calibration
from controller.cell.job import job_from_dict
from controller.cell.view_cameras import capture_groups, resolve_view_cameras
from controller.errors import ConfigError
from controller.geometry.camera_model import default_camera

J = [0.0, 10.0, 20.0, 0.0, 60.0, 0.0]
CALIBS = {"wrist": Calibration(default_camera(), T_flange_cam=np.eye(4)),
          "left": Calibration(default_camera(), T_base_cam=np.eye(4)),
          "right": Calibration(default_camera(), T_base_cam=np.eye(4))}


def job(views):
    return job_from_dict({"name": "j", "views": views, "seam": {"nominal_centre_mm": [0, 0, 0]}})


def test_mixed_cell_groups():
    vs = resolve_view_cameras(job([{"name": "a", "camera": "left"},
                                   {"name": "b", "camera": "right"},
                                   {"name": "c", "camera": "wrist", "joints_deg": J},
                                   {"name": "d", "camera": "left", "joints_deg": J}]), CALIBS)
    assert [(v.camera, v.fixed) for v in vs] == [("left", True), ("right", True),
                                                 ("wrist", False), ("left", True)]
    # The two fixed views at once, the wrist view after its move, the fixed view with joints
    # after its move.
    assert capture_groups(vs) == [[0, 1], [2], [3]]


def test_problems_name_job_view_and_camera():
    with pytest.raises(ConfigError) as info:
        resolve_view_cameras(job([{"name": "a", "camera": "left"},
                                  {"name": "b", "camera": "wrist"},
                                  {"name": "c", "camera": "middle"}, {"name": "d"}]), CALIBS)
    p = info.value.details["problems"]
    assert any("view b: camera wrist is on the flange and the view has no joints" in x for x in p)
    assert any("view c: camera 'middle' is not a camera of this cell" in x for x in p)
    assert any("view d does not name its camera" in x for x in p)
    one = {"camera": CALIBS["wrist"]}
    vs = resolve_view_cameras(job([{"name": "a", "joints_deg": J},
                                   {"name": "b", "joints_deg": J}]), one)
    assert [v.camera for v in vs] == ["camera", "camera"] and capture_groups(vs) == [[0], [1]]
