"""Training data for the learned look check (controller/vision/seam_look_model.py): every refined
seam candidate the detector weighs on the tuning part of the benchmark's scenes, its look features
and whether it lies on the joint.

Only the tuning part is read (``split`` is fixed): the held-out part is never trained or tuned on.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from bench.detect_cases import case_cached, load_case, plan, view_truth
from bench.detect_score import score_view
from controller.errors import SeamguideError
from controller.geometry.camera_model import default_camera
from controller.vision import seam_detect
from controller.vision.seam_look import FEATURE_NAMES, look_features

OUT = Path(__file__).resolve().parent / "out" / "seam_look_data.npz"


def _candidates_of(img: np.ndarray) -> list[list[Any]]:
    """Run the detector on ``img``; the candidate lists it weighed (one list per decision)."""
    seen: list[list[Any]] = []
    real = seam_detect.choose

    def spy(cands: list[Any], *a: Any, **k: Any) -> Any:
        seen.append(list(cands))
        return real(cands, *a, **k)

    seam_detect.choose = spy  # type: ignore[assignment]
    try:
        seam_detect.detect_seam(img, camera=default_camera())
    except SeamguideError:
        pass
    finally:
        seam_detect.choose = real  # type: ignore[assignment]
    return seen


def label(points: np.ndarray, truth: dict[str, Any]) -> int:
    """2: the joint, found as the benchmark scores it; 1: on the joint but part of it or other
    ends; 0: not on the joint."""
    r = score_view(points, truth)
    if r["result"] == "found":
        return 2
    return 1 if r.get("why") in ("partial", "end kind") else 0


def case_rows(case: tuple[str, str, str, int]) -> list[tuple[list[float], int, str, int, int]]:
    """(features, label, case name, view, decision) of every refined candidate of a case."""
    imgs, z = load_case(case)
    rows = []
    for i, img in enumerate(imgs):
        t = view_truth(z, i)
        grey = img if img.ndim == 2 else cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
        for k, cands in enumerate(_candidates_of(img)):
            for c in cands:
                if c.points is None or len(c.points) < 2:
                    continue
                rows.append((look_features(grey, c).tolist(), label(c.points, t),
                             "/".join(map(str, case)), i, k))
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--wide", type=int, default=110, help="wide tuning pairs per difficulty")
    ap.add_argument("--pen", type=int, default=60, help="pen tuning pairs")
    ap.add_argument("--classic", type=int, default=52, help="classic views per difficulty")
    ap.add_argument("--jobs", type=int, default=min(2, os.cpu_count() or 1))
    ap.add_argument("--out", default=str(OUT))
    a = ap.parse_args(argv)
    groups = plan({"classic": a.classic, "wide/tuning": a.wide, "wide/heldout": 0, "pen": a.pen},
                  ["easy", "medium", "hard"], ["tuning"], ["classic", "wide", "pen"])
    cases = [c for g in groups.values() for c in g]
    missing = [c for c in cases if not case_cached(c)]
    if missing:
        print(f"{len(missing)} case(s) not rendered, left out (render them with python -m "
              "bench.bench_detect --render-only --split tuning ...)", file=sys.stderr)
    cases = [c for c in cases if case_cached(c)]
    rows: list[Any] = []
    with ProcessPoolExecutor(a.jobs) as ex:
        for n, r in enumerate(ex.map(case_rows, cases), 1):
            rows.extend(r)
            if n % 25 == 0 or n == len(cases):
                print(f"{n}/{len(cases)} cases, {len(rows)} candidates", file=sys.stderr)
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    np.savez(a.out, X=np.array([r[0] for r in rows]), y=np.array([r[1] for r in rows]),
             case=np.array([r[2] for r in rows]), view=np.array([r[3] for r in rows]),
             decision=np.array([r[4] for r in rows]), names=np.array(FEATURE_NAMES))
    print(json.dumps({"cases": len(cases), "candidates": len(rows),
                      "labels": np.bincount([r[1] for r in rows], minlength=3).tolist()}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
