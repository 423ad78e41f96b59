"""Stereo benchmark: 3D seam accuracy, coverage, success and time on rendered scene pairs.

    .venv/bin/python bench/bench_locate.py [--pairs 50] [--difficulties easy medium hard]

For each difficulty, ``--pairs`` scenes (kinds in turn, fixed seeds) are rendered from the two
suggested view poses with the simulated cell's exact calibration (renders cached in
bench/cache/stereo/, git-ignored). Rows, all measured in the same run on the same images:

* ``oracle``: the true image curves triangulated by our locate (the error of geometry alone);
* ``ours``: our detector (the views in two threads, as the cycle runs it) + our locate;
* ``published epipolar+poly7`` / ``published closest rays``: the published stereo methods
  (bench/published_stereo.py) on our detections;
* ``published pipeline``: the published detector port (bench/published_detect.py) + epipolar+poly7.

Then a sensitivity table (hand-eye off by 0.3 mm / 0.1 deg, focal length off by 0.2 %) for the
oracle and ours, and the share of pairs where a hand-eye off by 5 mm is caught by the quality
checks. Writes bench/out/locate.json, bench/out/locate.md (the README tables) and
docs/img/stereo_error.png (a 3D seam with its error along it).
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

from controller.errors import SeamguideError, TriangulationError  # noqa: E402
from controller.geometry.poses import invert, make_pose, rotation_about  # noqa: E402
from controller.stereo.locate import ViewObservation, locate_seam  # noqa: E402
from controller.stereo.triangulate import PolylineDistance  # noqa: E402
from controller.vision.seam_detect import detect_seam  # noqa: E402
from controller.vision.seam_views import detect_seams  # noqa: E402
from drivers.sim.sim_cell import default_sim_cell  # noqa: E402
from drivers.sim.sim_render import render, suggest_view_poses  # noqa: E402
from drivers.sim.sim_scene import KINDS, make_scene  # noqa: E402

CACHE = ROOT / "bench" / "cache" / "stereo"
OUT = ROOT / "bench" / "out"


def scene_list(difficulty: str, n: int) -> list[tuple[str, int]]:
    return [(KINDS[i % len(KINDS)], 1000 + i) for i in range(n)]


def _cache_paths(kind: str, seed: int, difficulty: str) -> tuple[Path, Path, Path]:
    d = CACHE / difficulty
    return d / f"{kind}-{seed}-1.png", d / f"{kind}-{seed}-2.png", d / f"{kind}-{seed}.npz"


def view_poses(scene, cell, roll_deg: float | None = None) -> list[np.ndarray]:
    """The product's two views (controller/cell/dry_run.py): across the seam, view 2 rolled."""
    from controller.cell.dry_run import VIEW2_ROLL_DEG
    from controller.geometry.poses import rotation_about

    poses = suggest_view_poses(scene, cell.camera)
    roll = VIEW2_ROLL_DEG if roll_deg is None else roll_deg
    poses[1] = poses[1] @ make_pose(rotation_about([0, 0, 1], np.radians(roll)))
    return poses


