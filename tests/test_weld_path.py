import numpy as np
import pytest
from stereo_scenes import seam_curve

from controller.errors import ConfigError, ReachabilityError
from controller.geometry.kinematics import flange_pose, inverse_kinematics, irb2400
from controller.geometry.poses import invert, pose_error
from controller.path.weld_path import (
    WeldParams,
    WorkspaceBox,
    plan_weld,
    seam_normals,
    torch_poses,
)
from controller.stereo.seam_curve import resample_curve

UP = np.array([0.0, 0.0, 1.0])


@pytest.fixture(scope="module")
def robot():
    return irb2400()


@pytest.fixture(scope="module")
def arc_path(robot):
    pts = resample_curve(seam_curve("arc"), count=20)
    return pts, plan_weld(robot, pts, UP)


def test_targets_in_order_with_approach_and_depart(arc_path):
    pts, path = arc_path
    kinds = [t.kind for t in path.targets]
    assert kinds == ["approach"] + ["weld"] * 20 + ["depart"]
    assert [t.arc for t in path.targets] == [False] + [True] * 20 + [False]


def test_tool_offset_and_torch_angles(arc_path):
    pts, path = arc_path
    p = path.params
    for T, seam_pt in zip((t.T_base_tcp for t in path.weld_targets), pts, strict=True):
        z = T[:3, 2]
        # tip stands tool_offset_mm back from the seam point along the torch axis
        assert np.allclose(T[:3, 3] + p.tool_offset_mm * z, seam_pt, atol=1e-9)
        # the torch leans from the normal by the travel angle (work angle 0)
        angle = np.degrees(np.arccos(np.clip(-z @ UP, -1, 1)))
        assert abs(angle - p.travel_angle_deg) < 1e-6
    first = path.targets[0].T_base_tcp
    assert np.isclose(np.linalg.norm(first[:3, 3] - path.targets[1].T_base_tcp[:3, 3]),
                      p.approach_mm)


def test_push_angle_leans_the_tip_forward(arc_path):
    pts, path = arc_path
    travel = pts[1] - pts[0]
    z = path.weld_targets[0].T_base_tcp[:3, 2]
    assert z @ travel > 0


def test_joints_reach_every_target(robot, arc_path):
    _, path = arc_path
    T_tcp_flange = invert(path.params.T_flange_tcp)
    for t in path.targets:
        d_mm, d_deg = pose_error(flange_pose(robot, t.joints_deg), t.T_base_tcp @ T_tcp_flange)
        assert d_mm < 1e-6 and d_deg < 1e-6
    steps = [np.max(np.abs(a.joints_deg - b.joints_deg))
             for a, b in zip(path.weld_targets, path.weld_targets[1:], strict=False)]
    assert max(steps) < path.params.max_joint_step_deg


def test_outside_workspace_box_names_the_point(robot):
    pts = resample_curve(seam_curve("straight"), count=10)
    box = WorkspaceBox(min_mm=(300, -50, 0), max_mm=(1600, 900, 1500))
    with pytest.raises(ReachabilityError, match="target") as info:
        plan_weld(robot, pts, UP, workspace=box)
    assert "index" in info.value.details


def test_unreachable_seam_names_the_first_bad_point(robot):
    pts = resample_curve(seam_curve("straight"), count=10) + [1200.0, 0, 0]
    with pytest.raises(ReachabilityError, match="cannot be reached|outside"):
        plan_weld(robot, pts, UP, workspace=WorkspaceBox(max_mm=(5000, 900, 1500)))


def test_bad_parameters_refused():
    with pytest.raises(ConfigError, match="speed_mm_s"):
        WeldParams(speed_mm_s=500)
    with pytest.raises(ConfigError, match="travel_angle_deg"):
        WeldParams(travel_angle_deg=80)


def test_normal_along_the_seam_refused(robot):
    pts = resample_curve(seam_curve("straight"), count=5)
    with pytest.raises(ConfigError, match="normal"):
        plan_weld(robot, pts, np.array([0, 1.0, 0]))


def plan_full_set(robot, path_targets, params, start_joints):
    """The planner's reference choice: the full solution set at every target, the nearest kept
    (what plan_weld did before it solved by continuity). Returns joints, or the first index that
    has no solution or needs a flip between two weld targets."""
    T_tcp_flange = invert(params.T_flange_tcp)
    prev, out = start_joints, []
    for i, t in enumerate(path_targets):
        sols = inverse_kinematics(robot, t @ T_tcp_flange)
        if not sols:
            return out, i
        best = min(sols, key=lambda j: float(np.max(np.abs(j - prev))))
        if 1 < i < len(path_targets) - 1 and np.max(np.abs(best - prev)) > \
                params.max_joint_step_deg:
            return out, i
        out.append(best)
        prev = best
    return out, None


def test_continuity_picks_the_full_sets_nearest_solution(robot, arc_path):
    pts, path = arc_path
    ref, bad = plan_full_set(robot, [t.T_base_tcp for t in path.targets], path.params, np.zeros(6))
    assert bad is None
    assert np.allclose([t.joints_deg for t in path.targets], ref, atol=1e-6)


def test_seam_running_out_of_reach_is_refused_where_the_full_set_refuses(robot):
    # starts in reach, runs radially out of it: continuity must not accept a single point more
    x = np.linspace(1100.0, 1900.0, 81)
    pts = np.c_[x, np.zeros_like(x), np.full_like(x, 300.0)]
    params = WeldParams()
    weld = torch_poses(pts, seam_normals(pts, UP), params)
    approach = weld[0].copy()
    approach[:3, 3] -= params.approach_mm * weld[0][:3, 2]
    _, first_bad = plan_full_set(robot, [approach, *weld], params, np.zeros(6))
    assert first_bad is not None and first_bad > 5
    with pytest.raises(ReachabilityError, match="cannot be reached") as info:
        plan_weld(robot, pts, UP, workspace=WorkspaceBox(max_mm=(5000, 900, 1500)))
    assert info.value.details["index"] == first_bad


def test_seam_around_the_back_needs_a_flip_and_is_refused(robot):
    # an arc around the base through axis 1's +-180 deg limit: continuity leaves the limits there,
    # the full set's nearest solution is a whole turn of axis 1 away: refused as before
    a = np.radians(np.linspace(160.0, 200.0, 60))
    pts = np.c_[900.0 * np.cos(a), 900.0 * np.sin(a), np.full_like(a, 300.0)]
    box = WorkspaceBox(min_mm=(-1600, -900, -100), max_mm=(1600, 900, 1500))
    with pytest.raises(ReachabilityError, match="flip") as info:
        plan_weld(robot, pts, UP, workspace=box)
    params = WeldParams()
    weld = torch_poses(pts, seam_normals(pts, UP), params)
    approach = weld[0].copy()
    approach[:3, 3] -= params.approach_mm * weld[0][:3, 2]
    _, first_bad = plan_full_set(robot, [approach, *weld], params, np.zeros(6))
    assert info.value.details["index"] == first_bad
