"""Detector time as a ratio to ``cv2.Canny`` on the same image, in the same run.

Usage (from the repository root; needs the cached renders of ``bench.bench_detect``)::

    .venv/bin/python -m bench.bench_detect_speed [--scenes 6] [--runs 5] [--blocks 5] [--real]
        [--wide N]

For each of the first ``--scenes`` medium scenes of ``bench.bench_detect`` (2272x1704), the
detector and ``cv2.Canny(img, 50, 150)`` run alternately, ``--runs`` times each per block; the
median of the per-block medians is reported in ms and as a ratio (this machine's speed drifts by a
third from minute to minute; the ratio does not). ``--real`` adds the real photographs of
``../shared/data/real-seams`` (where the first way refuses and the valley paths run); ``--wide N``
the first view of the first ``N`` cached cases of each difficulty of the wide look's tuning part
(plain, shop and close-up looks: many are refused, after every way and the image shrunk were
tried), reported apart: the classic scenes alone are the views the first way finds at once.
"""

from __future__ import annotations

import argparse
import contextlib
import statistics
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from bench.detect_cases import case_cached, case_list, load_case, render_case
from controller.errors import AmbiguousSeam, SeamNotFound
from controller.vision.seam_detect import detect_seam
from drivers.sim.sim_scene import DIFFICULTIES


def _time(img: np.ndarray, runs: int, blocks: int) -> tuple[float, float]:
    """(detector ms, Canny ms): median over blocks of the per-block medians, alternating."""
    grey = img if img.ndim == 2 else cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    det_b, can_b = [], []
    for _ in range(blocks):
        d, c = [], []
        for _ in range(runs):
            t0 = time.perf_counter()
            with contextlib.suppress(SeamNotFound, AmbiguousSeam):
                detect_seam(img)
            d.append(1000 * (time.perf_counter() - t0))
            t0 = time.perf_counter()
            cv2.Canny(grey, 50, 150)
            c.append(1000 * (time.perf_counter() - t0))
        det_b.append(statistics.median(d))
        can_b.append(statistics.median(c))
    return statistics.median(det_b), statistics.median(can_b)


def main(argv: list[str] | None = None) -> int:
    """Print one line per image and the median ratio; returns 0."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", type=int, default=6)
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--blocks", type=int, default=5)
    ap.add_argument("--real", action="store_true")
    ap.add_argument("--wide", type=int, default=0, metavar="N")
    a = ap.parse_args(argv)
    rows: list[tuple[str, Any, float, float]] = []
    for case in case_list("classic", "medium", "tuning", a.scenes):
        render_case(case)  # cached under bench/cache after the first run
        imgs, _ = load_case(case)
        rows.append((f"medium {case[3]}", imgs[0].shape, *_time(imgs[0], a.runs, a.blocks)))
    for difficulty in DIFFICULTIES if a.wide else ():
        cached = [c for c in case_list("wide", difficulty, "tuning", 4 * a.wide) if case_cached(c)]
        for case in cached[:a.wide]:
            imgs, _ = load_case(case)
            rows.append((f"wide {difficulty} {case[3]}", imgs[0].shape,
                         *_time(imgs[0], max(1, a.runs // 5), a.blocks)))
    if a.real:
        root = Path(__file__).resolve().parents[2] / "shared" / "data" / "real-seams" / "images"
        for f in sorted(root.glob("*.jpg")):
            img = cv2.imread(str(f))
            rows.append((f.stem, img.shape, *_time(img, max(1, a.runs // 5), a.blocks)))
    for name, shape, d, c in rows:
        print(f"{name:12s} {shape[1]}x{shape[0]}  detector {d:8.1f} ms  Canny {c:6.2f} ms  "
              f"ratio {d / c:6.1f}")
    sim = [d / c for n, _, d, c in rows if n.startswith("medium")]
    sim_ms = [d for n, _, d, _ in rows if n.startswith("medium")]
    if sim:
        print(f"simulated 2272x1704: median detector/Canny ratio {statistics.median(sim):.1f}, "
              f"median detector {statistics.median(sim_ms):.1f} ms")
    wide = [d / c for n, _, d, c in rows if n.startswith("wide")]
    if wide:
        wide_ms = [d for n, _, d, _ in rows if n.startswith("wide")]
        print(f"wide look 2272x1704: median detector/Canny ratio {statistics.median(wide):.1f}, "
              f"median detector {statistics.median(wide_ms):.1f} ms")
    real = [d / c for n, _, d, c in rows if not n.startswith(("medium", "wide"))]
    if real:
        print(f"real photographs: median ratio {statistics.median(real):.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
