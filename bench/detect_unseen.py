"""Why no candidate lies on the joint: what the coarse search and the profiles see along it.

:mod:`bench.detect_funnel` puts a refused view in "no candidate on the joint" when no stage
handed on a line along the true centreline. That verdict covers three different failures, each
needing a different remedy, and this module tells them apart on the true centreline itself:

- **the coarse search does not see it**: the valley mask of the first way
  (:func:`controller.vision.seam_coarse.coarse_candidates`, ``DetectParams`` defaults) lies within
  a coarse pixel of under half the true line (a hairline whose dip averages away in the shrunk
  image, all the more between two bright ridges);
- **seen in pieces**: the mask covers half of it or more but its longest piece touching the line
  is shorter than a seam (``DetectParams.min_length_px``): the pieces were not joined into one
  candidate (tack welds, spatter and a faint gap break it up);
- **seen whole**: a piece of a seam's length lies along it, and what became of it is
  somewhere later (refined beside the gap, out-scored, handed on after
  ``DetectParams.max_candidates``).

Crossed with it, the share of full-resolution profiles across the true line (every
``DetectParams.step_px``) that fit the two-edge gap model
(:func:`controller.vision.seam_profiles.fit_at`): under half, the profile stage would refuse the
joint even if a candidate lay on it (a gap between two bright ridges of ground strips is not
the model's sheet-floor-sheet profile).

``.venv/bin/python -m bench.detect_unseen [--photos DIR]`` prints the same readings along the
real photographs' labelled lines (``../shared/data/real-seams``).
"""

from __future__ import annotations

import argparse
import collections
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from bench.real_seams import PHOTOS, have_photos, labelled_photos
from controller.vision.seam_coarse import coarse_candidates
from controller.vision.seam_params import DetectParams
from controller.vision.seam_profiles import fit_at, linear_lut, resample

#: Share of the true line the coarse mask must lie along for the joint to count as seen.
SEEN_SHARE = 0.5
#: Share of profiles across the true line that must fit a gap for the profiles to count as fitting.
FIT_SHARE = 0.5


def unseen_readings(grey: NDArray[np.uint8], truth_px: NDArray[np.float64],
                    p: DetectParams | None = None) -> dict[str, float]:
    """What the coarse search and the profiles see along the true centreline ``truth_px``
    ((M, 2) px of ``grey``, the full image).

    ``mask_cover``: share of points along it (every ``p.step_px``, where the profiles are read)
    with a pixel of the first way's valley mask within one coarse pixel; ``piece_px``: the
    longest mask piece (8-connected) touching it, as the diagonal of its bounding box in
    full-resolution px (how the coarse search measures a piece); ``profile_share``: share of
    profiles across it that fit a gap.
    """
    p = p or DetectParams()
    lut = linear_lut(p.gamma)
    _, _, mask, f = coarse_candidates(grey, lut, p)
    pts, nrm = resample(np.asarray(truth_px, np.float64), p.step_px, 0.0)
    h, w = mask.shape
    u = np.clip(np.floor((pts[:, 0] + 0.5) / f).astype(np.int64), 0, w - 1)
    v = np.clip(np.floor((pts[:, 1] + 0.5) / f).astype(np.int64), 0, h - 1)
    near = cv2.dilate(mask, np.ones((3, 3), np.uint8))[v, u] > 0
    _, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    touched = np.unique([labels[np.clip(v + dv, 0, h - 1), np.clip(u + du, 0, w - 1)]
                         for dv in (-1, 0, 1) for du in (-1, 0, 1)])
    touched = touched[touched > 0]
    diag = np.hypot(stats[:, cv2.CC_STAT_WIDTH], stats[:, cv2.CC_STAT_HEIGHT]) * f
    fit = fit_at(grey, lut, pts, nrm, p)
    return {"mask_cover": round(float(near.mean()), 3),
            "piece_px": round(float(max((diag[k] for k in touched), default=0.0)), 1),
            "profile_share": round(float(np.mean(fit["valid"])), 3)}


def unseen_class(r: dict[str, float], p: DetectParams | None = None) -> tuple[str, str]:
    """(what the coarse search saw, whether the profiles fit) for readings ``r`` of
    :func:`unseen_readings`."""
    p = p or DetectParams()
    if r["mask_cover"] < SEEN_SHARE:
        seen = "coarse search does not see it"
    elif r["piece_px"] < p.min_length_px:
        seen = "seen in pieces"
    else:
        seen = "seen whole"
    fits = "profiles fit" if r["profile_share"] >= FIT_SHARE else "profiles fail"
    return seen, fits


def unseen_table(rows: list[dict[str, Any]]) -> str:
    """Markdown: the views without a candidate on the joint (rows carrying ``unseen``
    readings), by what the coarse search saw and whether the profiles fit, per look family."""
    these = [r for r in rows if r.get("unseen")]
    if not these:
        return ""
    looks = sorted({r.get("family", "?") for r in these})
    count = collections.Counter((*unseen_class(r["unseen"]), r.get("family", "?"))
                                for r in these)
    out = [f"{len(these)} views with no candidate on the joint, by what the first way's coarse "
           "search and the profiles see along the true centreline (bench.detect_unseen):", "",
           "| coarse search | profiles across the true line | " + " | ".join(looks)
           + " | gap px (median) |", "|---" * (3 + len(looks)) + "|"]
    for seen in ("coarse search does not see it", "seen in pieces", "seen whole"):
        for fits in ("profiles fit", "profiles fail"):
            sel = [r for r in these if unseen_class(r["unseen"]) == (seen, fits)]
            if not sel:
                continue
            gap = float(np.median([r.get("gap_px", np.nan) for r in sel]))
            out.append(f"| {seen} | {fits} | "
                       + " | ".join(str(count[(seen, fits, k)]) for k in looks)
                       + f" | {gap:.1f} |")
    return "\n".join(out)


def photo_rows(root: Path = PHOTOS) -> list[dict[str, Any]]:
    """:func:`unseen_readings` along each labelled photograph's line (``root``, score.py's
    labels; photographs without a seam skipped), with its class."""
    rows = []
    for name, lab, grey in labelled_photos(root):
        if not lab.get("seam_present", True):
            continue
        r = unseen_readings(grey, np.asarray(lab["polyline_px"], np.float64))
        rows.append({"photo": name, **r, "class": " / ".join(unseen_class(r))})
    return rows


def main(argv: list[str] | None = None) -> int:
    """Print the readings along the real photographs' labelled lines; 0, or 1 without any."""
    ap = argparse.ArgumentParser(description="What the coarse search and the profiles see "
                                 "along the real photographs' labelled joints")
    ap.add_argument("--photos", type=Path, default=PHOTOS, help="score.py's folder")
    a = ap.parse_args(argv)
    if not have_photos(a.photos, "detect_unseen"):
        return 1
    rows = photo_rows(a.photos)
    print("| photograph | coarse mask along the line | longest piece px | profiles fitting | "
          "class |\n|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['photo']} | {r['mask_cover']:.2f} | {r['piece_px']:.0f} | "
              f"{r['profile_share']:.2f} | {r['class']} |")
    return 0 if rows else 1


if __name__ == "__main__":
    raise SystemExit(main())
