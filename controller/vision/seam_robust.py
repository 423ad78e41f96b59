"""The second way to a seam: whole-image valley paths, for gaps the profile model does not fit.

Real joints are often not the clean two-edge valley that :mod:`controller.vision.seam_centreline`
fits: ragged or crack-like edges, bright lips, gaps 20-30 px wide, tack welds and spatter every few
hundred pixels, dark noisy or colour-cast images. Here the seam is the best-supported valley path
through the working image (:mod:`controller.vision.seam_track`) on the multi-scale valley response
(:mod:`controller.vision.seam_valley`), which bridges covered stretches. Each path is then measured
at full resolution: a profile across it every ``step_px``; where the two-edge model fits close to
the path its centre is used (sub-pixel), else the darkest point of the smoothed profile near the
path when it is a valley, else (covered: a tack weld) the path is interpolated from both sides and
the stretch reported as occluded. Where the path ran on past the seam's end (into the table),
its ends are first brought back to the seam (:mod:`controller.vision.seam_path_ends`). The ends
are classified as in the first way
(:func:`controller.vision.seam_ends.end_offset`): the image border, a sheet border (``joint_end``),
or ``open`` (the line fades out inside a sheet: a pen or soapstone line, a scratch; rejected).
"""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
from numpy.typing import NDArray

from controller.vision.seam_coarse import share_near
from controller.vision.seam_ends import border_crossing, end_offset
from controller.vision.seam_params import (
    COVERED_END,
    F64,
    JOINED_LINES,
    OPEN_END,
    Candidate,
    DetectParams,
    runs_of,
)
from controller.vision.seam_path_ends import END_COVER_PX, follow_ends, trim_at_sheet_borders
from controller.vision.seam_profiles import bilinear, fit_at, resample
from controller.vision.seam_track import ValleyPath, find_paths, robust_line
from controller.vision.seam_valley import main_directions, shrink, valley_response, work_factor

MIN_DEPTH = 0.3  # median relative valley depth along a path for it to be a gap
MIN_RESP = 0.15  # valley response that counts as a valley on a clean image
MIN_SEEN = 0.4  # share of a path where the gap is measured at full resolution
MIN_SUPPORT = 0.65  # share of a path with a valley for it to be a gap (the rest covered)


def robust_candidates(grey: NDArray[np.uint8], lut: F64, p: DetectParams, max_paths: int = 3,
                      not_lines: list[F64] | None = None) -> list[Candidate]:
    """Seam candidates from whole-image valley paths, measured and with their ends judged.

    ``not_lines``: polylines (full-resolution px) already seen to fade out inside a sheet (pen
    lines): a path along one of them is rejected, even if it runs on to the image border along
    something else.
    """
    f = work_factor(grey.shape)
    img = shrink(grey, f)
    resp, scale = valley_response(img)
    bias = max(0.04, 1.5 * float(np.percentile(resp, 75)))
    thetas = main_directions(resp, 2 * bias)
    paths = find_paths(resp, thetas, bias, cap=0.5)
    out: list[Candidate] = []
    measured = 0
    for path in paths:
        if measured >= max_paths:
            break
        if any(_same_line(path.points * f, c.polyline) for c in out):
            continue
        c = _measure(grey, lut, path, f, scale, bias, p)
        measured += 1  # a path dropped below still counts: no further (rival) path for it
        if c.points is not None and any(k.points is not None
                                        and share_near(c.points, k.points, 3.0) >= 0.8
                                        for k in out):
            # Measured onto a line already judged (the raw paths ran apart in places): the same
            # line twice is neither a rival to itself nor a second chance for a pen line.
            continue
        if (not c.why_rejected and c.points is not None
                and any(_same_line(q, c.points) for q in not_lines or [])):
            c.why_rejected = ("valley path along a dark line that fades out inside a sheet (a "
                              "pen or soapstone line, a scratch: not a joint)")
            c.rival = True
        out.append(c)
    return out


