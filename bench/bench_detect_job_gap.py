"""Seam detection when the job states its gap: the dark band limit (``[seam] gap_mm``) measured.

Usage (from the repository root; needs the cached renders of ``bench.bench_detect``)::

    .venv/bin/python -m bench.bench_detect_job_gap [--jobs 2] [--range 0.5 1.5] [--cases N]
        [--out bench/out/detect_job_gap.json]

Over the cached ``wide`` and ``pen`` cases of ``bench.bench_detect`` (both parts), every view is
detected three ways: **defaults** (``DetectParams()``, as the benchmark measures); **scaled**
(``params_for_scale(px/mm, job gap)``: the scales a job stating its gap gives, without the band
limit); **job gap** (the same with ``limit_band``: what the cycle and ``detect --gap-mm`` now do).
Single views are counted as ``seamguide detect`` answers (``bench_detect.single_view``): a shadow
split off without the job's narrowest gap is refused as two readings (column ``2read``; ``band``:
refused for a band wider than the job's gap); pairs are located with both readings, as the cycle.
The job's gap is the scene's true gap times ``--range`` (default 0.5-1.5: a nominal gap with
+-50 %), px/mm the view's true gap in px over its gap in mm (the scale at the seam; the cycle
uses ``fx / Z`` at the nominal centre). Views are scored by ``bench.detect_score`` and pairs
located as ``bench.bench_detect`` does (no clipping), so the counts compare with its report.
Column ``wide``: views refused saying a line fitted a band wider than the scale's widest gap,
with the advice to state the gap (``seam_centreline.scale_advice``); for each part, a last line
says what the job's gap gives on the views the defaults refused so (:func:`advice_taken`).
"""

from __future__ import annotations

import argparse
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from typing import Any

from bench.detect_cases import FULL, case_cached, load_case, plan
from bench.detect_ways import detect_one_way, way_counts, write_and_print
from controller.geometry.camera_model import default_camera
from controller.vision.seam_centreline import TOO_WIDE
from controller.vision.seam_scale import params_for_scale

WAYS = ("defaults", "scaled", "job gap")


def run_case(args: tuple[tuple[str, str, str, int], tuple[float, float]]) -> dict[str, Any]:
    """One case's views detected the three ways, scored, and (pairs) located."""
    case, (lo, hi) = args
    cam = default_camera()
    imgs, z = load_case(case)
    row: dict[str, Any] = {"case": list(case), "family": str(z["family"])}
    for way in WAYS:
        def setting(i: int, truth: dict[str, Any], way: str = way) -> tuple[Any, None]:
            if way == "defaults":
                return None, None
            g_mm = truth["gap_mm"]
            return params_for_scale(truth["gap_px"] / g_mm, (lo * g_mm, hi * g_mm),
                                    limit_band=way == "job gap"), None
        row[way] = detect_one_way(imgs, z, cam, setting)
    return row


def summary(rows: list[dict[str, Any]], way: str) -> dict[str, int]:
    """Counts of one way's views (found / wrong / refused) and pairs (located / wrong)."""
    out = way_counts(rows, way)
    views = [v for r in rows for v in r[way]["views"]]
    # Refused for a band wider than the job's gap (seam_decision._mark_too_wide), and for two
    # readings one image cannot choose from (a shadow split without the job's gap: one_reading).
    out["refused_for_band"] = sum(v["result"] == "refused" and "the job's gap makes at most"
                                  in (v["error"] or "") for v in views)
    out["refused_two_readings"] = sum(v["result"] == "refused" and "one image cannot tell"
                                      in (v["error"] or "") for v in views)
    out["refused_too_wide"] = sum(_too_wide(v) for v in views)
    return out


def _too_wide(view: dict[str, Any]) -> bool:
    """Whether a view was refused with the advice to state the gap: a candidate's profiles
    fitted a band wider than the scale's widest gap (``seam_centreline._too_wide``)."""
    return view["result"] == "refused" and TOO_WIDE in (view["error"] or "")


def advice_taken(rows: list[dict[str, Any]]) -> dict[str, int]:
    """What the job's gap gives on the views the defaults refused with the advice to state it:
    ``{"advised": n, "found": .., "wrong": .., "refused": ..}`` ("job gap" way)."""
    out = {"advised": 0, "found": 0, "wrong": 0, "refused": 0}
    for r in rows:
        for d, j in zip(r["defaults"]["views"], r["job gap"]["views"], strict=True):
            if _too_wide(d):
                out["advised"] += 1
                out[j["result"]] += 1
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--range", type=float, nargs=2, default=(0.5, 1.5), metavar=("LO", "HI"),
                    help="the job's gap as fractions of the scene's true gap")
    ap.add_argument("--cases", type=int, help="only the first N cached cases (a quick look)")
    ap.add_argument("--out", default="bench/out/detect_job_gap.json")
    args = ap.parse_args(argv)
    groups = plan(FULL, ["easy", "medium", "hard"], ["tuning", "heldout"], ["wide", "pen"])
    cases = [c for g in groups.values() for c in g if case_cached(c)][:args.cases]
    if not cases:
        print("no cached renders: run `.venv/bin/python -m bench.bench_detect --render-only` "
              "first", file=sys.stderr)
        return 1
    t0 = time.time()
    with ProcessPoolExecutor(args.jobs) as ex:
        rows = list(ex.map(run_case, [(c, tuple(args.range)) for c in cases], chunksize=4))
    report: dict[str, Any] = {"range": list(args.range), "cases": len(cases),
                              "time_s": time.time() - t0, "summary": {}}
    for split in ("tuning", "heldout"):
        for fam in ("all", "plain", "shop", "closeup"):
            sel = [r for r in rows if r["case"][2] == split and fam in ("all", r["family"])]
            report["summary"][f"{split}/{fam}"] = {w: summary(sel, w) for w in WAYS}
        report[f"advice/{split}"] = advice_taken([r for r in rows if r["case"][2] == split])
    write_and_print(args.out, report, rows,
                    f"{len(cases)} cases in {report['time_s']:.0f} s; job gap = true gap x "
                    f"{args.range[0]:g}-{args.range[1]:g}", ("part/look", 18), 9,
                    [("band", "refused_for_band", 5), ("2read", "refused_two_readings", 5),
                     ("wide", "refused_too_wide", 5)])
    for split in ("tuning", "heldout"):
        a = report[f"advice/{split}"]
        print(f"{split}: {a['advised']} views refused with defaults for a band wider than the "
              f"widest gap (advice: state the gap); with the job's gap {a['found']} found, "
              f"{a['wrong']} wrong, {a['refused']} refused")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
