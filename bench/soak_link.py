"""Soak test of the robot link: many requests over a lossy line, nothing lost, nothing done twice.

The client talks to an in-process mock controller on a real pseudo-terminal; the mock corrupts a
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
             status_poll_s: float = 0.1) -> dict[str, Any]:
    url = f"mock://?seed={seed}&corrupt={corrupt}&drop={drop}&dup={dup}"
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
        "bytes_client_to_controller": stats["bytes_out"],
        "bytes_controller_to_client": mstats["bytes_tx"],
        "elapsed_s": round(elapsed, 2),
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--requests", type=int, default=10_000)
    ap.add_argument("--corrupt", type=float, default=0.02)
    ap.add_argument("--drop", type=float, default=0.01)
    ap.add_argument("--dup", type=float, default=0.0)
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--retries", type=int, default=40)
    args = ap.parse_args()
    result = run_soak(args.requests, args.corrupt, args.drop, args.dup, args.seed,
                      retries=args.retries)
    print(json.dumps(result, indent=2))
    ok = result["lost"] == result["executed_twice"] == result["unreported"] == 0
    return 0 if ok and result["wrong_position"] == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
