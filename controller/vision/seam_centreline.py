"""The sub-pixel centreline of one candidate, from its profiles, with honest ends.

The longest run of good profiles (short interruptions by a crossing scratch are bridged) is kept;
outliers are dropped and the centreline is smoothed by a local quadratic (Savitzky-Golay) fit over
arc length, which follows any shape without the curling of a global polynomial and without
shrinking curves; the ends come from :mod:`controller.vision.seam_ends`. The candidate is then
scored, or rejected with the reason.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from controller.errors import SeamguideError
from controller.vision.scipy_equivalents import CubicSpline, savgol_filter
from controller.vision.seam_ends import end_offset, measure_tails
from controller.vision.seam_params import (
    COVERED_END,
    F64,
    OPEN_END,
    Candidate,
    DetectParams,
    runs_of,
)
from controller.vision.seam_profiles import fit_at, resample, track_on
from controller.vision.seam_shadow import split_shadow

_MAX_PATCHES = 10  # covered patches (tack welds) crossed per candidate
#: A quadratic bridging a long hole that misses the samples it was fitted to by more than this
#: (RMS, px) does not follow the seam there: on a ragged gap the samples wander by 1-2 px; a pen
#: line crossing an S-bent seam (pen hard tuning 50054) left a hole whose 160 px quadratic on
#: each side missed them by 3.5 px and bridged it 5 px off.
BRIDGE_MISFIT_PX = 2.5


#: What a refusal says of a band wider than the scale's widest gap (seam_detect reads it).
TOO_WIDE = "wider than the widest gap at this scale"
#: Share of a candidate's profiles fitting a band wider than ``max_gap_px`` (and passing every
#: other test) from which a refusal says so (:func:`_too_wide`).
WIDE_SHARE = 0.25


def _too_wide(fit: dict[str, Any], p: DetectParams) -> str:
    """What a refusal adds where the profiles fit a band wider than the scale's widest gap.

    Measured again at the band's own scale, such bands were as often a shadow beside a gap or
    a T-corner's crossbar as a wide gap (README, *Measured and not kept, eighteenth session*):
    the detector does not widen its scale on its own; the working distance and the joint's
    gap do (:func:`controller.vision.seam_scale.params_for_scale`). "" otherwise.
    """
    too_wide = fit["too_wide"]
    if not too_wide.size or too_wide.mean() < WIDE_SHARE:
        return ""
    w = float(np.median(fit["width"][too_wide]))
    return (f"; {100 * too_wide.mean():.0f} % of them fit a dark band {w:.0f} px wide, "
            f"{TOO_WIDE} ({p.max_gap_px:.0f} px)")


def scale_advice(exc: SeamguideError, traced: list[list[Candidate]], p: DetectParams
                  ) -> SeamguideError:
    """``exc`` saying what to give where a candidate fitted a band wider than the scale takes.

    The detector's pixel scales (``p.max_gap_px``) are the defaults' unless the working
    distance and the joint's gap set them (:func:`controller.vision.seam_scale.params_for_scale`);
    a gap wider than that is refused by the profiles (:data:`TOO_WIDE`), and the
    refusal should say how to measure it. Returns ``exc`` itself where no candidate did.
    """
    n = len({id(c) for look in traced for c in look if TOO_WIDE in c.why_rejected})
    if not n:
        return exc
    if p.max_gap_px > DetectParams().max_gap_px:  # the scales were set already
        todo = ("if the joint's gap is that wide, check the working distance and the widest "
                "gap given (--distance-mm, --gap-mm; in a job, [seam] gap_mm)")
    else:
        todo = ("if the joint's gap is that wide, give the working distance and the joint's "
                "gap (detect --calibration C --distance-mm Z --gap-mm LO HI; in a job, its "
                "[seam] gap_mm) to measure it")
    return type(exc)(f"{exc}; {n} line(s) looked at fit a dark band {TOO_WIDE} "
                     f"({p.max_gap_px:.0f} px), a wide gap or a gap with a shadow or a mark "
                     f"beside it: {todo}", **exc.details)


def refine(grey: NDArray[np.uint8], lut: F64, c: Candidate, p: DetectParams,
           crossed: int = 0) -> None:
    """Fill in ``c.points``, ``c.width``, ``c.end_kinds`` and ``c.score``, or ``c.why_rejected``.

    Where an end is a covered patch (a tack weld: the gap goes on beyond it) the candidate is
    extended to the gap seen beyond and refined again (``crossed``: patches crossed so far); a
    covered end with no gap seen beyond stands.
    """
    c.band_points, c.band_width = None, None
    pts, nrm = resample(c.polyline, p.step_px, extend=24.0)
    fit = fit_at(grey, lut, pts, nrm, p)
    # The coarse search loses a faint stretch of the gap (thin, blurred, low contrast); the
    # profiles still see it, so follow it on at full resolution until they stop fitting.
    fit = track_on(grey, lut, fit, p, at_end=True)
    fit = track_on(grey, lut, fit, p, at_end=False)
    # A shadow band beside the gap widens the dark band to one side: the gap is its darker core.
    band_fit = fit
    fit, shadow = split_shadow(fit, p)
    c.stats.update(shadow)
    valid = fit["valid"]
    if valid.sum() >= 8:
        # Where a mark crosses the seam at a shallow angle the two valleys merge into one wide
        # one whose centre is pulled toward the mark: not a measurement of the gap.
        w_typ = float(np.median(fit["width"][valid]))
        valid = valid & (fit["width"] < 1.6 * w_typ + 1.0)
    # Longest run of valid profiles, bridging short interruptions; short islands at its ends are
    # dropped (a lone fit on the sheet border beyond the seam's end is not the seam).
    bridge = int(round(p.bridge_px / p.step_px))
    # A candidate extended across covered patches was seen to go on beyond each: every hole up
    # to the longest patch looked across is bridged, however short the pieces between.
    short = int(round(300.0 / p.step_px)) if crossed else None
    run = _longest_bridged_run(valid, bridge, min_island=max(3, int(round(12 / p.step_px))),
                               bridge_short=short)
    if run is None or (run[1] - run[0]) * p.step_px < p.min_length_px * 0.5:
        c.why_rejected = (f"candidate of {c.length_px:.0f} px has no long run of gap profiles "
                          f"({int(valid.sum())} of {len(valid)} good){_too_wide(fit, p)}")
        return
    i0, i1 = run
    sel = np.arange(i0, i1 + 1)
    ok = _trim_rims(valid[sel], hole=3, rim=int(round(16.0 / p.step_px)))
    # The run ends at its last measured samples (a patch at an end is not bridged into).
    kept = np.flatnonzero(ok)
    sel, ok = sel[kept[0]:kept[-1] + 1], ok[kept[0]:kept[-1] + 1]
    pts_run = fit["centre"][sel].copy()
    t = np.arange(len(sel), dtype=np.float64)
    # Split off a shadow: how far the core's centre lies from the whole band's, per sample, to
    # give the band's centreline too (one view cannot tell a shadow from a cut face in the gap;
    # two can: controller.stereo.band_check).
    split = bool(shadow.get("shadow_split"))
    shift = (fit["centre"][sel] - band_fit["centre"][sel]) if split else None
    if (~ok).any():
        # Bridged samples (a hole in the gap) follow a cubic through the measured ones; across a
        # long hole (a tack weld) a quadratic fitted to the gap on both sides (an interpolating
        # cubic swings with the last samples' noise: millimetres once triangulated).
        pts_run[~ok] = CubicSpline(t[ok], pts_run[ok], axis=0)(t[~ok])
        pts_run = _bridge_long_holes(t, pts_run, ok, long=int(round(40.0 / p.step_px)),
                                     reach=int(round(160.0 / p.step_px)))
    win = int(min((len(sel) - 1) // 2 * 2 + 1, 2 * int(round(14 / p.step_px)) + 1))
    if win >= 5:
        sm = savgol_filter(pts_run, win, 2, axis=0, mode="interp")
        dev = np.linalg.norm(pts_run - sm, axis=1)
        mad = np.median(dev[ok]) + 1e-6
        good = ok & (dev < max(4 * mad, 0.6))
        if (~good).any():
            pts_run[~good] = CubicSpline(t[good], pts_run[good], axis=0)(t[~good])
            pts_run = _bridge_long_holes(t, pts_run, good, long=int(round(40.0 / p.step_px)),
                                         reach=int(round(160.0 / p.step_px)))
        pts_run = savgol_filter(pts_run, win, 2, axis=0, mode="interp")
    if shift is not None:
        shift = np.column_stack([np.interp(t, t[ok], shift[ok, k]) for k in range(2)])
        if win >= 5:
            shift = savgol_filter(shift, win, 2, axis=0, mode="interp")
    depth_med = float(np.median(fit["depth"][sel][ok]))
    # Honest ends: where the sheets end (or the image does), found from the two sides separately.
    # Profiles within a profile length of an end may be crossed by the sheet border, so the
    # last stretch of the curve is extrapolated from the samples before it, only to guide short
    # profiles that measure it again (:func:`measure_tails`): a quadratic extrapolated over tens
    # of pixels drifts by 1-2 px on a curve.
    w_med = float(np.median(fit["width"][sel][ok]))
    w_run = fit["width"][sel]
    m = int(np.ceil(p.half_width_px / p.step_px)) + 1
    # The quadratic is fitted to 24 samples (~100 px): on a ragged gap the centres wander by
    # the edges' jag, and a curvature read off 12 samples curled the extrapolated end by several
    # px sideways (tuning part: 6 fewer wrong seams, one more found, than with 12).
    n_fit = 24
    use_extrap = len(pts_run) >= 2 * (m + n_fit)
    parts: list[F64] = []
    ders: list[F64] = []
    end_kinds: list[str] = []
    beyonds: list[F64 | None] = []
    lo, hi = 0, len(pts_run)
    for first in (True, False):
        seq = pts_run if not first else pts_run[::-1]  # seq runs toward this end
        L = len(seq)
        if use_extrap:
            tt = np.arange(L - m - n_fit, L - m, dtype=np.float64)
            coef = np.polyfit(tt - (L - 1), seq[L - m - n_fit:L - m], 2)
            e_pt = np.asarray(np.polyval(coef, 0.0), np.float64)
            d_pt = np.array([np.polyval(np.polyder(coef[:, k]), 0.0) for k in range(2)])
            tang = d_pt / (np.linalg.norm(d_pt) + 1e-12)
        else:
            e_pt = seq[-1]
            tang = seq[-1] - seq[max(0, L - 4)]
            tang /= np.linalg.norm(tang) + 1e-12
        chord = seq[-1] - seq[max(0, L - 1 - int(round(200.0 / p.step_px)))]
        chord = chord / (np.linalg.norm(chord) + 1e-12)
        k_end, end_kind, beyond = end_offset(grey, lut, e_pt, tang, w_med, chord)
        end_kinds.append(end_kind)
        beyonds.append(beyond)
        if use_extrap:
            # Extrapolated points from the last trusted sample to the end, one per step.
            t_end = k_end / max(float(np.linalg.norm(d_pt)), 1e-9)
            tq = np.arange(-m + 1.0, t_end, 1.0)
            tq = np.append(tq, t_end)
            ext = np.polyval(coef, tq[:, None])
            ders.append(np.column_stack([np.polyval(np.polyder(coef[:, k]), tq)
                                         for k in range(2)]))
            keep_n = L - m
        else:
            ext = (e_pt + k_end * tang)[None, :]
            along = (seq - e_pt) @ tang
            keep_n = int(np.sum(along < k_end - 0.5 * p.step_px))
        if first:
            lo = L - keep_n
        else:
            hi = keep_n
        parts.append(ext)
    if "covered" in end_kinds and crossed < _MAX_PATCHES and any(
            b is not None for b in beyonds):
        # Across the patch to the gap beyond, and the whole candidate again: the profiles across
        # the patch fail, and the run bridges them as a hole (reported as occluded). Where no
        # gap was seen beyond (a patch on the joint with the sheets going on beside it) there
        # is nothing to cross to: measured again and again (up to ten times, until ddc64a6) the
        # same line nearly always read the same end, and otherwise one the line's last px
        # happened to land on (README, *Twenty-sixth session*).
        b0, b1 = beyonds
        poly = np.vstack([b0[::-1] if b0 is not None else pts_run[:0], pts_run,
                          b1 if b1 is not None else pts_run[:0]])
        c.polyline = poly
        c.length_px = float(np.sum(np.linalg.norm(np.diff(poly, axis=0), axis=1)))
        refine(grey, lut, c, p, crossed + 1)
        return
    if use_extrap:
        parts = measure_tails(grey, lut, parts, ders, w_med, p)
    parts[0] = parts[0][::-1]
    c.end_kinds = (end_kinds[0], end_kinds[1])
    if hi - lo < 2:
        c.why_rejected = "seam candidate collapsed when its ends were measured"
        return
    body = pts_run[lo:hi]
    pts_run = np.vstack([parts[0], body, parts[1]])
    c.points = pts_run
    c.bridged = np.concatenate([np.zeros(len(parts[0]), bool), ~ok[lo:hi],
                                np.zeros(len(parts[1]), bool)])
    wb = w_run[lo:hi]
    c.width = np.concatenate([np.full(len(parts[0]), wb[0]), wb, np.full(len(parts[1]), wb[-1])])
    c.depth = depth_med
    if shift is not None:
        sb = shift[lo:hi]
        c.band_points = pts_run - np.vstack([np.repeat(sb[:1], len(parts[0]), axis=0), sb,
                                             np.repeat(sb[-1:], len(parts[1]), axis=0)])
        c.band_width = float(np.median(band_fit["width"][sel][ok]))
    c.valid_frac = float(ok.mean())
    c.resid = float(np.median(fit["rms"][sel][ok] / np.maximum(fit["contrast"][sel][ok], 1e-6)))
    length = float(np.sum(np.linalg.norm(np.diff(pts_run, axis=0), axis=1)))
    if length < p.min_length_px:
        c.why_rejected = f"gap run only {length:.0f} px long (< {p.min_length_px:.0f})"
        return
    c.length_px = length
    if "covered" in c.end_kinds:
        # Stopped by a tack weld or spatter with the same gap beyond: the seam goes on, so this
        # piece's end is not the joint's. The whole-image valley path bridges such patches.
        c.why_rejected = (f"gap of {length:.0f} px stops at a covered patch (a tack weld, "
                          "spatter) with the gap going on beyond it: not an end")
        c.refused = COVERED_END
        # A piece of a seam that goes on: another line is no surer than this one is strong.
        c.rival = True
        c.score = length * c.depth * c.valid_frac
        return
    if "open" in c.end_kinds:
        # A joint ends where a sheet ends or leaves the image; a line that fades out inside a
        # sheet (the sheet going on beside it) is a pen or soapstone line or a scratch, and one
        # that ends where only the sheet on one side does is a plate's outer edge.
        where = "both ends" if c.end_kinds == ("open", "open") else "one end"
        c.why_rejected = (f"dark line of {length:.0f} px fades out inside the sheet at {where} "
                          "(a pen line or scratch, or one plate's outer edge: not a joint)")
        c.refused = OPEN_END
        # Seen to a border at one end, it may be a faint joint whose other end is lost: it is not
        # returned, but a seam only a little stronger than it is not sure either. (Tried and
        # reverted, 2026-12-06: no rival when drawn beside a seam whose ends are both read,
        # seam_decision.fades_beside in dc626fd: extended tuning +7 found, no more wrong; held-out
        # +2 found, +1 wrong, medium 10090 view 0 returned at 1.0 with its end 10 px early. The
        # rival was what refused the seam's own misread end.)
        c.rival = where == "one end"
        c.score = length * c.depth * c.valid_frac if c.rival else 0.0
        return
    c.score = length * c.depth * c.valid_frac


def _bridge_long_holes(t: F64, pts: F64, ok: NDArray[np.bool_], long: int,
                       reach: int) -> F64:
    """``pts`` with each hole of ``long`` samples or more in ``ok`` refilled by a quadratic.

    The quadratic (per coordinate, over the sample index ``t``) is fitted by least squares to
    the measured samples within ``reach`` on both sides of the hole: it follows a curved seam
    and averages the noise of the samples next to the hole. Where it misses them by more than
    :data:`BRIDGE_MISFIT_PX` (RMS, px) the seam bends more than a quadratic follows over that
    span (an S-bend): it is fitted again to as many samples either side as the hole is long.
    """
    out = pts.copy()
    for a, b in runs_of(~ok):
        if b - a < long or a == 0 or b == len(ok):
            continue
        near = ok & (t >= t[a] - reach) & (t < t[b - 1] + reach + 1)
        if near[:a].sum() < 3 or near[b:].sum() < 3:
            continue
        coef = np.polyfit(t[near] - t[a], pts[near], 2)
        miss = pts[near] - np.polyval(coef, (t[near] - t[a])[:, None])
        if np.sqrt(np.mean(np.sum(miss**2, axis=1))) > BRIDGE_MISFIT_PX:
            r = max(long, b - a)
            near = ok & (t >= t[a] - r) & (t < t[b - 1] + r + 1)
            coef = np.polyfit(t[near] - t[a], pts[near], 2)
        tq = t[a:b] - t[a]
        out[a:b] = np.polyval(coef, tq[:, None])
    return out


def _trim_rims(ok: NDArray[np.bool_], hole: int, rim: int) -> NDArray[np.bool_]:
    """``ok`` without the ``rim`` samples next to each hole of ``hole`` samples or more.

    The last profiles before a tack weld or a spatter ball see its rim (and a crater can look
    like the gap beside the line): fits there pull the centreline off by pixels, millimetres
    once triangulated. The centreline is bridged across the wider hole instead. What is left
    of an island between a patch and the run's first or last sample (shorter than ``rim``) is
    the patch's far rim and is dropped too: the run then ends before the patch, and that end
    is judged like any other. ``ok`` is returned unchanged when fewer than 4 samples would
    remain.
    """
    out = ok.copy()
    for a, b in runs_of(~ok):
        if b - a >= hole:
            out[max(a - rim, 0):a] = False
            out[b:b + rim] = False
    # What is left of an island between a patch and the run's end is the patch's far rim.
    islands = runs_of(out)
    if len(islands) > 1:
        for a, b in (islands[0], islands[-1]):
            if b - a < rim:
                out[a:b] = False
    if out.sum() < 4:
        return ok
    return out


def _longest_bridged_run(valid: NDArray[np.bool_], bridge: int, min_island: int,
                         bridge_short: int | None = None) -> tuple[int, int] | None:
    """Longest run of valid samples after joining islands across holes.

    Islands shorter than ``min_island`` are dropped; a hole of up to ``bridge_short`` samples is
    always bridged, one of up to ``bridge`` only between two islands of at least 4 x min_island
    (a long hole is bridged only when the seam is clearly seen on both sides of it).
    """
    short = max(1, bridge // 6) if bridge_short is None else bridge_short
    islands = [(a, b) for a, b in runs_of(valid) if b - a >= min_island]
    if not islands:
        return None
    runs = [list(islands[0])]
    last_len = islands[0][1] - islands[0][0]
    for a, b in islands[1:]:
        hole = a - runs[-1][1]
        long_both = last_len >= 4 * min_island and b - a >= 4 * min_island
        if hole <= short or (hole <= bridge and long_both):
            runs[-1][1] = b
        else:
            runs.append([a, b])
        last_len = b - a
    a, b = max(runs, key=lambda r: r[1] - r[0])
    return a, b - 1
