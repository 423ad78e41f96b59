"""Stereo with two different cameras: locate on the stereo benchmark's scenes seen by the
fixed-stereo cell's two lenses, against the single wrist camera on the same scenes, same run.

    .venv/bin/python bench/bench_locate_cameras.py [--pairs 20] [--difficulties medium hard]

Single camera: bench_locate.py's pairs (the dry run's two views, one 2272x1704 44 deg camera,
cached in bench/cache/stereo/). Two cameras: the same scenes (kinds in turn, seeds 1000+)
rendered by the fixed-stereo cell's ``left`` camera (the same 2272x1704 lens) and ``right``
camera (2048x1536, 37 deg, stronger barrel and tangential distortion, off-centre principal point,
farther away and rolled; drivers/sim/sim_fixed_cell.py), each view located with its own camera
model (cached in bench/cache/stereo2/). Rows: the oracle (true image curves) and ours (our
detector + locate), success and within spec as in bench_locate.py. Writes
bench/out/locate_cameras.{json,md}.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

from bench_locate import (  # noqa: E402
    load_pair,
    region,
    render_pair,
    scene_list,
    summarise,
    truth_metrics,
)

from controller.errors import SeamguideError  # noqa: E402
from controller.stereo.locate import ViewObservation, locate_seam  # noqa: E402
from controller.vision.seam_views import detect_seams  # noqa: E402
from drivers.sim.sim_cell import default_sim_cell  # noqa: E402
from drivers.sim.sim_fixed_cell import fixed_stereo_cell  # noqa: E402
from drivers.sim.sim_render import render  # noqa: E402
from drivers.sim.sim_scene import make_scene  # noqa: E402

CACHE = ROOT / "bench" / "cache" / "stereo2"
OUT = ROOT / "bench" / "out"
NAMES = ("left", "right")


def _paths(kind: str, seed: int, difficulty: str) -> tuple[Path, Path, Path]:
    d = CACHE / difficulty
    return d / f"{kind}-{seed}-left.png", d / f"{kind}-{seed}-right.png", d / f"{kind}-{seed}.npz"


def render_two(args: tuple[str, int, str]) -> str:
    kind, seed, difficulty = args
    pl, pr, pz = _paths(kind, seed, difficulty)
    if pz.exists():
        return "cached"
    pz.parent.mkdir(parents=True, exist_ok=True)
    scene = make_scene(kind, seed, difficulty)
    cell = fixed_stereo_cell(scene)
    truth = {}
    for name, p in zip(NAMES, (pl, pr), strict=True):
        r = render(scene, cell.cameras[name], cell.T_base_cam[name], seed=seed)
        cv2.imwrite(str(p), r.image)
        truth[f"px_{name}"], truth[f"idx_{name}"] = r.seam_px, r.seam_index
    np.savez(pz, **truth)
    return "rendered"


def run_two(pairs, use_truth: bool) -> list[dict]:
    rows = []
    for kind, seed, diff in pairs:
        pl, pr, pz = _paths(kind, seed, diff)
        z = np.load(pz)
        scene = make_scene(kind, seed, diff)
        cell = fixed_stereo_cell(scene)
        cams = [cell.cameras[n] for n in NAMES]
        poses = [cell.T_base_cam[n] for n in NAMES]
        truth = scene.seam_points_mm[np.intersect1d(z["idx_left"], z["idx_right"])]
        imgs = [cv2.imread(str(p), cv2.IMREAD_GRAYSCALE) for p in (pl, pr)]
        t0 = time.perf_counter()
        try:
            curves = ([z[f"px_{n}"] for n in NAMES] if use_truth else
                      [d.points_px for d in detect_seams(imgs, camera=cams)])
            obs = [ViewObservation(c, T, px, n)
                   for c, T, px, n in zip(cams, poses, curves, NAMES, strict=True)]
            P3 = locate_seam(obs, nominal_region=region(scene)).dense_points_mm
            m = truth_metrics(P3, truth)
            m.update(ok=True, time_s=time.perf_counter() - t0)
        except SeamguideError as err:
            m = {"ok": False, "error": type(err).__name__, "time_s": time.perf_counter() - t0}
        m.update(kind=kind, seed=seed, difficulty=diff)
        rows.append(m)
    return rows


def run_one(pairs, use_truth: bool, cell) -> list[dict]:
    rows = []
    for kind, seed, diff in pairs:
        imgs, tpx, tidx, poses = load_pair(kind, seed, diff)
        scene = make_scene(kind, seed, diff)
        truth = scene.seam_points_mm[np.intersect1d(tidx[0], tidx[1])]
        t0 = time.perf_counter()
        try:
            curves = tpx if use_truth else [d.points_px for d in
                                             detect_seams(imgs, camera=cell.camera)]
            obs = [ViewObservation(cell.camera, T, c, f"view{i + 1}")
                   for i, (T, c) in enumerate(zip(poses, curves, strict=True))]
            P3 = locate_seam(obs, nominal_region=region(scene)).dense_points_mm
            m = truth_metrics(P3, truth)
            m.update(ok=True, time_s=time.perf_counter() - t0)
        except SeamguideError as err:
            m = {"ok": False, "error": type(err).__name__, "time_s": time.perf_counter() - t0}
        m.update(kind=kind, seed=seed, difficulty=diff)
        rows.append(m)
    return rows


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--pairs", type=int, default=20)
    ap.add_argument("--difficulties", nargs="+", default=["medium", "hard"])
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    cell = default_sim_cell()
    jobs = [(k, s, d) for d in args.difficulties for k, s in scene_list(d, args.pairs)]
    t0 = time.time()
    with ProcessPoolExecutor(args.workers) as ex:
        for i, (a, b) in enumerate(zip(ex.map(render_pair, jobs), ex.map(render_two, jobs),
                                       strict=True), 1):
            if i % 5 == 0 or i == len(jobs):
                print(f"renders {i}/{len(jobs)} ({a}, {b}), {time.time() - t0:.0f} s",
                      file=sys.stderr)
    res: dict = {}
    for d in args.difficulties:
        pairs = [(k, s, d) for k, s in scene_list(d, args.pairs)]
        res[d] = {}
        for name, rows in (("one camera, oracle", run_one(pairs, True, cell)),
                           ("one camera, ours", run_one(pairs, False, cell)),
                           ("two cameras, oracle", run_two(pairs, True)),
                           ("two cameras, ours", run_two(pairs, False))):
            res[d][name] = {"summary": summarise(rows), "rows": rows}
            s = res[d][name]["summary"]
            print(f"{d:6} {name:22} success {s['success']:.0%} spec {s['within_spec']:.0%} rms "
                  f"{s['rms_mm_median']:.4f} max {s['max_mm_median']:.4f}", file=sys.stderr)
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "locate_cameras.json").write_text(json.dumps(res, indent=1, default=float))
    lines = ["| difficulty | cameras | success | within spec | 3D RMS (median / p95) | max "
             "(median) | coverage | end error | time / pair |",
             "|---|---|---|---|---|---|---|---|---|"]
    for d, rows in res.items():
        for name, r in rows.items():
            s = r["summary"]
            lines.append(f"| {d} | {name} | {s['success']:.0%} | {s['within_spec']:.0%} | "
                         f"{s['rms_mm_median']:.3f} / {s['rms_mm_p95']:.3f} mm | "
                         f"{s['max_mm_median']:.3f} mm | {s['coverage_median']:.1%} | "
                         f"{s['end_mm_median']:.2f} mm | {s['time_ms_median']:.0f} ms |")
    (OUT / "locate_cameras.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
