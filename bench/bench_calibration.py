"""Calibration accuracy report: simulated teach sessions, and the two real data sets.

Usage::

    .venv/bin/python bench/bench_calibration.py [--seeds 3] [--views 20] [--width 2272]
                                               [--output bench/calibration_results.json]

1. Simulated sessions at full size (default 2272x1704, the published sensor): ``--views`` good
   views plus 2 motion-blurred views whose recorded pose is off and 1 view with the board partly
   out of frame; robot pose noise 0.05 mm / 0.01 deg per axis; sensor noise 1.5 grey levels.
   Each session is solved twice: *clean* (only the good views) and *with bad views* (all views
   whose board was detected). Methods:

   - ``opencv-<method>``: the plain OpenCV pipeline -- calibrateCamera on all views, solvePnP per
     view, calibrateHandEye with that method on all views;
   - ``ours``: solve_hand_eye (robot noise estimated; bad views named and left out).

   Errors against the simulator's ground truth: hand-eye translation (mm) and rotation (deg), and
   the focal length (%).
2. ETH ASL robot arm + SR300 poses (../shared/data/ethz-handeye-robot-arm): time offset by
   correlating angular speeds, 40 slow-motion samples, each method fitted on even samples and
   checked on odd ones (board pose predicted from the robot pose vs measured).
3. OpenCV sample chessboard images (../shared/data/opencv-chessboard, left*.jpg): our
   intrinsics vs a direct cv2.calibrateCamera on the same corners, and vs the upstream reference.
4. ``--auto-teach``: the automatic teach (``run_teach(auto_n=--views)``), simulated robot/camera.

Steep 28x17 boards and a noisy robot (1 mm / 0.1 deg): bench/bench_calibration_noise.py.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from calibration.handeye import (  # noqa: E402
    CLOSED_FORM_METHODS,
    Observation,
    opencv_calibrate_hand_eye,
    pair_pose_streams,
    solve_hand_eye,
)
from calibration.intrinsics import solve_intrinsics  # noqa: E402
from calibration.targets import detect_board, parse_board_spec  # noqa: E402
from controller.geometry.camera_model import default_camera  # noqa: E402
from controller.geometry.poses import invert, make_pose, pose_error, pose_from_rvec_tvec  # noqa: E402
from drivers.sim.sim_board import simulate_session  # noqa: E402

DATA = ROOT.parent / "shared" / "data"


def plain_opencv(A, dets, size):
    """The plain pipeline: calibrateCamera, solvePnP, calibrateHandEye (every method)."""
    obj = [d.object_points.astype(np.float32) for d in dets]
    img = [d.image_points.astype(np.float32) for d in dets]
    _, K, dist, rvecs, tvecs = cv2.calibrateCamera(obj, img, size, None, None)
    T_cb = [pose_from_rvec_tvec(r, t) for r, t in zip(rvecs, tvecs, strict=True)]
    out = {}
    for m in CLOSED_FORM_METHODS:
        out[m] = opencv_calibrate_hand_eye(A, T_cb, m)
    return out, float(K[0, 0])


def run_sim(seeds, n_views, width):
    cam = default_camera(width, round(width * 1704 / 2272))
    board = parse_board_spec("chessboard:9x6:20")
    rows = []
    for seed in seeds:
        t0 = time.perf_counter()
        s = simulate_session(cam, board, n_views=n_views, seed=seed, n_blurred=2,
                             n_out_of_frame=1)
        t_render = (time.perf_counter() - t0) / len(s.views)
        t0 = time.perf_counter()
        dets = [detect_board(v.image, board) for v in s.views]
        t_detect = (time.perf_counter() - t0) / len(s.views)
        found = [(v, d) for v, d in zip(s.views, dets, strict=True) if d is not None]
        missed = [v.kind for v, d in zip(s.views, dets, strict=True) if d is None]
        for cond in ("clean", "with bad views"):
            use = [(v, d) for v, d in found if cond != "clean" or v.kind == "good"]
            A = [v.T_base_flange for v, _ in use]
            ds = [d for _, d in use]
            names = [v.name for v, _ in use]
            kinds = {v.name: v.kind for v, _ in use}
            res = {"seed": seed, "condition": cond, "views": len(use),
                   "bad_views_in": sorted(k for k in kinds.values() if k != "good"),
                   "missed_detection": missed, "render_s_per_image": round(t_render, 3),
                   "detect_s_per_image": round(t_detect, 3)}
            closed, fx_cv = plain_opencv(A, ds, (cam.width, cam.height))
            for m, X in closed.items():
                d_mm, d_deg = pose_error(X, s.T_flange_cam)
                res[f"opencv-{m}"] = [d_mm, d_deg, 100 * (fx_cv / cam.fx - 1)]
            intr = solve_intrinsics([d.image_points for d in ds], [d.object_points for d in ds],
                                    (cam.width, cam.height), names=names)
            t0 = time.perf_counter()
            he = solve_hand_eye(A, [Observation(d.image_points, d.object_points) for d in ds],
                                intr.camera, names=names, refine_intrinsics=True)
            res["solve_s"] = round(time.perf_counter() - t0, 2)
            d_mm, d_deg = pose_error(he.T_flange_cam, s.T_flange_cam)
            assert he.camera is not None
            res["ours"] = [d_mm, d_deg, 100 * (he.camera.fx / cam.fx - 1)]
            res["ours_rejected"] = [(r["view"], kinds[r["view"]]) for r in he.rejected_views]
            res["ours_residual_px"] = he.residual_px
            rep = he.report()
            for k in ("std", "std_model", "std_jackknife"):
                res[f"ours_{k}_mm_cam_xyz"] = rep[f"hand_eye_{k}_mm_cam_xyz"]
            res["ours_noise"], res["ours_leave_one_out"] = rep["noise"], rep["leave_one_out"]
            res["ours_error_mm_cam_xyz"] = (invert(s.T_flange_cam)[:3, :3] @ (
                he.T_flange_cam[:3, 3] - s.T_flange_cam[:3, 3])).round(4).tolist()
            res["ours_consistency"] = [he.consistency_mm, he.consistency_deg]
            rows.append(res)
            print(json.dumps(res), file=sys.stderr)
    return rows


class _NoisyRobot:
    """An in-process IRB 2400: FK of its joints, read back with 0.05 mm / 0.01 deg noise."""

    def __init__(self, joints, seed):
        from controller.geometry.kinematics import irb2400

        self.robot = irb2400()
        self.j = np.asarray(joints, float)
        self.rng = np.random.default_rng(seed)

    def true_pose(self):
        from controller.geometry.kinematics import flange_pose

        return flange_pose(self.robot, self.j)

    def joints_deg(self):
        return self.j.copy()

    def flange_pose(self):
        from drivers.sim.sim_board import perturb

        return perturb(self.true_pose(), self.rng, 0.05, 0.01)

    def move_joints(self, joints_deg, timeout_s):
        self.j = np.asarray(joints_deg, float)


def run_auto_teach(seeds, n_views, width, fill=None, tilt=None):
    """``--auto n_views`` against a simulated robot and camera, first pose 330 mm above."""
    import io

    import calibration.teach as teach
    import calibration.teach_poses as teach_poses
    from controller.geometry.kinematics import irb2400, solve_ik
    from drivers.sim.sim_board import SimBoardCamera, default_board_pose, default_hand_eye, look_at

    cam = default_camera(width, round(width * 1704 / 2272))
    board = parse_board_spec("chessboard:9x6:20")
    X, Y = default_hand_eye(), default_board_pose(board)
    centre = Y[:3, :3] @ board.object_points().mean(axis=0) + Y[:3, 3]
    T_bc = look_at(centre + np.array([0, 0, 330.0]), centre, 0.0)
    j0 = solve_ik(irb2400(), T_bc @ invert(X))
    saved = teach_poses.AUTO_FILL, teach_poses.AUTO_TILT_DEG
    if fill is not None:
        teach_poses.AUTO_FILL = fill
    if tilt is not None:
        teach_poses.AUTO_TILT_DEG = tuple(tilt)
    rows = []
    try:
        for seed in seeds:
            robot = _NoisyRobot(j0, seed)
            camera = SimBoardCamera(cam, board, robot.true_pose, seed=seed)
            t0 = time.perf_counter()
            calib, report = teach.run_teach(robot, camera, board, auto_n=n_views,
                                            out=io.StringIO(), holdout_every=0, seed=seed)
            d_mm, d_deg = pose_error(calib.T_flange_cam, X)
            he = report["hand_eye"]
            rows.append({"seed": seed, "fill": teach_poses.AUTO_FILL,
                         "tilt_deg": teach_poses.AUTO_TILT_DEG,
                         "error_mm_deg": [d_mm, d_deg],
                         "focal_error_pct": 100 * (calib.camera.fx / cam.fx - 1),
                         "std_mm_cam_xyz": he.get("hand_eye_std_mm_cam_xyz"),
                         "std_deg_cam_xyz": he.get("hand_eye_std_deg_cam_xyz"),
                         "views_used": len(he["views_used"]),
                         "without_board": report["views_without_board"],
                         "s": round(time.perf_counter() - t0, 1)})
            print(json.dumps(rows[-1], default=float), file=sys.stderr)
    finally:
        teach_poses.AUTO_FILL, teach_poses.AUTO_TILT_DEG = saved
    return rows


def sim_table(rows):
    methods = [f"opencv-{m}" for m in CLOSED_FORM_METHODS] + ["ours"]
    lines = ["| method | clean: median / max mm | clean: median / max deg | "
             "bad views: median / max mm | bad views: median / max deg | focal error % "
             "(clean / bad, worst) |", "|---|---|---|---|---|---|"]
    for m in methods:
        cells = []
        fx = []
        for cond in ("clean", "with bad views"):
            e = np.array([r[m] for r in rows if r["condition"] == cond])
            cells.append(f"{np.median(e[:, 0]):.3f} / {e[:, 0].max():.3f}")
            cells.append(f"{np.median(e[:, 1]):.4f} / {e[:, 1].max():.4f}")
            fx.append(f"{np.abs(e[:, 2]).max():.3f}")
        lines.append(f"| {m} | " + " | ".join(cells) + f" | {' / '.join(fx)} |")
    return "\n".join(lines)


# ---------------------------------------------------------------------------------------------
def _load_stream(path):
    """(t s, poses 4x4 mm) from an ETH CSV: t, x y z (m), qx qy qz qw."""
    a = np.loadtxt(path, delimiter=",")
    R = Rotation.from_quat(a[:, 4:8]).as_matrix()  # scalar last, as the file
    return a[:, 0], [make_pose(R[i], a[i, 1:4] * 1000.0) for i in range(len(a))]


def ethz_pairs(n=80):
    """(T_base_hand list, T_cam_target list, offset_s, correlation) from the ETH ASL streams."""
    d = DATA / "ethz-handeye-robot-arm"
    tH, TH = _load_stream(d / "robot_arm_complete_bag_color_and_ir_base_link_sr300_hinge.csv")
    tE, TE = _load_stream(d / "robot_arm_complete_bag_color_and_ir_target_ir.csv")
    # The target stream is T_W_E (upstream naming): invert to get T_cam_target.
    return pair_pose_streams(tH, TH, tE, [invert(T) for T in TE], n)


def run_ethz():
    A, B, off, corr = ethz_pairs()
    train = list(range(0, len(A), 2))
    test = list(range(1, len(A), 2))
    out = {"samples": len(A), "time_offset_s": off, "speed_correlation": corr, "methods": {}}

    def holdout(X, Y):
        e_mm, e_deg = [], []
        for i in test:
            pred = invert(X) @ invert(A[i]) @ Y
            a, b = pose_error(pred, B[i])
            e_mm.append(a)
            e_deg.append(b)
        return float(np.median(e_mm)), float(np.median(e_deg))

    from calibration.handeye import _average_pose

    At, Bt = [A[i] for i in train], [B[i] for i in train]
    for m in CLOSED_FORM_METHODS:
        X = opencv_calibrate_hand_eye(At, Bt, m)
        Y = _average_pose([T @ X @ b for T, b in zip(At, Bt, strict=True)])
        out["methods"][m] = {"translation_mm": X[:3, 3].round(2).tolist(),
                             "holdout_median_mm_deg": holdout(X, Y)}
    r = solve_hand_eye(At, Bt, None, max_rms_px=1e9, reject_min_px=5.0)
    # Stability: the hand-eye from different sample sets (40, 60, 80 of the stillest moments).
    spread = {}
    sols: dict[str, list] = {m: [] for m in [*CLOSED_FORM_METHODS, "ours (pose refinement)"]}
    for n in (40, 60, 80):
        An, Bn, _, _ = ethz_pairs(n)
        for m in CLOSED_FORM_METHODS:
            sols[m].append(opencv_calibrate_hand_eye(An, Bn, m))
        sols["ours (pose refinement)"].append(
            solve_hand_eye(An, Bn, None, max_rms_px=1e9, reject_min_px=5.0).X)
    for m, Xs in sols.items():
        spread[m] = max(pose_error(a, b)[0] for a in Xs for b in Xs)
    out["stability_max_mm_between_sample_sets"] = spread
    out["methods"]["ours (pose refinement)"] = {
        "translation_mm": r.X[:3, 3].round(2).tolist(), "holdout_median_mm_deg": holdout(r.X, r.Y),
        "consistency_mm": r.consistency_mm, "consistency_deg": r.consistency_deg,
        "rejected": [x["view"] for x in r.rejected_views]}
    return out


def run_opencv_chessboard():
    board = parse_board_spec("chessboard:9x6:25")
    files = sorted((DATA / "opencv-chessboard").glob("left*.jpg"))
    dets = [detect_board(cv2.imread(str(p), cv2.IMREAD_GRAYSCALE), board) for p in files]
    ok = [d for d in dets if d is not None]
    r = solve_intrinsics([d.image_points for d in ok], [d.object_points for d in ok], (640, 480),
                         names=[p.name for p, d in zip(files, dets, strict=True) if d is not None])
    rms, K, dist, _, _ = cv2.calibrateCamera([d.object_points.astype(np.float32) for d in ok],
                                             [d.image_points.astype(np.float32) for d in ok],
                                             (640, 480), None, None)
    return {"images": len(files), "detected": len(ok), "ours": r.report(),
            "direct_calibrateCamera": {"rms_px": rms, "fx": K[0, 0], "fy": K[1, 1],
                                       "cx": K[0, 2], "cy": K[1, 2]},
            "max_abs_K_difference": float(np.abs(r.camera.K - K).max()),
            "upstream_reference": {"fx": 535.9157, "cx": 342.2832, "cy": 235.5708,
                                   "rms_px": 0.3926}}


def run_dry_run_check(seed=7, n_views=14, tmp=None):
    """Teach the dry run's own cell, write the file, dry-run with it and with the exact one."""
    import tempfile

    from calibration.calibration_file import save_calibration
    from calibration.teach import calibrate_from_folder
    from controller.cell.dry_run import run_dry_run
    from drivers.sim.sim_board import write_view_folder
    from drivers.sim.sim_cell import default_sim_cell

    cell = default_sim_cell()
    board = parse_board_spec("chessboard:9x6:20")
    tmpdir = Path(tmp or tempfile.mkdtemp(prefix="seamguide-calib-"))
    s = simulate_session(cell.camera, board, n_views=n_views, seed=seed, n_blurred=1,
                         T_flange_cam=cell.T_flange_cam)
    write_view_folder(s, tmpdir / "views", use_joints=False)
    calib, report = calibrate_from_folder(tmpdir / "views", board)
    path = tmpdir / "taught.yaml"
    save_calibration(path, calib)
    d_mm, d_deg = pose_error(calib.T_flange_cam, cell.T_flange_cam)
    out = {"hand_eye_error_mm_deg": [d_mm, d_deg],
           "focal_error_pct": 100 * (calib.camera.fx / cell.camera.fx - 1),
           "rejected": [r["view"] for r in report["hand_eye"]["rejected_views"]],
           "calibration_file": str(path), "dry_runs": {}}
    for name, cal in (("exact", None), ("taught", path)):
        rows = []
        for scene_seed in (1, 2, 3):
            rep = run_dry_run(None, seed=scene_seed, calibration=cal)
            rows.append([rep.seam_rms_mm, rep.seam_max_mm, rep.result.status])
        out["dry_runs"][name] = rows
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--views", type=int, default=20)
    ap.add_argument("--width", type=int, default=2272)
    ap.add_argument("--output", default=str(ROOT / "bench" / "calibration_results.json"))
    ap.add_argument("--skip-sim", action="store_true")
    ap.add_argument("--auto-teach", action="store_true",
                    help="also run the automatic teach (--auto VIEWS) on seeds 1..SEEDS")
    ap.add_argument("--dry-run", action="store_true",
                    help="also teach the dry run's cell and run dry runs with that calibration")
    args = ap.parse_args()
    out = Path(args.output)
    # Sections not run this time (e.g. with --skip-sim) keep their last figures.
    result = json.loads(out.read_text()) if out.is_file() else {}
    if not args.skip_sim:
        rows = run_sim(list(range(1, args.seeds + 1)), args.views, args.width)
        result["simulated"] = rows
        print("## Simulated teach sessions\n")
        print(sim_table(rows))
        print()
        for r in rows:
            if r["condition"] != "clean":
                print(f"seed {r['seed']}: ours rejected {r['ours_rejected']}, missed detection "
                      f"{r['missed_detection']}, residual {r['ours_residual_px']:.2f} px, "
                      f"render {r['render_s_per_image']} s/image, detect "
                      f"{r['detect_s_per_image']} s/image, solve {r['solve_s']} s")
    if (DATA / "ethz-handeye-robot-arm").exists():
        e = run_ethz()
        result["ethz"] = e
        print(f"\n## ETH ASL robot arm + SR300 (real poses)\n\n{e['samples']} samples, time "
              f"offset {e['time_offset_s']:.3f} s (angular-speed correlation "
              f"{e['speed_correlation']:.3f}); fitted on even samples, checked on odd ones.\n")
        print("| method | translation mm | hold-out median mm | hold-out median deg | "
              "spread over 40/60/80 samples, mm |")
        print("|---|---|---|---|---|")
        for m, v in e["methods"].items():
            h = v["holdout_median_mm_deg"]
            sp = e["stability_max_mm_between_sample_sets"][m]
            print(f"| {m} | {v['translation_mm']} | {h[0]:.2f} | {h[1]:.3f} | {sp:.1f} |")
    if (DATA / "opencv-chessboard").exists():
        c = run_opencv_chessboard()
        result["opencv_chessboard"] = c
        o, d = c["ours"], c["direct_calibrateCamera"]
        print(f"\n## OpenCV sample chessboard (left*.jpg)\n\n{c['detected']}/{c['images']} "
              f"detected; ours fx {o['fx']:.2f} fy {o['fy']:.2f} cx {o['cx']:.2f} cy "
              f"{o['cy']:.2f} (std fx {o['std']['fx']:.2f}), RMS {o['rms_px']:.3f} px; direct "
              f"calibrateCamera on the same corners: fx {d['fx']:.2f}, RMS {d['rms_px']:.3f} px "
              f"(max |K difference| {c['max_abs_K_difference']:.2e}); upstream reference fx "
              f"535.92, RMS 0.393 px.")
    if args.auto_teach:
        rows = run_auto_teach(list(range(1, args.seeds + 1)), args.views, args.width)
        result["auto_teach"] = rows
        print(f"\n## Automatic teach (--auto {args.views}, simulated robot and camera)\n")
        print("| seed | error mm | error deg | focal % | one sigma mm (camera x, y, z) | views |")
        print("|---|---|---|---|---|---|")
        for r in rows:
            print(f"| {r['seed']} | {r['error_mm_deg'][0]:.3f} | {r['error_mm_deg'][1]:.4f} | "
                  f"{r['focal_error_pct']:.4f} | {r['std_mm_cam_xyz']} | {r['views_used']} |")
    if args.dry_run:
        dr = run_dry_run_check()
        result["dry_run"] = dr
        print(f"\n## Dry run with a taught calibration\n\nhand-eye error "
              f"{dr['hand_eye_error_mm_deg'][0]:.3f} mm / {dr['hand_eye_error_mm_deg'][1]:.4f} "
              f"deg, focal {dr['focal_error_pct']:.4f} %, rejected {dr['rejected']}\n")
        print("| calibration | scene seed | seam RMS mm | seam max mm | result |")
        print("|---|---|---|---|---|")
        for name, rows in dr["dry_runs"].items():
            for k, r in enumerate(rows, start=1):
                rms = "-" if r[0] is None else f"{r[0]:.3f}"
                mx = "-" if r[1] is None else f"{r[1]:.3f}"
                print(f"| {name} | {k} | {rms} | {mx} | {r[2]} |")
    out.write_text(json.dumps(result, indent=1, default=float) + "\n")


if __name__ == "__main__":
    main()
