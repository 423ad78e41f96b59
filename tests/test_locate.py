import re

import numpy as np
import pytest
from stereo_scenes import CENTRE, camera_poses, observe, seam_curve

from controller.errors import InputError, TriangulationError
from controller.geometry.poses import make_pose, rotation_about
from controller.stereo.locate import QualityLimits, ViewObservation, _judge, locate_seam
from controller.stereo.triangulate import PolylineDistance


def error_to_truth(P, seam):
    d = PolylineDistance(P)(seam.dense_points_mm)
    return float(np.sqrt(np.mean(d**2))), float(d.max())


@pytest.mark.parametrize("kind", ["straight", "arc", "s_curve", "nonplanar"])
def test_exact_curves_triangulate_to_the_truth(kind):
    P = seam_curve(kind)
    seam = locate_seam(observe(P, camera_poses(P)))
    rms, mx = error_to_truth(P, seam)
    assert rms < 0.002 and mx < 0.01
    # true end points (coverage of the whole seam)
    ends = seam.points_mm[[0, -1]]
    assert min(np.linalg.norm(ends[0] - P[0]), np.linalg.norm(ends[0] - P[-1])) < 0.5
    assert min(np.linalg.norm(ends[1] - P[0]), np.linalg.norm(ends[1] - P[-1])) < 0.5


@pytest.mark.parametrize("kind", ["straight", "arc", "s_curve", "nonplanar"])
def test_noisy_curves_stay_within_a_tenth_of_a_millimetre(kind):
    P = seam_curve(kind)
    seam = locate_seam(observe(P, camera_poses(P), noise_px=0.3, seed=5))
    rms, mx = error_to_truth(P, seam)
    assert rms < 0.1 and mx < 0.3
    assert seam.quality["coverage"] > 0.98
    assert max(seam.quality["reprojection_px_rms"]) < 0.5


def test_resampling_spacing_and_count():
    P = seam_curve("arc")
    obs = observe(P, camera_poses(P))
    a = locate_seam(obs, spacing_mm=2.0)
    steps = np.linalg.norm(np.diff(a.points_mm, axis=0), axis=1)
    assert abs(np.median(steps) - 2.0) < 0.05
    b = locate_seam(obs, spacing_mm=None, count=15)
    assert len(b.points_mm) == 15
    assert np.allclose(b.points_mm[[0, -1]], a.points_mm[[0, -1]])


def test_three_views_are_accepted_and_more_accurate_than_noise_alone():
    P = seam_curve("s_curve")
    poses = camera_poses(P)
    poses.append(camera_poses(P, along=np.array([0, 1.0, 0]))[0])
    seam = locate_seam(observe(P, poses, noise_px=0.3, seed=2))
    assert seam.quality["views"] == 3
    assert error_to_truth(P, seam)[0] < 0.1


def test_seam_along_the_baseline_is_reported_as_degenerate_with_a_fix():
    P = seam_curve("straight")
    # baseline along the seam (y): every epipolar line runs along the seam
    obs = observe(P, camera_poses(P, along=np.array([0, 1.0, 0])))
    with pytest.raises(TriangulationError, match="epipolar") as info:
        locate_seam(obs)
    assert "across the seam" in str(info.value)


@pytest.mark.parametrize("kind", ["straight", "arc", "s_curve", "nonplanar"])
def test_exact_curves_reach_both_true_ends(kind):
    # Both views hold the seam's true end points (3001 samples, every 3rd): the located seam must
    # end there, not one reference sample (about 0.25 mm) short.
    P = seam_curve(kind, n=3001)
    obs = observe(P, camera_poses(P), step=3)
    assert all(np.allclose(o.camera.project(P[[0, -1]], o.T_base_cam), o.seam_px[[0, -1]])
               for o in obs)
    seam = locate_seam(obs)
    for a, b in (seam.dense_points_mm[[0, -1]], seam.points_mm[[0, -1]]):
        gap = min(max(np.linalg.norm(a - P[0]), np.linalg.norm(b - P[-1])),
                  max(np.linalg.norm(a - P[-1]), np.linalg.norm(b - P[0])))  # either direction
        assert gap < 0.05, gap
    assert max(seam.quality["endpoint_gap_mm"]) < 0.05


