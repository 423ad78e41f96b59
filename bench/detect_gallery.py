"""Pictures of the benchmark's failures: each chosen view with its truth and our detection.

Usage (from the repository root, after ``bench.bench_detect`` wrote its report)::

    .venv/bin/python -m bench.detect_gallery [--report bench/out/detect.json]
        [--result wrong|refused|found] [--part tuning|heldout] [--feature NAME]
        [--limit 40] [--out bench/out/gallery]

For each view of the wide and pen sets with that result (ours), from the render cache: the
image dimmed with our detection drawn as ``seamguide detect --overlay`` draws it (green seam,
orange ends, the reasons or the refusal on top), the true centreline in blue and any pen line
in magenta, 1600 px wide, as ``<out>/<set>-<difficulty>-<part>-<seed>-v<view>.png``, and
``<out>/index.md`` listing them with the scorer's verdict. The detection is run again (the
report keeps no points): the detector of the working tree, not necessarily the report's.

The default part is ``tuning``: the held-out part is there to measure, and looking through its
failures one by one is how a rule gets fitted to it. ``--part heldout`` draws it all the same,
and says so in the index and on every picture.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from bench.bench_detect import view_features
from bench.detect_cases import load_case, view_truth
from controller.errors import SeamguideError
from controller.geometry.camera_model import default_camera
from controller.vision.seam_detect import SeamDetection, detect_seam
from controller.vision.seam_overlay import draw_overlay

TRUTH_BGR = (255, 140, 0)
PEN_BGR = (255, 0, 255)


def picture(image: NDArray[np.uint8], truth: dict[str, Any], detection: SeamDetection | None,
            message: str | None, max_width: int = 1600) -> NDArray[np.uint8]:
    """BGR picture of one view: :func:`draw_overlay` over the truth (blue) and pen lines (magenta).

    ``truth`` as :func:`bench.detect_cases.view_truth` gives it (full-image px).
    """
    H, W = image.shape[:2]
    # The truth first, under the detection: where they agree the detection's green shows.
    img = np.asarray(image.copy() if image.ndim == 3 else cv2.cvtColor(image, cv2.COLOR_GRAY2BGR),
                     np.uint8)
    width = max(1, int(round(W / 400)))
    for P, colour in [(truth["seam_px"], TRUTH_BGR)] + [(q, PEN_BGR) for q in truth["pens"]]:
        if len(P) >= 2:
            pts = np.round(np.asarray(P, np.float64) * 16).astype(np.int32).reshape(-1, 1, 2)
            cv2.polylines(img, [pts], False, colour, width, cv2.LINE_AA, 4)
    out = draw_overlay(img, detection, message, max_width=W)
    if max_width < W:
        out = np.asarray(cv2.resize(out, (max_width, int(round(H * max_width / W))),
                                    interpolation=cv2.INTER_AREA), np.uint8)
    return out


def chosen(report: dict[str, Any], result: str, part: str, feature: str | None = None
           ) -> list[tuple[list[Any], int, dict]]:
    """(case, view, our scored result) of the report's wide and pen views with ``result``.

    ``feature``: only views counted under that name in the benchmark's table *by what the
    scene had* (:func:`bench.bench_detect.view_features`, e.g. ``"table dark"``).
    """
    out = []
    for key, rows in report["rows"].items():
        if key.startswith("classic") or not key.endswith("/" + part):
            continue
        for r in rows:
            for i, v in enumerate(r["views"]):
                if v["ours"]["result"] != result:
                    continue
                if feature is None or feature in view_features(r.get("scene", {}), v):
                    out.append((r["case"], i, v["ours"]))
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--report", default="bench/out/detect.json")
    ap.add_argument("--result", choices=("wrong", "refused", "found"), default="wrong")
    ap.add_argument("--part", choices=("tuning", "heldout"), default="tuning")
    ap.add_argument("--feature", default=None,
                    help='only views with this scene feature, as named in the benchmark\'s '
                         'table "by what the scene had", e.g. "table dark" or "plate corners: '
                         'a joint end in view, rounded"')
    ap.add_argument("--limit", type=int, default=40)
    ap.add_argument("--out", default="bench/out/gallery")
    args = ap.parse_args(argv)
    path = Path(args.report)
    if not path.exists():
        print(f"detect_gallery: no report at {path}; run `.venv/bin/python -m bench.bench_detect` "
              "first (or give --report)", file=sys.stderr)
        return 2
    views = chosen(json.loads(path.read_text()), args.result, args.part,
                   args.feature)[: args.limit]
    if not views:
        print(f"detect_gallery: no {args.result} view of the {args.part} part"
              + (f" with the feature {args.feature!r}" if args.feature else "")
              + f" in {path}; the feature names are those of the report's table by what the "
              "scene had (bench/out/detect.md)", file=sys.stderr)
        return 1
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    cam = default_camera()
    warn = (" (held-out part: to measure with, not to tune on)" if args.part == "heldout" else "")
    written = 0
    which = f" with {args.feature}" if args.feature else ""
    index = [f"# Our {args.result} views{which}, {args.part} part{warn}", "",
             "Blue: the true centreline; magenta: pen lines; green: our seam.", ""]
    for n, (case, i, scored) in enumerate(views, 1):
        try:
            imgs, z = load_case(tuple(case))
        except FileNotFoundError:
            print(f"detect_gallery: {case} is not in the render cache; skipped", file=sys.stderr)
            continue
        det: SeamDetection | None = None
        message = ("held-out part, to measure with, not to tune on; " if args.part == "heldout"
                   else "") + f"benchmark: {scored['result']}"
        if "why" in scored:
            message += f", {scored['why']} ({scored['rms']:.1f} px RMS off the truth)"
        try:
            det = detect_seam(imgs[i], camera=cam)
        except SeamguideError as err:
            message += f"; refused: {err}"
        name = f"{case[0]}-{case[1]}-{case[2]}-{case[3]:05d}-v{i}.png"
        cv2.imwrite(str(out / name), picture(imgs[i], view_truth(z, i), det, message))
        written += 1
        verdict = scored.get("why") or scored.get("error", "")[:160]
        index.append(f"- [{name}]({name}): {scored['result']}, {verdict}"
                     + (f", confidence {scored['confidence']:.2f}" if "confidence" in scored
                        else ""))
        print(f"{n}/{len(views)} {name}", file=sys.stderr)
    (out / "index.md").write_text("\n".join(index) + "\n")
    print(f"{written} pictures and index.md in {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
