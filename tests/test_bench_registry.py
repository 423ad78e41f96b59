"""bench/run_all.py (``make bench``) runs every benchmark of bench/."""

from __future__ import annotations

import importlib.util
from pathlib import Path

BENCH = Path(__file__).resolve().parents[1] / "bench"


def test_run_all_lists_every_benchmark():
    spec = importlib.util.spec_from_file_location("run_all", BENCH / "run_all.py")
    assert spec is not None and spec.loader is not None
    run_all = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(run_all)
    scripts = {next(w if w.endswith(".py") else w.replace(".", "/") + ".py"
                    for w in c if w.startswith("bench"))
               for c, _ in run_all.BENCHMARKS.values()}
    benches = {f"bench/{p.name}" for p in BENCH.glob("*.py")
               if p.name.startswith(("bench_", "soak_"))}
    assert benches - scripts == set(), "benchmarks make bench does not run"
    assert all((BENCH.parent / s).is_file() for s in scripts)
