"""Soak test of the robot link: many requests over a lossy line, nothing lost, nothing done twice.

The client talks to an in-process mock controller (or, ``--backend rapid``, the RAPID server
module itself run by the RAPID interpreter) on a real pseudo-terminal; the line corrupts a
fraction of the bytes and drops a fraction of the lines in both directions. Every 10th call is a
joint move (two requests, SV + MJ) that is waited for; the rest are reads (joints, pose, status,
identify). At the end the mock's log of executed motions is compared with what the client was told:

* lost: a motion the controller accepted (the client got its handle) that did not run exactly once
* twice: a motion id that ran more than once
* unreported: a motion that ran although the client raised before it knew it was accepted, and
  the client never learnt of it (checked against the motion ids of calls that raised)
* failures: every exception the API raised (each one is a reported failure)

    .venv/bin/python bench/soak_link.py                     # 10,000 requests, 2 % bytes, 1 % lines
    .venv/bin/python bench/soak_link.py --requests 2000 --corrupt 0.05
    .venv/bin/python bench/soak_link.py --weld-cycle        # link time of one weld cycle
    .venv/bin/python bench/soak_link.py --backend rapid     # against SGSERVER.mod itself

Prints one JSON object. The link figures (bytes, retransmissions) come from the client and mock.
"""

from __future__ import annotations

import argparse
import collections
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from controller.errors import SeamguideError  # noqa: E402
from drivers.robot import open_robot  # noqa: E402

TARGETS = ([10.0, 20.0, 10.0, 0.0, 30.0, 0.0], [-10.0, 5.0, 0.0, 20.0, 40.0, 10.0])


