"""``make mutation``: cosmic-ray over the functions that carry the safety checks.

Each group mutates a few functions of one module (only the lines of those functions, and never
inside a string: messages are not behaviour) with a compact operator set (comparisons turned
into their boundary and their negation, ``and``/``or``, ``not`` added or removed, numbers,
``+``/``-`` and ``*``/``/`` swapped, loops skipped, exceptions replaced), and runs the tests of
that module for each mutant in a scratch copy of the working tree (``PYTHONPATH`` puts it first).
Survivors are written to ``mutation/survivors.md`` with their diffs.

    .venv/bin/python mutation/run.py [--only GROUP,...] [--jobs N] [--timeout S]

Groups run ``--jobs`` at a time, each in its own copy (a mutant is written into the file). Not
part of ``make test`` or CI: a full run takes most of an hour on the shared 2-core machine.
"""

from __future__ import annotations

import argparse
import ast
import concurrent.futures
import os
import re
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from planted import ROOT, copy_tree

OPERATORS = re.compile(
    r"core/(ReplaceComparisonOperator_(Lt_LtE|Lt_GtE|LtE_Lt|LtE_Gt|Gt_GtE|Gt_LtE|GtE_Gt|GtE_Lt"
    r"|Eq_NotEq|NotEq_Eq|Is_IsNot|IsNot_Is)|ReplaceBinaryOperator_(Add_Sub|Sub_Add|Mul_Div|Div_Mul)"
    r"|ReplaceUnaryOperator_(Delete_Not|USub_UAdd)|AddNot|ReplaceTrueWithFalse"
    r"|ReplaceFalseWithTrue|ReplaceAndWithOr|ReplaceOrWithAnd|NumberReplacer|ExceptionReplacer"
    r"|ZeroIterationForLoop)$")


@dataclass(frozen=True)
class Group:
    """Functions (``Class.method`` or ``function``) of one module and the tests that guard them.

    ``only_lines``: when given, only lines holding one of these substrings are mutated (the
    refusal lines of a long function).
    """

    name: str
    module: str
    functions: tuple[str, ...]
    tests: tuple[str, ...]
    only_lines: tuple[str, ...] = ()


GROUPS = [
    Group("locate", "controller/stereo/locate.py", ("_judge",), ("tests/test_locate.py",)),
    Group("seam_ends", "controller/stereo/seam_ends.py", ("judge_ends", "view_end_cut"),
          ("tests/test_locate.py", "tests/test_seam_ends.py")),
    Group("robot_limits", "drivers/robot_commands.py",
          ("SafetyLimits.__post_init__", "SafetyLimits.check_point", "SafetyLimits.check_speed",
           "_speed", "MoveJoints.check", "MoveLinear.check", "PathTargets.check", "WeldRun.check"),
          ("tests/test_robot.py", "tests/test_robot_contract.py", "tests/test_path_upload.py")),
    Group("arc_bounds", "controller/geometry/segment_motion.py",
          ("Circle.axis_extreme_fractions",),
          ("tests/test_robot.py", "tests/test_segment_motion.py")),
    Group("joint_limits", "controller/geometry/kinematics.py",
          ("check_joint_limits", "within_limits"), ("tests/test_kinematics.py",)),
    Group("calibration_file", "calibration/calibration_file.py",
          ("_matrix", "_pose", "calibration_from_dict"), ("tests/test_calibration_file.py",)),
    Group("cycle", "controller/cell/cycle.py",
          ("WeldCycle.request_abort", "WeldCycle._make_safe", "WeldCycle._end",
           "WeldCycle.on_enter_FAULT", "WeldCycle.on_enter_ABORTED"),
          ("tests/test_cycle_machine.py",)),
    Group("abb_codec", "drivers/abb/abb_codec.py", ("checksum", "decode_frame"),
          ("tests/test_abb_codec.py",)),
    Group("handeye", "calibration/handeye.py", ("_solve",), ("tests/test_handeye.py",),
          only_lines=("max_rejected_fraction * n", "score[worst] <= 1.0", "resid > max_rms")),
    Group("handeye_pose_only", "calibration/handeye_pose_only.py", ("_solve_pose_only",),
          ("tests/test_handeye.py",),
          only_lines=("max_rejected_fraction * n", "err[i] > limit", "resid > max_rms")),
    Group("daemon_reload", "controller/cell/daemon.py", ("Daemon._do_reload",),
          ("tests/test_daemon.py::test_sighup_reload_between_cycles",)),
]


def _spans(path: Path, g: Group) -> tuple[set[int], list[tuple[tuple[int, int], tuple[int, int]]]]:
    """Lines of the group's functions (``only_lines`` applied) and every string's (start, end)."""
    src = path.read_text()
    tree = ast.parse(src)
    lines: set[int] = set()
    found: set[str] = set()

    def visit(node: ast.AST, prefix: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.ClassDef):
                visit(child, f"{prefix}{child.name}.")
            elif isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef):
                name = f"{prefix}{child.name}"
                if name in g.functions:
                    found.add(name)
                    body_start = child.body[0].lineno
                    assert child.end_lineno is not None
                    lines.update(range(body_start, child.end_lineno + 1))
    visit(tree, "")
    missing = set(g.functions) - found
    if missing:
        raise SystemExit(f"{g.module}: no function {sorted(missing)}; update mutation/run.py")
    if g.only_lines:
        text = src.splitlines()
        lines = {n for n in lines if any(s in text[n - 1] for s in g.only_lines)}
    strings = [((n.lineno, n.col_offset), (n.end_lineno or n.lineno, n.end_col_offset or 0))
               for n in ast.walk(tree)
               if isinstance(n, ast.JoinedStr) or (isinstance(n, ast.Constant)
                                                  and isinstance(n.value, str))]
    return lines, strings


