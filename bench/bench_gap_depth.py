"""How dark the gap is against the sheets beside it: the real photographs and the simulator.

For each view, profiles across the true centreline every 10 px (linear light, the detector's
gamma) give three figures:

- *core / level*: the darkest value within half the gap's width + 2 px of the centreline,
  over the darker side's level 12-30 px beyond the gap's edge (0: black, 1: no darker than the
  sheet). Medians over the profiles of a view.
- *ridge*: the brighter side's peak within 8 px beyond the gap's edge, over that side's level
  (the specular ridge of a ground strip: 1 none).

The photographs (``../shared/data/real-seams``, their labels' centrelines and widths) are read
as they are; the simulator's views from the render cache of a ``bench.bench_detect`` run
(``--rows FILE``: its JSON), with that run's verdict on each view, so the table says where in
depth the detector finds the joint, look by look::

    .venv/bin/python -m bench.bench_gap_depth --rows bench/out/detect.json

The figures of a view say what a person sees, not what the detector does: the simulator's looks
can be set against what real joints show (README, *How dark the gap is*).
"""

from __future__ import annotations

import argparse
import collections
import json
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from bench.real_seams import PHOTOS, labelled_photos
from controller.vision.seam_params import F64
from controller.vision.seam_profiles import bilinear, linear_lut, resample

OFFSETS = np.arange(-40.0, 40.25, 0.5)
#: Core / level bins of the table (upper edges).
BINS = (0.1, 0.25, 0.5, 0.75, np.inf)


def gap_figures(grey: np.ndarray, centre_px: F64, gap_px: float, gamma: float = 2.2
                ) -> tuple[float, float] | None:
    """(core / level, ridge) medians over profiles across ``centre_px`` (N, 2 image px).

    ``gap_px``: the gap's width (px). None when fewer than 5 profiles lie inside the image.
    """
    lut = linear_lut(gamma)
    pts, nrm = resample(np.asarray(centre_px, float), 10.0, extend=0.0)
    u = pts[:, 0, None] + OFFSETS[None, :] * nrm[:, 0, None]
    v = pts[:, 1, None] + OFFSETS[None, :] * nrm[:, 1, None]
    prof, inside = bilinear(grey, lut, u, v)
    prof = prof[inside.all(axis=1)]
    if len(prof) < 5:
        return None
    hw = gap_px / 2.0
    far = (np.abs(OFFSETS) >= hw + 12) & (np.abs(OFFSETS) <= hw + 30)
    near = (np.abs(OFFSETS) > hw) & (np.abs(OFFSETS) <= hw + 8)
    left, right = OFFSETS < 0, OFFSETS > 0
    lvl_l = np.median(prof[:, far & left], axis=1)
    lvl_r = np.median(prof[:, far & right], axis=1)
    core = prof[:, np.abs(OFFSETS) <= hw + 2].min(axis=1) / (np.minimum(lvl_l, lvl_r) + 1e-9)
    ridge = np.maximum(prof[:, near & left].max(axis=1) / (lvl_l + 1e-9),
                       prof[:, near & right].max(axis=1) / (lvl_r + 1e-9))
    return float(np.median(core)), float(np.median(ridge))


def photo_rows() -> list[dict[str, Any]]:
    """One row per labelled photograph: name, core / level, ridge."""
    rows = []
    for name, label, grey in labelled_photos(PHOTOS):
        got = gap_figures(grey, label["polyline_px"], float(label.get("gap_width_px", 6.0)))
        if got is not None:
            rows.append({"name": name, "core": got[0], "ridge": got[1]})
    return rows


def _sim_view(item: tuple[list[Any], int, str]) -> dict[str, Any] | None:
    from bench.detect_cases import load_case, view_truth

    case, v, verdict = item
    imgs, z = load_case(tuple(case))
    t = view_truth(z, v)
    img = imgs[v]
    grey = img if img.ndim == 2 else cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)  # as the detector
    got = gap_figures(grey, t["seam_px"], float(t["gap_px"]))
    if got is None:
        return None
    return {"family": str(z["family"]), "verdict": verdict, "core": got[0], "ridge": got[1]}


def sim_rows(bench_json: Path, jobs: int) -> list[dict[str, Any]]:
    """One row per view of a ``bench.bench_detect`` run's wide sets (renders from its cache)."""
    rep = json.loads(bench_json.read_text())
    items = [(r["case"], k, view["ours"]["result"])
             for key, rows in rep["rows"].items() if key.startswith("wide/")
             for r in rows for k, view in enumerate(r["views"])]
    with ProcessPoolExecutor(jobs) as ex:
        return [x for x in ex.map(_sim_view, items, chunksize=4) if x is not None]


def _q(a: list[float]) -> str:
    return " / ".join(f"{x:.2f}" for x in np.percentile(a, [25, 50, 75])) if a else "-"


def markdown(photos: list[dict[str, Any]], sim: list[dict[str, Any]]) -> str:
    """The two tables: figures by source, and the simulator's verdicts by core / level."""
    out = ["| views | n | core / level (quartiles) | ridge (quartiles) |", "|---|---|---|---|"]
    out.append(f"| photographs | {len(photos)} | {_q([r['core'] for r in photos])} | "
               f"{_q([r['ridge'] for r in photos])} |")
    by_family = collections.defaultdict(list)
    for r in sim:
        by_family[r["family"]].append(r)
    for fam, rows in sorted(by_family.items()):
        out.append(f"| simulator, {fam} | {len(rows)} | {_q([r['core'] for r in rows])} | "
                   f"{_q([r['ridge'] for r in rows])} |")
    edges = list(zip((0.0, *BINS[:-1]), BINS, strict=True))
    heads = [f"core < {hi}" if lo == 0 else (f"{lo}-{hi}" if np.isfinite(hi) else f">= {lo}")
             for lo, hi in edges]
    out += ["", "| look | " + " | ".join(heads) + " |", "|---" * (len(BINS) + 1) + "|"]
    for fam, rows in sorted(by_family.items()):
        cells = []
        for lo, hi in edges:
            inbin = [r for r in rows if lo <= r["core"] < hi]
            found = sum(r["verdict"] == "found" for r in inbin)
            wrong = sum(r["verdict"] not in ("found", "refused") for r in inbin)
            cells.append(f"{found}/{len(inbin)} found, {wrong} wrong" if inbin else "-")
        out.append(f"| {fam} | " + " | ".join(cells) + " |")
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    """Print the tables (markdown) and write the rows as JSON (``--out``)."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rows", type=Path, help="a bench.bench_detect JSON whose wide views to "
                    "read (from its render cache); without it, the photographs only")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", type=Path, default=Path("bench/out/gap_depth.json"))
    args = ap.parse_args(argv)
    if not PHOTOS.is_dir():
        raise SystemExit(f"no photographs at {PHOTOS}: the shared data folder is needed")
    photos = photo_rows()
    sim = sim_rows(args.rows, args.jobs) if args.rows else []
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"photos": photos, "sim": sim}, indent=1))
    for r in photos:
        print(f"{r['name']}: core / level {r['core']:.2f}, ridge {r['ridge']:.2f}")
    print(markdown(photos, sim))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
