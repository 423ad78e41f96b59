"""Link time and planning time of the benchmark weld cycle, and the path the arm executed.

The benchmark cycle is the dry run's default: scene ``s_curve`` seed 1 ``medium`` (a 180 mm
S-curve seam), two views, the exact calibration, the job's default path tolerance. It runs as the
cell runs it (``SimRig``: the real client over a pseudo-terminal) against the controller
(``--backend mock``: the Python mock; ``rapid``: SGSERVER.mod in the RAPID interpreter) at
``--baud`` with motion almost instantaneous, so the time spent inside the robot's calls is the
link time as the client sees it. Printed (one JSON object), all measured in the same run:

* ``cycle``: requests, bytes to / from the controller and the wire time they take at the baud
  rate (computed: bytes x 10 bits / baud), and the time measured inside the robot calls of the
  cycle (``--repeat N``: N cycles on fresh controllers, each measured, and their median); the
  session's opening (``HI`` + ``ID``, once per connection, before the cycle) apart;
* ``replay_*``: the cycle's robot calls again on a fresh controller of the same backend, with the
  path sent the old way (every dense point, ``XT`` / ``XP`` + ``XR``) and as the fitted segments,
  at the baud rate and on an infinitely fast line (``no_wire``: the client's and the
  controller's own processing);
* ``executed``: the weld the arm executed with the arc on (its own motion model, traced every
  0.05 mm; on both backends) against the dense planned path, both ways: the largest distance
  (mm), torch axis angle and spin about the torch axis (deg), and the whole orientation angle;
* ``planning``: ``plan_weld`` (inverse kinematics of every target with its reach checks) on the
  cycle's seam, by continuity (now) and with the full solution set at every target (before), each
  the median of 5 runs, as milliseconds and as a ratio to one forward kinematics call measured in
  the same run; and the segment fit's time.

    .venv/bin/python bench/bench_link_time.py                 # 9600 baud, the mock
    .venv/bin/python bench/bench_link_time.py --backend rapid --repeat 5  # SGSERVER.mod
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from controller.cell.dry_run import SimRig  # noqa: E402
from controller.geometry.kinematics import flange_pose, inverse_kinematics, irb2400  # noqa: E402
from controller.geometry.poses import invert  # noqa: E402
from controller.path.path_fit import axis_spin_deg, fit_segments  # noqa: E402
from controller.path.weld_path import WeldPath, plan_weld  # noqa: E402
from drivers.robot import open_robot  # noqa: E402

ROBOT_CALLS = ("read_joints", "read_pose", "set_tool", "move_joints", "move_linear",
               "upload_path", "run_weld", "status", "identify", "abort", "_wait_motion")


def timed_robot(robot: Any) -> dict[str, float]:
    """Wrap the robot's calls (on the instance) to add their wall time to the returned dict."""
    acc = {"s": 0.0}
    for name in ROBOT_CALLS:
        fn = getattr(robot, name)

        def wrapper(*a: Any, _fn: Any = fn, **k: Any) -> Any:
            t0 = time.perf_counter()
            try:
                return _fn(*a, **k)
            finally:
                acc["s"] += time.perf_counter() - t0

        setattr(robot, name, wrapper)
    return acc


