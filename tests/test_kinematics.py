"""IRB 2400 kinematics against an independent chain built by hand from standard DH parameters."""

import numpy as np
import pytest

from controller.errors import InputError, JointLimitError, PoseMismatchError, ReachabilityError
from controller.geometry.kinematics import (
    check_pose_consistency,
    controller_to_urdf,
    flange_pose,
    ik_from,
    inverse_kinematics,
    irb2400,
    solve_ik,
    solve_ik_near,
    urdf_to_controller,
    within_limits,
)
from controller.geometry.poses import (
    make_pose,
    pose_error,
    pose_to_dict,
    rotation_about,
    translation_error_mm,
)


def dh(theta, d, a, alpha):
    ct, st, ca, sa = np.cos(theta), np.sin(theta), np.cos(alpha), np.sin(alpha)
    return np.array([[ct, -st * ca, st * sa, a * ct],
                     [st, ct * ca, -ct * sa, a * st],
                     [0, sa, ca, d],
                     [0, 0, 0, 1.0]])


def dh_flange(joints_deg):
    """Standard DH chain of the IRB 2400 from the published dimensions (mm), written by hand.

    a1 = 100, d1 = 615, a2 = 705, a3 = 135, d4 = 755, d6 = 85. Controller axis 3 is measured
    against the horizontal (parallel linkage), so the DH elbow angle is axis3 - axis2; the DH
    shoulder angle has a -90 deg offset because link 2 stands vertical at zero. DH frame 6 differs
    from ABB's tool0 by a half turn about z.
    """
    a1, a2, a3, a4, a5, a6 = np.radians(joints_deg)
    T = (dh(a1, 615, 100, -np.pi / 2) @ dh(a2 - np.pi / 2, 0, 705, 0)
         @ dh(a3 - a2, 0, 135, -np.pi / 2) @ dh(a4, 755, 0, np.pi / 2)
         @ dh(a5, 0, 0, -np.pi / 2) @ dh(a6, 85, 0, 0))
    Rz180 = np.diag([-1.0, -1.0, 1.0, 1.0])
    return T @ Rz180


@pytest.fixture(scope="module")
def robot():
    return irb2400()


def test_home_pose_is_abb_reference(robot):
    d = pose_to_dict(flange_pose(robot, [0, 0, 0, 0, 0, 0]))
    assert np.allclose(d["position_mm"], [940, 0, 1455], atol=1e-9)
    assert np.allclose(d["quaternion_wxyz"], [0.7071068, 0, 0.7071068, 0], atol=1e-6)


@pytest.mark.parametrize("joints", [
    [0, 0, 0, 0, 0, 0],
    [30, 10, -20, 45, 30, 60],
    [-120, -60, 40, -170, -100, 350],
    [175, 100, -55, 190, 115, -390],
    [45, 45, 45, 45, 45, 45],
    [-10, 80, 60, 0, 90, 0],
])
def test_fk_matches_hand_built_dh_chain(robot, joints):
    d_mm, d_deg = pose_error(flange_pose(robot, joints), dh_flange(joints))
    assert d_mm < 0.01
    assert d_deg < 0.001


def test_fk_matches_dh_on_random_joints(robot):
    rng = np.random.default_rng(11)
    for _ in range(200):
        j = rng.uniform(robot.limits_deg[:, 0], robot.limits_deg[:, 1])
        d_mm, d_deg = pose_error(flange_pose(robot, j), dh_flange(j))
        assert d_mm < 0.01 and d_deg < 0.001


def test_coupling_round_trip_and_direction():
    j = np.array([10.0, 30.0, 5.0, 0, 0, 0])
    q = controller_to_urdf(j)
    assert np.isclose(np.degrees(q[2]), 5.0 - 30.0)
    assert np.allclose(urdf_to_controller(q), j)


def test_parallel_linkage_keeps_upper_arm_level(robot):
    # Moving axis 2 alone translates the wrist but keeps the upper arm (and tool) orientation.
    A = flange_pose(robot, [0, 0, 0, 0, 0, 0])
    B = flange_pose(robot, [0, 30, 0, 0, 0, 0])
    assert pose_error(A, B)[1] < 1e-9
    assert translation_error_mm(A, B) > 100


def test_ik_round_trip_on_1000_random_reachable_poses(robot):
    rng = np.random.default_rng(2024)
    worst = 0.0
    for _ in range(1000):
        j = rng.uniform(robot.limits_deg[:, 0], robot.limits_deg[:, 1])
        T = flange_pose(robot, j)
        sols = inverse_kinematics(robot, T)
        assert sols, f"no IK solution for FK of {j}"
        for s in sols:
            worst = max(worst, translation_error_mm(flange_pose(robot, s), T))
        if abs(j[4]) > 0.5:  # away from the wrist singularity the original branch must be found
            assert any(np.max(np.abs(s - j)) < 1e-6 for s in sols), j
    assert worst < 1e-6