def _same_line(a: F64, b: F64, tol: float = 12.0) -> bool:
    """Whether most of ``a`` lies within ``tol`` px of ``b`` (subsampled)."""
    d = np.linalg.norm(a[::8, None, :] - b[None, ::8, :], axis=2).min(axis=1)
    return bool(np.mean(d < tol) > 0.5)


def _measure(grey: NDArray[np.uint8], lut: F64, path: ValleyPath, f: int,
             scale: NDArray[np.float32], bias: float, p: DetectParams) -> Candidate:
    """One valley path measured at full resolution as a :class:`Candidate` (or why rejected)."""
    H, W = grey.shape
    raw = (path.points + 0.5) * f - 0.5
    sup = path.resp > max(1.5 * bias, MIN_RESP)
    c = Candidate(raw, path.score, float(np.sum(np.linalg.norm(np.diff(raw, axis=0), axis=1))),
                  way="valley path")
    if len(raw) < 12 or c.length_px < p.min_length_px:
        c.why_rejected = f"valley path only {c.length_px:.0f} px long"
        return c
    # The path as a smooth line through where the gap is seen (covered stretches bridged
    # straight, excursions along other dark features dropped), back in full-resolution px.
    line, _ = robust_line(path.rows, path.cols, sup, win=2 * int(round(200.0 / f)) + 1, tol=2.0)
    canvas = np.column_stack([line, path.rows])
    guide = (canvas @ path.to_image[:, :2].T + path.to_image[:, 2] + 0.5) * f - 0.5
    sc = scale[np.clip(path.points[:, 1].round().astype(int), 0, scale.shape[0] - 1),
               np.clip(path.points[:, 0].round().astype(int), 0, scale.shape[1] - 1)]
    r_med = float(np.median(sc[sup])) if sup.any() else 1.0
    w_est = max(1.0, 1.2 * r_med * f)  # the gap is about as wide as the best side distance
    pts, nrm = resample(guide, p.step_px, extend=0.0)
    hw = float(np.clip(1.5 * w_est + 6.0, 14.0, 60.0))
    pp = replace(p, max_gap_px=max(p.max_gap_px, 2.5 * w_est), half_width_px=hw)
    fit = fit_at(grey, lut, pts, nrm, pp)
    tol = max(3.0, 1.5 * f)
    off_fit = np.einsum("kd,kd->k", fit["centre"] - pts, nrm)
    lm_ok = fit["valid"] & (np.abs(off_fit) <= tol)
    off_min, rel = _darkest(grey, lut, pts, nrm, w_est, tol)
    # Seen where the valley is about as deep as the gap is along most of its length: the rim of
    # a tack weld or a spatter ball beside the covered gap is a shallower or a different valley.
    typical = float(np.median(rel[rel > 0.1])) if np.any(rel > 0.1) else 0.0
    c.stats = {"full_depth": typical, "support": float(sup.mean())}
    min_ok = rel > max(0.1, 0.6 * typical)
    lm_ok &= fit["depth"] > 0.6 * typical
    off = np.where(lm_ok, off_fit, off_min)
    seen = lm_ok | min_ok
    if seen.sum() < 8:
        c.why_rejected = "valley path: too few profiles across it show a gap"
        return c
    idx = np.arange(len(pts), dtype=np.float64)
    k = max(5, int(round(60.0 / p.step_px)) // 2 * 2 + 1)
    kc = max(k, int(round(400.0 / p.step_px)) // 2 * 2 + 1)
    off, kept = robust_line(idx, off, seen, win=kc, tol=max(2.0, 0.25 * w_est), out_win=k)
    # A short island of "seen" inside a covered stretch is the rim of the tack weld or a dark
    # spot in it, not the gap.
    kept = _drop_short_runs(kept, max(3, int(round(24.0 / p.step_px))))
    if kept.sum() < 8:
        c.why_rejected = "valley path: too few profiles across it show a gap"
        return c
    # A covered stretch is bridged only as long as a tack weld or a spatter cluster can be; a
    # longer one means the path joined two different lines (a pen line and the joint beyond its
    # end): the longer piece is kept. A covered stretch at an end goes on to the image border
    # only over a short distance (a tack weld at the border); else the line ends where last seen.
    raw_centre = pts + nrm * off[:, None]
    bent = _bent_bridge(raw_centre, kept, int(round(40.0 / p.step_px)),
                        int(round(100.0 / p.step_px)))
    centre = _bridge(raw_centre, kept, max(8, int(round(200.0 / p.step_px))))
    seen = kept
    width = np.where(lm_ok, fit["width"], w_est)
    centre, seen, width = follow_ends(grey, lut, centre, seen, width, pp)
    lo, hi = trim_at_sheet_borders(grey, lut, centre, seen, float(np.median(width[seen])), p)
    if (hi - lo) * p.step_px >= p.min_length_px:
        # (Cut shorter than a seam, it is judged as a whole, as it was found.)
        centre, seen, width = centre[lo:hi], seen[lo:hi], width[lo:hi]
    w_med = float(np.median(width[seen]))
    kinds: list[str] = []
    for first in (True, False):
        if first:
            centre, seen, width = centre[::-1], seen[::-1], width[::-1]
        e_pt = centre[-1]
        tang = centre[-1] - centre[max(0, len(centre) - 6)]
        tang /= np.linalg.norm(tang) + 1e-12
        k_end, kind, _ = end_offset(grey, lut, e_pt, tang, w_med)
        if kind != "image border" and _near_border(e_pt, W, H, 2.0 * f + 4.0):
            kind, k_end = "image border", border_crossing(e_pt, tang, W, H, 0.0)
        # The end where the sheets (or the image) end: the path trimmed there, or extended.
        along = (centre - e_pt) @ tang
        n = max(int(np.sum(along < k_end - 0.5 * p.step_px)), 2)
        kind = _seen_to_border(kind, seen[:n], p.step_px)
        centre = np.vstack([centre[:n], e_pt + k_end * tang])
        seen, width = np.append(seen[:n], True), np.append(width[:n], width[n - 1])
        if first:
            centre, seen, width = centre[::-1], seen[::-1], width[::-1]
        kinds.append(kind)
    c.end_kinds = (kinds[0], kinds[1])
    c.points = centre
    c.width = width
    c.bridged = ~seen
    c.depth = float(np.median(path.resp[sup])) if sup.any() else 0.0
    # For the confidence: the share of the path where the working image shows a valley (a
    # covered stretch is not a reason to doubt the seam; a path mostly through nothing is).
    c.valid_frac = float(sup.mean())
    c.resid = 0.0
    c.length_px = float(np.sum(np.linalg.norm(np.diff(centre, axis=0), axis=1)))
    # A gap is a slot through the material: of two valley lines otherwise alike (the gap and the
    # edge line of a ground strip, a scribed line), the wider one is the gap.
    c.score = c.length_px * min(c.depth, 0.5) * float(sup.mean()) * float(np.sqrt(w_med))
    if bent is not None:
        c.stats["bent_deg"] = bent
    judge_path(c)
    return c


def judge_path(c: Candidate) -> None:
    """Set ``c.why_rejected`` and ``c.rival`` of a measured valley path from what it is.

    From its end kinds, depth, the share of it where the gap was measured (``c.bridged``) and
    where the working image shows a valley, and a turn across an unseen stretch
    (``c.stats``): run again where its end kinds are settled later
    (:mod:`controller.vision.seam_tee`).
    """
    assert c.bridged is not None
    c.why_rejected, c.rival, c.refused = "", False, ""
    seen = float(np.mean(~c.bridged))
    support = c.stats.get("support", 0.0)
    bent = c.stats.get("bent_deg")
    if bent is not None:
        c.why_rejected = (f"valley path turns {bent:.0f} deg across an unseen stretch: it joins "
                          "two different lines (a covered joint does not turn under the patch)")
        c.refused = JOINED_LINES
        # One of the two lines may be the joint: a strong rival all the same.
        c.rival = True
    elif "covered" in c.end_kinds:
        c.why_rejected = (f"valley path of {c.length_px:.0f} px stops at a covered patch (a tack "
                          "weld, spatter) with the gap going on beyond it: not an end")
        c.refused = COVERED_END
    elif "open" in c.end_kinds:
        c.why_rejected = (f"dark line of {c.length_px:.0f} px fades out inside a sheet "
                          "(a pen or soapstone line, a scratch, one plate's outer edge: not a "
                          "joint)")
        c.refused = OPEN_END
        # A whole-image path may have joined a line with pieces of another: a rejected line as
        # strong as the best one leaves the choice in doubt.
        c.rival = True
    elif c.depth < MIN_DEPTH:
        c.why_rejected = (f"valley path of {c.length_px:.0f} px: too shallow to be a gap "
                          f"(relative depth {c.depth:.2f} < {MIN_DEPTH})")
    elif seen < MIN_SEEN:
        c.why_rejected = (f"valley path of {c.length_px:.0f} px: a gap profile is measured on "
                          f"only {100 * seen:.0f} % of it")
        c.rival = True  # the gap may be ragged or covered: it still makes another line doubtful
    elif support < MIN_SUPPORT:
        c.why_rejected = (f"valley path of {c.length_px:.0f} px: the gap is seen on only "
                          f"{100 * support:.0f} % of it")


def _seen_to_border(kind: str, seen: NDArray[np.bool_], step_px: float) -> str:
    """The kind of an end, ``"open"`` for a sheet border the gap was not seen to run to.

    ``seen``: per path sample (``step_px`` apart) up to the end, whether the gap was measured
    there. A sheet border reached across more than ``END_COVER_PX`` where no gap was seen (more
    than a tack weld at the end covers) is where the path was led, not where a gap was followed:
    a path from a pen line's end across the sheet to a plate's corner. The image border is not
    judged so: the seam may run on out of view under a patch.
    """
    if not kind.endswith("sheet border"):
        return kind
    last = np.flatnonzero(seen)
    unseen = (len(seen) - 1 - int(last[-1]) if len(last) else len(seen)) * step_px
    return "open" if unseen > END_COVER_PX else kind


def _bent_bridge(centre: F64, kept: NDArray[np.bool_], long: int, n_fit: int) -> float | None:
    """The largest turn (deg) of a long unseen stretch's chord against the seen line beside it.

    For each hole of at least ``long`` samples inside ``kept``, the chord across it (between
    the last seen samples) against the direction of the seen line over ``n_fit`` samples on
    each side. A joint under a tack weld goes straight on (a curve of 500 px radius turns by
    about 12 deg over a 200 px patch); a path that left one line for another crosses between
    them. Returns the turn when above 20 deg, else None.
    """
    worst = 0.0
    for a, b in runs_of(~kept):
        if b - a < long or a == 0 or b == len(kept):
            continue
        chord = centre[b] - centre[a - 1]
        chord /= np.linalg.norm(chord) + 1e-12
        for side in (centre[max(0, a - n_fit):a][kept[max(0, a - n_fit):a]],
                     centre[b:b + n_fit][kept[b:b + n_fit]]):
            if len(side) < 4:
                continue
            d = side[-1] - side[0]
            d /= np.linalg.norm(d) + 1e-12
            worst = max(worst, float(np.degrees(np.arccos(np.clip(abs(d @ chord), 0, 1)))))
    return worst if worst > 20.0 else None


def _drop_short_runs(mask: NDArray[np.bool_], n: int) -> NDArray[np.bool_]:
    """``mask`` without its runs of set samples shorter than ``n``."""
    out = mask.copy()
    for a, b in runs_of(mask):
        if b - a < n:
            out[a:b] = False
    return out


def _bridge(centre: F64, kept: NDArray[np.bool_], n_fit: int) -> F64:
    """``centre`` with the stretches not ``kept`` replaced by straight lines between the kept ones.

    Covered stretches inside the seam: linear between the last kept points on both sides.
    Covered stretches at an end: the line fitted to the ``n_fit`` kept points next to them, on to
    the end (a gap hidden by a tack weld at the image border goes on straight).
    """
    out = centre.copy()
    idx = np.flatnonzero(kept)
    if len(idx) < 2:
        return out
    inner = np.arange(idx[0], idx[-1] + 1)
    for k in range(2):
        out[inner, k] = np.interp(inner, idx, centre[idx, k])
    for sl, ref in ((np.arange(0, idx[0]), idx[:n_fit]), (np.arange(idx[-1] + 1, len(out)),
                                                          idx[-n_fit:])):
        if len(sl) and len(ref) >= 2:
            for k in range(2):
                coef = np.polyfit(ref.astype(np.float64), centre[ref, k], 1)
                out[sl, k] = np.polyval(coef, sl.astype(np.float64))
    return out


def _darkest(grey: NDArray[np.uint8], lut: F64, pts: F64, nrm: F64, w: float,
             tol: float) -> tuple[F64, F64]:
    """Offset (px along ``nrm``) of the darkest point near each of ``pts`` and its relative depth.

    The profile is smoothed over about a quarter of the gap width; the minimum within ``tol`` of
    the path is compared with both sides, read at half a width plus 3 px beyond it: the relative
    depth is (darker side - floor) / darker side.
    """
    reach = tol + w / 2 + 4.0
    x = np.arange(-reach, reach + 1e-9, 1.0)
    U = pts[:, 0:1] + nrm[:, 0:1] * x[None, :]
    V = pts[:, 1:2] + nrm[:, 1:2] * x[None, :]
    prof, _ = bilinear(grey, lut, U, V)
    sig = max(1.0, w / 4.0)
    kx = np.arange(-int(3 * sig), int(3 * sig) + 1)
    ker = np.exp(-0.5 * (kx / sig) ** 2)
    ker /= ker.sum()
    # Rows smoothed at once, the ends held (edge padding): the same as np.convolve on each padded
    # row (the kernel is symmetric), without a Python call per row (and without scipy, whose
    # import costs more than a detection: controller/vision/scipy_equivalents.py).
    sm = cv2.filter2D(prof, cv2.CV_64F, ker[None, :], borderType=cv2.BORDER_REPLICATE)
    zone = np.abs(x) <= tol
    zi = np.flatnonzero(zone)
    j = zi[np.argmin(sm[:, zone], axis=1)]
    rows = np.arange(len(pts))
    jm, jp = np.clip(j - 1, 0, len(x) - 1), np.clip(j + 1, 0, len(x) - 1)
    a, b, cc = sm[rows, jm], sm[rows, j], sm[rows, jp]
    den = a - 2 * b + cc
    frac = np.where(den > 1e-12, 0.5 * (a - cc) / np.maximum(den, 1e-12), 0.0)
    off = x[j] + np.clip(frac, -0.5, 0.5)
    d = int(round(w / 2 + 3.0))
    left = sm[rows, np.clip(j - d, 0, len(x) - 1)]
    right = sm[rows, np.clip(j + d, 0, len(x) - 1)]
    side = np.minimum(left, right)
    rel = (side - b) / np.maximum(side, 1e-6)
    return off, rel


def _near_border(pt: F64, W: int, H: int, margin: float) -> bool:
    return bool(pt[0] < margin or pt[1] < margin or pt[0] > W - 1 - margin
                or pt[1] > H - 1 - margin)
