"""Fixed pair calibration on simulated sessions: each camera's pose, and the cross-check's catch.

    .venv/bin/python bench/bench_fixed_pair.py [--seeds 1 2 3] [--views 20] [--scale 1.0]

The fixed-stereo cell's two cameras (drivers/sim/sim_fixed_cell.py: 2272x1704 44 deg and
2048x1536 37 deg with stronger distortion, on stands for the s_curve scene) see a 9x6 chessboard
of 20 mm squares held by the robot (drivers/sim/sim_fixed_pair.py), robot pose noise 0.05 mm /
0.01 deg per axis, sensor noise 1.5 grey levels. Per seed: a session of ``--views`` robot poses,
each camera calibrated eye-to-hand on its own (calibration/fixed_pair.py), errors against the
simulator's truth; then check sessions of 2 new robot poses: the cameras where they were
calibrated, and each camera knocked by 1 mm (random direction) or 0.2 deg (random axis through
the camera). Writes bench/out/fixed_pair.json and prints a Markdown table.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from calibration.fixed_pair import (  # noqa: E402
    calibrate_fixed_cameras,
    cross_check,
    shared_views_from_sessions,
)
from calibration.targets import detect_board, parse_board_spec  # noqa: E402
from controller.errors import CalibrationError  # noqa: E402
from controller.geometry.poses import make_pose, pose_error, rotation_about  # noqa: E402
from drivers.sim.sim_fixed_cell import fixed_stereo_cell  # noqa: E402
from drivers.sim.sim_fixed_pair import simulate_pair_session  # noqa: E402
from drivers.sim.sim_scene import make_scene  # noqa: E402

BOARD = parse_board_spec("chessboard:9x6:20")
OUT = ROOT / "bench" / "out"


def shared(sess):
    dets = {k: [detect_board(im, BOARD) for im in ims] for k, ims in sess.images.items()}
    return shared_views_from_sessions(sess.names, sess.T_base_flange, dets)


def run_seed(seed: int, n_views: int, scale: float) -> dict:
    cell = fixed_stereo_cell(make_scene("s_curve", 1, "medium"))
    cams = {k: (c.scaled(scale) if scale != 1.0 else c) for k, c in cell.cameras.items()}
    t0 = time.time()
    sess = simulate_pair_session(cams, cell.T_base_cam, BOARD, n_views=n_views, seed=seed)
    t_render = time.time() - t0
    views = shared(sess)
    t0 = time.time()
    calibs, report = calibrate_fixed_cameras(
        views, BOARD, {k: (c.width, c.height) for k, c in cams.items()})
    t_solve = time.time() - t0
    out: dict = {"seed": seed, "render_s": round(t_render, 1), "solve_s": round(t_solve, 1),
                 "cameras": {}, "calibration_cross_check": report["cross_check"]["worst"]}
    for k, c in calibs.items():
        d_mm, d_deg = pose_error(c.T_base_cam, cell.T_base_cam[k])
        out["cameras"][k] = {"mm": d_mm, "deg": d_deg,
                             "focal_pct": 100 * abs(c.camera.fx / cams[k].fx - 1)}
    rng = np.random.default_rng(seed + 100)
    checks = {"none": None}
    for k in cams:
        d = rng.normal(size=3)
        checks[f"{k} 1 mm"] = (k, make_pose(t_mm=1.0 * d / np.linalg.norm(d)))
        checks[f"{k} 0.2 deg"] = (k, make_pose(rotation_about(list(rng.normal(size=3)),
                                                              np.radians(0.2))))
    out["checks"] = {}
    for i, (name, knock) in enumerate(checks.items()):
        poses = dict(cell.T_base_cam)
        if knock is not None:
            poses[knock[0]] = poses[knock[0]] @ knock[1]
        v = shared(simulate_pair_session(cams, poses, BOARD, n_views=2, seed=1000 * seed + i))
        try:
            r = cross_check(calibs, v, BOARD)
            out["checks"][name] = {"caught": False, "named": None,
                                   "worst": r["worst"]["left-right"]}
        except CalibrationError as err:
            out["checks"][name] = {"caught": True, "named": err.details.get("camera"),
                                   "worst": err.details["cross_check"]["worst"]["left-right"]}
        print(f"seed {seed} check {name}: {out['checks'][name]}", file=sys.stderr)
    return out


def _knocked(ch: dict, kind: str) -> str:
    out = []
    for k in ("left", "right"):
        c = ch[f"{k} {kind}"]
        out.append(f"{k}: {'yes' if c['caught'] else 'NO'} ({c['worst']['mm']:.2f} mm / "
                   f"{c['worst']['deg']:.3f} deg, named {c['named']})")
    return ", ".join(out)


def markdown(rows: list[dict]) -> str:
    lines = ["| seed | left: mm / deg | right: mm / deg | focal error % (left / right) | "
             "cross-check, cameras in place: mm / deg | knocked 1 mm: caught, named | "
             "knocked 0.2 deg: caught, named |", "|---|---|---|---|---|---|---|"]
    for r in rows:
        c, ch = r["cameras"], r["checks"]
        lines.append(
            f"| {r['seed']} | {c['left']['mm']:.3f} / {c['left']['deg']:.4f} | "
            f"{c['right']['mm']:.3f} / {c['right']['deg']:.4f} | {c['left']['focal_pct']:.4f} / "
            f"{c['right']['focal_pct']:.4f} | {ch['none']['worst']['mm']:.3f} / "
            f"{ch['none']['worst']['deg']:.4f} ({'caught!' if ch['none']['caught'] else 'passed'})"
            f" | {_knocked(ch, '1 mm')} | {_knocked(ch, '0.2 deg')} |")
    return "\n".join(lines) + "\n"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--views", type=int, default=20)
    ap.add_argument("--scale", type=float, default=1.0)
    args = ap.parse_args()
    rows = []
    for seed in args.seeds:
        rows.append(run_seed(seed, args.views, args.scale))
        print(json.dumps(rows[-1], default=float), file=sys.stderr)
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "fixed_pair.json").write_text(json.dumps(rows, indent=1, default=float))
    print(markdown(rows))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