def test_ik_returns_only_distinct_solutions_within_limits(robot):
    T = flange_pose(robot, [20, 30, 10, 40, 50, 60])
    sols = inverse_kinematics(robot, T)
    assert len(sols) >= 2
    for i, a in enumerate(sols):
        assert np.all(a >= robot.limits_deg[:, 0] - 1e-9)
        assert np.all(a <= robot.limits_deg[:, 1] + 1e-9)
        for b in sols[i + 1:]:
            assert np.max(np.abs(a - b)) > 1e-6


def test_unreachable_pose_raises_reachability_error(robot):
    T = make_pose(np.eye(3), [3000, 0, 500])
    assert inverse_kinematics(robot, T) == []
    with pytest.raises(ReachabilityError, match="3000.0"):
        solve_ik(robot, T, name="weld point 7")


@pytest.mark.parametrize("joints,axis", [
    ([0, 0, 70, 0, 0, 0], 3), ([0, -101, 0, 0, 0, 0], 2), ([181, 0, 0, 0, 0, 0], 1),
    ([0, 0, 0, 0, 0, 401], 6)])
def test_joints_outside_limits_refused(robot, joints, axis):
    with pytest.raises(JointLimitError, match=f"axis {axis}") as info:
        flange_pose(robot, joints)
    assert info.value.details["axis"] == axis


@pytest.mark.parametrize("axis", range(6))
@pytest.mark.parametrize("side", [0, 1])
def test_every_joint_limit_is_inclusive_and_refused_just_past(robot, axis, side):
    bound = robot.limits_deg[axis, side]
    j = np.zeros(6)
    j[axis] = bound
    flange_pose(robot, j)  # at the limit: allowed
    assert within_limits(robot, j)
    j[axis] = bound + (1e-6 if side else -1e-6)
    assert not within_limits(robot, j)
    with pytest.raises(JointLimitError, match=f"axis {axis + 1} ") as info:
        flange_pose(robot, j)
    assert info.value.details["axis"] == axis + 1


def test_the_first_axis_out_of_its_limits_is_named(robot):
    with pytest.raises(JointLimitError, match="axis 2 ") as info:
        flange_pose(robot, [0, -101, 0, 0, 0, 401])
    assert info.value.details["axis"] == 2


@pytest.mark.parametrize("joints", [[0, 0, 0, 0, 0], [0] * 7, [0, 0, float("nan"), 0, 0, 0]])
def test_wrong_joint_count_or_nan_refused(robot, joints):
    with pytest.raises(InputError, match="joint"):
        flange_pose(robot, joints)


def test_pose_consistency_check(robot):
    j = [10, 20, 10, 30, 40, 50]
    T = flange_pose(robot, j)
    assert check_pose_consistency(robot, j, T)[0] < 1e-9
    tool = make_pose(np.eye(3), [0, 0, 3.0])  # a tool active on the controller: 3 mm off
    with pytest.raises(PoseMismatchError, match="tool0"):
        check_pose_consistency(robot, j, T @ tool)


def test_ik_from_continues_the_seeds_branch(robot):
    rng = np.random.default_rng(11)
    for _ in range(50):
        j = rng.uniform(robot.limits_deg[:, 0] * 0.8, robot.limits_deg[:, 1] * 0.8)
        if abs(j[4]) < 5:  # keep off the wrist singularity
            continue
        T = flange_pose(robot, j + rng.uniform(-0.5, 0.5, 6))
        got = ik_from(robot, T, j)
        assert got is not None
        assert pose_error(flange_pose(robot, got), T)[0] < 1e-6
        assert np.allclose(got, solve_ik(robot, T, near_deg=j), atol=1e-6)


def test_ik_from_fails_out_of_reach_and_outside_limits(robot):
    j = np.array([0.0, 20.0, 10.0, 0.0, 40.0, 0.0])
    far = make_pose(np.eye(3), [3000.0, 0.0, 500.0])
    assert ik_from(robot, far, j) is None
    # axis 1 just past its limit: the seed's branch leaves the limits, no other branch is tried
    edge = np.array([179.5, 20.0, 10.0, 0.0, 40.0, 0.0])
    T = flange_pose(robot, [179.9, 20.0, 10.0, 0.0, 40.0, 0.0])
    T_past = make_pose(rotation_about([0, 0, 1], np.radians(1.0)) @ T[:3, :3],
                       rotation_about([0, 0, 1], np.radians(1.0)) @ T[:3, 3])
    assert ik_from(robot, T, edge) is not None
    assert ik_from(robot, T_past, edge) is None


def test_solve_ik_near_agrees_with_the_full_set_and_refuses_alike(robot):
    rng = np.random.default_rng(12)
    for _ in range(30):
        j = rng.uniform(robot.limits_deg[:, 0] * 0.8, robot.limits_deg[:, 1] * 0.8)
        if abs(j[4]) < 5:
            continue
        T = flange_pose(robot, j + rng.uniform(-3.0, 3.0, 6))
        assert np.allclose(solve_ik_near(robot, T, j), solve_ik(robot, T, near_deg=j), atol=1e-6)
    far = make_pose(np.eye(3), [3000.0, 0.0, 500.0])
    with pytest.raises(ReachabilityError, match="far point"):
        solve_ik_near(robot, far, np.zeros(6), name="far point")
