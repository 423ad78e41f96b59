"""How the joint looks across in the simulator and in the real photographs, side by side.

Usage (from the repository root)::

    .venv/bin/python -m bench.detect_realism [--pairs 30] [--set wide|rough]
        [--out bench/out/detect_realism.json]

A detector tuned on our renderer is only as general as the renderer is wide. Here the joint
itself is compared, not the detector: along the **true** centreline of simulated views (the wide
set's tuning part, ``--pairs`` pairs per difficulty, or with ``--set rough`` the rough set's,
``--pairs`` in all; rendered into the benchmark's cache where missing) and along the
**labelled** centreline of the photographs of ``../shared/data/real-seams``, profiles across the
joint at up to 60 places (covered spans left out), 25 samples over 4 half-widths ``h = max(w, 2)
/ 2 + 1`` each side of the centre (``w``: the gap's width, true or labelled, px) and 3 on each
sheet beyond (``4 h`` + 4, 12, 24 px), in linear radiance divided by the brighter sheet's level.
Per view (:func:`joint_stats`):

- ``floor``: the mean profile's lowest level within one half-width of the centre (0 black,
  1 as bright as the brighter sheet);
- ``rim``: its highest level between one and four half-widths out (above 1: a bright ridge
  beside the gap, a ground strip's edge);
- ``sides``: log of the darker sheet's level over the brighter's;
- ``along``: how much the profile changes along the joint (the median over the 31 samples of
  their spread along it, in units of the brighter sheet's level);
- ``sheet_cv``: the sheets' own variation along the joint (spread over mean of the outer
  samples);
- ``look_alike``: the share of the detector's own gap profiles (``seam_profiles.fit_at``, the
  default parameters) that pass on four lines parallel to the joint, ``w`` + 40 and ``w`` + 80 px
  each side of it: how often the sheets themselves look like a gap, at the places the detector
  would look (scratches, pits, rust, brushing);
- ``width_px``.

``bench.bench_gap_depth`` sets the gap's depth and a ridge beside it against the detector's
verdicts, look by look; here every statistic is ranked against the simulator's spread. Prints, per
statistic, the simulator's 5 / 50 / 95 % (all views, and per look family) and each
photograph's value with its rank among the simulated views; the last column counts the
photographs outside the simulator's 5-95 % range. A statistic most photographs lie outside of is
a way the renderer is narrower than the world (README, *Seam vision*). Writes the rows as JSON.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from bench.detect_cases import case_cached, case_list, load_case, render_case, view_truth
from bench.real_seams import PHOTOS, have_photos, labelled_photos
from controller.vision.seam_params import DetectParams
from controller.vision.seam_profiles import bilinear, fit_at, linear_lut, resample

ACROSS = np.linspace(-4.0, 4.0, 25)
SHEETS_PX = (4.0, 12.0, 24.0)
PLACES = 60
STATS = ("floor", "rim", "sides", "along", "sheet_cv", "look_alike", "width_px")
#: Lines parallel to the joint for ``look_alike``: this far beyond the gap's width, px.
BESIDE_PX = (40.0, 80.0)
F64 = NDArray[np.float64]


def _covered(s: F64, spans: Any) -> NDArray[np.bool_]:
    """Per arc length ``s`` (px): inside one of ``spans`` ([s0, s1] px along the line)."""
    out = np.zeros(len(s), bool)
    for a, b in np.asarray(spans, np.float64).reshape(-1, 2):
        out |= (s >= a) & (s <= b)
    return out


def joint_stats(grey: NDArray[np.uint8], line_px: F64, width_px: float,
                spans: Any = ()) -> dict[str, float] | None:
    """The module's statistics of the joint along ``line_px`` (px), or None if too little of
    it is in the image and uncovered. ``spans``: covered stretches, px along the line."""
    pts, nrm = resample(np.asarray(line_px, np.float64), 4.0, 0.0)
    s = np.arange(len(pts)) * 4.0
    keep = np.flatnonzero(~_covered(s, spans))
    if len(keep) < 10:
        return None
    keep = keep[np.linspace(0, len(keep) - 1, min(PLACES, len(keep))).round().astype(int)]
    h = max(width_px, 2.0) / 2 + 1.0
    out = [-(4 * h + d) for d in SHEETS_PX[::-1]] + [4 * h + d for d in SHEETS_PX]
    offs = np.concatenate([ACROSS * h, out])
    P = pts[keep][:, None, :] + offs[None, :, None] * nrm[keep][:, None, :]
    prm = DetectParams()
    lut = linear_lut(prm.gamma)
    val, ok = bilinear(grey, lut, P[..., 0].ravel(), P[..., 1].ravel())
    val = np.where(ok, val, np.nan).reshape(len(keep), len(offs))
    n = len(ACROSS)
    rows_ok = np.all(np.isfinite(val), axis=1)
    if rows_ok.sum() < 10:
        return None
    val = val[rows_ok]
    left = np.median(val[:, n:n + 3], axis=1)
    right = np.median(val[:, n + 3:], axis=1)
    ref = np.maximum(left, right)[:, None] + 1e-3
    nv = val / ref
    mean = nv[:, :n].mean(axis=0)
    centre = np.abs(ACROSS) <= 1.0
    return {"floor": float(mean[centre].min()), "rim": float(mean[~centre].max()),
            "sides": float(np.log((np.median(np.minimum(left, right)) + 1e-3)
                                  / (np.median(np.maximum(left, right)) + 1e-3))),
            "along": float(np.median(nv.std(axis=0))),
            "sheet_cv": float(np.median(val[:, n:].std(axis=0) / (val[:, n:].mean(axis=0)
                                                                  + 1e-3))),
            "look_alike": _look_alike(grey, lut, prm, pts[keep], nrm[keep], width_px),
            "width_px": float(width_px)}


def _look_alike(grey: NDArray[np.uint8], lut: F64, p: DetectParams, pts: F64, nrm: F64,
                width_px: float) -> float:
    """Share of gap profiles (``fit_at`` with ``p``, ``lut``) passed on lines parallel to the
    joint ``pts`` (px, normals ``nrm``) ``width_px`` + :data:`BESIDE_PX` each side; places
    whose profile leaves the image not counted; NaN where none is left."""
    h, w = grey.shape
    reach = p.half_width_px + 1.0  # a profile's half length and its bilinear neighbour
    passed, looked = 0, 0
    for d in BESIDE_PX:
        for sign in (-1.0, 1.0):
            q = pts + sign * (width_px + d) * nrm
            inside = ((q[:, 0] >= reach) & (q[:, 0] <= w - 1 - reach)
                      & (q[:, 1] >= reach) & (q[:, 1] <= h - 1 - reach))
            if not inside.any():
                continue
            fit = fit_at(grey, lut, q[inside], nrm[inside], p)
            passed += int(fit["valid"].sum())
            looked += int(inside.sum())
    return passed / looked if looked else float("nan")


def simulated_rows(pairs: int, kind_set: str = "wide") -> list[dict[str, Any]]:
    """:func:`joint_stats` of each view of a set's tuning part (rendered where missing).

    ``pairs``: per difficulty for the wide set, in all for a set that mixes them (``rough``).
    """
    rows = []
    diffs = ("easy", "medium", "hard")
    cases = ([c for d in diffs for c in case_list("wide", d, "tuning", pairs)]
             if kind_set == "wide" else case_list(kind_set, "", "tuning", pairs))
    for case in cases:
        if not case_cached(case):
            render_case(case)
        imgs, z = load_case(case)
        for i, img in enumerate(imgs):
            truth = view_truth(z, i)
            tp = np.asarray(truth["seam_px"], np.float64)
            if len(tp) < 2 or not np.isfinite(truth["gap_px"]):
                continue
            grey = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY) if img.ndim == 3 else img
            st = joint_stats(grey, tp, truth["gap_px"], truth["spans"])
            if st is not None:
                rows.append({"case": list(case), "view": i, "family": truth["family"], **st})
    return rows


def photo_rows(root: Path = PHOTOS) -> list[dict[str, Any]]:
    """:func:`joint_stats` of each labelled photograph with a seam in ``root``."""
    rows = []
    for name, lab, img in labelled_photos(root, need=("polyline_px", "gap_width_px")):
        if not lab.get("seam_present", True):
            continue
        st = joint_stats(img, np.asarray(lab["polyline_px"], np.float64),
                         float(lab["gap_width_px"]), lab.get("occluded_spans", ()))
        if st is not None:
            rows.append({"photo": name, **st})
    return rows


def table(sim: list[dict[str, Any]], photos: list[dict[str, Any]]) -> str:
    """The markdown table the module docstring describes."""
    fams = sorted({r["family"] for r in sim})
    head = (["statistic", "simulator 5 / 50 / 95 %"] + [f"{f} 50 %" for f in fams]
            + [p["photo"] for p in photos] + ["photos outside 5-95 %"])
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for k in STATS:
        # look_alike is NaN where no parallel line lies in the image: left out, shown as -.
        v = np.array([r[k] for r in sim], np.float64)
        v = v[np.isfinite(v)]
        lo, mid, hi = np.percentile(v, [5, 50, 95])
        cells = [k, f"{lo:.2f} / {mid:.2f} / {hi:.2f}"]
        cells += [f"{np.nanmedian([r[k] for r in sim if r['family'] == f]):.2f}" for f in fams]
        seen = [p for p in photos if np.isfinite(p[k])]
        cells += [f"{p[k]:.2f} ({100 * np.mean(v <= p[k]):.0f} %)" if np.isfinite(p[k]) else "-"
                  for p in photos]
        cells.append(f"{sum(not lo <= p[k] <= hi for p in seen)} of {len(seen)}")
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Measure both, print the table, write the rows; 0, or 1 without the photographs."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pairs", type=int, default=30,
                    help="tuning pairs per difficulty (wide), in all (rough)")
    ap.add_argument("--set", choices=("wide", "rough"), default="wide", dest="kind_set")
    ap.add_argument("--photos", type=Path, default=PHOTOS)
    ap.add_argument("--out", default="bench/out/detect_realism.json")
    a = ap.parse_args(argv)
    if not have_photos(a.photos, "detect_realism"):
        return 1
    photos = photo_rows(a.photos)
    sim = simulated_rows(a.pairs, a.kind_set)
    print(f"{len(sim)} simulated views ({a.kind_set} set, tuning part), {len(photos)} photographs")
    print(table(sim, photos))
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    Path(a.out).write_text(json.dumps({"simulated": sim, "photos": photos}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