def third_view(scene, standoff_mm: float = 350.0, offset_mm: float = 100.0) -> np.ndarray:
    """A verification view displaced *along* the seam (the other two are displaced across it), so
    that the three flange rotations are not about one common axis."""
    from controller.geometry.poses import look_at

    P = scene.seam_points_mm
    centre = P[len(P) // 2]
    normal = scene.surface_normal
    chord = P[-1] - P[0]
    chord -= normal * (chord @ normal)
    chord /= np.linalg.norm(chord)
    across = np.cross(normal, chord)
    eye = centre + normal * np.sqrt(standoff_mm**2 - offset_mm**2) + chord * offset_mm
    return look_at(eye, centre, up=across)


def render_pair(args: tuple[str, int, str]) -> str:
    kind, seed, difficulty = args
    p1, p2, pz = _cache_paths(kind, seed, difficulty)
    if pz.exists():
        return "cached"
    pz.parent.mkdir(parents=True, exist_ok=True)
    cell = default_sim_cell()
    scene = make_scene(kind, seed, difficulty)
    poses = [*view_poses(scene, cell), third_view(scene)]
    p3 = p1.with_name(p1.name.replace("-1.png", "-3.png"))
    truth = {}
    for i, (T, p) in enumerate(zip(poses, (p1, p2, p3), strict=True)):
        r = render(scene, cell.camera, T, seed=seed)
        cv2.imwrite(str(p), r.image)
        truth[f"px{i}"] = r.seam_px
        truth[f"idx{i}"] = r.seam_index
        truth[f"T{i}"] = T
    np.savez(pz, **truth)
    return "rendered"


def load_pair(kind: str, seed: int, difficulty: str, views: int = 2):
    p1, p2, pz = _cache_paths(kind, seed, difficulty)
    p3 = p1.with_name(p1.name.replace("-1.png", "-3.png"))
    z = np.load(pz)
    imgs = [cv2.imread(str(p), cv2.IMREAD_GRAYSCALE) for p in (p1, p2, p3)[:views]]
    return (imgs, [z[f"px{i}"] for i in range(views)], [z[f"idx{i}"] for i in range(views)],
            [z[f"T{i}"] for i in range(views)])


def truth_metrics(P3: np.ndarray, truth: np.ndarray) -> dict[str, float]:
    """Errors of located points P3 against the true visible seam (mm) and its coverage."""
    d = PolylineDistance(truth)(P3)
    back = PolylineDistance(P3)(truth) if len(P3) > 1 else np.full(len(truth), np.inf)
    seg = np.linalg.norm(np.diff(truth, axis=0), axis=1)
    covered = (back[:-1] <= 1.0) & (back[1:] <= 1.0)
    ends = [min(np.linalg.norm(P3[0] - truth[0]), np.linalg.norm(P3[0] - truth[-1])),
            min(np.linalg.norm(P3[-1] - truth[0]), np.linalg.norm(P3[-1] - truth[-1]))]
    return {"rms_mm": float(np.sqrt(np.mean(d**2))), "max_mm": float(d.max()),
            "coverage": float(seg[covered].sum() / seg.sum()), "end_mm": float(max(ends))}


def observations(cam, poses, curves):
    return [ViewObservation(cam, T, c, f"view{i + 1}")
            for i, (T, c) in enumerate(zip(poses, curves, strict=True))]


def run_row(name, fn, pairs, cell):
    rows = []
    for kind, seed, diff in pairs:
        imgs, tpx, tidx, poses = load_pair(kind, seed, diff)
        scene = make_scene(kind, seed, diff)
        both = np.intersect1d(tidx[0], tidx[1])
        truth = scene.seam_points_mm[both]
        t0 = time.perf_counter()
        try:
            P3 = fn(imgs, tpx, poses, scene, cell)
            dt = time.perf_counter() - t0
            m = truth_metrics(P3, truth)
            m.update(ok=True, time_s=dt)
        except SeamguideError as err:
            m = {"ok": False, "error": type(err).__name__, "time_s": time.perf_counter() - t0}
        except Exception as err:  # noqa: BLE001 - a ported method crashing is a failure, not a stop
            m = {"ok": False, "error": f"crash: {type(err).__name__}",
                 "time_s": time.perf_counter() - t0}
        m.update(kind=kind, seed=seed, difficulty=diff)
        rows.append(m)
    return rows


def region(scene):
    return np.asarray(scene.centre_mm), scene.region_radius_mm + 20.0


def fn_oracle(imgs, tpx, poses, scene, cell, calib_cam=None, calib_T=None):
    cam = calib_cam or cell.camera
    T = calib_T or poses
    return locate_seam(observations(cam, T, tpx), nominal_region=region(scene)).dense_points_mm


def fn_ours(imgs, tpx, poses, scene, cell, calib_cam=None, calib_T=None):
    # As the cycle locates (controller/cell/guidance.py): each view's end kinds, gap width and
    # split-off band go with its centreline (until 2026-12-04 only the centrelines did).
    from controller.cell.guidance import ViewInput, observation

    cam = calib_cam or cell.camera
    T = calib_T or poses
    views = [ViewInput(f"view{i + 1}", im, cam, Ti) for i, (im, Ti) in enumerate(zip(imgs, T,
                                                                                     strict=True))]
    dets = detect_seams(imgs, camera=cam)
    return locate_seam([observation(v, d) for v, d in zip(views, dets, strict=True)],
                       nominal_region=region(scene)).dense_points_mm


def fn_pub_epi(imgs, tpx, poses, scene, cell):
    from published_stereo import epipolar_poly7

    curves = [d.points_px for d in detect_seams(imgs, camera=cell.camera)]
    return epipolar_poly7(cell.camera, curves[0], poses[0], curves[1], poses[1])


def fn_pub_rays(imgs, tpx, poses, scene, cell):
    from published_stereo import closest_rays

    curves = [d.points_px for d in detect_seams(imgs, camera=cell.camera)]
    return closest_rays(cell.camera, curves[0], poses[0], curves[1], poses[1])


def fn_pub_full(imgs, tpx, poses, scene, cell):
    from published_detect import published_detect
    from published_stereo import epipolar_poly7

    curves = [published_detect(im) for im in imgs]
    if any(c is None or len(c) < 8 for c in curves):
        raise SeamguideError("published detector found no seam")
    return epipolar_poly7(cell.camera, curves[0], poses[0], curves[1], poses[1])


def summarise(rows):
    ok = [r for r in rows if r["ok"]]
    good = [r for r in ok if r["max_mm"] <= 0.5 and r["coverage"] >= 0.98]
    def med(k):
        return (float(np.median([r[k] for r in ok])) if ok else float("nan"))
    return {"n": len(rows), "success": len(ok) / len(rows), "within_spec": len(good) / len(rows),
            "rms_mm_median": med("rms_mm"),
            "rms_mm_p95": float(np.percentile([r["rms_mm"] for r in ok], 95)) if ok else None,
            "max_mm_median": med("max_mm"), "coverage_median": med("coverage"),
            "end_mm_median": med("end_mm"),
            "wrong_but_returned": sum(r["max_mm"] > 2.0 for r in ok),
            "time_ms_median": 1000 * float(np.median([r["time_s"] for r in rows]))}


def perturbed(cell, kind: str, rng):
    """(camera, T_flange_cam) of a calibration that is off in one way."""
    cam, He = cell.camera, cell.T_flange_cam
    if kind == "handeye_0.3mm":
        d = rng.normal(size=3)
        return cam, He @ make_pose(np.eye(3), 0.3 * d / np.linalg.norm(d))
    if kind == "handeye_0.1deg":
        return cam, He @ make_pose(rotation_about(rng.normal(size=3), np.radians(0.1)))
    if kind == "focal_0.2pct":
        from controller.geometry.camera_model import CameraModel

        K = cam.K.copy()
        K[0, 0] *= 1.002
        K[1, 1] *= 1.002
        return CameraModel(cam.width, cam.height, K, cam.dist), He
    if kind == "handeye_5mm":
        d = rng.normal(size=3)
        return cam, He @ make_pose(np.eye(3), 5.0 * d / np.linalg.norm(d))
    raise ValueError(kind)


def gross_error_catch_rate(cell, n_scenes: int = 20, trials: int = 3) -> dict[str, dict]:
    """Share of 5 mm hand-eye errors (random directions) caught by the quality checks, for three
    view layouts, on the exact projected seam curves (geometry only, no rendering needed).

    Two views displaced across the seam differ by a rotation about one axis; a hand-eye offset is
    then equivalent to moving that axis, and the reconstruction shifts rigidly: nothing in the
    images can show it. Rolling view 2 about its optical axis breaks the symmetry.
    """
    from controller.cell.dry_run import VIEW2_ROLL_DEG

    layouts = {"2 views across the seam, same roll": (0.0, False),
               f"2 views, view 2 rolled {VIEW2_ROLL_DEG:.0f} deg (the default)":
                   (VIEW2_ROLL_DEG, False),
               "2 views, view 2 rolled 90 deg": (90.0, False),
               "3 views, same roll (third along the seam)": (0.0, True)}
    out = {}
    for name, (roll, third) in layouts.items():
        caught, errs = 0, []
        n = 0
        for i in range(n_scenes):
            kind = KINDS[i % len(KINDS)]
            scene = make_scene(kind, 2000 + i, "medium")
            P = scene.seam_points_mm
            poses = view_poses(scene, cell, roll)
            if third:
                poses.append(third_view(scene))
            curves = []
            for T in poses:
                uv = cell.camera.project(P, T)
                curves.append(uv[cell.camera.in_image(uv)])
            rng = np.random.default_rng(i)
            for _ in range(trials):
                d = rng.normal(size=3)
                He = cell.T_flange_cam @ make_pose(np.eye(3), 5.0 * d / np.linalg.norm(d))
                Tw = [T @ invert(cell.T_flange_cam) @ He for T in poses]
                n += 1
                try:
                    seam = locate_seam(observations(cell.camera, Tw, curves),
                                       nominal_region=region(scene))
                    e = PolylineDistance(P)(seam.dense_points_mm)
                    errs.append(float(np.sqrt(np.mean(e**2))))
                except TriangulationError:
                    caught += 1
        out[name] = {"trials": n, "caught": caught / n,
                     "uncaught_rms_mm_median": float(np.median(errs)) if errs else None}
    return out


def sensitivity(pairs, cell, kinds=("handeye_0.3mm", "handeye_0.1deg", "focal_0.2pct")):
    out = {}
    for k in kinds:
        rng = np.random.default_rng(7)
        res = {"oracle": [], "ours": []}
        views = 3 if k.endswith("3 views") else 2
        for kind, seed, diff in pairs:
            imgs, tpx, tidx, poses = load_pair(kind, seed, diff, views)
            scene = make_scene(kind, seed, diff)
            cam, He = perturbed(cell, k.split("/")[0], rng)
            T_wrong = [T @ invert(cell.T_flange_cam) @ He for T in poses]
            truth = scene.seam_points_mm[np.intersect1d(tidx[0], tidx[1])]
            for row, fn in (("oracle", fn_oracle), ("ours", fn_ours)):
                try:
                    P3 = fn(imgs, tpx, poses, scene, cell, calib_cam=cam, calib_T=T_wrong)
                    m = truth_metrics(P3, truth)
                    m["caught"] = False
                except TriangulationError:
                    m = {"caught": True}
                except SeamguideError as err:
                    m = {"caught": True, "error": type(err).__name__}
                res[row].append(m)
        out[k] = {row: {"caught": float(np.mean([m["caught"] for m in v])),
                        "rms_mm_median": float(np.median([m["rms_mm"] for m in v
                                                          if not m["caught"]] or [np.nan])),
                        "max_mm_median": float(np.median([m["max_mm"] for m in v
                                                          if not m["caught"]] or [np.nan]))}
                  for row, v in res.items()}
    return out


def plot_example(cell):
    from controller.cell.seam_plot import seam_plot_png

    kind, seed, diff = "nonplanar", 1001, "medium"
    pairs = [(k, s, diff) for k, s in scene_list(diff, 8) if k == "nonplanar"]
    kind, seed, _ = pairs[0]
    imgs, tpx, tidx, poses = load_pair(kind, seed, diff)
    scene = make_scene(kind, seed, diff)
    seam = locate_seam(observations(cell.camera, poses,
                                    [detect_seam(im, camera=cell.camera).points_px
                                     for im in imgs]), nominal_region=region(scene))
    err = PolylineDistance(scene.seam_points_mm)(seam.dense_points_mm)
    png = seam_plot_png(seam.dense_points_mm, error_mm=err,
                        title=f"{kind} seam (seed {seed}, {diff}): located vs truth, "
                              f"RMS {np.sqrt(np.mean(err**2)):.3f} mm")
    (ROOT / "docs" / "img").mkdir(parents=True, exist_ok=True)
    (ROOT / "docs" / "img" / "stereo_error.png").write_bytes(png)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--pairs", type=int, default=50)
    ap.add_argument("--difficulties", nargs="+", default=["easy", "medium", "hard"])
    ap.add_argument("--sensitivity-pairs", type=int, default=20)
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    cell = default_sim_cell()
    jobs = [(k, s, d) for d in args.difficulties for k, s in scene_list(d, args.pairs)]
    t0 = time.time()
    with ProcessPoolExecutor(args.workers) as ex:
        for i, st in enumerate(ex.map(render_pair, jobs), 1):
            if i % 10 == 0 or i == len(jobs):
                print(f"renders {i}/{len(jobs)} ({st}), {time.time() - t0:.0f} s", file=sys.stderr)
    results: dict = {"rows": {}, "per_difficulty": {}}
    fns = {"oracle": fn_oracle, "ours": fn_ours, "published epipolar+poly7 (our detections)":
           fn_pub_epi, "published closest rays (our detections)": fn_pub_rays,
           "published pipeline (published detector + epipolar+poly7)": fn_pub_full}
    for d in args.difficulties:
        pairs = [(k, s, d) for k, s in scene_list(d, args.pairs)]
        results["per_difficulty"][d] = {}
        for name, fn in fns.items():
            rows = run_row(name, fn, pairs, cell)
            results["per_difficulty"][d][name] = summarise(rows)
            results["rows"][f"{d}/{name}"] = rows
            s = results["per_difficulty"][d][name]
            print(f"{d:6} {name:58} success {s['success']:.0%} spec {s['within_spec']:.0%} "
                  f"rms {s['rms_mm_median']:.3f} max {s['max_mm_median']:.3f} "
                  f"cov {s['coverage_median']:.3f} {s['time_ms_median']:.0f} ms", file=sys.stderr)
    sens_pairs = [(k, s, "medium") for k, s in scene_list("medium", args.sensitivity_pairs)]
    results["sensitivity"] = sensitivity(sens_pairs, cell)
    results["gross_handeye_5mm"] = gross_error_catch_rate(cell)
    print(json.dumps({k: results[k] for k in ("sensitivity", "gross_handeye_5mm")}, indent=1),
          file=sys.stderr)
    plot_example(cell)
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "locate.json").write_text(json.dumps(results, indent=1, default=float))
    (OUT / "locate.md").write_text(markdown(results))
    print(markdown(results))
    return 0


