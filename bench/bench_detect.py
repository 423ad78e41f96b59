"""Seam detection benchmark: ours vs the published method on rendered scenes, by split.

Usage (from the repository root)::

    .venv/bin/python -m bench.bench_detect [--quick] [--split tuning|heldout|both]
        [--difficulty easy medium hard] [--sets classic wide pen] [--pairs N]
        [--tuning-pairs N] [--pen-pairs N] [--classic N] [--timing-runs 10] [--jobs 2]
        [--render-only] [--out bench/out/detect.json]

Scenes (bench/detect_cases.py): the classic set as before (52 views per difficulty, seeds 0-51);
the ``wide`` set (wide-look scenes, drivers/sim/sim_look.py) as pairs of views, 100 pairs per
difficulty on the held-out part and 50 on the tuning part (every view also counts as a single
view: 200 and 100 views); the ``pen`` set (1-3 lines parallel to the joint), 25 pairs (50 views)
per part. ``--quick``: 8 classic views, 10 wide pairs per difficulty and part, 6 pen pairs.
Renders are cached under bench/cache/detect/ (git-ignored; ``SEAMGUIDE_DETECT_CACHE=DIR`` uses
another folder, e.g. another worktree's cache), rendered by a pool of ``--jobs``
processes (about 1.5-3 s per 2272x1704 image on an idle machine, several times that when it is
shared).

Each view goes to our detector (with the camera's calibration, no region of interest, no nominal
seam) and to the published method's port (bench/published_detect.py): **found**, **refused**
(SeamNotFound / AmbiguousSeam / any SeamguideError) or **wrong** (bench/detect_score.py: not on
the true seam within tolerance, short of its ends, the wrong end kinds, or the pen line). Each
pair of our detections is triangulated with the exact calibration as the cycle does
(controller.stereo.locate with each view's end kinds and gap width, the scene's nominal region
as the job would give it, unseen ends not clipped): **located** (every point within 0.5 mm of the
true seam both views see, covering >= 90 % of it), **partial** (within 0.5 mm, shorter),
**wrong** (a point off by more than 1 mm) or **refused**; and again with a job that clips the
ends no view sees to that region (``[seam] clip_unseen_ends``; a seam that leaves both images
can only be located so). Then a reliability table (confidence
bins vs the share of returned seams that were found) and the time per 2272x1704 image as a ratio
to ``cv2.Canny(grey, 50, 150)`` on the same image in the same run (the three alternating).
Writes ``--out`` (JSON) and the README tables next to it (``.md``).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from collections.abc import Iterator
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from bench.detect_cases import (
    FULL,
    QUICK,
    case_cached,
    libraries,
    load_case,
    make_case_scene,
    plan,
    render_case,
    render_order,
    rendered_with,
    view_truth,
)
from bench.detect_score import end_kinds_of, score_view
from bench.published_detect import published_detect
from controller.cell.other_view import seam_from_other_view
from controller.errors import AmbiguousSeam, SeamguideError, SeamNotFound
from controller.geometry.camera_model import default_camera
from controller.stereo.locate import ViewObservation, locate_seam
from controller.stereo.triangulate import PolylineDistance
from controller.vision.seam_detect import DetectParams, detect_seam
from controller.vision.seam_edge_ends import one_image_answer
from controller.vision.seam_lines import measured_lines

BINS = (0.0, 0.5, 0.6, 0.7, 0.8, 0.9, 0.95, 0.99, 1.0001)


def _detect(name: str, img: np.ndarray, cam: Any, params: Any = None,
            hint: Any = None) -> dict[str, Any]:
    # ``params``: ours' DetectParams (None: the defaults, as the benchmark measures); ``hint``:
    # the job's nominal seam in the view (px; None: none, as the benchmark measures).
    t0 = time.perf_counter()
    try:
        if name == "ours":
            det = detect_seam(img, camera=cam, params=params, hint=hint)
            pts, conf, kinds = det.points_px, float(det.confidence), end_kinds_of(det)
            width: float | None = det.gap_width_px
            way = str(det.stats.get("way", ""))
            band = None if det.band_px is None else (det.band_px, det.band_width_px)
            try:  # what `seamguide detect` answers from this image alone
                one_image_answer(det, params or DetectParams(), (0, 0, img.shape[1], img.shape[0]))
                alone = None
            except (AmbiguousSeam, SeamNotFound) as err:
                alone = f"{type(err).__name__}: {str(err)[:600]}"
            stats: dict[str, Any] = {k: v for k, v in det.stats.items() if k != "way"}
            stats["ends_px"] = np.round(det.endpoints_px, 1).tolist()
        else:
            pts, conf, kinds, width, way = published_detect(img), 1.0, None, None, ""
            band, alone = None, None
            stats = {}
    except SeamguideError as err:
        return {"result": "refused", "error": f"{type(err).__name__}: {str(err)[:600]}",
                "time_s": time.perf_counter() - t0}
    except Exception as err:  # noqa: BLE001 - a crash is a result to count, not a stop
        return {"result": "crash", "error": f"{type(err).__name__}: {str(err)[:600]}",
                "time_s": time.perf_counter() - t0}
    return {"result": "returned", "points": pts, "confidence": conf, "kinds": kinds,
            "width_px": width, "way": way, "stats": stats, "band": band,
            "alone": alone, "time_s": time.perf_counter() - t0}


def single_view(r: dict[str, Any]) -> dict[str, Any]:
    """A scored ``_detect`` result as ``seamguide detect`` answers: refused where the image alone
    gives no answer (``seam_edge_ends.one_image_answer``: two readings of a shadow split off
    without the job's gap, or an end called the image border left inside the image), with what
    the seam returned would have scored (``core_result``). The cycle still locates with it
    (``_locate``)."""
    if not r.get("alone"):
        r.pop("alone", None)
        return r
    return {"result": "refused", "error": r["alone"], "time_s": r["time_s"],
            "core_result": r["result"], "split": bool(r.get("split"))}


def run_case(case: tuple[str, str, str, int], cam: Any = None) -> dict[str, Any]:
    """Detect in every view of a case (both detectors) and locate the pair (ours)."""
    cam = cam or default_camera()
    imgs, z = load_case(case)
    row: dict[str, Any] = {"case": list(case), "family": str(z["family"]), "views": [],
                           "scene": scene_features(case)}
    curves: list[np.ndarray] = []
    widths: list[float | None] = []
    kinds: list[tuple[str, str] | None] = []
    bands: list[tuple[np.ndarray, float] | None] = []
    refused: list[int] = []  # views ours refused (seam not found, ambiguous)
    for i, img in enumerate(imgs):
        truth = view_truth(z, i, img)
        v: dict[str, Any] = {"gap_px": truth["gap_px"], "end_kinds": truth["end_kinds"],
                             "spans": len(truth["spans"]), "pens": len(truth["pens"])}
        for name in ("ours", "published"):
            r = _detect(name, img, cam)
            if name == "ours" and r["result"] == "refused" and r["error"].startswith(
                    (SeamNotFound.__name__, AmbiguousSeam.__name__)):
                refused.append(i)
            if r["result"] == "returned":
                said = r.pop("kinds")
                r.update(score_view(r["points"], truth, said))
                if name == "ours":
                    curves.append(r["points"])
                    widths.append(r["width_px"])
                    bands.append(r["band"])
                    kinds.append(tuple(said) if said and len(said) == 2 else None)
                r.pop("points")
            w = r.pop("width_px", None)
            if name == "ours" and w is not None:
                r["width_px"] = round(float(w), 2)  # the detected band's median width
            if r.pop("band", None) is not None:
                r["split"] = True  # a shadow split off: the whole band's reading came along
            v[name] = single_view(r)
        row["views"].append(v)
    if len(imgs) == 2:
        lines = (measured_lines(imgs[refused[0]], camera=cam)
                 if len(curves) == 1 and len(refused) == 1 else None)
        # Without, then with a job that lets the seam be clipped to its nominal region where no
        # view sees an end ([seam] clip_unseen_ends): how long seams are welded.
        for key, clip in (("pair", False), ("pair_clip", True)):
            if len(curves) == 2:
                row[key] = _locate(z, curves, widths, kinds, cam, clip=clip, bands=bands)
            elif lines is not None:
                row[key] = _other_view_pair(z, lines, refused[0], curves[0], widths[0],
                                            kinds[0], bands[0], cam, clip)
            else:
                row[key] = {"result": "refused"}
        row["pair"]["ends_seen"] = all(k == "joint_end" for v in row["views"]
                                       for k in v["end_kinds"])
    return row


def _other_view_pair(z: dict[str, Any], lines: list[Any], b: int, curve: np.ndarray,
                     width: float | None, kind: tuple[str, str] | None,
                     band: tuple[np.ndarray, float] | None, cam: Any, clip: bool
                     ) -> dict[str, Any]:
    # As the cycle does where one view is refused (controller/cell/guidance.py): the refused
    # view's line whose ends meet the other view's seam (controller/cell/other_view.py), then
    # the pair located and scored as any other.
    a = 1 - b
    found = ViewObservation(cam, z[f"T{a}"], curve, f"view{a + 1}", kind, width,
                            None if band is None else band[0], None if band is None else band[1])
    like = ViewObservation(cam, z[f"T{b}"], curve, f"view{b + 1}")
    region = (np.asarray(z["centre_mm"]), float(z["radius_mm"]) + 20.0)
    other = seam_from_other_view(lines, like, found, b == 0, lambda views: locate_seam(
        views, nominal_region=region, clip_unseen_ends=clip))
    if other is None:
        return {"result": "refused", "other_view_lines": len(lines)}
    obs = other.observation
    curves, widths, kinds = [curve, curve], [width, width], [kind, kind]
    bands: list[tuple[np.ndarray, float] | None] = [None, None]
    curves[b], widths[b], kinds[b], bands[a] = obs.seam_px, obs.gap_width_px, obs.end_kinds, band
    out = _locate(z, curves, widths, kinds, cam, clip=clip, bands=bands)
    out["other_view"] = True
    return out


def scene_features(case: tuple[str, str, str, int]) -> dict[str, Any]:
    """What a case's scene has that the wrong seams are counted by (the look's parameters).

    ``table``: the table kind; ``step_shadow``: a higher plate edge casts a shadow band beside
    the gap; ``shadow_vs_floor``: that shadow's reflectance (the shadowed sheet's albedo times
    the shadow's darkening) over the gap floor's (1 or less: the shadow is no brighter than the
    floor, so no profile across the band can tell the gap from it). ``corner_mm``: the radius of
    the plates' rounded corners at the joint's ends (0: square corners).
    """
    scene = make_case_scene(case)
    look = scene.look
    if look is None:
        return {"table": "classic", "step_shadow": False, "corner_mm": 0.0}
    out: dict[str, Any] = {"table": look.table, "step_shadow": look.step_shadow_mm > 0,
                           "corner_mm": round(float(look.corner_mm), 2)}
    if out["step_shadow"]:
        albedo = scene.albedo_a if look.step_side < 0 else scene.albedo_b
        out["shadow_vs_floor"] = round(albedo * (1.0 - look.step_depth)
                                       / max(scene.gap_floor, 1e-6), 2)
    return out


def _locate(z: dict[str, Any], curves: list[np.ndarray], widths: list[float | None],
            kinds: list[tuple[str, str] | None], cam: Any, clip: bool = False,
            bands: list[tuple[np.ndarray, float] | None] | None = None,
            nominal_line: tuple[np.ndarray, float] | None = None) -> dict[str, Any]:
    # As the cycle locates (controller/cell/guidance.py): with each view's end kinds, width and
    # split-off band (``bands``: (band_px, width px) or None per view); ``clip``: the job allows
    # clipping ends no view sees to its nominal region; ``nominal_line``: the job's drawn seam
    # (mm) and its tolerance (mm), the 3D seam held to it.
    both = np.intersect1d(z["seam_index0"], z["seam_index1"])
    truth = z["seam_points_mm"][both]
    bands = bands or [None] * len(curves)
    views = [ViewObservation(cam, z[f"T{i}"], c, f"view{i + 1}", k, w,
                             None if b is None else b[0], None if b is None else b[1])
             for i, (c, w, k, b) in enumerate(zip(curves, widths, kinds, bands, strict=True))]
    t0 = time.perf_counter()
    try:
        seam = locate_seam(views, nominal_region=(np.asarray(z["centre_mm"]),
                                                  float(z["radius_mm"]) + 20.0),
                           clip_unseen_ends=clip, nominal_line=nominal_line)
    except SeamguideError as err:
        return {"result": "refused", "error": f"{type(err).__name__}: {str(err)[:600]}"}
    dt = time.perf_counter() - t0
    P3 = seam.dense_points_mm
    if len(truth) < 2:
        return {"result": "wrong", "why": "no common seam in view", "time_s": dt}
    d = PolylineDistance(truth)(P3)
    back = PolylineDistance(P3)(truth) if len(P3) > 1 else np.full(len(truth), np.inf)
    seg = np.linalg.norm(np.diff(truth, axis=0), axis=1)
    cov = float(seg[(back[:-1] <= 0.5) & (back[1:] <= 0.5)].sum() / seg.sum())
    res = "located" if d.max() <= 0.5 and cov >= 0.9 else (
        "partial" if d.max() <= 1.0 else "wrong")
    return {"result": res, "rms_mm": float(np.sqrt(np.mean(d**2))), "max_mm": float(d.max()),
            "coverage": cov, "time_s": dt, "band_reading": seam.quality.get("band_reading")}


def summarise(rows: list[dict[str, Any]], name: str) -> dict[str, Any]:
    """Counts of one detector's single-view results over rows (and ours' pairs)."""
    views = [v[name] for r in rows for v in r["views"]]
    out: dict[str, Any] = {"views": len(views)}
    for k in ("found", "refused", "wrong", "crash"):
        out[k] = sum(v["result"] == k for v in views)
    out["wrong_pen"] = sum(v.get("why") == "pen line" for v in views)
    # Found with a joint end at the image border reported as the image border (detect_score).
    out["found_end_at_border"] = sum(v["result"] == "found" and v.get("kind_near_border", 0) > 0
                                     for v in views)
    out["wrong_why"] = sorted({v.get("why", "") for v in views if v["result"] == "wrong"})
    out["split"] = sum(bool(v.get("split")) for v in views)
    pairs = [r["pair"] for r in rows if "pair" in r]
    if name == "ours" and pairs:
        out["pairs"] = len(pairs)
        for k in ("located", "partial", "wrong", "refused"):
            out[f"pairs_{k}"] = sum(p["result"] == k for p in pairs)
        seen = [p for p in pairs if p["ends_seen"]]
        out["pairs_ends_seen"] = len(seen)
        out["pairs_ends_seen_located"] = sum(p["result"] == "located" for p in seen)
        # Pairs with both views split, by the reading the views agreed on (stereo.band_check).
        read = [str((p.get("band_reading") or {}).get("reading")) for p in pairs]
        out["pairs_band_read"] = {k: read.count(k) for k in sorted(set(read)) if k != "None"}
        rms = [p["rms_mm"] for p in pairs if p["result"] == "located"]
        out["pairs_rms_mm_median"] = float(np.median(rms)) if rms else None
        clip = [r["pair_clip"] for r in rows if "pair_clip" in r]  # reports before 2026-12-03
        if clip:
            for k in ("located", "partial", "wrong"):
                out[f"pairs_clip_{k}"] = sum(p["result"] == k for p in clip)
        # Pairs with one view refused, located with its line the other view's seam chose
        # (controller/cell/other_view.py): by result, without and with clipping.
        for key, ps in (("pairs_other_view", pairs), ("pairs_clip_other_view", clip)):
            got = [p["result"] for p in ps if p.get("other_view")]
            out[key] = {k: got.count(k) for k in sorted(set(got))}
    return out


def reliability(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Confidence bins vs the share of our returned seams that were found."""
    ret = [v["ours"] for r in rows for v in r["views"] if v["ours"].get("confidence") is not None]
    out = []
    for lo, hi in zip(BINS[:-1], BINS[1:], strict=True):
        b = [v for v in ret if lo <= v["confidence"] < hi]
        out.append({"bin": [lo, min(hi, 1.0)], "n": len(b),
                    "found": sum(v["result"] == "found" for v in b),
                    "wrong": sum(v["result"] == "wrong" for v in b)})
    return out


