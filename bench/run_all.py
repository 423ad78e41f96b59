"""Run every benchmark, one after the other, each as its own process (what ``make bench`` does).

    .venv/bin/python bench/run_all.py              # every benchmark with its own defaults
    .venv/bin/python bench/run_all.py --quick      # a quick subset of each (smoke, minutes)
    .venv/bin/python bench/run_all.py --only kinematics cli_startup
    .venv/bin/python bench/run_all.py --list

Each benchmark prints its own figures (and writes its files under bench/out/, as its docstring
says); this prints a summary at the end: name, exit code, wall time. The exit code is non-zero
when any benchmark failed. Timings are only comparable within one run (the machine is shared).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

#: name -> (command after the interpreter, extra arguments for --quick). Every benchmark of
#: bench/ is here; tests/test_bench_registry.py fails when one is missing.
BENCHMARKS: dict[str, tuple[list[str], list[str]]] = {
    "kinematics": (["bench/bench_kinematics.py"], []),
    "cli_startup": (["bench/bench_cli_startup.py"], ["--quick"]),
    "detect": (["-m", "bench.bench_detect"], ["--quick"]),
    # After "detect": the gap's depth of the views that run wrote (bench/out/detect.json).
    "gap_depth": (["-m", "bench.bench_gap_depth", "--rows", "bench/out/detect.json"], []),
    "detect_scale": (["-m", "bench.bench_detect_scale"], ["--quick"]),
    "detect_noseam": (["-m", "bench.bench_detect_noseam"], ["--views", "6", "--shifts", "200"]),
    "detect_job_gap": (["-m", "bench.bench_detect_job_gap"], ["--cases", "12"]),
    "detect_nominal": (["-m", "bench.bench_detect_nominal"], ["--cases", "12"]),
    "detect_speed": (["-m", "bench.bench_detect_speed"],
                     ["--scenes", "2", "--runs", "2", "--blocks", "2"]),
    "locate": (["bench/bench_locate.py"],
               ["--pairs", "3", "--sensitivity-pairs", "2", "--difficulties", "medium"]),
    "locate_cameras": (["bench/bench_locate_cameras.py"], ["--pairs", "3"]),
    "calibration": (["bench/bench_calibration.py", "--seeds", "6"],
                    ["--seeds", "1", "--views", "12", "--output",
                     "bench/out/calibration_quick.json"]),
    "calibration_noise": (["bench/bench_calibration_noise.py", "--steep", "24",
                           "--noisy-seeds", "3", "--eight-view", "4"],
                          ["--steep", "2", "--noisy-seeds", "1", "--eight-view", "1", "--output",
                           "bench/out/calibration_noise_quick.json"]),
    "fixed_pair": (["bench/bench_fixed_pair.py"], ["--seeds", "1", "--views", "12"]),
    "link_time": (["bench/bench_link_time.py"], []),
    "soak_link": (["bench/soak_link.py"], ["--requests", "300"]),
    "soak_daemon": (["bench/soak_daemon.py"], ["--cycles", "5"]),
}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="a quick subset of each benchmark")
    ap.add_argument("--only", nargs="+", choices=sorted(BENCHMARKS), metavar="NAME",
                    help=f"run only these ({', '.join(BENCHMARKS)})")
    ap.add_argument("--list", action="store_true", help="list the benchmarks and their commands")
    args = ap.parse_args(argv)
    names = args.only or list(BENCHMARKS)
    if args.list:
        for name in names:
            cmd, quick = BENCHMARKS[name]
            print(f"{name:15s} python {' '.join(cmd)}   (--quick: {' '.join(quick) or 'same'})")
        return 0
    results = []
    for name in names:
        cmd, quick = BENCHMARKS[name]
        full = [sys.executable, *cmd, *(quick if args.quick else [])]
        print(f"\n=== {name}: {' '.join(full[1:])}", flush=True)
        t0 = time.monotonic()
        code = subprocess.run(full, cwd=ROOT, check=False).returncode
        results.append((name, code, time.monotonic() - t0))
    print("\n| benchmark | exit code | wall time |\n|---|---|---|")
    for name, code, dt in results:
        print(f"| {name} | {code} | {dt:.0f} s |")
    return 0 if all(code == 0 for _, code, _ in results) else 1


if __name__ == "__main__":
    sys.exit(main())
