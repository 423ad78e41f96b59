"""Views with no seam in them: is every one refused? By table kind, on the wide look.

    .venv/bin/python -m bench.bench_detect_noseam     # 48 views at 200 mm + 24 at 120 mm
    .venv/bin/python -m bench.bench_detect_noseam --views 6 --shifts 200

For seeds 20001, 20002, ... (both parts of the split, fixed), a wide-look straight scene
(difficulties in turn) is seen by the dry run's first view moved ``--shifts`` mm sideways (along
the camera's y axis, alternately either way), so that the joint is out of view: the table, the
edges and the inside of the sheets, their marks, dots and rust remain. A view that still shows
the seam is skipped. Every view must be refused (``SeamNotFound`` / ``AmbiguousSeam``); a
returned seam is a wrong seam. Prints a table by table kind and writes
bench/out/detect_noseam.json.
"""

from __future__ import annotations

import argparse
import json
import time
from collections import Counter
from pathlib import Path

from controller.errors import AmbiguousSeam, SeamNotFound
from controller.geometry.camera_model import default_camera
from controller.vision.seam_detect import detect_seam
from drivers.sim.sim_look import split_of
from drivers.sim.sim_render import render, suggest_view_poses
from drivers.sim.sim_scene import make_scene

OUT = Path(__file__).resolve().parent / "out" / "detect_noseam.json"


def run(views: int, shift_mm: float) -> list[dict[str, object]]:
    """Detect in ``views`` seamless views moved ``shift_mm`` sideways; one row per view."""
    cam = default_camera()
    rows: list[dict[str, object]] = []
    seed, n = 20000, 0
    while n < views:
        seed += 1
        n += 1
        diff = ("easy", "medium", "hard")[n % 3]
        scene = make_scene("straight", seed, diff, variety="wide")
        assert scene.look is not None
        T = suggest_view_poses(scene, cam, standoff_mm=350.0)[0].copy()
        T[:3, 3] += T[:3, 1] * (1.0 if n % 2 else -1.0) * shift_mm
        r = render(scene, cam, T, seed=0)
        if len(r.seam_px):
            continue
        row: dict[str, object] = {"seed": seed, "difficulty": diff, "part": split_of(seed),
                                  "table": scene.look.table, "shift_mm": shift_mm}
        t0 = time.perf_counter()
        try:
            det = detect_seam(r.image, camera=cam)
            row.update(result="returned", confidence=round(float(det.confidence), 3),
                       way=str(det.stats.get("way")))
        except (SeamNotFound, AmbiguousSeam) as err:
            row.update(result="refused", why=type(err).__name__)
        row["time_s"] = round(time.perf_counter() - t0, 3)
        print(row, flush=True)
        rows.append(row)
    return rows


def main(argv: list[str] | None = None) -> int:
    """Run, print the table by table kind, write the JSON; returns 0."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--views", type=int, nargs="+", default=[48, 24],
                    help="views per shift (one number per --shifts)")
    ap.add_argument("--shifts", type=float, nargs="+", default=[200.0, 120.0])
    a = ap.parse_args(argv)
    if len(a.views) != len(a.shifts):
        ap.error("give one --views number per --shifts distance")
    rows = [row for v, s in zip(a.views, a.shifts, strict=True) for row in run(v, s)]
    seen = Counter(str(r["table"]) for r in rows)
    wrong = Counter(str(r["table"]) for r in rows if r["result"] == "returned")
    print("\n| table | views without a seam | refused | seam returned (wrong) |")
    print("|---|---|---|---|")
    for t in sorted(seen):
        print(f"| {t} | {seen[t]} | {seen[t] - wrong[t]} | {wrong[t]} |")
    print(f"| all | {len(rows)} | {len(rows) - sum(wrong.values())} | {sum(wrong.values())} |")
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
