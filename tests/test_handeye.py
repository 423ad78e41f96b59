
import numpy as np
import pytest
from shared_data import ETHZ, needs

from calibration.handeye import (
    CLOSED_FORM_METHODS,
    Observation,
    closed_form,
    opencv_calibrate_hand_eye,
    solve_hand_eye,
    view_residuals,
)
from calibration.targets import parse_board_spec
from controller.errors import CalibrationError
from controller.geometry.camera_model import default_camera
from controller.geometry.poses import (
    invert,
    make_pose,
    pose_error,
    rotation_about,
    transform_points,
)
from drivers.sim.sim_board import default_board_pose, default_hand_eye, look_at, perturb

CAM = default_camera(640, 480)
BOARD = parse_board_spec("chessboard:9x6:20")
X_TRUE = default_hand_eye()
Y_TRUE = default_board_pose(BOARD)


def session(n=14, seed=0, noise_px=0.05, sigma_mm=0.05, sigma_deg=0.01, eye_to_hand=False,
            bad=(), az_step=2.4):
    """Corner observations without rendering: true projections plus noise.

    Eye-in-hand views step around the board by ``az_step`` rad of azimuth (0: all from one side).
    """
    rng = np.random.default_rng(seed)
    obj = BOARD.object_points()
    centre = Y_TRUE[:3, :3] @ obj.mean(axis=0) + Y_TRUE[:3, 3]
    A, obs, true_A = [], [], []
    T_base_cam_fixed = look_at(np.array([1500.0, -300, 1000]), np.array([1000.0, 0, 650]), 0.0,
                               up=np.array([0, 0, 1.0]))
    Rfb = rotation_about([1, 0, 0], np.pi)
    Y_e2h = make_pose(Rfb, np.array([0, 0, 150.0]) - Rfb @ obj.mean(axis=0))
    i = 0
    while len(A) < n:
        i += 1
        if eye_to_hand:
            R = rotation_about([np.cos(2.4 * i), np.sin(2.4 * i), 0], np.radians(
                rng.uniform(15, 40))) @ rotation_about([0, 0, 1], rng.uniform(-0.6, 0.6))
            c = obj.mean(axis=0)
            T_cb = make_pose(R, np.array([rng.uniform(-30, 30), rng.uniform(-20, 20),
                                          rng.uniform(280, 360)]) - R @ c)
            T_bf = T_base_cam_fixed @ T_cb @ invert(Y_e2h)
        else:
            az, tilt = az_step * i + rng.uniform(-0.2, 0.2), np.radians(rng.uniform(20, 45))
            eye = centre + rng.uniform(280, 360) * np.array(
                [np.sin(tilt) * np.cos(az), np.sin(tilt) * np.sin(az), np.cos(tilt)])
            target = centre + np.array([rng.uniform(-40, 40), rng.uniform(-30, 30), 0])
            T_bc = look_at(eye, target, rng.uniform(-0.6, 0.6))
            T_bf = T_bc @ invert(X_TRUE)
            T_cb = invert(T_bc) @ Y_TRUE
        uv = CAM.project_cam(transform_points(T_cb, obj))
        if not np.all(np.isfinite(uv)) or uv.min() < 5 or uv[:, 0].max() > 635 or \
                uv[:, 1].max() > 475:
            continue
        rec = perturb(T_bf, rng, sigma_mm, sigma_deg)
        if len(A) in bad:
            rec[:3, 3] += [1.0, -0.8, 0.6]
            rec[:3, :3] = rec[:3, :3] @ rotation_about([0.3, 1, 0], np.radians(0.25))
        A.append(rec)
        true_A.append(T_bf)
        obs.append(Observation(uv + rng.normal(0, noise_px, uv.shape), obj))
    truth = (T_base_cam_fixed, Y_e2h) if eye_to_hand else (X_TRUE, Y_TRUE)
    return A, obs, truth


@pytest.mark.parametrize("method", list(CLOSED_FORM_METHODS))
def test_opencv_wrapper_conventions_exact(method):
    A, obs, (X, Y) = session(n=6, noise_px=0, sigma_mm=0, sigma_deg=0)
    T_cb = [invert(X) @ invert(a) @ Y for a in A]
    Xs = opencv_calibrate_hand_eye(A, T_cb, method)
    assert pose_error(Xs, X)[0] < 1e-3 and pose_error(Xs, X)[1] < 1e-4
    Xc, Yc = closed_form(A, T_cb, method=method)
    assert pose_error(Yc, Y)[0] < 1e-2