def markdown(res) -> str:
    lines = ["| difficulty | method | success | within spec | 3D RMS (median) | max (median) | "
             "coverage | end error | time / pair |", "|---|---|---|---|---|---|---|---|---|"]
    for d, rows in res["per_difficulty"].items():
        for name, s in rows.items():
            lines.append(f"| {d} | {name} | {s['success']:.0%} | {s['within_spec']:.0%} | "
                         f"{s['rms_mm_median']:.3f} mm | {s['max_mm_median']:.3f} mm | "
                         f"{s['coverage_median']:.1%} | {s['end_mm_median']:.2f} mm | "
                         f"{s['time_ms_median']:.0f} ms |")
    lines += ["", "| calibration error (medium) | row | caught by quality checks | 3D RMS "
              "(median) | max (median) |", "|---|---|---|---|---|"]
    for k, rows in res["sensitivity"].items():
        for row, s in rows.items():
            lines.append(f"| {k} | {row} | {s['caught']:.0%} | {s['rms_mm_median']:.3f} mm | "
                         f"{s['max_mm_median']:.3f} mm |")
    lines += ["", "| hand-eye off by 5 mm (random directions) | trials | caught | 3D RMS of the "
              "uncaught (median) |", "|---|---|---|---|"]
    for k, s in res["gross_handeye_5mm"].items():
        un = s["uncaught_rms_mm_median"]
        lines.append(f"| {k} | {s['trials']} | {s['caught']:.0%} | "
                     f"{'-' if un is None else f'{un:.1f} mm'} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    raise SystemExit(main())
