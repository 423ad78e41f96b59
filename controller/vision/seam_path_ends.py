"""The ends of a whole-image valley path: where the seam it follows stops.

A valley path (:mod:`controller.vision.seam_robust`) runs through the whole working image, on to
the image border. Where the joint stops before that, the path goes on over whatever is beyond:
the table, a covered stretch, another line. Here the path's ends are brought back to the seam:
the gap followed from where it was last seen (:func:`follow_ends`), and a long unseen stretch at
an end cut off where the sheets end or where it runs over a dark table
(:func:`trim_at_sheet_borders`). Pixels are (u, v) in the distorted image.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from controller.vision.seam_ends import darker_than_sheets, end_offset
from controller.vision.seam_params import F64, DetectParams
from controller.vision.seam_profiles import bilinear, fit_at, track_on

END_COVER_PX = 100.0  # longest unseen stretch at an end carried on to it (a tack weld there)
END_REF = 25  # samples where the gap is seen next to an unseen end stretch, to compare it with
_SIDE_PX = 12.0  # beside the gap's edge, where the sheets are read
_START = 16  # samples where the gap was last seen, to follow it on from


def trim_at_sheet_borders(grey: NDArray[np.uint8], lut: F64, centre: F64,
                           kept: NDArray[np.bool_], w_med: float,
                           p: DetectParams) -> tuple[int, int]:
    """The samples of ``centre`` (px) to keep, ``[lo, hi)``: cut where the seen gap meets a border.

    A path through the whole image runs on to the image border; where the gap was last seen
    more than ``END_COVER_PX`` before it and the sheets are seen to end right there (a sheet
    border across the seam, :func:`controller.vision.seam_ends.end_offset`), or the stretch
    beyond a tack weld's length from there runs over a dark table (:func:`over_table`), what
    follows is the table (a dark table carries the valley on), not a covered stretch of the
    joint. A long unseen stretch between sheets that go on (a ragged or covered gap) is kept.
    ``centre`` (px) and ``kept`` (the gap seen) per path sample, ``p.step_px`` apart.
    """
    idx = np.flatnonzero(kept)
    lo, hi = 0, len(kept)
    for first in (True, False):
        i = int(idx[0]) if first else int(idx[-1])
        unseen = i if first else len(kept) - 1 - i
        if unseen * p.step_px <= END_COVER_PX:
            continue
        j = int(idx[min(5, len(idx) - 1)]) if first else int(idx[max(0, len(idx) - 6)])
        tang = centre[i] - centre[j]
        tang /= np.linalg.norm(tang) + 1e-12
        _, kind, _ = end_offset(grey, lut, centre[i], tang, w_med)
        # Beyond a tack weld's length from where the gap was last seen.
        n_cover = int(END_COVER_PX / p.step_px)
        outer = np.arange(0, i - n_cover) if first else np.arange(i + 1 + n_cover, len(kept))
        ref = idx[:END_REF] if first else idx[-END_REF:]
        if kind == "sheet border" or over_table(grey, lut, centre, outer, ref, w_med):
            if first:
                lo = i
            else:
                hi = i + 1
    return lo, hi


def over_table(grey: NDArray[np.uint8], lut: F64, centre: F64, stretch: NDArray[np.intp],
                ref: NDArray[np.intp], w_med: float) -> bool:
    """Whether the samples ``stretch`` of ``centre`` (px) run over a dark table, not between sheets.

    Read on both sides, half the gap plus ``_SIDE_PX`` away. Where the gap is seen (``ref``)
    that is the two sheets. A path carried on past the sheets' end over a dark table has table
    on both sides all along; a covered stretch of the joint (a tack weld: a dark crater, a
    bright bead) or a ragged one has sheet or bead as bright as the sheets somewhere on one
    side: the stretch is table when even the brighter side at each sample is darker than the
    sheets (:func:`controller.vision.seam_ends.darker_than_sheets`).
    """
    der = np.gradient(centre, axis=0)
    der /= np.linalg.norm(der, axis=1, keepdims=True) + 1e-12
    nrm = np.column_stack([-der[:, 1], der[:, 0]])
    off = w_med / 2 + _SIDE_PX
    levels = []
    for sel in (ref, stretch):
        sides = []
        for o in (-off, off):
            q = centre[sel] + o * nrm[sel]
            val, inside = bilinear(grey, lut, q[:, 0:1], q[:, 1:2])
            sides.append(np.where(inside[:, 0], val[:, 0], np.nan))
        levels.append(np.vstack(sides))
    # (fmin / fmax take the side inside the image where only one is.)
    sheet = np.fmin(*levels[0])
    sheet = sheet[np.isfinite(sheet)]
    brighter = np.fmax(*levels[1])
    brighter = brighter[np.isfinite(brighter)]
    if len(sheet) < 3 or len(brighter) < 3:
        return False
    return darker_than_sheets(brighter, float(np.median(sheet)))


def follow_ends(grey: NDArray[np.uint8], lut: F64, centre: F64, seen: NDArray[np.bool_],
                width: F64, p: DetectParams) -> tuple[F64, NDArray[np.bool_], F64]:
    """(centre, seen, width) with each end's unseen stretch replaced by the gap followed to its end.

    The valley path is a smoothed line through the working image: where the seam reaches a dark
    table it can run straight on into the table while the gap curves away, and the profiles read
    across the path stop seeing the gap some way before the sheets end. From the last samples
    where the gap was seen, the gap is followed on (:func:`track_on`, profiles predicted from the
    last good centres). It replaces the path's end when it is followed to the image border, or
    to a sheet border with the path beyond it over a table (:func:`over_table`): what the path
    did there is not the seam. Otherwise (a tack weld at the end, a line fading out, a chessboard
    square's corner with more squares beyond) the path is kept as it was, for the end rules.
    ``centre`` (px), ``seen`` and ``width`` (px) per path sample, ``p.step_px`` apart.
    """
    for first in (True, False):
        if first:
            centre, seen, width = centre[::-1], seen[::-1], width[::-1]
        followed = _followed(grey, lut, centre, seen, p)
        if followed is not None:
            last, new, ok, w_new = followed
            centre = np.vstack([centre[:last + 1], new])
            seen = np.append(seen[:last + 1], ok)
            width = np.append(width[:last + 1], w_new)
        if first:
            centre, seen, width = centre[::-1], seen[::-1], width[::-1]
    return centre, seen, width


def _followed(grey: NDArray[np.uint8], lut: F64, centre: F64, seen: NDArray[np.bool_],
              p: DetectParams) -> tuple[int, F64, NDArray[np.bool_], F64] | None:
    """At the path's last end: (last seen sample, followed centres, seen, widths) or None."""
    idx = np.flatnonzero(seen)
    last = int(idx[-1]) if len(idx) else -1
    if len(seen) - 1 - last < 3 or last < _START - 1:
        return None
    pts = centre[last - _START + 1:last + 1]
    der = np.gradient(pts, axis=0)
    der /= np.linalg.norm(der, axis=1, keepdims=True) + 1e-12
    fit = fit_at(grey, lut, pts, np.column_stack([-der[:, 1], der[:, 0]]), p)
    if int(fit["valid"][-8:].sum()) < 6:
        return None
    tail = (len(seen) - 1 - last) * p.step_px
    fit = track_on(grey, lut, fit, p, at_end=True, max_px=tail + 200.0)
    ok = fit["valid"][_START:]
    n = int(np.flatnonzero(ok)[-1]) + 1 if ok.any() else 0
    # Followed, not guessed: most of the profiles on the way show the gap.
    if n < 2 or not ok[0] or ok[:n].mean() < 0.75:
        return None
    new, w_new = fit["centre"][_START:_START + n], fit["width"][_START:_START + n]
    tang = new[-1] - (new[n - 4] if n >= 4 else pts[-1])
    tang = tang / (np.linalg.norm(tang) + 1e-12)
    w_med = float(np.median(w_new[ok[:n]]))
    _, kind, _ = end_offset(grey, lut, new[-1], tang, w_med)
    rest = np.arange(min(last + 1 + n, len(seen)), len(seen))
    if kind == "image border" or (kind.endswith("sheet border") and (
            len(rest) < 3 or over_table(grey, lut, centre, rest, idx[-END_REF:], w_med))):
        return last, new, ok[:n], w_new
    return None