def test_unknown_method():
    with pytest.raises(CalibrationError, match="unknown hand-eye method"):
        opencv_calibrate_hand_eye([np.eye(4)] * 3, [np.eye(4)] * 3, "magic")


def test_joint_refinement_accuracy_and_report():
    A, obs, (X, Y) = session(n=16)
    r = solve_hand_eye(A, obs, CAM)
    d_mm, d_deg = pose_error(r.T_flange_cam, X)
    assert d_mm < 0.2 and d_deg < 0.03
    assert pose_error(r.T_base_board, Y)[0] < 0.5
    assert r.rejected_views == [] and len(r.used_views) == 16
    assert r.residual_px < 0.6 and r.consistency_mm < 0.15 and r.consistency_deg < 0.03
    assert set(r.closed_form) == set(CLOSED_FORM_METHODS)
    rep = r.report()
    assert rep["mode"] == "eye-in-hand" and "T_flange_cam" in rep
    # A view's residual under the solution (as held-out validation uses it).
    res = view_residuals(r, A[0], obs[0])
    assert res.shape == (54, 2) and np.sqrt(np.mean(res ** 2)) < 1.0


def test_hand_eye_uncertainty_from_the_refinement():
    # One sigma of the hand-eye along the camera axes, from the refinement's Jacobian: reported,
    # consistent with the actual error, and larger along the optical axis when every view looks
    # at the board from the same side (the weakness the bench sessions had before their views
    # were spread around the board).
    A, obs, (X, _) = session(n=16, seed=3, noise_px=0.1)
    r = solve_hand_eye(A, obs, CAM, refine_intrinsics=True)
    assert r.std_mm is not None and r.std_deg is not None
    assert np.all(r.std_mm > 0.005) and np.all(r.std_mm < 0.2) and np.all(r.std_deg < 0.05)
    err_cam = X[:3, :3].T @ (r.T_flange_cam[:3, 3] - X[:3, 3])
    assert np.all(np.abs(err_cam) < 4 * r.std_mm + 1e-3)
    # The report gives the larger of the covariance's and the jackknife's one-sigma per axis.
    assert r.jackknife_std_mm is not None
    assert r.report()["hand_eye_std_mm_cam_xyz"] == [
        round(float(v), 4) for v in np.maximum(r.std_mm, r.jackknife_std_mm)]
    A1, obs1, _ = session(n=16, seed=3, noise_px=0.1, az_step=0.0)
    r1 = solve_hand_eye(A1, obs1, CAM, refine_intrinsics=True)
    assert r1.std_mm is not None and r1.std_mm[2] > 1.5 * r.std_mm[2]


def test_bad_views_named_and_left_out():
    A, obs, (X, Y) = session(n=16, bad=(3, 11))
    names = [f"v{i}" for i in range(16)]
    r = solve_hand_eye(A, obs, CAM, names=names)
    assert sorted(x["view"] for x in r.rejected_views) == ["v11", "v3"]
    assert all("recorded robot pose" in x["reason"] for x in r.rejected_views)
    assert pose_error(r.T_flange_cam, X)[0] < 0.25
    # The plain closed form on all views is pulled off by the two bad views.
    assert pose_error(r.closed_form["tsai"], X)[0] > pose_error(r.T_flange_cam, X)[0]


def test_too_many_bad_views_refuse_the_calibration_and_name_them():
    names = [f"v{i}" for i in range(10)]
    A, obs, (X, _) = session(n=10, bad=(1, 4, 7))  # 3 of 10: within 34 %, left out
    r = solve_hand_eye(A, obs, CAM, names=names)
    assert sorted(x["view"] for x in r.rejected_views) == ["v1", "v4", "v7"]
    assert pose_error(r.T_flange_cam, X)[0] < 0.25
    A, obs, _ = session(n=10, bad=(1, 4, 7, 8))  # 4 of 10: the session is refused
    with pytest.raises(CalibrationError, match=r"too many bad views \(") as e:
        solve_hand_eye(A, obs, CAM, names=names)
    assert sorted(x["view"] for x in e.value.details["rejected_views"]) == ["v1", "v4", "v7",
                                                                           "v8"]
    assert "6 of 10 views are left" in str(e.value)


