"""Which calibration a view uses, and its camera pose (wrist, fixed, mixed cells)."""

from pathlib import Path

import numpy as np
import pytest

from calibration.calibration_file import Calibration
from controller.errors import CalibrationError, InputError
from controller.geometry.camera_model import default_camera
from controller.geometry.poses import make_pose, pose_error, rotation_about
from controller.geometry.view_file import View
from controller.stereo.view_geometry import calibration_for_view, camera_pose

HE = make_pose(rotation_about([1, 0, 0], 0.02), [-80, 4, 250])
FIXED = make_pose(rotation_about([0, 1, 0], np.pi), [1000, 100, 700])
FLANGE = make_pose(rotation_about([0, 1, 0], 0.3), [900, 0, 800])
WRIST = Calibration(default_camera(), T_flange_cam=HE)
LEFT = Calibration(default_camera(1600, 1200), T_base_cam=FIXED)


def view(**kw):
    return View(Path("v.json"), Path("v.png"), **kw)


def test_pick_by_camera_name_and_unnamed():
    calibs = {"wrist": WRIST, "left": LEFT}
    assert calibration_for_view(view(camera="left"), calibs) is LEFT
    assert calibration_for_view(view(camera="wrist"), calibs) is WRIST
    # One unnamed calibration applies to every view, named or not (as before cameras had names).
    assert calibration_for_view(view(camera="left"), {None: WRIST}) is WRIST
    assert calibration_for_view(view(), {None: WRIST}) is WRIST
    assert calibration_for_view(view(), {"left": LEFT}) is LEFT


def test_pick_errors_name_view_and_camera():
    with pytest.raises(InputError, match=r"camera 'right'.*no calibration.*left, wrist"):
        calibration_for_view(view(camera="right"), {"wrist": WRIST, "left": LEFT})
    with pytest.raises(InputError, match=r"v.json does not say which camera"):
        calibration_for_view(view(), {"wrist": WRIST, "left": LEFT})


def test_camera_pose_wrist_fixed_and_given():
    assert pose_error(camera_pose(view(T_base_flange=FLANGE), WRIST), FLANGE @ HE)[0] < 1e-9
    assert pose_error(camera_pose(view(camera="left"), LEFT), FIXED)[0] < 1e-12
    # The view's own pose agreeing with the calibration's is fine ...
    assert pose_error(camera_pose(view(T_base_cam=FIXED.copy()), LEFT), FIXED)[0] < 1e-12
    # ... a stale one is refused with both named.
    moved = FIXED @ make_pose(t_mm=[0.5, 0, 0])
    with pytest.raises(CalibrationError, match=r"0.500 mm .* stale"):
        camera_pose(view(T_base_cam=moved, camera="left"), LEFT)


def test_camera_pose_missing_transform():
    with pytest.raises(CalibrationError, match="fixed camera .* needs no robot pose"):
        camera_pose(view(T_base_flange=FLANGE, camera="left"), LEFT)
    with pytest.raises(CalibrationError, match="must hold the fixed camera's pose"):
        camera_pose(view(camera="wrist"), WRIST)
