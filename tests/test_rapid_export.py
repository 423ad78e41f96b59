import re

import numpy as np
import pytest
from stereo_scenes import seam_curve

from controller.errors import ConfigError
from controller.geometry.kinematics import irb2400
from controller.geometry.poses import pose_error, pose_from_pos_quat
from controller.path.rapid_export import rapid_module
from controller.path.weld_path import plan_weld
from controller.stereo.seam_curve import resample_curve


@pytest.fixture(scope="module")
def path():
    pts = resample_curve(seam_curve("s_curve"), count=12)
    return plan_weld(irb2400(), pts, np.array([0, 0, 1.0]))


def test_module_structure(path):
    text = rapid_module(path, module="SgTest")
    assert text.startswith("MODULE SgTest")
    assert text.rstrip().endswith("ENDMODULE")
    assert text.count("CONST robtarget") == len(path.targets)
    # arc on after reaching the first weld point, off after the last, and in the error handler
    body = text[text.index("PROC sg_weld"):]
    on, off = body.index("SetDO do_arc_on, 1"), body.index("SetDO do_arc_on, 0")
    assert body.index("MoveL sg_p1,") < on < body.index("MoveL sg_p2,")
    assert body.index(f"MoveL sg_p{len(path.targets) - 2},") < off
    assert "ERROR" in body


def test_targets_round_trip_to_a_hundredth_of_a_millimetre(path):
    text = rapid_module(path)
    pat = re.compile(r"CONST robtarget sg_p(\d+) := \[\[([^\]]+)\],\[([^\]]+)\]")
    found = pat.findall(text)
    assert len(found) == len(path.targets)
    for idx, pos, quat in found:
        T = pose_from_pos_quat([float(v) for v in pos.split(",")],
                               [float(v) for v in quat.split(",")])
        d_mm, _ = pose_error(T, path.targets[int(idx)].T_base_tcp)
        assert d_mm < 0.001
        # orientation written with 6 decimals: the torch tip (350 mm out) moves < 0.01 mm
        tip = T[:3, :3] @ [0, 0, 350.0]
        ref = path.targets[int(idx)].T_base_tcp[:3, :3] @ [0, 0, 350.0]
        assert np.linalg.norm(tip - ref) < 0.01


def test_bad_names_refused(path):
    with pytest.raises(ConfigError, match="module name"):
        rapid_module(path, module="1bad")
    with pytest.raises(ConfigError, match="signal"):
        rapid_module(path, arc_output="do arc")