def to_polyline(points: np.ndarray, poly: np.ndarray) -> tuple[np.ndarray, ...]:
    """Distance of each point (M, 3) to a polyline (N, 3), its nearest chord and the fraction."""
    a, ab = poly[:-1], poly[1:] - poly[:-1]
    L2 = np.einsum("kj,kj->k", ab, ab)
    out_d, out_k, out_t = [], [], []
    for chunk in np.array_split(points, max(1, len(points) // 2000)):
        t = np.clip(np.einsum("mkj,kj->mk", chunk[:, None] - a[None], ab)
                    / np.where(L2 > 0, L2, 1.0), 0, 1)
        d = np.linalg.norm(a[None] + t[..., None] * ab[None] - chunk[:, None], axis=2)
        k = d.argmin(axis=1)
        out_d.append(d.min(axis=1))
        out_k.append(k)
        out_t.append(t[np.arange(len(chunk)), k])
    return np.concatenate(out_d), np.concatenate(out_k), np.concatenate(out_t)


def executed_vs_planned(executed: np.ndarray, dense: np.ndarray) -> dict[str, float]:
    """Largest deviation of the executed TCP poses from the dense planned poses, both ways."""
    d, k, t = to_polyline(executed[:, :3, 3], dense[:, :3, 3])
    R = Rotation.from_matrix(dense[:, :3, :3])
    rel = (R[:-1].inv() * R[1:]).as_rotvec()
    planned = (R[k] * Rotation.from_rotvec(t[:, None] * rel[k])).as_matrix()
    ax, sp = axis_spin_deg(executed[:, :3, :3], planned)
    whole = (Rotation.from_matrix(executed[:, :3, :3]).inv() * Rotation.from_matrix(planned))
    back = to_polyline(dense[:, :3, 3], executed[:, :3, 3])[0]
    return {"max_mm": round(float(max(d.max(), back.max())), 4),
            "max_torch_axis_deg": round(float(ax.max()), 4),
            "max_spin_deg": round(float(sp.max()), 4),
            "max_whole_orientation_deg": round(float(np.degrees(whole.magnitude()).max()), 4)}


def replay(path: WeldPath, views: list[np.ndarray], backend: str, baud: int, dense: bool
           ) -> dict[str, Any]:
    """The cycle's robot calls again on a fresh controller: the path dense (before) or fitted.

    The calls the cycle makes (``WeldCycle._weld``): the two views (move, joints, pose), the
    tool, the approach, the dry line to the weld's start, the upload, the weld, the dry depart.
    """
    with open_robot(f"{backend}://?baud={baud}", timeout_s=60.0) as robot:
        opening = dict(robot.mock.link_stats)  # HI + ID: not the cycle's
        acc = timed_robot(robot)
        for v in views:
            robot.move_joints(v, speed_mm_s=200.0).wait(60.0)
            robot.read_joints()
            robot.read_pose()
        robot.set_tool(path.params.T_flange_tcp)
        robot.move_joints(path.targets[0].joints_deg, speed_mm_s=200.0).wait(60.0)
        speed = path.params.speed_mm_s
        robot.move_linear(path.start, speed_mm_s=speed).wait(60.0)
        if dense:
            sent = [t.T_base_tcp for t in path.weld_targets[1:]]
            robot.upload_path(sent)
        else:
            sent, circles = path.upload()
            robot.upload_path(sent, circles, start=path.start)
        robot.run_weld(speed).wait(120.0)
        robot.move_linear(path.targets[-1].T_base_tcp, speed_mm_s=speed).wait(60.0)
        st = {k: robot.mock.link_stats[k] - opening[k] for k in ("bytes_rx", "bytes_tx",
                                                                 "lines_rx")}
    total = st["bytes_rx"] + st["bytes_tx"]
    baud = baud or 1_000_000_000  # no wire time
    return {"path_points_sent": len(sent), "requests": int(st["lines_rx"]),
            "bytes_to_controller": int(st["bytes_rx"]),
            "bytes_from_controller": int(st["bytes_tx"]),
            "computed_s": round(10.0 * total / baud, 2), "measured_s": round(acc["s"], 2)}


def planning_figures(seam_mm: np.ndarray, normal: np.ndarray, params: Any, workspace: Any,
                     start: np.ndarray, reps: int = 5) -> dict[str, Any]:
    """plan_weld by continuity against the full solution set per target, as ratios to one FK."""
    robot = irb2400()

    def full_set() -> None:
        path = plan_weld(robot, seam_mm, normal, params, workspace, start_joints_deg=start)
        T_tcp_flange = invert(params.T_flange_tcp)
        for t in path.targets:  # what every target cost before: the whole solution set
            inverse_kinematics(robot, t.T_base_tcp @ T_tcp_flange)

    def fk() -> None:
        for _ in range(100):
            flange_pose(robot, start)

    def median(fn: Any) -> float:
        times = []
        for _ in range(reps):
            t0 = time.perf_counter()
            fn()
            times.append(time.perf_counter() - t0)
        return statistics.median(times)

    plan_weld(robot, seam_mm, normal, params, workspace, start_joints_deg=start)  # warm up
    t_fk = median(fk) / 100.0
    t_new = median(lambda: plan_weld(robot, seam_mm, normal, params, workspace,
                                     start_joints_deg=start))
    t_full = median(full_set) - t_new  # the full sets alone, the planner's own work taken off
    path = plan_weld(robot, seam_mm, normal, params, workspace, start_joints_deg=start)
    weld = [t.T_base_tcp for t in path.weld_targets]
    t_fit = median(lambda: fit_segments(weld))
    t_fk2 = median(fk) / 100.0
    fk_s = 0.5 * (t_fk + t_fk2)
    return {"targets": len(path.targets), "fk_ms": round(1e3 * fk_s, 3),
            "continuity_ms": round(1e3 * t_new, 1), "continuity_fk_calls": round(t_new / fk_s),
            "full_set_ms": round(1e3 * t_full, 1), "full_set_fk_calls": round(t_full / fk_s),
            "fit_ms": round(1e3 * t_fit, 1), "fit_fk_calls": round(t_fit / fk_s)}


def run_cycle(args: argparse.Namespace, measured: list[float] | None) -> dict[str, Any]:
    """The benchmark cycle once on a fresh controller: its link figures and the executed path.

    ``measured``: the link times of earlier runs; with it the result has their spread and the
    objects the rest of the benchmark needs (``_path``, ``_views``, ``_job``, ``_seam``).
    """
    rig = SimRig(scene_kind="s_curve", seed=1, difficulty="medium", speedup=1e6,
                 robot_options=f"baud={args.baud}")
    if args.backend == "rapid":
        rig.robot_url = rig.robot_url.replace("mock://", "rapid://")
    with rig:
        opening = dict(rig.mock.link_stats)  # the session's HI + ID, once per connection
        acc = timed_robot(rig.robot)
        result = rig.cycle(None).run()
        if not result.ok:
            return {"status": result.status, "reason": result.reason}
        st = {k: rig.mock.link_stats[k] - opening[k] for k in ("bytes_rx", "bytes_tx",
                                                               "lines_rx", "lines_tx")}
        path = result.path
        assert path is not None and result.seam is not None
        out: dict[str, Any] = {"backend": args.backend, "baud": args.baud,
                               "dense_weld_points": len(path.weld_targets),
                               "segments": len(path.segments),
                               "movec": sum(s.via_mm is not None for s in path.segments)}
        opened = opening["bytes_rx"] + opening["bytes_tx"]
        out["session_opening"] = {"requests": int(opening["lines_rx"]), "bytes": int(opened),
                                  "computed_s": round(10.0 * opened / args.baud, 2)}
        total = st["bytes_rx"] + st["bytes_tx"]
        out["cycle"] = {"requests": int(st["lines_rx"]),
                        "lines_from_controller": int(st["lines_tx"]),
                        "bytes_to_controller": int(st["bytes_rx"]),
                        "bytes_from_controller": int(st["bytes_tx"]),
                        "computed_s": round(10.0 * total / args.baud, 2),
                        "measured_in_robot_calls_s": round(acc["s"], 2)}
        if measured is None:
            return out
        if measured:
            runs = sorted([*measured, out["cycle"]["measured_in_robot_calls_s"]])
            out["cycle"]["measured_runs_s"] = runs
            out["cycle"]["measured_median_s"] = round(statistics.median(runs), 2)
        if args.backend == "mock":  # the pass: one motion of the mock's arm
            weld = [e for e in rig.mock.executed if e["kind"] == "weld"]
            segs = weld[-1]["tcp_segments"]
        else:  # the interpreter's arm runs each move instruction as its own segment
            segs = [g for e in rig.mock.arm.segments_run if e["arc"] for g in e["tcp_segments"]]
        trace = rig.mock.arm.trace({"tcp_segments": segs}, step_mm=0.05)
        dense = np.array([t.T_base_tcp for t in path.weld_targets])
        out["executed"] = {"segments_run_arc_on": len(segs),
                           **executed_vs_planned(trace, dense)}
        out.update(_path=path, _views=[np.asarray(v.joints_deg) for v in rig.job.views],
                   _job=rig.job, _seam=result.seam.points_mm)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--baud", type=int, default=9600)
    ap.add_argument("--backend", choices=("mock", "rapid"), default="mock")
    ap.add_argument("--no-replay", action="store_true",
                    help="skip the replays (the cycle and planning only)")
    ap.add_argument("--repeat", type=int, default=1,
                    help="run the whole cycle this many times (fresh controller each), for the "
                    "spread of the measured link time")
    args = ap.parse_args()
    measured: list[float] = []
    for i in range(args.repeat):
        out = run_cycle(args, measured if i == args.repeat - 1 else None)
        if out.get("status"):
            print(json.dumps(out))
            return 1
        measured.append(out["cycle"]["measured_in_robot_calls_s"])
    measured.pop()  # the last run's own figure is in out
    path, views, job, seam = out.pop("_path"), out.pop("_views"), out.pop("_job"), out.pop("_seam")
    if not args.no_replay:
        b = args.backend
        out["replay_dense"] = replay(path, views, b, args.baud, dense=True)
        out["replay_segments"] = replay(path, views, b, args.baud, dense=False)
        # the same calls on an infinitely fast line: the client's and the controller's own time
        out["replay_segments_no_wire"] = replay(path, views, b, 0, dense=False)
        out["replay_dense_no_wire"] = replay(path, views, b, 0, dense=True)
    normal = np.asarray(job.seam.normal, dtype=np.float64)
    start = views[-1]  # where the cycle plans from: the robot at the last view
    out["planning"] = planning_figures(seam, normal, job.weld_params(), job.workspace(), start)
    print(json.dumps(out, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
