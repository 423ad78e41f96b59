"""Honest end points of the seam: where the sheets (or the image) end, and the last stretch before.

:func:`end_offset` reads each side of the gap on lines parallel to the centreline and finds where a
sheet border crosses them (a straight border: its crossings lie on one line); :func:`measure_tails`
measures the last stretch before an end again with short profiles, which a border does not reach.
An end point that ran on past the sheets (over the table, past two rounded corners) is read again
from before it (:func:`_read_back`, :func:`_backed_off`); whether the gap goes on beyond a patch
on the joint is :func:`controller.vision.seam_resume.gap_resumes`.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from controller.vision.seam_border import (
    Border,
    border_goes_on,
    border_line,
    gap_reaches_image_border,
    side_crossings,
    side_steps,
)
from controller.vision.seam_params import F64, DetectParams
from controller.vision.seam_profiles import bilinear, fit_at
from controller.vision.seam_resume import RESUME_RUN_PX, gap_resumes
from controller.vision.seam_wedge import wedge_end


def measure_tails(grey: NDArray[np.uint8], lut: F64, guides: list[F64], ders: list[F64],
                  w_med: float, p: DetectParams) -> list[F64]:
    """Measure the last stretches of the seam (``guides``, extrapolated toward its ends) again.

    ``ders`` are the guides' tangents (not normalised). The profiles of all stretches are fitted
    together (one fit call is cheaper than one per end), then each stretch as below.

    Profiles of full length there may be crossed by the sheet border, so the stretch was
    extrapolated; an extrapolation over tens of pixels drifts on a curve. Short profiles (just
    wider than the gap) are not reached by the border until the end itself: where they fit the
    gap near the guide they replace it; within a profile length of the end (where even a short
    profile may reach past the border) the guide is shifted by the offset measured last.
    """
    der = np.vstack(ders)
    tang = der / (np.linalg.norm(der, axis=1, keepdims=True) + 1e-12)
    nrms = np.column_stack([-tang[:, 1], tang[:, 0]])
    hw = max(6.0, w_med / 2 + 5.0)
    fits = fit_at(grey, lut, np.vstack(guides), nrms, p, half_width=hw)
    out: list[F64] = []
    i0 = 0
    for guide in guides:
        sl = slice(i0, i0 + len(guide))
        i0 += len(guide)
        fit = {k: fits[k][sl] for k in ("centre", "valid", "width")}
        out.append(_tail(guide, nrms[sl], fit, hw, w_med))
    return out


def _tail(guide: F64, nrm: F64, fit: dict[str, NDArray[Any]], hw: float, w_med: float) -> F64:
    """One stretch of :func:`measure_tails`: the guide corrected by the offsets measured."""
    off = np.einsum("kd,kd->k", fit["centre"] - guide, nrm)
    seg = np.linalg.norm(np.diff(guide, axis=0), axis=1)
    to_end = np.concatenate([np.cumsum(seg[::-1])[::-1], [0.0]])
    # A profile within its own length of the end may reach past the border: not used.
    ok = (fit["valid"] & (np.abs(off) < 2.0) & (fit["width"] < 1.6 * w_med + 1.0)
          & (to_end >= hw + 3.0))
    if not ok.any():
        return guide
    idx = np.arange(len(guide), dtype=np.float64)
    # Offsets from the guide along the stretch: measured where the profiles fit, linear between,
    # the last measured one held to the end; then smoothed (one profile is noisy).
    o = np.interp(idx, idx[ok], off[ok])
    if len(o) >= 5:
        o = moving_line(o, min(len(o) // 2 * 2 - 1, 7))
    return np.asarray(guide + nrm * o[:, None])


def moving_line(x: F64, win: int) -> F64:
    """``savgol_filter(x, win, 1, mode="interp")`` (odd ``win`` <= len(x)) much faster.

    A straight line fitted over a window is its mean at the centre: a moving average inside, and
    at each end the line fitted to the first (last) ``win`` samples.
    """
    h = win // 2
    out = np.array(x, dtype=np.float64)
    out[h:len(x) - h] = np.convolve(x, np.full(win, 1.0 / win), mode="valid")
    t = np.arange(win, dtype=np.float64) - h
    for sl, ts in ((slice(0, win), slice(0, h)), (slice(len(x) - win, len(x)), slice(h + 1, win))):
        seg = x[sl]
        slope = float(t @ (seg - seg.mean())) / float(t @ t)
        out[sl][ts] = seg.mean() + slope * t[ts]
    return out


def end_offset(grey: NDArray[np.uint8], lut: F64, e_pt: F64, tang: F64,
               w_med: float, chord: F64 | None = None) -> tuple[float, str, F64 | None]:
    """Distance (px, along ``tang``) from ``e_pt`` to the seam's end, and what ends it there.

    As :func:`_end_at`, which reads the end within about 20 px of ``e_pt``, from where it can be
    read (:func:`_read_back`): where that finds nothing (``"open"``) because ``e_pt`` has run on
    past the sheets over a dark table (between two rounded plate corners a wide gap merges with
    the table and the line followed runs on into it), the end is read again further back
    (:func:`_backed_off`). A line that fades out inside a sheet has the sheet around its end,
    not the table: it stays open.
    """
    res = _read_back(grey, lut, e_pt, tang, w_med, chord)
    if res[1] != "open":
        return res
    return _backed_off(grey, lut, e_pt, tang, w_med, chord) or res


_BACK_STEP_PX = 16.0  # steps back along the seam to read an end from


def _read_back(grey: NDArray[np.uint8], lut: F64, e_pt: F64, tang: F64, w_med: float,
               chord: F64 | None) -> tuple[float, str, F64 | None]:
    """:func:`_end_at` at ``e_pt``, read again ``_BACK_STEP_PX`` before a border seen too late.

    Where the lines next to the gap show no step at all and a border is read off the outer
    lines alone, ``e_pt`` is past where the sheets stopped facing each other (the inner lines
    left them before the window begins): past two rounded corners, the outer lines step
    where the corners have receded further than the end is defined by. The end is read again
    from ``_BACK_STEP_PX`` before the border found, and taken when the inner lines step there
    and no other border is as well supported (not ``"unsure"``); otherwise the border read off
    the outer lines is kept as ``"unsure sheet border"``: the end may lie well before it.
    """
    k, kind, beyond, outer_only = _end_at(grey, lut, e_pt, tang, w_med, chord)
    if kind.endswith("sheet border") and outer_only:
        back = k - _BACK_STEP_PX
        k2, kind2, beyond2, outer2 = _end_at(grey, lut, e_pt + back * tang, tang, w_med, chord)
        if kind2 == "sheet border" and not outer2:
            return back + k2, kind2, beyond2
        # Not confirmed: the end may lie well before the point read.
        kind = "unsure sheet border"
    return k, kind, beyond


def _backed_off(grey: NDArray[np.uint8], lut: F64, e_pt: F64, tang: F64, w_med: float,
                chord: F64 | None) -> tuple[float, str, F64 | None] | None:
    """The end read back from ``e_pt`` when ``e_pt`` lies beyond the sheets, over the table.

    Steps back by ``_BACK_STEP_PX`` up to three gap widths (at least 64 px) until an end is read;
    it counts only as a sheet border before ``e_pt`` with ``e_pt`` itself over the table: on the
    lines beside it (half the gap plus 12 px out, 8 px on either side of ``e_pt`` along), even
    the brighter side is darker than the sheets read 10-20 px before that border (the darker
    side's median; :func:`darker_than_sheets`).
    """
    nrm = np.array([-tang[1], tang[0]])
    off = w_med / 2 + 12.0
    for d in np.arange(_BACK_STEP_PX, max(64.0, 3.0 * w_med) + 1e-9, _BACK_STEP_PX):
        # (Where the point is over the table there is nothing to look beyond for: the sheets
        # are read first, and the whole reading is done only where they show a border.)
        if _end_at(grey, lut, e_pt - d * tang, tang, w_med, chord, sheets_only=True)[1] == "open":
            continue
        # (Not open here, nor after: the whole reading only adds a covered or image-border end.)
        k, kind, beyond = _read_back(grey, lut, e_pt - d * tang, tang, w_med, chord)
        if not kind.endswith("sheet border") or k > d:
            return None
        levels = []
        for at, span in ((k - d - 15.0, 5.0), (0.0, 8.0)):
            ks = np.arange(-span, span + 1e-9, 1.0)
            sides = []
            for o in (-off, off):
                q = e_pt + o * nrm + np.outer(at + ks, tang)
                val, inside = bilinear(grey, lut, q[:, 0], q[:, 1])
                sides.append(val[inside])
            levels.append(sides)
        if min(len(v) for sides in levels for v in sides) < 3:
            return None
        sheet = min(float(np.median(v)) for v in levels[0])
        brighter = max(levels[1], key=lambda v: float(np.percentile(v, 90)))
        return (k - d, kind, beyond) if darker_than_sheets(brighter, sheet) else None
    return None


def darker_than_sheets(beside: F64, sheet_level: float) -> bool:
    """Whether samples read beside the seam lie over a dark table rather than the sheets.

    ``beside``: linear levels read on the brighter side of a stretch; ``sheet_level``: the
    sheets' level where the gap is seen. Table when even the brighter samples (90th percentile) are
    under half the sheets' level: a covered stretch of the joint (a tack weld's dark crater next
    to its bright bead) or a ragged one has sheet or bead that bright somewhere beside it.
    """
    return bool(np.percentile(beside, 90) < 0.5 * sheet_level)


_LINE_KS = np.arange(-28.0, 20.01, 0.5)  # where an end's lines are read: px along from it


def end_lines(grey: NDArray[np.uint8], lut: F64, e_pt: F64, tang: F64, w_med: float
              ) -> tuple[tuple[float, ...], list[list[tuple[float, bool]]]]:
    """The lines an end is read on: offsets (px; the centreline, two each side), steps on each."""
    nrm = np.array([-tang[1], tang[0]])
    q = e_pt + np.outer(_LINE_KS, tang)
    delta = w_med / 2 + 2.5
    offs = (-2 * delta, -delta, 0.0, delta, 2 * delta)
    return offs, [side_steps(grey, lut, q + o * nrm, _LINE_KS) for o in offs]


def _end_at(grey: NDArray[np.uint8], lut: F64, e_pt: F64, tang: F64, w_med: float,
            chord: F64 | None = None, sheets_only: bool = False
            ) -> tuple[float, str, F64 | None, bool]:
    """Distance (px, along ``tang``) from ``e_pt`` to the seam's end, and what ends it there.

    (The fourth value: no step at all on the two lines next to the gap. ``sheets_only``: the
    kind as the lines beside the gap read it, without looking beyond the end for the gap going
    on (:func:`gap_resumes`, most of the time taken): where that says "open", no border crosses
    the lines here, whatever is beyond.)

    The kind is ``"sheet border"``, ``"image border"``, ``"open"`` (the gap fades out inside a
    sheet: a pen mark or scratch does that, a joint does not) or ``"covered"`` (something on the
    joint stops the gap, which goes on beyond it: :func:`gap_resumes`). The third value is the
    gap's centres where it is seen again beyond a covered end (px, outward), else None.
    ``chord``: the seam's direction over a longer stretch (unit), to look beyond along (the
    local tangent wobbles at a tack weld); default ``tang``.

    The end is where the sheets end. Each side of the gap is read on two lines parallel to the
    centreline just outside the gap, and the gap itself on the centreline; where a sheet border
    crosses a line the brightness steps (where the gap ends, its dark floor gives way to the
    table). A straight border's crossings of the lines lie on one line in (offset across,
    distance along): :func:`controller.vision.seam_border.border_line` finds the steps that
    agree and follows that line in to the centreline (a step that agrees with no other, such as
    the edge of a table hole beyond the border, is not the end), or reads two rounded plate
    corners. A border seen on one side of the gap only is where one plate ends, not the joint
    (a plate's outer edge at its corner), unless the other side steps there faintly
    (:func:`_other_side_ends`). When no line steps, the seam runs out of the image (the end is
    the image border) or ends where the profiles stopped fitting. Where the gap opens out into
    a wedge of table between two rounded corners
    (:func:`controller.vision.seam_wedge.wedge_end`), the end is read off the wedge instead.
    """
    H, W = grey.shape
    # Each line read once: its lasting steps for the border, all of them for a band before it.
    offs, marked = end_lines(grey, lut, e_pt, tang, w_med)
    steps = [[k for k, lasting in m if lasting] for m in marked]
    line = border_line(offs, steps, w_med)
    line = _band_before([[k for k, _ in m] for m in marked], offs, w_med, line)
    # A border seen beside the gap only (a mottle patch, a pen line's end) is not a sure end.
    k_line = line.k
    unsure = line.unsure or not border_goes_on(grey, lut, e_pt, tang, line, offs[-1], _LINE_KS)
    outer_only = not steps[1] and not steps[3]
    if k_line is not None and not all(line.sides) and not _other_side_ends(grey, lut, e_pt, tang,
                                                                          line, offs):
        # The border crosses one side of the line only: one plate turns away, the other side
        # goes on (a plate's outer edge at its corner, a slot's end). Not where a joint ends.
        k_line = None
    k_border = border_crossing(e_pt, tang, W, H, float(_LINE_KS[-1]))
    kind = "unsure sheet border" if unsure else "sheet border"
    if k_line is not None:
        k = k_line
    elif k_border < 40.0 and gap_reaches_image_border(grey, lut, e_pt, tang, w_med, k_border):
        # Profiles fail within a profile length of the image border: the seam runs out there.
        k, kind = k_border, "image border"
    else:
        k, kind = 0.0, "open"
    if k_border <= k:
        k, kind = k_border, "image border"
    beyond = None
    if sheets_only:
        return float(k), kind, beyond, outer_only
    border = kind.endswith("sheet border")
    if border or kind == "open":
        # A step on the joint (a bead on it), or a line that fades out: is the same gap seen
        # again beyond? Asked before the sheets beside are read: a mark or a pen line 50 px
        # beside a tack weld steps where the sheets do not end.
        ahead = tang if chord is None else chord
        # First, whether the gap opens out between two rounded corners here: their edges cross
        # the lines beside the gap too gently to step (the end read open or unsure) or step
        # late (read past the end), and the wedge of table beyond looks to the resume check
        # like a wider stretch of the same gap.
        kw = wedge_end(grey, lut, e_pt, tang, w_med)
        if kw is not None:
            return kw, "sheet border", None, outer_only
        beyond = gap_resumes(grey, lut, e_pt + k * tang, ahead, w_med,
                             border_crossing(e_pt + k * tang, ahead, W, H, 0.0))
        if beyond is not None:
            # What stopped the gap is a patch on the joint (a tack weld, spatter, slag, a marker
            # ring), not the end of the sheets nor of a line: the same gap goes on beyond it.
            kind = "covered"
        elif border and _sheets_end(grey, lut, e_pt + k * tang, tang, w_med):
            return float(k), kind, None, outer_only
        elif border:
            # Not the joint's end. Near the image border the gap beyond cannot be seen: the
            # view of the seam stops here; elsewhere the seam is covered and this piece is not
            # a seam by itself.
            kind = "image border" if k_border - k < _VERIFY_PX else "covered"
    return float(k), kind, beyond, outer_only


def _band_before(steps: list[list[float]], offs: tuple[float, ...], w_med: float,
                 line: Border) -> Border:
    """``line``, or the near edge of a dark band across the seam before it (a T-corner).

    ``steps``: every step on each line at ``offs`` (:func:`side_steps`, lasting or not).

    A gap running across the seam's end (the crossbar of a T, the slot to the next plate) is a
    dark band the brightness comes back from, which :func:`side_crossings` drops (a dot on a
    sheet does that too): the border was read at the band's far side, a band's width past the
    joint's end. A band's near edge is taken when it is straight across all four lines beside
    the gap (a dot is not; the centreline need not step: the band may be as dark as the gap)
    and nearer than ``line`` (or ``line`` is none). Where it lies where ``line`` does (within 3
    px) and ``line`` was unsure (another line through the lasting steps as well supported: the
    band's far edge, an oblique crossbar's crossings spread over the lines), the near edge seen
    on all four lines settles it.
    """
    near = border_line(offs, steps, w_med)
    if near.k is None:
        return line
    on = sum(1 for o, s in zip(offs, steps, strict=True)
             if o != 0.0 and s and abs(s[0] - (near.k + near.slope * o)) <= 1.5)
    if on != len(offs) - 1:
        return line
    if line.k is not None and near.k > line.k - 3.0:
        same = line.unsure and not near.unsure and abs(near.k - line.k) <= 3.0
        return near if same else line
    return near


def _other_side_ends(grey: NDArray[np.uint8], lut: F64, e_pt: F64, tang: F64, line: Border,
                     offs: tuple[float, ...]) -> bool:
    """Whether the side of the gap that showed no border step ends where ``line`` says too.

    ``line`` was seen on one side of the gap only (and maybe on the centreline). A joint ends
    where both sheets do; a sheet about as bright as the table beyond it does not step by the
    25 % :func:`controller.vision.seam_border.side_crossings` asks, but it steps a little: on
    that side's lines, where the border would cross them, the median brightness over 3-9 px
    before and after differs by ``_FAINT_STEP`` or more. Where the table goes on past the end of
    one plate (a plate's outer edge, a slot) the brightness does not change there. A line whose
    window leaves the image is no evidence.
    """
    if line.k is None:
        return False
    nrm = np.array([-tang[1], tang[0]])
    side = 1.0 if line.sides[0] else -1.0
    kk = np.arange(-9.0, 9.01, 0.5)
    for o in offs:
        if o * side <= 0:
            continue
        pts = e_pt + o * nrm + np.outer(line.k + line.slope * o + kk, tang)
        val, inside = bilinear(grey, lut, pts[:, 0], pts[:, 1])
        if not inside.all():
            continue
        before, after = float(np.median(val[kk <= -3])), float(np.median(val[kk >= 3]))
        if abs(after - before) >= _FAINT_STEP * max(before, after, 1e-6):
            return True
    return False


_FAINT_STEP = 0.10  # relative step of a sheet border where the sheet and the table look alike


def _sheets_end(grey: NDArray[np.uint8], lut: F64, end_pt: F64, tang: F64, w_med: float) -> bool:
    """Whether a sheet ends near ``end_pt`` away from the joint, not only on it.

    A sheet border runs across the sheets; a tack weld or a spatter ball is a patch on the
    joint a few tens of px across. Lines parallel to the seam ``_FAR_PX`` (+ half the gap)
    beside it, from 30 px before the end to 80 px past it, cross a border (a sharp, lasting
    step, as in :func:`end_offset`) and pass beside a patch. One side is enough (a T-corner, a
    rounded corner further on). A line that leaves the image before it shows a step is no
    evidence.
    """
    H, W = grey.shape
    nrm = np.array([-tang[1], tang[0]])
    ks = np.arange(-30.0, 80.01, 0.5)
    off = _FAR_PX + w_med / 2
    for o in (-off, off):
        start = end_pt + o * nrm
        if not (0 <= start[0] <= W - 1 and 0 <= start[1] <= H - 1):
            continue
        # A step is seen to last over what is left of the image after it, at least _ROOM_PX.
        room = border_crossing(start, tang, W, H, float(ks[-1])) - _ROOM_PX
        if any(k < room for k in side_crossings(grey, lut, start + np.outer(ks, tang), ks,
                                                entered=True)):
            return True
    return False


_FAR_PX = 48.0  # beside the joint, past the half width of a tack bead
# Image needed after a step beside the joint for it to count as lasting: what side_steps reads
# each side of a step. Was 20 px: a border 10-30 px from the image edge was no evidence (wide
# easy tuning 10188 v1, 10186 v1, hard 10081 v0: called the image border at 0.8-1.0).
_ROOM_PX = 6.0
# Room beyond a sheet-border end to tell it from a tack weld: a bead (up to ~80 px) and a run.
_VERIFY_PX = 80.0 + RESUME_RUN_PX


def border_crossing(e_pt: F64, tang: F64, W: int, H: int, default: float) -> float:
    """Distance along ``tang`` from ``e_pt`` (inside the image) to the image border (px).

    ``default`` when ``tang`` is zero. The border is the outer edge of the edge pixels.
    """
    ts = []
    for lo, hi, x, d in ((-0.5, W - 0.5, e_pt[0], tang[0]), (-0.5, H - 0.5, e_pt[1], tang[1])):
        if d > 1e-9:
            ts.append((hi - x) / d)
        elif d < -1e-9:
            ts.append((lo - x) / d)
    return float(min(ts)) if ts else default