def test_too_many_inconsistent_board_poses_refuse_the_pose_only_calibration():
    A, obs, (X, Y) = session(n=10, noise_px=0, sigma_mm=0.02, sigma_deg=0.005)

    def board_poses(bad):
        T_cb = [invert(X) @ invert(a) @ Y for a in A]
        for i in bad:  # the board seen 10 mm / 2 deg away from where the others put it
            T_cb[i] = T_cb[i] @ make_pose(rotation_about([0, 1, 0], np.radians(2)), [10.0, 0, 0])
        return T_cb

    r = solve_hand_eye(A, board_poses((1, 4, 7)), None)
    assert sorted(x["view"] for x in r.rejected_views) == ["view02", "view05", "view08"]
    with pytest.raises(CalibrationError, match=r"too many inconsistent poses \(view"):
        solve_hand_eye(A, board_poses((1, 4, 7, 8)), None)


def test_refine_intrinsics():
    A, obs, (X, Y) = session(n=16, seed=2)
    K = CAM.K.copy()
    K[0, 0] *= 1.004
    K[1, 1] *= 1.004
    from controller.geometry.camera_model import CameraModel

    wrong = CameraModel(640, 480, K, CAM.dist)
    r = solve_hand_eye(A, obs, wrong, refine_intrinsics=True)
    assert abs(r.camera.fx / CAM.fx - 1) < 0.001
    assert pose_error(r.T_flange_cam, X)[0] < 0.3


def test_eye_to_hand():
    A, obs, (X, Y) = session(n=14, eye_to_hand=True, seed=3)
    r = solve_hand_eye(A, obs, CAM, eye_to_hand=True)
    assert r.T_flange_cam is None and r.T_base_cam is not None
    d_mm, d_deg = pose_error(r.T_base_cam, X)
    assert d_mm < 1.0 and d_deg < 0.05
    assert pose_error(r.T_flange_board, Y)[0] < 1.0


def test_pose_only_input():
    A, obs, (X, Y) = session(n=12, noise_px=0, sigma_mm=0.02, sigma_deg=0.005)
    T_cb = [invert(X) @ invert(a) @ Y for a in A]
    r = solve_hand_eye(A, T_cb, None)
    assert pose_error(r.T_flange_cam, X)[0] < 0.3 and r.camera is None


def test_too_few_views():
    A, obs, _ = session(n=4)
    with pytest.raises(CalibrationError, match=r"at least 5 good views, got 4 \(view01"):
        solve_hand_eye(A, obs, CAM)


def test_robot_did_not_move():
    A, obs, _ = session(n=6)
    A = [A[0].copy() for _ in A]
    with pytest.raises(CalibrationError, match="robot did not move: views view01, view02"):
        solve_hand_eye(A, obs, CAM)


def test_pure_translation_is_degenerate():
    A, obs, _ = session(n=6)
    A2 = [A[0].copy() for _ in A]
    for k, T in enumerate(A2):
        T[:3, 3] += [20.0 * k, -10.0 * k, 5.0 * k]
    with pytest.raises(CalibrationError, match="too little rotation between views view01"):
        solve_hand_eye(A2, obs, CAM)


def test_single_axis_rotation_is_degenerate():
    A, obs, _ = session(n=6)
    A2 = [A[0] @ make_pose(rotation_about([0, 0, 1], np.radians(10 * k))) for k in range(6)]
    with pytest.raises(CalibrationError, match="rotate only about one axis"):
        solve_hand_eye(A2, obs, CAM)


def test_bad_residuals_refused():
    A, obs, _ = session(n=10)
    wrong = parse_board_spec("chessboard:9x6:21").object_points()  # wrong square size
    obs = [Observation(o.image_points, wrong) for o in obs]
    with pytest.raises(CalibrationError, match="hand-eye refused") as e:
        solve_hand_eye(A, obs, CAM, max_consistency_mm=0.2)
    assert "view" in str(e.value)




def _ethz_stream(name):
    from scipy.spatial.transform import Rotation

    a = np.loadtxt(ETHZ / name, delimiter=",")
    R = Rotation.from_quat(a[:, 4:8]).as_matrix()  # x, y, z, w as in the file
    return a[:, 0], [make_pose(R[i], a[i, 1:4] * 1000.0) for i in range(len(a))]


