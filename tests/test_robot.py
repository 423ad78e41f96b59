"""The Robot interface's value objects: the safety box, the speed limit and the joint limits, each
probed at its bound (accepted) and just past it (refused before anything is encoded)."""

from __future__ import annotations

import numpy as np
import pytest

from controller.errors import (
    ConfigError,
    InputError,
    JointLimitError,
    ReachabilityError,
    SafetyError,
)
from controller.geometry.kinematics import IRB2400_LIMITS_DEG, flange_pose, irb2400
from controller.geometry.poses import make_pose, rotation_about
from drivers.robot_commands import (
    MoveJoints,
    MoveLinear,
    PathTargets,
    SafetyLimits,
    ToolData,
    WeldRun,
)

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
    LIMITS.check_speed(0.5, "probe")  # slow is allowed: only 0 and below are refused
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


def test_a_linear_move_is_checked_at_its_target_position():
    wide = SafetyLimits()  # holds the origin, so a column of the rotation would pass
    with pytest.raises(SafetyError, match="move_linear target at \\(1850.0"):
        MoveLinear(make_pose(t_mm=[1850.0, 0.0, 800.0]), 50.0).check(wide, ToolData(np.eye(4)))


def test_the_box_itself_is_validated():
    with pytest.raises(ConfigError, match="min < max"):
        SafetyLimits(workspace_min_mm=(0.0, 0.0, 0.0), workspace_max_mm=(1.0, 1.0, 0.0))
    with pytest.raises(ConfigError, match="3 finite values"):
        SafetyLimits(workspace_min_mm=(0.0, 0.0), workspace_max_mm=(1.0, 1.0, 1.0))
    with pytest.raises(ConfigError, match="3 finite values"):
        SafetyLimits(workspace_min_mm=(0.0, 0.0, 0.0), workspace_max_mm=(1.0, 1.0, 1.0, 1.0))
    assert SafetyLimits(max_speed_mm_s=0.5).max_speed_mm_s == 0.5  # slow, but a speed
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


def test_speeds_must_be_positive_however_small():
    assert MoveJoints(np.zeros(6), 0.5).speed_mm_s == 0.5
    for bad in (0.0, -0.5, np.nan):
        with pytest.raises(InputError, match="positive finite speed"):
            MoveJoints(np.zeros(6), bad)


@pytest.mark.parametrize(("bad", "cause"), [("fast", ValueError), ("", ValueError),
                                            (None, TypeError), ([50.0], TypeError)])
def test_a_speed_that_is_not_a_number_is_refused_by_name(bad, cause):
    # float() raises ValueError for text, TypeError for None or a list: both become the
    # product's InputError naming the command and the value, never a bare Python error
    for make, name in ((lambda v: MoveJoints(np.zeros(6), v), "move_joints speed"),
                       (lambda v: MoveLinear(make_pose(t_mm=[1000.0, 0.0, 800.0]), v),
                        "move_linear speed"),
                       (lambda v: WeldRun(v), "weld speed")):
        with pytest.raises(InputError, match=f"{name} must be a speed in mm/s, got") as info:
            make(bad)
        assert isinstance(info.value.__cause__, cause)
    assert MoveJoints(np.zeros(6), "50").speed_mm_s == 50.0  # text of a number is a number


J_VIEW = np.array([0.0, 10.0, 0.0, 0.0, 60.0, 0.0])
TOOL = ToolData(make_pose(t_mm=[0.0, 0.0, 250.0]))


def _box_around(p, half=50.0):
    return SafetyLimits(workspace_min_mm=tuple(p - half), workspace_max_mm=tuple(p + half))


def test_move_joints_checks_where_the_tcp_ends_up():
    tcp = (flange_pose(irb2400(), J_VIEW) @ TOOL.T_flange_tcp)[:3, 3]
    MoveJoints(J_VIEW, 50.0).check(_box_around(tcp), TOOL)
    elsewhere = _box_around(tcp + [0.0, 0.0, 120.0])  # the TCP ends up 70 mm under this box
    with pytest.raises(SafetyError, match=r"move_joints target \(TCP\)"):
        MoveJoints(J_VIEW, 50.0).check(elsewhere, TOOL)


def test_every_path_point_is_checked_against_the_box():
    T0 = flange_pose(irb2400(), J_VIEW) @ TOOL.T_flange_tcp
    path = [T0 @ make_pose(t_mm=[0.0, 2.0 * i, 0.0]) for i in range(5)]
    box = _box_around(T0[:3, 3], half=30.0)
    PathTargets(tuple(path)).check(box, TOOL, capacity=10)
    path[3] = T0 @ make_pose(t_mm=[0.0, 0.0, -40.0])  # 40 mm along the tool axis: out
    with pytest.raises(SafetyError, match="path point 4 at"):
        PathTargets(tuple(path)).check(box, TOOL, capacity=10)
    with pytest.raises(SafetyError, match="buffer holds 4"):
        PathTargets(tuple(path)).check(box, TOOL, capacity=4)
    path[3] = T0 @ make_pose(t_mm=[0.0, 6.0, 0.0])
    PathTargets(tuple(path)).check(box, TOOL, capacity=5)  # exactly as many as the buffer holds