def run_soak(requests: int = 10_000, corrupt: float = 0.02, drop: float = 0.01,
             dup: float = 0.0, seed: int = 7, motion_every: int = 10,
             ack_timeout_s: float = 0.05, retries: int = 40,
             status_poll_s: float = 0.1, disconnect: float = 0.0,
             backend: str = "mock") -> dict[str, Any]:
    """``backend``: ``mock`` (the Python mock controller) or ``rapid`` (SGSERVER.mod itself in
    the RAPID interpreter), on the same fault-injected line."""
    url = (f"{backend}://?seed={seed}&corrupt={corrupt}&drop={drop}&dup={dup}"
           f"&disconnect={disconnect}")
    failures: collections.Counter[str] = collections.Counter()
    accepted: list[int] = []
    outcome_unknown: list[int] = []
    wrong_position = 0
    calls = 0
    t0 = time.perf_counter()
    with open_robot(url, timeout_s=60.0, ack_timeout_s=ack_timeout_s, retries=retries,
                    status_poll_s=status_poll_s) as robot:
        mock = robot.mock
        while robot.link.stats["requests"] < requests:
            calls += 1
            if calls % motion_every == 0:
                target = TARGETS[(calls // motion_every) % 2]
                mid_before = robot._mid
                try:
                    h = robot.move_joints(target, speed_mm_s=200.0)
                except SeamguideError as err:
                    failures[type(err).__name__] += 1
                    if robot._mid != mid_before:
                        outcome_unknown.append(robot._mid)
                    continue
                accepted.append(h.mid)
                try:
                    h.wait(30.0)
                except SeamguideError as err:
                    failures[type(err).__name__] += 1
                    continue
                if not np.allclose(mock.joints_deg, target, atol=1e-3):
                    wrong_position += 1
                continue
            op = calls % 4
            try:
                if op == 0:
                    robot.read_joints()
                elif op == 1:
                    robot.status()
                elif op == 2:
                    robot.identify()
                else:
                    robot.read_pose()
            except SeamguideError as err:
                failures[type(err).__name__] += 1
        stats = dict(robot.link.stats)
        mstats = dict(mock.link_stats)
        runs = collections.Counter(e["mid"] for e in mock.executed)
        results = collections.Counter(e["result"] for e in mock.executed)
    elapsed = time.perf_counter() - t0
    lost = [m for m in accepted if runs[m] != 1]
    twice = [m for m, c in runs.items() if c > 1]
    unreported = [m for m in runs if m not in accepted and m not in outcome_unknown]
    return {
        "url": url, "requests": stats["requests"], "api_calls": calls,
        "motions_accepted": len(accepted), "motions_outcome_unknown": len(outcome_unknown),
        "motions_executed": sum(runs.values()), "motion_results": dict(results),
        "lost": len(lost), "executed_twice": len(twice), "unreported": len(unreported),
        "wrong_position": wrong_position,
        "failures_reported": sum(failures.values()), "failures_by_type": dict(failures),
        "retransmissions": stats["retransmissions"], "bad_lines_client": stats["bad_lines"],
        "bad_lines_controller": mstats["bad_lines"],
        "duplicates_suppressed": mstats["duplicates_suppressed"],
        "reconnects": stats["reconnects"],
        "bytes_client_to_controller": stats["bytes_out"],
        "bytes_controller_to_client": mstats["bytes_tx"],
        "elapsed_s": round(elapsed, 2),
    }


def run_weld_cycle(baud: int = 0, points: int = 100, vary_orientation: bool = False
                   ) -> dict[str, Any]:
    """One weld cycle's link traffic: two views, tool, a ``points``-point path, the weld.

    Views: ``move_joints`` + wait + ``read_joints`` + ``read_pose`` each; then ``set_tool``, a
    ``move_linear`` approach, ``upload_path`` and ``run_weld`` (one progress event per point), and
    a final ``status``. Motion is instantaneous (time_scale=0); with ``baud`` > 0 every byte takes
    its wire time for real, so the elapsed time is the link time as the client sees it. With
    ``vary_orientation`` the torch tilts a little at every point, so no orientation repeats (the
    worst case; a constant torch orientation goes as ``XR``).
    """
    from controller.geometry.kinematics import flange_pose, irb2400
    from controller.geometry.poses import make_pose, rotation_about

    tool = make_pose(t_mm=[0.0, 0.0, 300.0])
    start = flange_pose(irb2400(), [0.0, 10.0, 0.0, 0.0, 60.0, 0.0]) @ tool
    path = [start @ make_pose(t_mm=[0.0, 2.0 * i - 100.0, 0.0]) for i in range(points)]
    if vary_orientation:
        path = [T @ make_pose(rotation_about([1.0, 0.0, 0.0], np.radians(0.1 * i)))
                for i, T in enumerate(path)]
    views = ([20.0, 5.0, 5.0, 0.0, 60.0, 0.0], [-20.0, 5.0, 5.0, 0.0, 60.0, 0.0])
    t0 = time.perf_counter()
    with open_robot(f"mock://?baud={baud}", timeout_s=60.0) as robot:
        mock = robot.mock
        t_open = time.perf_counter()
        for v in views:
            robot.move_joints(v, speed_mm_s=200.0).wait(60.0)
            robot.read_joints()
            robot.read_pose()
        robot.set_tool(tool)
        robot.move_linear(path[0], speed_mm_s=100.0).wait(60.0)
        t_up = time.perf_counter()
        robot.upload_path(path)
        t_weld = time.perf_counter()
        h = robot.run_weld(10.0)
        h.wait(120.0)
        robot.status()
        t_end = time.perf_counter()
        st = dict(mock.link_stats)
        retrans = robot.link.stats["retransmissions"]
    total = st["bytes_rx"] + st["bytes_tx"]
    return {
        "baud": baud, "path_points": points, "orientation_varies": vary_orientation,
        "requests": st["requests"],
        "lines_to_controller": st["lines_rx"], "lines_from_controller": st["lines_tx"],
        "bytes_to_controller": st["bytes_rx"], "bytes_from_controller": st["bytes_tx"],
        "computed_wire_s_9600": round(10.0 * total / 9600, 2),
        "computed_wire_s_19200": round(10.0 * total / 19200, 2),
        "measured_cycle_s": round(t_end - t_open, 2),
        "measured_upload_s": round(t_weld - t_up, 2),
        "measured_open_s": round(t_open - t0, 2),
        "retransmissions": retrans,
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--requests", type=int, default=10_000)
    ap.add_argument("--corrupt", type=float, default=0.02)
    ap.add_argument("--drop", type=float, default=0.01)
    ap.add_argument("--dup", type=float, default=0.0)
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--retries", type=int, default=40)
    ap.add_argument("--disconnect", type=float, default=0.0,
                    help="probability of a link drop after each received line")
    ap.add_argument("--backend", choices=("mock", "rapid"), default="mock",
                    help="the controller: the Python mock, or SGSERVER.mod in the RAPID "
                    "interpreter (rapid://)")
    ap.add_argument("--weld-cycle", action="store_true",
                    help="instead of the soak: the link time of one weld cycle (2 views, "
                    "100-point path) computed from the bytes and measured at 9600 and 19200 baud")
    args = ap.parse_args()
    if args.weld_cycle:
        out = [run_weld_cycle(b, vary_orientation=v) for v in (False, True)
               for b in (9600, 19200)]
        print(json.dumps(out, indent=2))
        return 0
    result = run_soak(args.requests, args.corrupt, args.drop, args.dup, args.seed,
                      retries=args.retries, disconnect=args.disconnect, backend=args.backend)
    print(json.dumps(result, indent=2))
    ok = result["lost"] == result["executed_twice"] == result["unreported"] == 0
    return 0 if ok and result["wrong_position"] == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