#: The sets whose views the per-look, per-way, per-width, per-feature and reliability tables
#: count together under the part's name; any other set's views are counted apart, under
#: "SET PART" (a run with the rough or T-corner set does not change the wide and pen rows).
POOLED = ("wide", "pen")


def part_of(key: str) -> str:
    """The part a row key (``set/difficulty/part``) is counted under in the tables: the part
    for the wide and pen sets, ``"SET PART"`` for any other."""
    kind_set, part = key.split("/", 1)[0], key.rsplit("/", 1)[-1]
    return part if kind_set in POOLED else f"{kind_set} {part}"


def _our_single_views(rows: dict[str, list[dict[str, Any]]]
                      ) -> Iterator[tuple[str, str, dict[str, Any]]]:
    """(part as :func:`part_of`, look family, our result) of every non-classic single view."""
    for key, rs in rows.items():
        if key.startswith("classic"):
            continue
        part = part_of(key)
        for r in rs:
            for v in r["views"]:
                yield part, r["family"], v["ours"]


def by_look(rows: dict[str, list[dict[str, Any]]]) -> dict[str, dict[str, int]]:
    """Our single views of the wide and pen sets per look family and part: found, refused, wrong.

    The family is the scene's look (``plain``, ``shop``: the photographs' imitation with tack
    welds, ground strips and rust, ``closeup``: dark defocused close-ups), so that a look the
    detector fails on shows however the difficulties mix it.
    """
    out: dict[str, dict[str, int]] = {}
    for part, family, o in _our_single_views(rows):
        cell = out.setdefault(f"{family}/{part}",
                              {"views": 0, "found": 0, "refused": 0, "wrong": 0, "crash": 0})
        cell["views"] += 1
        cell[o["result"]] += 1
    return dict(sorted(out.items()))