# ---- a MoveC arc: the arc itself in the box, not only its three points -------------------------
# A 170 deg circle of radius 60 mm in the tool's x-y plane at J_VIEW: tilted in the base frame,
# starting at 129 deg, so every base coordinate turns inside the arc, 6.7-11.6 mm past all three
# points (one side per axis: an arc under 180 deg has one turning point per coordinate).

ARC_R_MM, ARC_A0, ARC_SWEEP = 60.0, np.radians(129.0), np.radians(170.0)
ARC_CENTRE = np.array([-40.0, 25.0, 0.0])  # tool frame at J_VIEW, mm
T_VIEW_TCP = flange_pose(irb2400(), J_VIEW) @ TOOL.T_flange_tcp


def _on_arc(a):
    """Base positions (N, 3) at angles ``a`` of the circle, from its own parametrisation."""
    a = np.atleast_1d(a)
    local = ARC_CENTRE + ARC_R_MM * np.column_stack([np.cos(a), np.sin(a), 0 * a])
    return local @ T_VIEW_TCP[:3, :3].T + T_VIEW_TCP[:3, 3]


def _arc():
    """Start pose (torch turned about its z with the circle), circle point, end pose, and the
    arc densely (200001 points: 1e-9 mm sagitta between neighbours)."""
    def pose(a):
        return make_pose(T_VIEW_TCP[:3, :3] @ rotation_about([0, 0, 1], a - ARC_A0), _on_arc(a)[0])
    dense = _on_arc(ARC_A0 + np.linspace(0.0, ARC_SWEEP, 200_001))
    return pose(ARC_A0), _on_arc(ARC_A0 + np.radians(90.0))[0], pose(ARC_A0 + ARC_SWEEP), dense


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_an_arc_bulging_past_a_face_of_the_box_is_refused_at_its_extreme(axis):
    start, via, end, dense = _arc()
    three = np.array([start[:3, 3], via, end[:3, 3]])
    lo, hi = dense.min(axis=0), dense.max(axis=0)
    side = "max" if hi[axis] - three[:, axis].max() > 1.0 else "min"  # where the bulge is
    extreme, outward = (hi[axis], 1.0) if side == "max" else (lo[axis], -1.0)
    assert (outward * (extreme - three[:, axis])).min() > 5.0  # past all three points

    def box(face):
        b_lo, b_hi = lo - 100.0, hi + 100.0
        (b_hi if side == "max" else b_lo)[axis] = face
        return SafetyLimits(tuple(b_lo), tuple(b_hi))

    path = PathTargets((start, end), (None, via))
    path.check(box(extreme + outward * 1e-3), TOOL, capacity=4)  # 1 um outside the arc: passes
    with pytest.raises(SafetyError, match="the circle to path point 2 at .* outside"):
        path.check(box(extreme - outward * 1e-3), TOOL, capacity=4)


def test_the_bulge_between_sixteen_samples_of_the_arc_is_not_missed():
    # The check used to sample the arc at 16 points: the extreme of one coordinate lies between
    # two of them, farther out than both by more than the 0.05 mm the face is moved in.
    start, via, end, dense = _arc()
    sampled = _on_arc(ARC_A0 + np.linspace(0.0, ARC_SWEEP, 16))
    gaps = np.maximum(dense.max(axis=0) - sampled.max(axis=0),
                      sampled.min(axis=0) - dense.min(axis=0))
    axis = int(np.argmax(gaps))
    assert gaps[axis] > 0.1
    lo, hi = dense.min(axis=0) - 100.0, dense.max(axis=0) + 100.0
    if dense[:, axis].max() - sampled[:, axis].max() == gaps[axis]:
        hi[axis] = dense[:, axis].max() - 0.05
    else:
        lo[axis] = dense[:, axis].min() + 0.05
    with pytest.raises(SafetyError, match="the circle to path point 2"):
        PathTargets((start, end), (None, via)).check(SafetyLimits(tuple(lo), tuple(hi)), TOOL,
                                                     capacity=4)


def test_the_middle_of_an_arc_must_be_reachable():
    # two ends 900 mm apart across the base's x axis, both reachable (a MoveL between them
    # passes); the circle through a point 360 mm farther out takes the flange out of reach
    wide = SafetyLimits((-3000.0,) * 3, (3000.0,) * 3)
    start, end = T_VIEW_TCP.copy(), T_VIEW_TCP.copy()
    start[1, 3] -= 450.0
    end[1, 3] += 450.0
    PathTargets((start, end)).check(wide, TOOL, capacity=4)
    via = T_VIEW_TCP[:3, 3] + [360.0, 0.0, 0.0]
    with pytest.raises(ReachabilityError, match="the circle to path point 2 at .* out of reach"):
        PathTargets((start, end), (None, via)).check(wide, TOOL, capacity=4)
