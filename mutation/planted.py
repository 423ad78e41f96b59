"""Plant the 21 bugs of issue 19 one at a time in a scratch copy and check that a test fails.

Each bug is one textual change to one safety path (a quality gate switched off, a refusal
removed, a limit moved, a make-safe step skipped). The copy of the working tree is made once
(``git ls-files``), each bug is applied to it, the tests named for that bug are run against the
copy (``PYTHONPATH`` puts it before the editable install), and the file is restored. A bug that
no test catches is a failure of this script (exit 1).

    .venv/bin/python mutation/planted.py [--only N,M] [--out mutation/planted.md]
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


@dataclass(frozen=True)
class Bug:
    """One planted bug: ``old`` (found exactly once in ``path``) becomes ``new``."""

    what: str
    path: str
    old: str
    new: str
    tests: tuple[str, ...]


E2E = "tests/test_cycle_e2e.py"
BUGS: list[Bug] = [
    Bug("cycle: a fault no longer aborts the robot (arc off, stop)", "controller/cell/cycle.py",
        "        try:\n            self.robot.abort()\n        except SeamguideError as err:\n"
        "            log.error(\"could not make the robot safe",
        "        try:\n            pass\n        except SeamguideError as err:\n"
        "            log.error(\"could not make the robot safe",
        ("tests/test_cycle_machine.py", f"{E2E}::test_a_fault_of_the_pc_while_the_arc_is_on_"
                                        "aborts_then_moves_to_the_safe_pose")),
    Bug("cycle: a fault no longer moves the robot to the safe pose", "controller/cell/cycle.py",
        "if move_to_safe_pose and self.safe_joints_deg is not None:", "if False:",
        ("tests/test_cycle_machine.py", f"{E2E}::test_camera_failure")),
    Bug("cycle: an operator abort no longer reaches the robot", "controller/cell/cycle.py",
        "        self._abort.set()\n        try:\n            self.robot.abort()",
        "        self._abort.set()\n        try:\n            pass",
        (f"{E2E}::test_operator_abort_during_the_weld",)),
    Bug("locate: ray angle gate off", "controller/stereo/locate.py",
        'if q["angle_deg_min"] < lim.min_angle_deg:', "if False:", ("tests/test_locate.py",)),
    Bug("locate: ray gap gate off", "controller/stereo/locate.py",
        'if q["ray_gap_mm_max"] > lim.max_ray_gap_mm:', "if False:", ("tests/test_locate.py",)),
    Bug("locate: ends cut by the image border gate off", "controller/stereo/locate.py",
        "if lim.require_ends_in_view and unseen:", "if False:",
        ("tests/test_locate.py",)),
    Bug("locate: coverage gate off", "controller/stereo/locate.py",
        'if q["coverage"] < lim.min_coverage:', "if False:", ("tests/test_locate.py",)),
    Bug("locate: end-point gap gate off", "controller/stereo/locate.py",
        'if q["endpoint_gap_mm"] and max(q["endpoint_gap_mm"]) > lim.max_endpoint_gap_mm:',
        "if False:", ("tests/test_locate.py",)),
    Bug("locate: nominal region check off", "controller/stereo/locate.py",
        'if q.get("distance_from_nominal_mm_max", 0.0) > q.get("nominal_radius_mm", np.inf):',
        "if False:", ("tests/test_locate.py",)),
    Bug("detector: ambiguity threshold 0.6 -> 0.95", "controller/vision/seam_params.py",
        "ambiguity_ratio: float = 0.6", "ambiguity_ratio: float = 0.95",
        ("tests/test_seam_detect.py::test_ambiguity_threshold_at_its_edge",)),
    Bug("hand-eye: 'too many bad views' refusal removed", "calibration/handeye.py",
        "        if len(used) < min_views or len(rejected) > max_rejected_fraction * n:\n"
        "            listed",
        "        if len(used) < min_views:\n            listed",
        ("tests/test_handeye.py::test_too_many_bad_views_refuse_the_calibration_and_name_them",)),
    Bug("calibration file: camera-matrix bottom row not checked", "calibration/calibration_file.py",
        "if not np.allclose(K[2], [0, 0, 1]) or K[1, 0] != 0:", "if K[1, 0] != 0:",
        ("tests/test_calibration_file.py",)),
    Bug("calibration file: non-finite hand-eye translation accepted",
        "calibration/calibration_file.py",
        "if tv.shape != (3,) or not np.all(np.isfinite(tv)):", "if tv.shape != (3,):",
        ("tests/test_calibration_file.py",)),
    Bug("safety box: lower bound not checked", "drivers/robot_commands.py",
        "np.any(p < lo) or ", "", ("tests/test_robot.py",)),
    Bug("safety box: upper bound not checked", "drivers/robot_commands.py",
        " or np.any(p > hi)", "", ("tests/test_robot.py",)),
    Bug("speed limit not checked", "drivers/robot_commands.py",
        "not 0 < speed_mm_s <= self.max_speed_mm_s", "not 0 < speed_mm_s",
        ("tests/test_robot.py",)),
    Bug("joint limits: axis 6 not checked", "controller/geometry/kinematics.py",
        "bad = np.flatnonzero((j < lo - 1e-9) | (j > hi + 1e-9))",
        "bad = np.flatnonzero(((j < lo - 1e-9) | (j > hi + 1e-9))[:5])",
        ("tests/test_kinematics.py", "tests/test_robot.py")),
    Bug("path longer than the controller buffer accepted", "drivers/robot_commands.py",
        "if len(self.targets) > capacity:", "if False:", ("tests/test_abb_link.py",)),
    Bug("run_weld accepted with no path uploaded", "drivers/abb/abb_robot.py",
        "if self._path_len == 0:", "if False:", ("tests/test_robot_contract.py",)),
    Bug("codec: a frame with a wrong checksum accepted", "drivers/abb/abb_codec.py",
        "if chk != checksum(head):", "if False:", ("tests/test_abb_codec.py",)),
    Bug("daemon: a bad configuration reload is not survived", "controller/cell/daemon.py",
        "        except SeamguideError as err:\n            log.error(\"SIGHUP: configuration",
        "        except ZeroDivisionError as err:\n            log.error(\"SIGHUP: configuration",
        ("tests/test_daemon.py::test_sighup_reload_between_cycles",)),
]


def copy_tree(dest: Path) -> None:
    """The working tree's tracked files (as they are now, edits included) into ``dest``."""
    files = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, check=True,
                           capture_output=True).stdout.decode().split("\0")
    for f in filter(None, files):
        src = ROOT / f
        if src.is_file():
            (dest / f).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dest / f)