def wrong_by_scene(rows: dict[str, list[dict[str, Any]]]) -> dict[str, dict[str, int]]:
    """Our single views of the wide and pen sets per part and scene feature: views, found, wrong.

    Features (:func:`scene_features`): each table kind, a step shadow beside the gap (split
    into one at least as dark as the gap floor and one lighter), and per view whether a joint
    end is in view and the plates' corners there are rounded or square: where the wrong seams
    and the refusals come from, whatever the difficulty.
    """
    out: dict[str, dict[str, int]] = {}
    for key, rs in rows.items():
        if key.startswith("classic"):
            continue
        part = part_of(key)
        for r in rs:
            for v in r["views"]:
                for feat in view_features(r.get("scene", {}), v):
                    cell = out.setdefault(f"{feat}/{part}", {"views": 0, "found": 0, "wrong": 0})
                    cell["views"] += 1
                    if v["ours"]["result"] in ("found", "wrong"):
                        cell[v["ours"]["result"]] += 1
    return dict(sorted(out.items()))


def view_features(scene: dict[str, Any], view: dict[str, Any]) -> list[str]:
    """The names a view is counted under in :func:`wrong_by_scene` (and picked by in the gallery).

    ``scene``: a row's :func:`scene_features`; ``view``: the report's view (its true
    ``end_kinds``). ``table KIND``, ``step shadow: none|as dark as the floor|lighter``, and
    ``plate corners: no joint end in view|a joint end in view, rounded|..., square`` (not for
    a report written before ``corner_mm`` was recorded).
    """
    shadow = "none"
    if scene.get("step_shadow"):
        shadow = "as dark as the floor" if scene["shadow_vs_floor"] <= 1.0 else "lighter"
    out = [f"table {scene.get('table', '?')}", f"step shadow: {shadow}"]
    if "corner_mm" in scene:
        corner = "no joint end in view"
        if "joint_end" in view.get("end_kinds", ()):
            corner = ("a joint end in view, rounded" if scene["corner_mm"] > 0
                      else "a joint end in view, square")
        out.append(f"plate corners: {corner}")
    return out


