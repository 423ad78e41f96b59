"""What the probes over the benchmark's cached views share: their command line and their run.

``bench.detect_funnel``, ``bench.detect_unsure`` and ``bench.detect_rescue`` each read the
cached cases of one part (``--part tuning|heldout``, tuning by default: reading the held-out
part's views one by one is how a rule gets fitted to it), run a function over each case in
``--jobs`` processes, print their tables and write the rows as JSON (``--out``).
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable, Iterable
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from bench.detect_cases import Case, case_cached, case_list
from controller.vision.seam_params import Candidate
from drivers.sim.sim_scene import DIFFICULTIES


def part_parser(description: str, pairs: dict[str, int], out: str) -> argparse.ArgumentParser:
    """The command line of a probe over the cached views of one part.

    ``--part``, ``--pairs`` (wide pairs per difficulty, default ``pairs["wide"]``),
    ``--SET-pairs`` for each other set of ``pairs`` (its default the value there), ``--jobs``
    and ``--out`` (default ``out``).
    """
    ap = argparse.ArgumentParser(description=description)
    ap.add_argument("--part", choices=("tuning", "heldout"), default="tuning")
    for name, n in pairs.items():
        flag = "--pairs" if name == "wide" else f"--{name}-pairs"
        ap.add_argument(flag, dest=f"{name}_pairs", type=int, default=n,
                        help="pairs per difficulty" if name == "wide" else f"{name} pairs")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", default=out)
    return ap


def cached_cases(args: argparse.Namespace, pairs: dict[str, int], tool: str) -> list[Case]:
    """The cached cases of the part ``args`` (from :func:`part_parser` with these ``pairs``).

    ``wide`` takes its pairs for each difficulty; the other sets mix theirs. None cached: says so
    on stderr, naming ``tool`` and the command that renders them, and returns an empty list.
    """
    cases: list[Case] = []
    for name in pairs:
        n = getattr(args, f"{name}_pairs")
        if name == "wide":
            cases += [c for d in DIFFICULTIES for c in case_list("wide", d, args.part, n)]
        else:
            cases += case_list(name, "mixed", args.part, n)
    cases = [c for c in cases if case_cached(c)]
    if not cases:
        print(f"{tool}: no cached renders of that part: run `.venv/bin/python -m "
              "bench.bench_detect --render-only` first", file=sys.stderr)
    return cases



def distinct_lines(cands: Iterable[Candidate]) -> list[Candidate]:
    """The first of ``cands`` (with points) for each line: a later stage lists a candidate again
    (the finer grid's list holds the first way's), told by its end points rounded to the px."""
    out, seen = [], set()
    for c in cands:
        assert c.points is not None
        key = tuple(np.round(c.points[[0, -1]]).ravel().tolist())
        if key not in seen:
            seen.add(key)
            out.append(c)
    return out

def run_probe(argv: list[str] | None, description: str, pairs: dict[str, int], out: str,
              tool: str, run_case: Callable[[Case], list[dict[str, Any]]],
              report: Callable[[list[dict[str, Any]]], str], chunksize: int = 2) -> int:
    """Parse ``argv`` (:func:`part_parser`), run ``run_case`` over the cached cases, print
    ``report(rows)`` and write the rows to ``--out``; 0, or 1 when none is cached."""
    a = part_parser(description, pairs, out).parse_args(argv)
    cases = cached_cases(a, pairs, tool)
    if not cases:
        return 1
    with ProcessPoolExecutor(a.jobs) as ex:
        rows = [r for rs in ex.map(run_case, cases, chunksize=chunksize) for r in rs]
    if a.part == "heldout":
        print("(the held-out part: to measure with, not to tune on)")
    print(report(rows))
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    Path(a.out).write_text(json.dumps(rows, indent=1))
    return 0