def test_partly_degenerate_seam_is_flagged():
    # an arc whose middle runs along the baseline direction
    P = seam_curve("arc")
    obs = observe(P, camera_poses(P, along=np.array([0, 1.0, 0])))
    with pytest.raises(TriangulationError, match="epipolar") as info:
        locate_seam(obs, limits=QualityLimits(max_degenerate_fraction=0.02))
    msg = str(info.value)
    assert "nan" not in msg.lower(), msg
    # The hint: the baseline runs along y (along the middle of the arc); it should run across
    # the seam there, along x.
    hint = re.search(r"runs along \[([^\]]+)\] \(across the seam\)", msg)
    assert hint is not None, msg
    fix = np.array([float(v) for v in hint.group(1).split(",")])
    assert abs(abs(fix[0]) - 1.0) < 0.05 and np.linalg.norm(fix[1:]) < 0.1, fix
    # With the default degenerate limit the same views are refused with a reason, never a crash
    # on a seam curve of NaN (the spline through the degenerate gap).
    with pytest.raises(TriangulationError, match="quality checks"):
        locate_seam(obs)


def test_wrong_pose_of_one_view_is_caught_by_end_point_gap():
    P = seam_curve("s_curve")
    poses = camera_poses(P)
    obs = observe(P, poses)
    # 5 mm along the camera x axis, i.e. along the seam (an error along the baseline is a pure
    # change of scale that no two-view check can see: see the nominal region check)
    wrong = poses[1] @ make_pose(rotation_about([0, 0, 1], 0.0), [5.0, 0, 0])
    obs[1] = ViewObservation(obs[1].camera, wrong, obs[1].seam_px, "view2")
    with pytest.raises(TriangulationError, match="where the seam ends") as info:
        locate_seam(obs)
    assert max(info.value.details["quality"]["endpoint_gap_mm"]) > 1.0


def _shifted(obs: ViewObservation, px: float) -> np.ndarray:
    """``obs``'s curve moved ``px`` across itself (image normal), as a band's middle would be."""
    uv = obs.seam_px
    t = np.gradient(uv, axis=0)
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    return uv + px * np.column_stack([-t[:, 1], t[:, 0]])


def test_a_view_that_took_a_shadow_band_for_the_gap_is_refused_by_the_gap_widths():
    # View 2 took the gap (2.8 px) and a shadow band beside it (7 px) as one dark band: its
    # centreline is 3.5 px off the joint's. The epipolar matching absorbs that as depth: the
    # seam comes out a millimetre off and passes every reprojection check.
    P = seam_curve("s_curve")
    obs = observe(P, camera_poses(P))
    off = ViewObservation(obs[1].camera, obs[1].T_base_cam, _shifted(obs[1], 3.5), "view2")
    seam = locate_seam([obs[0], off])
    err = PolylineDistance(P)(seam.dense_points_mm)
    assert np.median(err) > 0.5  # the blind spot: a wrong seam, accepted
    a = ViewObservation(obs[0].camera, obs[0].T_base_cam, obs[0].seam_px, "view1",
                        gap_width_px=2.8)
    b = ViewObservation(off.camera, off.T_base_cam, off.seam_px, "view2", gap_width_px=9.8)
    with pytest.raises(TriangulationError, match="different widths") as info:
        locate_seam([a, b])
    w = info.value.details["quality"]["gap_width_mm"]
    T = obs[0].T_base_cam  # px / mm = fx / the seam's depth in front of the camera
    px_mm = obs[0].camera.fx / float(np.median((P - T[:3, 3]) @ T[:3, 2]))
    assert w[0] == pytest.approx(2.8 / px_mm, rel=0.05) and w[1] == pytest.approx(9.8 / px_mm,
                                                                                   rel=0.05)
    # The same gap seen about as wide in both views (a ragged edge, blur): accepted.
    b_ok = ViewObservation(obs[1].camera, obs[1].T_base_cam, obs[1].seam_px, "view2",
                           gap_width_px=3.6)
    seam = locate_seam([a, b_ok])
    assert seam.quality["gap_width_mm"][1] == pytest.approx(3.6 / px_mm, rel=0.05)
    # A view without a width (a detector that does not measure one) is not compared.
    assert locate_seam([a, obs[1]]).quality["gap_width_mm"][1] is None


def test_another_seam_in_view_two_lands_outside_the_nominal_region():
    P = seam_curve("straight")
    Q = P.copy()
    Q[:, 0] += 60  # view 2 found a parallel edge 60 mm away: geometrically consistent, but the
    obs = observe(P, camera_poses(P))  # triangulated seam is far from where the job says it is
    other = observe(Q, camera_poses(P))[1]
    region = (P.mean(axis=0), 100.0)  # the seam is 180 mm long; the wrong one lands 110 mm low
    locate_seam(obs, nominal_region=region)
    with pytest.raises(TriangulationError, match="nominal"):
        locate_seam([obs[0], other], nominal_region=region)