def by_way(rows: dict[str, list[dict[str, Any]]]) -> dict[str, dict[str, int]]:
    """Our returned single views of the wide and pen sets per way and part: found, wrong.

    The way is how the seam was found (``profiles``: the two-edge profile model; ``valley
    path``: the whole-image valley path, when the first refused): how far each can be trusted.
    """
    out: dict[str, dict[str, int]] = {}
    for part, _, o in _our_single_views(rows):
        if o["result"] in ("found", "wrong"):
            cell = out.setdefault(f"{o.get('way') or '?'}/{part}",
                                  {"returned": 0, "found": 0, "wrong": 0})
            cell["returned"] += 1
            cell[o["result"]] += 1
    return dict(sorted(out.items()))


#: Bins (px, detected median band width) of :func:`by_width`.
WIDTH_BINS = (0.0, 3.0, 5.0, 8.0, 12.0, 16.0, float("inf"))


def by_width(rows: dict[str, list[dict[str, Any]]]) -> dict[str, dict[str, int]]:
    """Our returned single views of the wide and pen sets per detected band width and part.

    The width is the returned seam's median dark-band width (px, ``gap_width_px``): the wider
    the band, the more room for a shadow, a cut face or a mark inside it beside the gap, and for
    an end read a few px off; how far a returned seam can be trusted by its width.
    """
    counts: dict[tuple[str, int], dict[str, int]] = {}
    for part, _, o in _our_single_views(rows):
        if o["result"] not in ("found", "wrong") or o.get("width_px") is None:
            continue
        i = int(np.searchsorted(WIDTH_BINS, o["width_px"], side="right")) - 1
        cell = counts.setdefault((part, i), {"returned": 0, "found": 0, "wrong": 0})
        cell["returned"] += 1
        cell[o["result"]] += 1
    out = {}
    for part, i in sorted(counts):
        lo, hi = WIDTH_BINS[i], WIDTH_BINS[i + 1]
        name = f"{lo:.0f}-{hi:.0f} px" if np.isfinite(hi) else f">= {lo:.0f} px"
        out[f"{name}/{part}"] = counts[(part, i)]
    return out


