"""The Robot interface's value objects: the safety box, the speed limit and the joint limits, each
probed at its bound (accepted) and just past it (refused before anything is encoded)."""

from __future__ import annotations

import numpy as np
import pytest

from controller.errors import ConfigError, JointLimitError, SafetyError
from controller.geometry.kinematics import IRB2400_LIMITS_DEG
from controller.geometry.poses import make_pose
from drivers.robot import MoveJoints, MoveLinear, SafetyLimits, ToolData, WeldRun

LIMITS = SafetyLimits(workspace_min_mm=(-1000.0, -800.0, 100.0),
                      workspace_max_mm=(1500.0, 900.0, 1600.0), max_speed_mm_s=200.0)
INSIDE = np.array([1000.0, 0.0, 800.0])
EPS_MM = 1e-6


@pytest.mark.parametrize("axis", [0, 1, 2])
@pytest.mark.parametrize("side", ["min", "max"])
def test_every_face_of_the_safety_box_at_and_just_past_it(axis, side):
    bound = (LIMITS.workspace_min_mm if side == "min" else LIMITS.workspace_max_mm)[axis]
    past = bound - EPS_MM if side == "min" else bound + EPS_MM
    at = INSIDE.copy()
    at[axis] = bound
    LIMITS.check_point(at, "probe")  # on the face: inside
    out = INSIDE.copy()
    out[axis] = past
    with pytest.raises(SafetyError, match="probe at .* outside the safety workspace box"):
        LIMITS.check_point(out, "probe")


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_a_non_finite_point_is_outside_the_box(bad):
    p = INSIDE.copy()
    p[1] = bad
    with pytest.raises(SafetyError, match="outside"):
        LIMITS.check_point(p, "probe")


def test_speed_limit_at_and_past_it():
    LIMITS.check_speed(200.0, "probe")
    for bad in (200.0 + 1e-9, 0.0, -1.0, np.nan, np.inf):
        with pytest.raises(SafetyError, match="safety limit"):
            LIMITS.check_speed(bad, "probe")
    WeldRun(200.0).check(LIMITS)
    with pytest.raises(SafetyError):
        WeldRun(200.1).check(LIMITS)


def test_a_linear_move_below_the_box_is_refused():
    T = make_pose(t_mm=[1000.0, 0.0, 100.0 - 0.5])
    with pytest.raises(SafetyError, match="move_linear target"):
        MoveLinear(T, 50.0).check(LIMITS, ToolData(np.eye(4)))


def test_the_box_itself_is_validated():
    with pytest.raises(ConfigError, match="min < max"):
        SafetyLimits(workspace_min_mm=(0.0, 0.0, 0.0), workspace_max_mm=(1.0, 1.0, 0.0))
    with pytest.raises(ConfigError, match="min < max"):
        SafetyLimits(workspace_min_mm=(0.0, 0.0, np.nan), workspace_max_mm=(1.0, 1.0, 1.0))
    with pytest.raises(ConfigError, match="max_speed_mm_s"):
        SafetyLimits(max_speed_mm_s=0.0)


@pytest.mark.parametrize("axis", range(6))
@pytest.mark.parametrize("side", [0, 1])
def test_move_joints_at_every_joint_limit_and_just_past_it(axis, side):
    bound = IRB2400_LIMITS_DEG[axis, side]
    j = np.zeros(6)
    j[axis] = bound
    assert MoveJoints(j, 50.0).joints_deg[axis] == bound
    j[axis] = bound + (1e-6 if side else -1e-6)
    with pytest.raises(JointLimitError, match=f"axis {axis + 1} ") as info:
        MoveJoints(j, 50.0)
    assert info.value.details["axis"] == axis + 1