def _filter(db_path: Path, module: Path, g: Group) -> int:
    """Mark every work item outside the group's lines, in a string, or of another operator."""
    from cosmic_ray.work_db import WorkDB, use_db
    from cosmic_ray.work_item import WorkerOutcome, WorkResult

    lines, strings = _spans(module, g)
    kept = 0
    with use_db(str(db_path), WorkDB.Mode.open) as db:
        for item in db.pending_work_items:
            m = item.mutations[0]
            pos = (m.start_pos[0], m.start_pos[1])
            in_string = any(a <= pos < b for a, b in strings)
            if m.start_pos[0] in lines and not in_string and OPERATORS.match(m.operator_name):
                kept += 1
                continue
            db.set_result(item.job_id, WorkResult(output="outside the safety checks",
                                                  worker_outcome=WorkerOutcome.SKIPPED))
    return kept


def run_group(copy: Path, g: Group, timeout_s: float) -> tuple[int, int, list[str], float]:
    """Init, filter, exec one group; (mutants run, killed, survivor reports, seconds)."""
    from cosmic_ray.work_db import WorkDB, use_db
    from cosmic_ray.work_item import TestOutcome, WorkerOutcome

    cfg = copy / f"cr-{g.name}.toml"
    db = copy / f"cr-{g.name}.sqlite"
    tests = " ".join(g.tests)
    cfg.write_text(f'[cosmic-ray]\nmodule-path = "{g.module}"\ntimeout = {timeout_s}\n'
                   f'excluded-modules = []\n'
                   f'test-command = "{sys.executable} -m pytest -x -q -p no:cacheprovider '
                   f'{tests}"\n\n[cosmic-ray.distributor]\nname = "local"\n')
    env = dict(os.environ, PYTHONPATH=str(copy))
    cr = [sys.executable, "-m", "cosmic_ray.cli"]
    subprocess.run([*cr, "init", str(cfg), str(db)], cwd=copy, env=env, check=True)
    kept = _filter(db, copy / g.module, g)
    print(f"[{g.name}] {kept} mutants of {', '.join(g.functions)}", flush=True)
    t0 = time.monotonic()
    subprocess.run([*cr, "exec", str(cfg), str(db)], cwd=copy, env=env, check=True)
    secs = time.monotonic() - t0
    print(f"[{g.name}] done in {secs:.0f} s", flush=True)
    survivors, run, killed = [], 0, 0
    with use_db(str(db), WorkDB.Mode.open) as wdb:
        for item, result in wdb.completed_work_items:
            if result.worker_outcome == WorkerOutcome.SKIPPED:
                continue
            run += 1
            if result.test_outcome == TestOutcome.SURVIVED:
                m = item.mutations[0]
                survivors.append(f"- `{g.module}:{m.start_pos[0]}` {m.operator_name} "
                                 f"(occurrence {m.occurrence})\n\n```diff\n"
                                 f"{(result.diff or '').strip()}\n```\n")
            else:
                killed += 1
    return run, killed, survivors, secs


def main() -> int:
    """Run the groups; write mutation/survivors.md; exit 0 (survivors are reported, not fatal)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", help="comma-separated group names: "
                    + ", ".join(g.name for g in GROUPS))
    ap.add_argument("--timeout", type=float, default=600.0, help="seconds per mutant test run")
    ap.add_argument("--jobs", type=int, default=3, help="groups run at the same time")
    ap.add_argument("--out", default=str(ROOT / "mutation" / "survivors.md"))
    a = ap.parse_args()
    picked = [g for g in GROUPS if not a.only or g.name in a.only.split(",")]
    out = ["# Surviving mutants (`make mutation`)\n",
           "| group | functions | mutants | killed | survived | seconds |",
           "|---|---|---|---|---|---|"]
    details: list[str] = []

    def one(g: Group) -> None:
        with tempfile.TemporaryDirectory(prefix=f"seamguide-mutation-{g.name}-") as tmp:
            copy = Path(tmp)
            copy_tree(copy)
            run, killed, surv, secs = run_group(copy, g, a.timeout)
        out.append(f"| {g.name} | {', '.join(g.functions)} | {run} | {killed} | {len(surv)} "
                   f"| {secs:.0f} |")
        details.extend([f"\n## {g.name}\n"] + (surv or ["none\n"]))
        # Written after every group: a long run stopped half-way keeps what it found.
        Path(a.out).write_text("\n".join(out) + "\n" + "\n".join(details))

    with concurrent.futures.ThreadPoolExecutor(max_workers=max(1, a.jobs)) as pool:
        list(pool.map(one, picked))
    return 0


if __name__ == "__main__":
    sys.exit(main())
