"""How fast the command line starts: each command against the bare imports it cannot avoid.

Real processes, in one run, the command and its reference alternating (the order swapped every
round), medians over the rounds:

    seamguide --help               vs  python -c "import numpy"            (target 1.5x)
    seamguide fk 0 0 0 0 0 0       vs  python -c "import numpy, pinocchio" (target 1.5x)
    seamguide detect IMAGE         vs  python -c "import numpy, cv2"       (target 2.5x)

IMAGE is a rendered 2272x1704 view of the simulated workpiece (made once, cached in
bench/cache/cli_startup/). The detect time includes reading the image and finding the seam.

    .venv/bin/python bench/bench_cli_startup.py            # 9 rounds
    .venv/bin/python bench/bench_cli_startup.py --quick    # 3 rounds

Writes bench/out/cli_startup.json and .md.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

CACHE = ROOT / "bench" / "cache" / "cli_startup"
OUT = ROOT / "bench" / "out"
PY = sys.executable
SEAMGUIDE = str(Path(PY).parent / "seamguide")


def test_image() -> Path:
    """A 2272x1704 rendered view with a seam (rendered once)."""
    path = CACHE / "view.png"
    if not path.is_file():
        import cv2

        from drivers.sim.sim_cell import default_sim_cell
        from drivers.sim.sim_render import render, suggest_view_poses
        from drivers.sim.sim_scene import make_scene

        cell = default_sim_cell()
        scene = make_scene("s_curve", 1, "medium")
        T = suggest_view_poses(scene, cell.camera, n=2)[0]
        CACHE.mkdir(parents=True, exist_ok=True)
        cv2.imwrite(str(path), render(scene, cell.camera, T, seed=1).image)
    return path


def run_s(cmd: list[str]) -> float:
    """Wall time (s) of one process; it must succeed."""
    t0 = time.perf_counter()
    done = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, check=False)
    dt = time.perf_counter() - t0
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({done.returncode}): {done.stderr.decode()}")
    return dt


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rounds", type=int, default=9)
    ap.add_argument("--quick", action="store_true", help="3 rounds")
    args = ap.parse_args(argv)
    rounds = 3 if args.quick else args.rounds
    image = test_image()
    cases = [
        ("seamguide --help", [SEAMGUIDE, "--help"], "import numpy", 1.5),
        ("seamguide fk 0 0 0 0 0 0", [SEAMGUIDE, "fk", "0", "0", "0", "0", "0", "0"],
         "import numpy, pinocchio", 1.5),
        ("seamguide detect IMAGE (2272x1704)", [SEAMGUIDE, "detect", str(image)],
         "import numpy, cv2", 2.5),
    ]
    rows = []
    for name, cmd, ref, target in cases:
        ref_cmd = [PY, "-c", ref]
        run_s(cmd), run_s(ref_cmd)  # warm the file cache
        t_cmd, t_ref = [], []
        for r in range(rounds):
            pair = [(cmd, t_cmd), (ref_cmd, t_ref)]
            for c, acc in (pair if r % 2 == 0 else pair[::-1]):
                acc.append(run_s(c))
        m_cmd, m_ref = statistics.median(t_cmd), statistics.median(t_ref)
        rows.append({"command": name, "reference": f'python -c "{ref}"',
                     "median_s": round(m_cmd, 3), "reference_median_s": round(m_ref, 3),
                     "ratio": round(m_cmd / m_ref, 2), "target_ratio": target,
                     "rounds": rounds})
        print(f"{name:38s} {m_cmd:6.3f} s   {ref:28s} {m_ref:6.3f} s   "
              f"{m_cmd / m_ref:4.2f}x (target {target}x)", flush=True)
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "cli_startup.json").write_text(json.dumps(rows, indent=1) + "\n")
    md = ["| command | median | reference (bare imports) | median | ratio | target |",
          "|---|---|---|---|---|---|"]
    md += [f"| `{r['command']}` | {r['median_s']:.2f} s | `{r['reference']}` | "
           f"{r['reference_median_s']:.2f} s | {r['ratio']:.2f}x | {r['target_ratio']}x |"
           for r in rows]
    (OUT / "cli_startup.md").write_text("\n".join(md) + "\n")
    return 0 if all(r["ratio"] <= r["target_ratio"] for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