def run_bug(copy: Path, bug: Bug) -> tuple[bool, str, float]:
    """Plant ``bug`` in ``copy``, run its tests; (caught, failing tests, seconds). Restores."""
    target = copy / bug.path
    text = target.read_text()
    if text.count(bug.old) != 1:
        raise SystemExit(f"{bug.what}: the text to change is in {bug.path} "
                         f"{text.count(bug.old)} times, expected once; update mutation/planted.py")
    target.write_text(text.replace(bug.old, bug.new))
    env = dict(os.environ, PYTHONPATH=str(copy))
    t0 = time.monotonic()
    try:
        r = subprocess.run([sys.executable, "-m", "pytest", "-q", "-x", "-p", "no:cacheprovider",
                            *bug.tests], cwd=copy, env=env, capture_output=True, text=True)
    finally:
        target.write_text(text)
    failed = [ln.split(" ")[1] for ln in r.stdout.splitlines() if ln.startswith("FAILED ")]
    return r.returncode == 1 and bool(failed), ", ".join(failed), time.monotonic() - t0


def main() -> int:
    """Run every bug (or ``--only``); print and write the table; 1 when one is not caught."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", help="comma-separated bug numbers (1-based)")
    ap.add_argument("--out", default=str(ROOT / "mutation" / "planted.md"))
    a = ap.parse_args()
    picks = [int(x) for x in a.only.split(",")] if a.only else range(1, len(BUGS) + 1)
    rows, missed = [], 0
    with tempfile.TemporaryDirectory(prefix="seamguide-planted-") as tmp:
        copy = Path(tmp)
        copy_tree(copy)
        for i in picks:
            bug = BUGS[i - 1]
            caught, failed, secs = run_bug(copy, bug)
            missed += not caught
            row = (f"| {i} | {bug.what} | `{bug.path}` | "
                   f"{failed if caught else '**not caught**'} |")
            print(row, f"({secs:.0f} s)", flush=True)
            rows.append(row)
    table = ("| # | planted bug | file | first failing test |\n|---|---|---|---|\n"
             + "\n".join(rows) + "\n")
    if not a.only:
        Path(a.out).write_text(table)
    return 1 if missed else 0


if __name__ == "__main__":
    sys.exit(main())