@needs(ETHZ)
def test_real_robot_poses_ethz():
    """Real robot and SR300 target poses (no images): time alignment, AX = XB, consistency."""
    from calibration.handeye import pair_pose_streams

    tH, TH = _ethz_stream("robot_arm_complete_bag_color_and_ir_base_link_sr300_hinge.csv")
    tE, TE = _ethz_stream("robot_arm_complete_bag_color_and_ir_target_ir.csv")
    A, B, offset, corr = pair_pose_streams(tH, TH, tE, [invert(T) for T in TE], 40,
                                           max_offset_s=0.2)
    assert abs(offset - 0.018) < 0.005 and corr > 0.95 and len(A) == 40
    r = solve_hand_eye(A, B, None, max_rms_px=1e9, reject_min_px=5.0)
    # mm-level consistency, as the SR300's target poses allow; the closed forms agree within
    # a couple of centimetres (Daniilidis excepted: unstable on this data).
    assert r.consistency_mm < 6.0 and r.consistency_deg < 1.0
    for m in ("tsai", "park", "horaud", "andreff"):
        assert pose_error(r.closed_form[m], r.X)[0] < 25.0
    # The other direction of the target stream is clearly wrong.
    with pytest.raises(CalibrationError, match="refused"):
        solve_hand_eye(A, [invert(T) for T in B], None, max_rms_px=50.0, reject_min_px=5.0)


def test_robot_noise_estimated_from_the_residuals():
    """A robot 4-6x noisier than the old fixed assumption: its noise is estimated (within 35 %),
    reported, and the one-sigma follows it (the error within 4 sigma)."""
    A, obs, (X, _) = session(n=16, seed=5, noise_px=0.1, sigma_mm=0.3, sigma_deg=0.05)
    r = solve_hand_eye(A, obs, CAM)
    assert abs(r.noise["robot_sigma_mm"] / 0.3 - 1) < 0.35
    assert abs(r.noise["robot_sigma_deg"] / 0.05 - 1) < 0.35
    assert abs(r.noise["corner_sigma_px"] / 0.1 - 1) < 0.2
    rep = r.report()
    assert rep["noise"]["robot_noise"] == "estimated from the residuals"
    err_cam = X[:3, :3].T @ (r.T_flange_cam[:3, 3] - X[:3, 3])
    assert np.all(np.abs(err_cam) < 4 * np.asarray(rep["hand_eye_std_mm_cam_xyz"]))
    # Given instead of estimated, the noise is used as given.
    g = solve_hand_eye(A, obs, CAM, robot_sigma_mm=0.3, robot_sigma_deg=0.05, leave_out=False)
    assert g.noise["robot_sigma_mm"] == 0.3 and g.noise["robot_noise"] == "given"


def test_leave_one_out_matches_exact_refits():
    """The one-step leave-one-out prediction of a view agrees with solving again without it
    (same noise) and predicting it from its recorded pose; the jackknife's one-sigma is of the
    covariance's size."""
    A, obs, _ = session(n=10, seed=2, noise_px=0.1, sigma_mm=0.2, sigma_deg=0.03)
    names = [f"v{i}" for i in range(10)]
    r = solve_hand_eye(A, obs, CAM, names=names)
    rep = r.report()["leave_one_out"]
    assert set(rep["per_view_px_mm"]) == set(names) and len(rep["worst_views"]) == 3
    assert rep["rms_px"] > r.residual_px  # a view predicted is worse than a view fitted
    for k in (0, 4, 7):
        keep = [i for i in range(10) if i != k]
        sub = solve_hand_eye([A[i] for i in keep], [obs[i] for i in keep], CAM,
                             names=[names[i] for i in keep], leave_out=False,
                             robot_sigma_mm=r.noise["robot_sigma_mm"],
                             robot_sigma_deg=r.noise["robot_sigma_deg"])
        res = view_residuals(sub, A[k], obs[k])
        exact = float(np.sqrt(np.mean(np.sum(res ** 2, axis=1))))
        assert abs(r.leave_one_out[names[k]][0] / exact - 1) < 0.15, (k, exact)
    assert r.std_mm is not None and r.jackknife_std_mm is not None
    ratio = r.jackknife_std_mm / r.std_mm
    assert np.all(ratio > 0.4) and np.all(ratio < 2.5)


