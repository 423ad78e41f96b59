"""The detector's pixel scales from the working distance: defaults vs scaled, on close-ups and on
the detection benchmark's cached renders.

    .venv/bin/python -m bench.bench_detect_scale                 # close-ups + cached renders
    .venv/bin/python -m bench.bench_detect_scale --quick         # 6 close-ups, no cache

1. **Close-ups** (rendered here, fixed seeds): classic scenes (straight / arc / s_curve /
   nonplanar, easy / medium / hard, gap 0.8-1.2 mm) seen from ``--distances`` mm by the half-size
   camera (1136x852, fx 1420 px: 20 px/mm at 70 mm, a 1.2 mm gap 24 px wide), across the seam as
   the dry run looks. Each view is detected with the defaults (``DetectParams()``, what
   ``seamguide detect`` does without a distance) and with the scales of its distance
   (:func:`controller.vision.seam_scale.params_for_scale`, the job's default gap range).
2. **Cached renders** of ``bench/bench_detect.py`` (``--cache``, default the benchmark's cache;
   cases not rendered are skipped, nothing is rendered): each view with the defaults and with
   the scales the cycle would give it (:func:`controller.cell.guidance.view_params`: the scene's
   nominal region, its radius + 20 mm as the dry run's job, the job's default gap range).

Each view is scored as bench/bench_detect.py does (:func:`bench.detect_score.score_view`:
found, wrong, refused). Times are per view, as a ratio scaled / defaults in the same run.
Writes bench/out/detect_scale.json.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from bench.detect_cases import CACHE, CACHE_TAG, view_truth
from bench.detect_score import end_kinds_of, score_view
from controller.cell.guidance import GuidanceSettings, view_params
from controller.errors import SeamguideError
from controller.geometry.camera_model import default_camera
from controller.vision.seam_detect import DetectParams, detect_seam
from controller.vision.seam_scale import params_for_scale
from drivers.sim.sim_render import render, suggest_view_poses
from drivers.sim.sim_scene import make_scene

KINDS = ("straight", "arc", "s_curve", "nonplanar")


def _detect(img: np.ndarray, truth: dict[str, Any], cam: Any,
            params: DetectParams | None) -> dict[str, Any]:
    t0 = time.perf_counter()
    try:
        det = detect_seam(img, camera=cam, params=params)
    except SeamguideError as err:
        return {"result": "refused", "why": str(err)[:120], "time_s": time.perf_counter() - t0}
    dt = time.perf_counter() - t0
    sc = score_view(det.points_px, truth, end_kinds_of(det))
    return {"result": sc["result"], "why": sc.get("why", ""), "p95_px": sc.get("p95"),
            "way": det.stats.get("way"), "time_s": dt}


def close_ups(distances: list[float], seeds: int) -> list[dict[str, Any]]:
    """Close-up views, defaults vs scaled (module doc, part 1)."""
    cam = default_camera().scaled(0.5)
    rows = []
    for z_mm in distances:
        scaled = params_for_scale(cam.K[0, 0] / z_mm)
        for i in range(seeds):
            kind, diff = KINDS[i % 4], ("easy", "medium", "hard")[i % 3]
            seed = 1 + i
            sc = make_scene(kind, seed, diff, gap_mm=round(0.8 + 0.1 * ((i * 7) % 5), 2))
            T = suggest_view_poses(sc, cam, standoff_mm=z_mm,
                                   baseline_mm=200.0 * z_mm / 350.0)[seed % 2]
            r = render(sc, cam, T, seed=seed)
            truth = {"seam_px": r.seam_px, "end_kinds": list(r.end_kinds),
                     "end_tol_px": r.end_tol_px, "spans": r.occluded_spans_px,
                     "pens": r.pen_lines_px, "gap_px": r.gap_px, "gap_mm": sc.gap_mm,
                     "ragged_mm": 0.0, "family": "classic"}
            row = {"distance_mm": z_mm, "kind": kind, "difficulty": diff, "seed": seed,
                   "gap_px": round(float(r.gap_px), 1),
                   "default": _detect(r.image, truth, cam, None),
                   "scaled": _detect(r.image, truth, cam, scaled)}
            rows.append(row)
            print(f"{z_mm:5.0f} mm {kind:9s} {diff:6s} gap {r.gap_px:5.1f} px: default "
                  f"{row['default']['result']:7s} scaled {row['scaled']['result']}", flush=True)
    return rows


def cached(cache: Path, per: int) -> list[dict[str, Any]]:
    """The benchmark's cached renders, defaults vs the cycle's scales (module doc, part 2)."""
    cam = default_camera()
    rows = []
    for kind_set in ("classic", "pen", "wide"):
        for diff in ("easy", "medium", "hard"):
            for f in sorted((cache / CACHE_TAG / kind_set / diff).glob("*.npz"))[:per]:
                z = dict(np.load(f))
                settings = GuidanceSettings(
                    nominal_centre_mm=tuple(float(v) for v in z["centre_mm"]),  # type: ignore
                    nominal_radius_mm=float(z["radius_mm"]) + 20.0)
                for i in range(int(z["n_views"])):
                    img = cv2.imread(str(f)[:-4] + f"-{i}.png", cv2.IMREAD_UNCHANGED)
                    truth = view_truth(z, i, img)
                    p = view_params(cam, z[f"T{i}"], settings)
                    rows.append({"set": kind_set, "difficulty": diff, "case": f.stem, "view": i,
                                 "gap_px": round(float(truth["gap_px"]), 1),
                                 "max_gap_px": None if p is None else round(p.max_gap_px, 1),
                                 "default": _detect(img, truth, cam, None),
                                 "scaled": _detect(img, truth, cam, p)})
    return rows


def summary(rows: list[dict[str, Any]], key: str | None) -> dict[str, Any]:
    """Counts of found / wrong / refused per arm (per ``key`` value), and the time ratio."""
    out: dict[str, Any] = {}
    groups = sorted({r[key] for r in rows}) if key else [None]
    for g in groups:
        sel = [r for r in rows if key is None or r[key] == g]
        d = {arm: {k: sum(r[arm]["result"] == k for r in sel)
                   for k in ("found", "wrong", "refused")} for arm in ("default", "scaled")}
        d["changed"] = sum(r["default"]["result"] != r["scaled"]["result"] for r in sel)
        t_d = float(np.median([r["default"]["time_s"] for r in sel]))
        t_s = float(np.median([r["scaled"]["time_s"] for r in sel]))
        d["median_time_ratio_scaled_over_default"] = round(t_s / t_d, 2)
        out[str(g) if key else "all"] = d
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--distances", type=float, nargs="+", default=[70.0, 100.0])
    ap.add_argument("--seeds", type=int, default=12, help="close-up scenes per distance")
    ap.add_argument("--cache", type=Path, default=CACHE)
    ap.add_argument("--per", type=int, default=12, help="cached cases per set and difficulty")
    ap.add_argument("--out", default="bench/out/detect_scale.json")
    args = ap.parse_args(argv)
    if args.quick:
        args.distances, args.seeds, args.per = [70.0], 6, 0
    rep: dict[str, Any] = {"close_ups": close_ups(args.distances, args.seeds)}
    rep["close_ups_summary"] = summary(rep["close_ups"], "distance_mm")
    print(json.dumps(rep["close_ups_summary"], indent=1))
    if args.per > 0:
        rep["cached"] = cached(args.cache, args.per)
        rep["cached_summary"] = summary(rep["cached"], "set") if rep["cached"] else {}
        print(json.dumps(rep["cached_summary"], indent=1))
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(rep, indent=1, default=float))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
