"""Where a gap opens out between two rounded plate corners: the end read from the gap's width.

Where both plates end in a rounded corner, each sheet's edge curves away from the gap: the gap
widens, slowly at first (a circle of radius r recedes by u^2 / 2r), then opens onto the table.
The sheets stop facing each other where the gap is twice its width (the simulator's truth and
the issue's definition of a ``joint_end``). A border read as a step along lines parallel to the
seam (:mod:`controller.vision.seam_border`) misses such an edge when the radius is large: it
crosses those lines at a shallow angle, with no sharp step.

:func:`widening_end` reads the two edges on profiles *across* the seam instead, station by
station along it, and returns where their distance has grown by the gap's width over what it
was along the seam before. A line that fades out inside a sheet (a pen line, a scratch) does not
widen: the sheet goes on across its end, and its edges close in. A dot or marker ring on the line
widens it and closes again within its diameter: the gap must stay open over ``_STAY_PX``.

It is used as a check on a sheet border read beside the gap
(:func:`controller.vision.seam_ends.end_offset`: a border past this point is unsure), not as an
end by itself: as the end where nothing else read one, it added wrong seams on the extended
tuning part (a shadow band beside the gap widens its fitted width, so the doubling is read
late; a tack weld's dark crater looks like the gap opening out), 7e44936.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from controller.vision.seam_params import F64
from controller.vision.seam_profiles import bilinear

_REACH_PX = 40.0  # how far past the gap's half width each edge is followed
_BASE_PX = (-70.0, -30.0)  # the stretch before the end point read for the gap's width there
_AHEAD_PX = 160.0  # how far past the end point the end is looked for
_STAY_PX = 60.0  # the gap must stay open this far past the end (at least 8 gap widths)
_BAND = 0.15  # an edge: where the profile comes within this share of the sheet's level


def widening_end(grey: NDArray[np.uint8], lut: F64, e_pt: F64, tang: F64,
                 w_med: float) -> float | None:
    """Distance (px, along ``tang``) from ``e_pt`` to where the gap has opened to twice its width.

    ``e_pt`` (u, v) px is the last point of the seam measured and ``tang`` the unit direction
    beyond it; ``w_med`` the gap's fitted width (px). Stations every px from 70 px before
    ``e_pt`` to ``_AHEAD_PX`` past it carry a profile across (``_REACH_PX`` past the gap's half
    width on each side); on each, the two sheet edges are where the brightness, walking out from
    the middle between the edges of the station before, comes within ``_BAND`` of that side's
    sheet level (read 30-70 px before ``e_pt``) and stays there for 3 px. The gap's own width is
    its dark core's there (at most ``w_med``).

    Returns None (no such end) unless: the gap is darker than both sheets before ``e_pt`` (by
    25 % or more); the edges' distance grows by the gap's width over its median before
    ``e_pt`` at some station from 8 px before ``e_pt`` on (not already at the first: the end
    is then before the window); up to there the gap was seen all along (the distance never
    under half of what it was); both edges recede over the last ``2 w_med + 10`` px before it,
    each by a fifth of ``w_med`` or more (two corners, not a line merging from one side); and
    from there it stays open for ``max(_STAY_PX, 8 w_med)`` px (or to the image border, at least
    half that far), grown by twice the gap's width at the last station (a dot closes again).
    """
    nrm = np.array([-tang[1], tang[0]])
    reach = w_med / 2 + _REACH_PX
    offs = np.arange(-reach, reach + 1e-9, 0.5)
    stay = max(_STAY_PX, 8.0 * w_med)
    ss = np.arange(_BASE_PX[0], _AHEAD_PX + stay + 1e-9, 1.0)
    pts = e_pt + ss[:, None, None] * tang + offs[None, :, None] * nrm
    val, inside = bilinear(grey, lut, pts[..., 0].ravel(), pts[..., 1].ravel())
    val = val.reshape(len(ss), len(offs))
    whole: NDArray[np.bool_] = np.asarray(inside.reshape(len(ss), len(offs)).all(axis=1))
    base = (ss <= _BASE_PX[1]) & whole
    if base.sum() < 16:
        return None
    mid = len(offs) // 2
    near = np.abs(offs) <= w_med / 2 + 1.0
    floor = float(np.median(val[base][:, near].min(axis=1)))
    # The sheets' levels: a cut face or a shadow band beside the gap is darker than its sheet,
    # and counts with the gap (its width is the same before the end and cancels).
    sheet_l = float(np.percentile(val[base][:, offs <= -w_med / 2 - 3], 75))
    sheet_r = float(np.percentile(val[base][:, offs >= w_med / 2 + 3], 75))
    if min(sheet_l, sheet_r) * 0.75 < floor:
        return None
    left, right = _edges(val, whole, offs, mid, (sheet_l, sheet_r))
    width = right - left
    w_base = _median_or_nan(width[base])
    if not np.isfinite(w_base) or w_base > w_med + 2 * _REACH_PX / 3:
        return None
    # The gap opens to twice *its* width: the dark core's, which a shadow band or a valley
    # path's width estimate beside it would overstate.
    w_gap = min(w_med, _core_width(val[base], offs, near, floor, min(sheet_l, sheet_r)))
    grown = width - w_base
    # A running median over 5 stations: one profile across a texture stripe is noise.
    g = np.array([_median_or_nan(grown[max(i - 2, 0):i + 3]) for i in range(len(grown))])
    open_ = (g >= w_gap) | ~np.isfinite(g)
    cand = np.flatnonzero(open_ & (ss >= -8.0) & (ss <= _AHEAD_PX) & whole)
    first = int(np.searchsorted(ss, -8.0))
    for i in cand[:1]:
        if i == first:
            # Open already where the search starts: the end lies before it, unread.
            return None
        # The gap is seen all the way from before the end point to the end: a line that fades
        # out (its edges close in) and a dark patch further on (another line, a plate corner
        # beside it) is no gap opening.
        run = (ss > _BASE_PX[1]) & (ss < ss[i])
        if np.any(~(np.abs(g[run]) < np.inf) | (width[run] < 0.5 * w_base)):
            return None
        # Both sheets' edges recede toward the end (two corners), each by a share of the
        # widening over the last stretch: a line merging into it or a patch beside it moves one.
        back = int(np.searchsorted(ss, ss[i] - 2.0 * w_med - 10.0))
        rec = (left[back] - left[i], right[i] - right[back])
        if not all(np.isnan(r) or r >= 0.2 * w_med for r in rec):
            return None
        last = min(int(np.searchsorted(ss, ss[i] + stay)), len(ss) - 1)
        seen = whole[i:last + 1]
        n_seen = int(np.argmin(seen)) if not seen.all() else len(seen)
        if n_seen < stay / 2:
            return None
        j = i + n_seen - 1
        if not open_[i:j + 1].all():
            return None
        if np.isfinite(g[j]) and g[j] < 2.0 * w_med:
            return None
        a, b = (float(g[i - 1]), float(g[i])) if i > 0 else (np.nan, np.nan)
        if not (np.isfinite(a) and np.isfinite(b) and a < w_gap <= b):
            return float(ss[i])
        # Between the two stations, where the growth passes the gap's width.
        return float(ss[i - 1] + (w_gap - a) / (b - a))
    return None


def _median_or_nan(x: F64) -> float:
    """Median of the finite values of ``x``; NaN when there are none (no warning)."""
    fin = x[np.isfinite(x)]
    return float(np.median(fin)) if len(fin) else float("nan")


def _core_width(rows: F64, offs: F64, near: NDArray[np.bool_], floor: float,
                sheet: float) -> float:
    """Median width (px) of the dark core on ``rows``: the run below half-way to ``sheet``.

    On each profile the run of samples below the level half-way from ``floor`` to ``sheet``
    around the darkest sample within ``near`` (the gap's own width about the middle).
    """
    half = 0.5 * (floor + sheet)
    step = float(offs[1] - offs[0])
    idx = np.flatnonzero(near)
    out = []
    for row in rows:
        j = int(idx[np.argmin(row[idx])])
        below = row < half
        lo, hi = j, j
        while lo > 0 and below[lo - 1]:
            lo -= 1
        while hi < len(row) - 1 and below[hi + 1]:
            hi += 1
        out.append((hi - lo + 1) * step)
    return float(np.median(out))


def _edges(val: F64, whole: NDArray[np.bool_], offs: F64, mid: int,
           sheets: tuple[float, float]) -> tuple[F64, F64]:
    """Left and right edge offsets (px) on each station's profile; NaN where not found.

    Walking out from the middle between the previous station's edges (the first station: the
    profile's middle), the first place where the profile stays within ``_BAND`` of that side's
    sheet level (``sheets``) for 6 samples (3 px): the table beyond the sheets may be darker or
    brighter than they are. A station not wholly inside the image keeps the last middle.
    """
    n = 6
    left = np.full(len(val), np.nan)
    right = np.full(len(val), np.nan)
    m = mid
    for i in range(len(val)):
        if not whole[i]:
            continue
        row = val[i]
        up_l = np.abs(row[m::-1] - sheets[0]) <= _BAND * sheets[0]
        up_r = np.abs(row[m:] - sheets[1]) <= _BAND * sheets[1]
        jl, jr = _first_run(up_l, n), _first_run(up_r, n)
        if jl is not None:
            left[i] = offs[m - jl]
        if jr is not None:
            right[i] = offs[m + jr]
        if jl is not None and jr is not None:
            m = (2 * m - jl + jr) // 2
    return left, right


def _first_run(up: NDArray[np.bool_], n: int) -> int | None:
    """Index of the first of ``n`` consecutive True values in ``up``, or None."""
    if len(up) < n:
        return None
    runs = np.lib.stride_tricks.sliding_window_view(up, n).all(axis=1)
    return int(np.argmax(runs)) if runs.any() else None