def timing(images: list[np.ndarray], runs: int, cam: Any) -> dict[str, Any]:
    """Median ms of ours, the published port and cv2.Canny on the same images, alternating."""
    greys = [im if im.ndim == 2 else cv2.cvtColor(im, cv2.COLOR_BGR2GRAY) for im in images]
    fns = {"ours": lambda im, g: _detect("ours", im, cam),
           "published": lambda im, g: _detect("published", im, cam),
           "canny": lambda im, g: cv2.Canny(g, 50, 150)}
    t: dict[str, list[float]] = {k: [] for k in fns}
    ratio: dict[str, list[float]] = {"ours": [], "published": []}
    for _ in range(runs):
        for im, g in zip(images, greys, strict=True):
            one = {}
            for k, fn in fns.items():
                t0 = time.perf_counter()
                fn(im, g)
                one[k] = 1000 * (time.perf_counter() - t0)
                t[k].append(one[k])
            for k in ratio:
                ratio[k].append(one[k] / one["canny"])
    return {**{f"{k}_ms": statistics.median(v) for k, v in t.items()},
            **{f"{k}_over_canny": statistics.median(v) for k, v in ratio.items()},
            "images": len(images), "runs": runs}


def _git(*args: str) -> str:
    try:
        return subprocess.run(["git", *args], capture_output=True, text=True, check=True,
                              cwd=Path(__file__).resolve().parent.parent).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "?"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--split", choices=["tuning", "heldout", "both"], default="both")
    ap.add_argument("--difficulty", nargs="+", default=["easy", "medium", "hard"])
    ap.add_argument("--sets", nargs="+", default=["classic", "wide", "pen"])
    ap.add_argument("--pairs", type=int, help="wide pairs per difficulty, held-out part")
    ap.add_argument("--tuning-pairs", type=int, help="wide pairs per difficulty, tuning part")
    ap.add_argument("--pen-pairs", type=int, help="pen pairs per part")
    ap.add_argument("--tee-pairs", type=int,
                    help="T-corner close-up pairs per part (with --sets ... tee)")
    ap.add_argument("--rough-pairs", type=int,
                    help="rough-sheet pairs per part (with --sets ... rough)")
    ap.add_argument("--strip-pairs", type=int,
                    help="ground-strip pairs per part (with --sets ... strip)")
    ap.add_argument("--classic", type=int, help="classic views per difficulty")
    ap.add_argument("--timing-runs", type=int, default=10, help="0: no timing")
    ap.add_argument("--jobs", type=int, default=min(2, os.cpu_count() or 1))
    ap.add_argument("--render-only", action="store_true")
    ap.add_argument("--cached-only", action="store_true",
                    help="use only the cases already rendered (a run cut short by the clock)")
    ap.add_argument("--out", default="bench/out/detect.json")
    args = ap.parse_args(argv)
    sizes = dict(QUICK if args.quick else FULL)
    for key, val in (("wide/heldout", args.pairs), ("wide/tuning", args.tuning_pairs),
                     ("pen", args.pen_pairs), ("tee", args.tee_pairs), ("rough", args.rough_pairs),
                     ("strip", args.strip_pairs),
                     ("classic", args.classic)):
        if val is not None:
            sizes[key] = val
    splits = ["tuning", "heldout"] if args.split == "both" else [args.split]
    groups = plan(sizes, args.difficulty, splits, args.sets)
    if args.cached_only:
        groups = {k: [c for c in g if case_cached(c)] for k, g in groups.items()}
        sizes = {f"{k} (cached)": len(g) for k, g in groups.items()}
    cases = render_order(groups)
    t0 = time.time()
    with ProcessPoolExecutor(args.jobs) as ex:
        for i, st in enumerate(ex.map(render_case, cases), 1):
            if st == "rendered" and i % 10 == 0:
                print(f"rendered {i}/{len(cases)}, {time.time() - t0:.0f} s", file=sys.stderr)
    t_render = time.time() - t0
    if args.render_only:
        print(f"{len(cases)} cases rendered or cached in {t_render:.0f} s", file=sys.stderr)
        return 0
    cam = default_camera()
    t1 = time.time()
    # Detection in the pool too (timing is measured apart, below, in this process alone).
    with ProcessPoolExecutor(args.jobs) as ex:
        done = iter(ex.map(run_case, cases))
        by_case = {tuple(c): next(done) for c in cases}
    rows = {key: [by_case[tuple(c)] for c in g] for key, g in groups.items()}
    t_detect = time.time() - t1
    report: dict[str, Any] = {
        "sizes": sizes, "render_s": t_render, "detect_s": t_detect,
        "commit": _git("rev-parse", "--short", "HEAD"),
        "detector_commit": _git("log", "-1", "--format=%h (%cd)", "--date=format:%H:%M",
                                "--", "controller/vision"),
        "libraries": libraries(), "rendered_with": rendered_with(cases),
        "summary": {key: {n: summarise(r, n) for n in ("ours", "published")}
                    for key, r in rows.items()},
        "reliability": {part: reliability([r for key, rs in rows.items() for r in rs
                                           if part_of(key) == part])
                        for part in dict.fromkeys(part_of(k) for k in rows
                                                  if not k.startswith("classic"))},
        "by_look": by_look(rows),
        "by_way": by_way(rows),
        "by_width": by_width(rows),
        "wrong_by_scene": wrong_by_scene(rows),
        "rows": rows}
    timing_imgs = [load_case(g[0])[0][0] for g in groups.values() if g][:6]
    if args.timing_runs > 0:  # 0: accuracy only
        report["timing"] = timing(timing_imgs, args.timing_runs, cam)
    report["total_s"] = time.time() - t0
    md = markdown(report)
    print(md)
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(report, indent=1, default=float))
    Path(args.out).with_suffix(".md").write_text(md)
    return 0