def test_bad_input():
    P = seam_curve("straight")
    obs = observe(P, camera_poses(P))
    with pytest.raises(InputError, match="at least two views"):
        locate_seam(obs[:1])
    bad = ViewObservation(obs[1].camera, obs[1].T_base_cam, np.array([[1.0, 2.0]]), "bad")
    with pytest.raises(InputError, match="bad"):
        locate_seam([obs[0], bad])


# ---- each quality gate, tripped alone by a scene built for it --------------------------------
# Every test asserts that the gate's own problem is the only one raised and that the same scene
# passes with that one limit relaxed: switching the gate off must fail the test.

def only_problem(obs, limits=None):
    with pytest.raises(TriangulationError) as info:
        locate_seam(obs, limits=limits or QualityLimits())
    problems = info.value.details["problems"]
    assert len(problems) == 1, problems
    return problems[0], info.value.details["quality"]


def test_views_too_close_together_trip_the_ray_angle_gate_alone():
    P = seam_curve("s_curve")
    obs = observe(P, camera_poses(P, baseline_mm=40.0))  # 6.6 deg between the rays
    problem, q = only_problem(obs)
    assert "too similar directions" in problem
    assert 6.0 < q["angle_deg_min"] < QualityLimits().min_angle_deg
    locate_seam(obs, limits=QualityLimits(min_angle_deg=q["angle_deg_min"]))  # at the limit


def test_rays_of_three_noisy_views_missing_each_other_trip_the_ray_gap_gate_alone():
    P = seam_curve("s_curve")
    poses = camera_poses(P)
    poses.append(camera_poses(P, along=np.array([0, 1.0, 0]))[0])
    obs = observe(P, poses, noise_px=0.5, seed=2)  # reprojection stays under 1 px RMS / 4 px
    problem, q = only_problem(obs)
    assert "rays miss each other" in problem
    assert QualityLimits().max_ray_gap_mm < q["ray_gap_mm_max"] < 0.6
    locate_seam(obs, limits=QualityLimits(max_ray_gap_mm=q["ray_gap_mm_max"]))  # at the limit


def test_a_seam_longer_than_the_image_trips_the_border_gate_alone():
    s = np.linspace(-1, 1, 6000)
    P = np.column_stack([0 * s, 400 * s, 0 * s]) + CENTRE  # 800 mm: runs out of both images
    obs = observe(P, camera_poses(P))
    problem, q = only_problem(obs)
    assert "runs out of the image" in problem
    assert len(q["ends_cut_by_image_border"]) == 4
    locate_seam(obs, limits=QualityLimits(require_ends_in_view=False))


def test_a_seam_seen_in_part_by_one_view_trips_the_coverage_gate():
    # An unmatched end of the reference curve is a real end in the image, so the end-point gap
    # always trips with coverage: it is relaxed here to see the coverage gate on its own.
    P = seam_curve("s_curve")
    obs = observe(P, camera_poses(P))
    short = obs[1].seam_px[: int(0.8 * len(obs[1].seam_px))]
    obs = [obs[0], ViewObservation(obs[1].camera, obs[1].T_base_cam, short, "view2")]
    problem, q = only_problem(obs, QualityLimits(max_endpoint_gap_mm=1e9))
    assert "only 79% of the seam was matched" in problem
    locate_seam(obs, limits=QualityLimits(max_endpoint_gap_mm=1e9, min_coverage=0.75))


def test_a_detection_stopped_short_at_the_far_end_is_caught_at_that_end():
    P = seam_curve("s_curve")
    obs = observe(P, camera_poses(P))
    short = obs[1].seam_px[: int(0.98 * len(obs[1].seam_px))]  # 2 % (4 mm) short at its end
    obs = [obs[0], ViewObservation(obs[1].camera, obs[1].T_base_cam, short, "view2")]
    problem, q = only_problem(obs)
    assert "where the seam ends" in problem
    start, end = q["endpoint_gap_mm"]
    assert start < 0.5 < QualityLimits().max_endpoint_gap_mm < end
    # both views end at a joint end there: the end is seen (and judged by its gap), with no
    # reason for a view not to see it, though view 1's end lies ~4 mm beyond the 3D end
    far = q["ends"][1]
    assert far["status"] == "seen" and far["seen_by"] == ["view1", "view2"]
    assert far["not_seen"] == []


def _bent_view_two(bend):
    """The straight seam with view 2's curve bent across the seam (v, the epipolar direction for
    this baseline): the rays still meet, so the bend goes into depth, which the smoothing takes
    out, and the smoothed seam reprojects off view 2's curve while it stays on view 1's."""
    P = seam_curve("straight")
    obs = observe(P, camera_poses(P))
    px = obs[1].seam_px.copy()
    px[:, 1] += bend(np.arange(len(px)))
    return [obs[0], ViewObservation(obs[1].camera, obs[1].T_base_cam, px, "view2")]


