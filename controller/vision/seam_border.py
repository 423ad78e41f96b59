"""Where a sheet border crosses lines beside the seam, and where it meets the seam.

:func:`side_crossings` finds the sharp, lasting brightness steps along one line;
:func:`border_line` takes the first step on each of five lines parallel to the seam and reads
where the border meets the centreline: a straight border (the line through the most steps) or,
where both sheets' edges curve away from the gap, two rounded plate corners
(:func:`rounded_corners`). Used by :mod:`controller.vision.seam_ends` at each end of the seam.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from controller.vision.seam_params import F64
from controller.vision.seam_profiles import bilinear

_MIN_STEP = 0.25  # relative brightness step that marks a sheet border
#: How much further out than the outer line beside the gap :func:`border_goes_on` looks (px),
#: and how near the straight border's course a step there must lie (px, along the seam).
FAR_PX = (20.0, 40.0)
FAR_TOL_PX = 6.0


class Border(NamedTuple):
    """A sheet border read across the lines beside the seam (:func:`border_line`).

    ``k``: px along the seam where it meets the centreline, or None (no border); ``unsure``: a
    rival line is as well supported; ``slope``: px along per px across (the steps of line
    ``o`` lie at ``k + slope * o``); ``sides``: whether lines left (negative offsets) and right
    of the gap step on it; ``rounded``: read as two rounded plate corners, not a straight line.
    """

    k: float | None
    unsure: bool = False
    slope: float = 0.0
    sides: tuple[bool, bool] = (False, False)
    rounded: bool = False


def border_line(offs: tuple[float, ...], steps: list[list[float]],
                w: float | None = None) -> Border:
    """Distance along the seam at which a straight border through the steps meets the centreline.

    ``steps[i]`` are the step positions found on the line at offset ``offs[i]`` across the seam,
    inner first; the first one on each line is where that line leaves its sheet, unless the
    sheet and the table look alike there (then it is something beyond, such as a table hole).
    Every pair of first steps defines a border line (crossing the seam at 15 degrees or more);
    the one most lines agree with (within 1.5 px) wins, the inner one on a tie, and is fitted
    to them. A lone step, seen on one line only, is no border: where only the centreline
    steps the sheet continues on both sides (the end of a pen line inside a sheet).
    Also says whether the end is unsure: the winner is seen on two lines only and another line
    seen on as many crosses the seam more than 3 px away (a mark meeting the seam at the border
    can do that; the inner one is then no better a guess than the other). Where the best line
    is seen on fewer than four lines and the steps are those of two rounded plate corners, the
    end is read as such instead (:func:`rounded_corners`, with the gap's width ``w``): three
    steps of a curved border can lie on a line by chance, a line through them says nothing
    about where the gap opens. (Four or more agreeing: a straight border, whose steps on the
    inner lines a ragged edge can move by its jag.)
    """
    firsts = [(o, s[0]) for o, s in zip(offs, steps, strict=True) if s]
    # (-agreeing lines, k at the centreline, slope, offsets of the agreeing lines)
    best: tuple[int, float, float, F64] | None = None
    fits: list[tuple[int, float]] = []
    for i in range(len(firsts)):
        for j in range(i + 1, len(firsts)):
            (oa, ka), (ob, kb) = firsts[i], firsts[j]
            s = (kb - ka) / (ob - oa)
            if abs(s) > 3.7:
                continue
            sel = [(o, k) for o, k in firsts if abs(k - ka - s * (o - oa)) <= 1.5]
            o_arr, k_arr = np.array(sel).T
            slope, k0 = (float(v) for v in np.polyfit(o_arr, k_arr, 1))
            fits.append((-len(sel), k0))
            if best is None or (-len(sel), k0) < best[:2]:
                best = (-len(sel), k0, slope, o_arr)
    if best is not None:
        k_round = rounded_corners(offs, steps, w) if w is not None and best[0] > -4 else None
        if k_round is not None:
            return Border(k_round, False, 0.0, (True, True), True)
        rivals = [k for n, k in fits if n == best[0] and abs(k - best[1]) > 3.0]
        return Border(best[1], best[0] == -2 and bool(rivals), best[2],
                      (bool(np.any(best[3] < 0)), bool(np.any(best[3] > 0))))
    # Only the centreline steps: the dark line ends but the sheet goes on beside it on both
    # sides. That is how a pen or soapstone line or a scratch ends inside a sheet; a joint ends
    # where a sheet does. Not an end (the caller calls it open).
    return Border(None)


def border_goes_on(grey: NDArray[np.uint8], lut: F64, e_pt: F64, tang: F64, line: Border,
                   outer_px: float, ks: F64) -> bool:
    """Whether a straight border read beside the gap goes on across the sheets, further out.

    ``line`` was read at the seam's end ``e_pt`` (px; ``tang``: the seam's direction outward) on
    lines up to ``outer_px`` px each side of the centreline, a few px from the gap. There a
    patch of rust or mottle a dozen px across, or the end of a pen line on a brushed sheet,
    steps on every line at about one place, as a border does; a sheet's border runs on across
    its sheet. So on each side that stepped, one of the lines :data:`FAR_PX` further out must
    step (lasting or not: a T-corner's crossbar is a band) within :data:`FAR_TOL_PX` of the
    border's course (``line.k + line.slope * offset``), read over ``ks`` (px along, as
    :func:`side_steps`). A line that leaves the image is no evidence either way. True for no
    border and for rounded corners (their edges curve away: no straight course to follow).
    """
    if line.k is None or line.rounded:
        return True
    H, W = grey.shape
    nrm = np.array([-tang[1], tang[0]])
    for side, stepped in zip((-1.0, 1.0), line.sides, strict=True):
        if not stepped:
            continue
        looked = False
        for extra in FAR_PX:
            o = side * (outer_px + extra)
            q = e_pt + np.outer(line.k + line.slope * o + ks, tang) + o * nrm
            if not np.all((q >= 0) & (q <= np.array([W - 1, H - 1]))):
                continue
            looked = True
            if any(abs(k) <= FAR_TOL_PX for k, _ in side_steps(grey, lut, q, ks)):
                break
        else:
            if looked:
                return False
    return True


def rounded_corners(offs: tuple[float, ...], steps: list[list[float]], w: float) -> float | None:
    """Where the gap (``w`` px wide) has opened to twice its width between two rounded corners.

    ``offs`` are (-2d, -d, 0, d, 2d) as in :func:`controller.vision.seam_ends.end_offset`.
    Where both sheets end in a rounded corner the border is no straight line: each sheet's
    edge curves away from the gap, so on each side the line nearer the gap leaves its sheet
    first and the outer one later. The sheets stop facing each other where the gap is twice
    its width, i.e. where each edge has receded by ``w / 2``: the line at offset ``w`` would
    step there. On each side that point is read from the two lines' steps; the end is the mean
    of the two sides. Returns None unless the four side lines all step and on both sides the
    outer line steps more than 1.5 px after the inner one (a straight border across the seam
    recedes on one side only, if at all: it is read as the line through its steps).
    """
    firsts = {o: s[0] for o, s in zip(offs, steps, strict=True) if s}
    ks = []
    for inner, outer in ((offs[1], offs[0]), (offs[3], offs[4])):
        if inner not in firsts or outer not in firsts or firsts[outer] <= firsts[inner] + 1.5:
            return None
        # How far the edge has receded from the gap at each line, and at the end (w / 2). Near
        # where it starts to curve away a rounded edge recedes as the square of the distance
        # along (a circle of radius r: by u^2 / 2r): the distance goes as the root of the recess.
        a_in, a_out = abs(inner) - w / 2, abs(outer) - w / 2
        # (A gap narrower than 5 px has opened to twice its width before the inner line
        # leaves its sheet: read back from the two steps by the same law.)
        t = float(np.clip((np.sqrt(w / 2) - np.sqrt(a_in)) / (np.sqrt(a_out) - np.sqrt(a_in)),
                          -1.0, 1.0))
        ks.append(firsts[inner] + t * (firsts[outer] - firsts[inner]))
    return float(np.mean(ks))


def side_crossings(grey: NDArray[np.uint8], lut: F64, ps: F64, ks: F64,
                   entered: bool = False) -> list[float]:
    """Where the brightness along the line ``ps`` (at offsets ``ks``) steps sharply and lastingly.

    The lasting ones of :func:`side_steps` (the brightness never comes back past half-way: a dot
    or a glare band on the sheet is left again; the table beyond a border is not), inner first.
    """
    return [k for k, lasting in side_steps(grey, lut, ps, ks, entered) if lasting]


def side_steps(grey: NDArray[np.uint8], lut: F64, ps: F64, ks: F64,
               entered: bool = False) -> list[tuple[float, bool]]:
    """(offset, lasting) of each sharp brightness step along the line ``ps`` (at ``ks``).

    From well inside the sheet (``ks > -14``) outward: a step is where the median brightness
    over the next 6 px differs from the median over the last 6 px by at least 25 %. A dark
    scratch or a texture stripe is a dip too narrow to move a median, and a gradual change of
    light moves it too slowly. Each step is placed where the brightness passes half-way between
    the two levels, and must be sharp (a few pixels of blur). All steps are returned, inner
    first: which one is the sheet border is decided across lines (:func:`border_line`);
    ``lasting``: the brightness never comes back past half-way beyond it.
    ``entered``: also drop the far side of a dip (the line was at the outer level just before).
    A step the brightness comes back from (not ``lasting``) is the near edge of a dark band: a
    dot, or a gap running across the seam's end at a T-corner; the caller decides which.
    """
    val, inside = bilinear(grey, lut, ps[:, 0], ps[:, 1])
    val = np.convolve(np.pad(val, 1, mode="edge"), np.ones(3) / 3, mode="valid")
    # Only samples inside the image count (outside, the border pixels are repeated).
    lim = int(np.argmin(inside)) if not inside.all() else len(ks)
    n_in = int(np.sum(ks <= -14))
    hold = 12  # samples (6 px) on each side of a step
    if n_in < hold or lim - n_in < hold + 2:
        return []
    win = np.lib.stride_tricks.sliding_window_view(val[:lim], hold)
    med = np.median(win, axis=1)  # med[i]: median of val[i:i + hold]
    js = np.arange(n_in, lim - hold + 1)
    behind, ahead = med[js - hold], med[js]
    step = np.abs(ahead - behind)
    big = np.concatenate([[0], (step > _MIN_STEP * np.maximum(np.maximum(behind, ahead), 1e-6))
                          .astype(np.int8), [0]])
    out: list[tuple[float, bool]] = []
    for g0, g1 in zip(np.flatnonzero(np.diff(big) == 1), np.flatnonzero(np.diff(big) == -1),
                      strict=True):
        jj = int(g0) + int(np.argmax(step[g0:g1]))
        j = int(js[jj])
        lvl_in, lvl_out = float(behind[jj]), float(ahead[jj])
        half = 0.5 * (lvl_in + lvl_out)
        sgn = np.sign(lvl_in - half)
        on_in = sgn * (val - half) > 0
        # The half-level crossing nearest j: back to the last sample on the inner side, or on
        # to the first one past it.
        k = j
        if on_in[k]:
            while k + 1 < lim and on_in[k + 1]:
                k += 1
        else:
            while k > 0 and not on_in[k]:
                k -= 1
            if not on_in[k]:
                continue
        if k + 1 >= lim:
            continue
        amp = abs(lvl_in - half)
        lo_i, hi_i = max(k - 7, 0), min(k + 8, lim - 1)
        if sgn * (val[lo_i] - half) < 0.25 * amp or sgn * (val[hi_i] - half) > -0.25 * amp:
            continue
        # Off the sheet for good: the brightness never comes back past half-way (a dot or a
        # glare band on the sheet is left again; the table beyond a border is not).
        lasting = not np.any(sgn * (val[k + 2:lim] - half) > 0.2 * amp)
        # The way out of a dot read from inside it; not asked for at the seam's end (there it
        # cost a real photograph).
        if entered and np.any(
                sgn * (val[max(k - hold - 16, 0):max(k - hold, 0)] - half) < -0.5 * amp):
            continue
        v0, v1 = val[k], val[k + 1]
        frac = (v0 - half) / (v0 - v1) if v0 != v1 else 0.5
        out.append((float(ks[k] + frac * (ks[k + 1] - ks[k])), bool(lasting)))
    return out


#: A gap that runs out of the image is seen as a valley up to this near the image border (px):
#: closer, the lines beside it are cut by the border and nothing can be read.
NEAR_IMAGE_BORDER_PX = 8.0


def gap_reaches_image_border(grey: NDArray[np.uint8], lut: F64, e_pt: F64, tang: F64,
                             w_med: float, k_border: float) -> bool:
    """Whether the gap is still seen from ``e_pt`` up to the image border ``k_border`` px ahead.

    Where the profiles stop within a profile length of the image border the seam is taken to
    run out of the image. That holds only where the gap goes on up to the border: a joint that
    ends 10-40 px inside the image (its sheet border too close to the image border for the
    lines beside the gap to show a step) is not a seam leaving the image. The gap's relative
    depth (centre against the darker of two lines ``w_med / 2 + 2.5`` px either side, all px)
    is read 6-30 px before ``e_pt`` and from ``e_pt`` on: it reaches the border when at least
    half the samples ahead are a quarter as deep as those before (a gap fading toward the edge
    still does; the sheets beside an end, or the table beyond it, do not). True where fewer than
    :data:`NEAR_IMAGE_BORDER_PX` px are left to read, or nothing clear to compare with.
    """
    nrm = np.array([-tang[1], tang[0]])
    delta = w_med / 2 + 2.5

    def depth(ks: F64) -> tuple[F64, NDArray[np.bool_]]:
        q = e_pt + np.outer(ks, tang)
        c, ic = bilinear(grey, lut, q[:, 0], q[:, 1])
        a, ia = bilinear(grey, lut, q[:, 0] + delta * nrm[0], q[:, 1] + delta * nrm[1])
        b, ib = bilinear(grey, lut, q[:, 0] - delta * nrm[0], q[:, 1] - delta * nrm[1])
        side = np.minimum(a, b)
        return (side - c) / np.maximum(side, 1e-6), ic & ia & ib

    ahead = np.arange(0.0, k_border - 1.0, 1.0)
    if len(ahead) < NEAR_IMAGE_BORDER_PX:
        return True
    before, ok_b = depth(np.arange(-30.0, -6.0 + 1e-9, 1.0))
    d, ok = depth(ahead)
    if ok_b.sum() < 5 or ok.sum() < 5:
        return True
    ref = float(np.median(before[ok_b]))
    if ref <= 0.05:
        return True
    return bool(np.mean(d[ok] > 0.25 * ref) >= 0.5)