def _clip_cell(x: dict[str, Any]) -> str:
    """located (share) / partial / wrong of the pairs located with unseen ends clipped."""
    if "pairs_clip_located" not in x:
        return "-"
    return (f"{_pct(x['pairs_clip_located'], x['pairs'])} / {x['pairs_clip_partial']} / "
            f"{x['pairs_clip_wrong']}")


def _pct(a: int, n: int) -> str:
    return f"{a}/{n} ({100 * a / n:.0f} %)" if n else "-"


def _count_table(title: str, first: str, cells: dict[str, dict[str, int]], total: str,
                 rest: tuple[str, ...]) -> list[str]:
    """Markdown lines of a table of counts per key: key, ``total``, found (share), ``rest``."""
    out = ["", title, "", f"| {first} / part | {total} | found | " + " | ".join(rest) + " |",
           "|---|" + "---|" * (2 + len(rest))]
    for key, c in cells.items():
        out.append(f"| {key} | {c[total]} | {_pct(c['found'], c[total])} | "
                   + " | ".join(str(c[k]) for k in rest) + " |")
    return out


def _reliability_lines(rel: dict[str, list[dict[str, Any]]]) -> list[str]:
    """Markdown lines of the reliability table, a column per part; none for a run without any
    non-classic view (the classic set is not counted in it)."""
    if not rel:
        return []
    out = ["", "Reliability (ours, single views of the wide and pen sets; any other set in a "
           "column of its own): share of returned seams found per confidence bin.", "",
           "| confidence | " + " | ".join(rel) + " |", "|---|" + "---|" * len(rel)]
    for i, lo_hi in enumerate(BINS[:-1]):
        cells = [f"{b['found']}/{b['n']} found, {b['wrong']} wrong" if b["n"] else "-"
                 for b in (rel[part][i] for part in rel)]
        out.append(f"| {lo_hi:.2f}-{min(BINS[i + 1], 1.0):.2f} | " + " | ".join(cells) + " |")
    return out