def test_a_narrow_bump_in_one_view_trips_the_reprojection_gate_on_its_maximum_alone():
    obs = _bent_view_two(lambda s: 12.0 * np.exp(-0.5 * ((s - len(s) // 2) / 5.0) ** 2))
    problem, q = only_problem(obs)
    assert "reprojects" in problem
    rms1, rms2 = q["reprojection_px_rms"]
    mx1, mx2 = q["reprojection_px_max"]
    assert mx1 < 1e-3 and rms1 < 1e-3  # view 1 is met: only view 2's curve is off
    lim = QualityLimits()
    assert rms2 < lim.max_reprojection_rms_px < lim.max_reprojection_px < mx2 < 8.0
    assert q["ray_gap_mm_max"] < 1e-6
    locate_seam(obs, limits=QualityLimits(max_reprojection_px=mx2))  # at the limit


def test_a_fine_wiggle_in_one_view_trips_the_reprojection_gate_on_its_rms_alone():
    obs = _bent_view_two(lambda s: 2.0 * np.sin(2.0 * np.pi * s / 8.0))  # 2 px, 8 samples
    problem, q = only_problem(obs)
    assert "reprojects" in problem
    lim = QualityLimits()
    rms2, mx2 = q["reprojection_px_rms"][1], q["reprojection_px_max"][1]
    assert lim.max_reprojection_rms_px < rms2 < 1.5 and mx2 < lim.max_reprojection_px
    locate_seam(obs, limits=QualityLimits(max_reprojection_rms_px=rms2))  # at the limit


def test_degenerate_hint_without_a_direction_gives_none():
    # A degenerate stretch of one sample has no tangent: the reason keeps its advice but names
    # no direction (never [nan, nan, nan] nor [0.0, 0.0, 0.0]).
    P = seam_curve("straight")
    obs = observe(P, camera_poses(P))
    dense = P[::100]
    q = {"coverage": 1.0, "degenerate_fraction": 0.5, "angle_deg_min": 30.0,
         "ray_gap_mm_max": 0.0, "reprojection_px_rms": [0.0], "reprojection_px_max": [0.0],
         "endpoint_gap_mm": [0.0], "ends": [], "length_mm": 180.0}
    degenerate = np.zeros(len(dense), dtype=bool)
    degenerate[3] = True
    with pytest.raises(TriangulationError) as info:
        _judge(q, QualityLimits(), degenerate, dense, np.arange(len(dense), dtype=float), 0, obs,
               {})
    msg = str(info.value)
    assert "runs across the seam" in msg and "runs along [" not in msg, msg


def _leaving_pair():
    """The seam seen by view 1; view 2's curve leaves it along another line near one end (up to
    60 mm aside at the end); both run out of their images at both ends (unseen ends)."""
    from dataclasses import replace

    P = seam_curve("straight")
    s = np.linspace(-1.0, 1.0, len(P))
    Q = P.copy()
    Q[:, 0] += 60.0 * np.clip(s - 0.3, 0.0, None) ** 2 / 0.49
    poses = camera_poses(P)
    kinds = ("image_border", "image_border")
    right = [replace(o, end_kinds=kinds) for o in observe(P, poses)]
    return P, right, [right[0], replace(observe(Q, poses)[1], end_kinds=kinds)]


def test_a_curve_leaving_the_seam_near_a_clipped_end_is_refused_by_the_nominal_line():
    P, right, wrong = _leaving_pair()
    region = (P.mean(axis=0), 70.0)
    line = (P[::150], 5.0)  # the seam as drawn, every ~6 mm; 5 mm tolerance
    # Clipping to the region hides the curve that left the seam (it would be refused without
    # clipping): what is kept still runs millimetres off the seam toward the region's edge.
    with pytest.raises(TriangulationError, match="nominal seam centre"):
        locate_seam(wrong, nominal_region=region)
    hidden = locate_seam(wrong, nominal_region=region, clip_unseen_ends=True)
    assert error_to_truth(P, hidden)[1] > 2.0
    with pytest.raises(TriangulationError, match="from the job's nominal line"):
        locate_seam(wrong, nominal_region=region, clip_unseen_ends=True, nominal_line=line)
    seam = locate_seam(right, nominal_region=region, clip_unseen_ends=True, nominal_line=line)
    assert seam.quality["distance_from_nominal_line_mm_max"] < 0.5
    assert error_to_truth(P, seam)[1] < 0.1