def test_noisy_robot_no_worse_than_opencv_park():
    """Robot pose noise 1 mm / 0.1 deg, corners 0.1 px: the robot is far worse than the camera.
    Over three sessions ours is, on the truth, no worse than Park on the same corners, within
    10 % (both are at the accuracy this robot allows: over eight sessions ours was 1.10 mm /
    0.045 deg, Park 1.08 mm / 0.051 deg; the report's one-sigma matched both). (At
    640x480 such a robot is refused by default: 4 px of reprojection error, over the limit of
    0.25 % of the image diagonal; a user who knows the robot raises it.)"""
    from calibration.closed_form import _pnp

    ours, park = [], []
    for seed in (11, 12, 13):
        A, obs, (X, _) = session(n=20, seed=seed, noise_px=0.1, sigma_mm=1.0, sigma_deg=0.1)
        r = solve_hand_eye(A, obs, CAM, leave_out=False, max_rms_px=10.0)
        Xp = opencv_calibrate_hand_eye(A, [_pnp(CAM, o)[0] for o in obs], "park")
        ours.append(pose_error(r.X, X))
        park.append(pose_error(Xp, X))
    ours_a, park_a = np.array(ours), np.array(park)
    assert ours_a[:, 0].mean() <= 1.1 * park_a[:, 0].mean()
    assert ours_a[:, 1].mean() <= 1.1 * park_a[:, 1].mean()


def _true_view_error_px(A_recorded, obs, X, Y):
    """Per view, the RMS px between its corners and where its recorded pose puts them with the
    true hand-eye and board: how far off a view's pose is, whatever the solver."""
    out = []
    for a, o in zip(A_recorded, obs, strict=True):
        uv = CAM.project_cam(transform_points(invert(a @ X) @ Y, o.object_points))
        out.append(float(np.sqrt(np.mean(np.sum((uv - o.image_points) ** 2, axis=1)))))
    return np.array(out)


def test_eight_views_millimetres_off_refused_naming_the_worst_views():
    """Issue 18's two real 8-view sets at 640x480, simulated (their images are not in
    ../shared/data): with the default limits (reprojection 0.25 % of the diagonal, 2.0 px here;
    consistency 3 mm / 0.5 deg) a set whose recorded poses are millimetres off (2 mm / 0.2 deg
    per axis) is refused, the message naming views among the three whose poses are truly the
    worst; a consistent set of the same views (0.2 mm / 0.03 deg) passes."""
    names = [f"v{i}" for i in range(8)]
    for seed in (21, 22, 23):
        A, obs, (X, _) = session(n=8, seed=seed, noise_px=0.1, sigma_mm=0.2, sigma_deg=0.03)
        r = solve_hand_eye(A, obs, CAM, names=names, refine_intrinsics=True)  # not refused
        assert r.rejected_views == [] and pose_error(r.X, X)[0] < 1.0
        A, obs, (X, Y) = session(n=8, seed=seed, noise_px=0.1, sigma_mm=2.0, sigma_deg=0.2)
        with pytest.raises(CalibrationError, match="hand-eye refused") as e:
            solve_hand_eye(A, obs, CAM, names=names, refine_intrinsics=True)
        d = e.value.details
        named = d.get("worst_views") or [v["view"] for v in d.get("rejected_views", [])]
        truly = {names[i] for i in np.argsort(-_true_view_error_px(A, obs, X, Y))[:3]}
        assert len(set(named[:3]) & truly) >= 2, (seed, named, truly, str(e.value))
        assert all(v in str(e.value) for v in named[:3])


@pytest.mark.parametrize("mistake, words", [
    ("metres", "metres"), ("xyzw", "x, y, z, w"), ("inverted", "inverted"),
    ("square_units", "different units")])
def test_usual_mistakes_named(mistake, words):
    """Poses in metres, quaternions written x,y,z,w, inverted poses, a board in other units than
    the robot: refused with a message naming the mistake, before any refinement."""
    from scipy.spatial.transform import Rotation

    A, obs, _ = session(n=10, seed=4)
    if mistake == "metres":
        A = [make_pose(T[:3, :3], T[:3, 3] / 1000.0) for T in A]
    elif mistake == "xyzw":
        # The file held x, y, z, w and was read as w, x, y, z.
        # The file held x, y, z, w and was read as w, x, y, z: scipy's x, y, z, w gets y, z, w, x.
        A = [make_pose(Rotation.from_quat(np.roll(Rotation.from_matrix(T[:3, :3]).as_quat(), -1)
                                          ).as_matrix(), T[:3, 3]) for T in A]
    elif mistake == "inverted":
        A = [invert(T) for T in A]
    else:
        obs = [Observation(o.image_points, o.object_points * 25.4) for o in obs]  # inches
    with pytest.raises(CalibrationError, match="refused") as e:
        solve_hand_eye(A, obs, CAM)
    assert words in str(e.value), str(e.value)