def markdown(rep: dict[str, Any]) -> str:
    """The README tables of a report."""

    lines = [f"Detector: commit {rep['detector_commit']} (tree {rep['commit']}). Render "
             f"{rep['render_s']:.0f} s (cached renders are not redone), detection and scoring "
             f"{rep['detect_s']:.0f} s, whole run {rep['total_s']:.0f} s. Detected with "
             f"{rep.get('libraries', '?')}; views rendered with "
             + ", ".join(f"{k} ({n} cases)" for k, n in rep.get("rendered_with", {}).items())
             + ".", "",
             "| set / difficulty / part | detector | views | found (of them, a joint end at the "
             "image border called image_border) | refused | wrong (pen line) | crash |",
             "|---|---|---|---|---|---|---|"]
    for key, s in rep["summary"].items():
        for name in ("ours", "published"):
            x = s[name]
            lines.append(f"| {key} | {name} | {x['views']} | {_pct(x['found'], x['views'])} "
                         f"({x.get('found_end_at_border', 0)}) | {x['refused']} | "
                         f"{x['wrong']} ({x['wrong_pen']}) | {x['crash']} |")
    lines += ["", "| pairs: set / difficulty / part | pairs | located | partial | wrong | "
              "refused | located, both ends seen in both views | 3D RMS median (located) | "
              "the job clipping unseen ends: located / partial / wrong |",
              "|---|---|---|---|---|---|---|---|---|"]
    for key, s in rep["summary"].items():
        x = s["ours"]
        if "pairs" in x:
            rms = "-" if x["pairs_rms_mm_median"] is None else f"{x['pairs_rms_mm_median']:.3f} mm"
            lines.append(f"| {key} | {x['pairs']} | {_pct(x['pairs_located'], x['pairs'])} | "
                         f"{x['pairs_partial']} | {x['pairs_wrong']} | {x['pairs_refused']} | "
                         f"{_pct(x['pairs_ends_seen_located'], x['pairs_ends_seen'])} | {rms} | "
                         f"{_clip_cell(x)} |")
    split = {k: (s["ours"].get("split", 0), s["ours"].get("pairs_band_read", {}))
             for k, s in rep["summary"].items() if s["ours"].get("split")}
    if split:
        lines += ["", "Shadow splits (ours): views whose dark band was split into gap and shadow; "
                  "pairs with both views split, by the reading the two views agreed on "
                  "(core: a shadow beside the gap; band: a cut face inside it): " + "; ".join(
                      f"{k} {n} views, pairs {r or '-'}" for k, (n, r) in split.items()) + "."]
    lines += _reliability_lines(rep["reliability"])
    for key, title, first, total, rest in (
            ("by_look", "per look (single views", "look", "views", ("refused", "wrong")),
            ("by_way", "per way (returned single views", "way", "returned", ("wrong",)),
            ("by_width", "by the detected band's width (returned single views", "width",
             "returned", ("wrong",)),
            ("wrong_by_scene", "by what the scene had (single views", "scene feature", "views",
             ("wrong",))):
        if rep.get(key):
            lines += _count_table(f"Ours {title} of the wide and pen sets; any other set in "
                                  "rows of its own):", first, rep[key],
                                  total, rest)
    t = rep.get("timing")
    if t is None:
        return "\n".join(lines) + "\n"
    lines += ["", f"Time per 2272x1704 image ({t['images']} images x {t['runs']} runs, the three "
              f"alternating): ours {t['ours_ms']:.1f} ms = **{t['ours_over_canny']:.2f} x "
              f"cv2.Canny** ({t['canny_ms']:.1f} ms), published port {t['published_ms']:.1f} ms "
              f"= {t['published_over_canny']:.2f} x Canny (medians of the per-run ratios)."]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    sys.exit(main())
