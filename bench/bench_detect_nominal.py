"""Seam detection with the job's nominal line (``[seam] nominal_line_mm``) measured.

Usage (from the repository root; needs the cached renders of ``bench.bench_detect``)::

    .venv/bin/python -m bench.bench_detect_nominal [--jobs 2] [--shift-mm 3] [--turn-deg 1]
        [--tolerance-mm 10] [--cases N] [--out bench/out/detect_nominal.json]

Over the cached ``wide``, ``pen`` and ``tee`` cases of ``bench.bench_detect`` (both parts), every
view is detected two ways: **defaults** (``DetectParams()``, no nominal seam: what the benchmark
measures and the issues' targets are about) and **nominal line** (as the cycle does with a job
stating ``nominal_line_mm``: the line projected into the view by
:func:`controller.cell.guidance.nominal_hint`, and no candidate ``--tolerance-mm`` or more from it,
at the view's scale ``fx / Z`` of the nominal centre, returned; the detector's other parameters
are the defaults, so that the two ways differ by the line alone).

The nominal line is the scene's true seam (base frame) as a drawing would give it, placed with a
fixture's error: moved by up to ``--shift-mm`` in a random direction and turned by up to
``--turn-deg`` about a random axis through its middle (seeded by the case; the same for both
views). Views are scored by ``bench.detect_score`` and counted as ``seamguide detect`` answers
(``bench_detect.single_view``); pairs are located as ``bench.bench_detect`` does (no clipping),
and again as a job that clips the ends no view sees (``cloc`` / ``cwrong``: located / wrong),
the nominal line way's 3D seam then held within the tolerance of the line (since 2026-12-07,
``locate_seam(nominal_line=...)``).
"""

from __future__ import annotations

import argparse
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from bench.detect_cases import FULL, case_cached, load_case, plan
from bench.detect_ways import detect_one_way, way_counts, write_and_print
from controller.cell.guidance import nominal_hint
from controller.geometry.camera_model import default_camera
from controller.vision.seam_params import DetectParams
from controller.vision.seam_scale import px_per_mm_at

WAYS = ("defaults", "nominal line")


def nominal_line(seam_mm: np.ndarray, seed: int, shift_mm: float, turn_deg: float) -> np.ndarray:
    """``seam_mm`` (N, 3) moved and turned as a fixture would place the part (module doc)."""
    rng = np.random.default_rng([seed, 7])
    d = rng.normal(size=3)
    shift = d / np.linalg.norm(d) * rng.uniform(0.0, shift_mm)
    axis = rng.normal(size=3)
    rot = Rotation.from_rotvec(axis / np.linalg.norm(axis) * np.radians(rng.uniform(0, turn_deg)))
    mid = seam_mm[len(seam_mm) // 2]
    return np.asarray(rot.apply(seam_mm - mid) + mid + shift)


def run_case(args: tuple[tuple[str, str, str, int], float, float, float]) -> dict[str, Any]:
    """One case's views detected both ways, scored, and (pairs) located."""
    case, shift_mm, turn_deg, tol_mm = args
    cam = default_camera()
    imgs, z = load_case(case)
    line = nominal_line(np.asarray(z["seam_points_mm"]), case[3], shift_mm, turn_deg)

    def with_line(i: int, truth: dict[str, Any]) -> tuple[Any, Any]:
        T = z[f"T{i}"]
        s = px_per_mm_at(cam.fx, T, np.asarray(z["centre_mm"]))
        params = None if s is None else replace(DetectParams(), hint_tol_px=tol_mm * s)
        return params, nominal_hint(cam, T, line)

    return {"case": list(case), "family": str(z["family"]),
            "defaults": detect_one_way(imgs, z, cam, lambda i, truth: (None, None)),
            "nominal line": detect_one_way(imgs, z, cam, with_line, (line, tol_mm))}


def summary(rows: list[dict[str, Any]], way: str) -> dict[str, int]:
    """Counts of one way's views (found / wrong / refused, refused as ambiguous) and pairs."""
    out = way_counts(rows, way)
    out["ambiguous"] = sum(v["result"] == "refused" and (v["error"] or "").startswith(
        "AmbiguousSeam") for r in rows for v in r[way]["views"])
    return out


def main(argv: list[str] | None = None) -> int:
    """Run both ways over the cached cases, print the table, write the rows; 0, or 1 if none."""
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--shift-mm", type=float, default=3.0,
                    help="the nominal line lies up to this far (mm) from the true seam")
    ap.add_argument("--turn-deg", type=float, default=1.0,
                    help="and is turned by up to this much about its middle")
    ap.add_argument("--tolerance-mm", type=float, default=10.0,
                    help="the job's seam.line_tolerance_mm")
    ap.add_argument("--cases", type=int, help="only the first N cached cases (a quick look)")
    ap.add_argument("--out", default="bench/out/detect_nominal.json")
    args = ap.parse_args(argv)
    groups = plan(FULL, ["easy", "medium", "hard"], ["tuning", "heldout"], ["wide", "pen", "tee"])
    cases = [c for g in groups.values() for c in g if case_cached(c)][:args.cases]
    if not cases:
        print("no cached renders: run `.venv/bin/python -m bench.bench_detect --render-only` "
              "first", file=sys.stderr)
        return 1
    t0 = time.time()
    work = [(c, args.shift_mm, args.turn_deg, args.tolerance_mm) for c in cases]
    with ProcessPoolExecutor(args.jobs) as ex:
        rows = list(ex.map(run_case, work, chunksize=4))
    report: dict[str, Any] = {"shift_mm": args.shift_mm, "turn_deg": args.turn_deg,
                              "tolerance_mm": args.tolerance_mm, "cases": len(cases),
                              "time_s": time.time() - t0, "summary": {}}
    for split in ("tuning", "heldout"):
        for st in ("wide", "pen", "tee"):
            sel = [r for r in rows if r["case"][2] == split and r["case"][0] == st]
            if sel:
                report["summary"][f"{split}/{st}"] = {w: summary(sel, w) for w in WAYS}
    write_and_print(args.out, report, rows,
                    f"{len(cases)} cases in {report['time_s']:.0f} s; nominal line within "
                    f"{args.shift_mm:g} mm and {args.turn_deg:g} deg of the seam, tolerance "
                    f"{args.tolerance_mm:g} mm", ("part/set", 14), 12, [("ambig", "ambiguous", 5)])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
