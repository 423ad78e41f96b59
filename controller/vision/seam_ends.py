"""Honest end points of the seam: where the sheets (or the image) end, and the last stretch before.

:func:`end_offset` reads each side of the gap on lines parallel to the centreline and finds where a
sheet border crosses them (a straight border: its crossings lie on one line); :func:`measure_tails`
measures the last stretch before an end again with short profiles, which a border does not reach.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from controller.vision.seam_border import Border, border_line, side_crossings, side_steps
from controller.vision.seam_params import F64, DetectParams, runs_of
from controller.vision.seam_profiles import bilinear, fit_at


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
        o = _moving_line(o, min(len(o) // 2 * 2 - 1, 7))
    return np.asarray(guide + nrm * o[:, None])


def _moving_line(x: F64, win: int) -> F64:
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
    the image border) or ends where the profiles stopped fitting.
    """
    H, W = grey.shape
    nrm = np.array([-tang[1], tang[0]])
    ks = np.arange(-28.0, 20.01, 0.5)
    q = e_pt + np.outer(ks, tang)
    delta = w_med / 2 + 2.5
    offs = (-2 * delta, -delta, 0.0, delta, 2 * delta)
    # Each line read once: its lasting steps for the border, all of them for a band before it.
    marked = [side_steps(grey, lut, q + o * nrm, ks) for o in offs]
    steps = [[k for k, lasting in m if lasting] for m in marked]
    line = border_line(offs, steps, w_med)
    line = _band_before([[k for k, _ in m] for m in marked], offs, w_med, line)
    k_line, unsure = line.k, line.unsure
    if k_line is not None and not all(line.sides) and not _other_side_ends(grey, lut, e_pt, tang,
                                                                          line, offs):
        # The border crosses one side of the line only: one plate turns away, the other side
        # goes on (a plate's outer edge at its corner, a slot's end). Not where a joint ends.
        k_line = None
    k_border = _border_crossing(e_pt, tang, W, H, float(ks[-1]))
    kind = "unsure sheet border" if unsure else "sheet border"
    if k_line is not None:
        k = k_line
    elif k_border < 40.0:
        # Profiles fail within a profile length of the image border: the seam runs out there.
        k, kind = k_border, "image border"
    else:
        k, kind = 0.0, "open"
    if k_border <= k:
        k, kind = k_border, "image border"
    beyond = None
    border = kind.endswith("sheet border")
    if border or kind == "open":
        # A step on the joint (a bead on it), or a line that fades out: is the same gap seen
        # again beyond? Asked before the sheets beside are read: a mark or a pen line 50 px
        # beside a tack weld steps where the sheets do not end.
        ahead = tang if chord is None else chord
        beyond = gap_resumes(grey, lut, e_pt + k * tang, ahead, w_med,
                             _border_crossing(e_pt + k * tang, ahead, W, H, 0.0))
        if beyond is not None:
            # What stopped the gap is a patch on the joint (a tack weld, spatter, slag, a marker
            # ring), not the end of the sheets nor of a line: the same gap goes on beyond it.
            kind = "covered"
        elif border and _sheets_end(grey, lut, e_pt + k * tang, tang, w_med):
            return float(k), kind, None
        elif border:
            # Not the joint's end. Near the image border the gap beyond cannot be seen: the
            # view of the seam stops here; elsewhere the seam is covered and this piece is not
            # a seam by itself.
            kind = "image border" if k_border - k < _VERIFY_PX else "covered"
    return float(k), kind, beyond


def _band_before(steps: list[list[float]], offs: tuple[float, ...], w_med: float,
                 line: Border) -> Border:
    """``line``, or the near edge of a dark band across the seam before it (a T-corner).

    ``steps``: every step on each line at ``offs`` (:func:`side_steps`, lasting or not).

    A gap running across the seam's end (the crossbar of a T, the slot to the next plate) is a
    dark band the brightness comes back from, which :func:`side_crossings` drops (a dot on a
    sheet does that too): the border was read at the band's far side, a band's width past the
    joint's end. A band's near edge is taken when it is straight across all four lines beside
    the gap (a dot is not; the centreline need not step: the band may be as dark as the gap)
    and nearer than ``line`` (or ``line`` is none).
    """
    near = border_line(offs, steps, w_med)
    if near.k is None or (line.k is not None and near.k > line.k - 3.0):
        return line
    on = sum(1 for o, s in zip(offs, steps, strict=True)
             if o != 0.0 and s and abs(s[0] - (near.k + near.slope * o)) <= 1.5)
    return near if on == len(offs) - 1 else line


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
        # A step needs 20 px of image after it to be seen to last.
        room = _border_crossing(start, tang, W, H, float(ks[-1])) - 20.0
        if any(k < room for k in side_crossings(grey, lut, start + np.outer(ks, tang), ks,
                                                entered=True)):
            return True
    return False


_RESUME_REACH_PX = 260.0  # longest covered stretch looked across (a tack weld ~5-12 mm)
_RESUME_RUN_PX = 40.0  # the gap must be seen again over this length, in one run
_FAR_PX = 48.0  # beside the joint, past the half width of a tack bead
# Room needed beyond a sheet-border end to tell it from a tack weld: a bead (up to ~80 px in the
# dry run's and the photographs' views) and a run of the gap beyond it.
_VERIFY_PX = 80.0 + _RESUME_RUN_PX
_FAN_DEG = tuple(float(a) for a in range(-16, 17, 4))  # 4 deg: +-8 px at 115 px


def gap_resumes(grey: NDArray[np.uint8], lut: F64, end_pt: F64, tang: F64, w_med: float,
                room_px: float) -> F64 | None:
    """Where the gap (median width ``w_med`` px) is seen again beyond ``end_pt`` (px), or None.

    Looks along ``tang`` (unit, pointing out of the seam) from 12 px past the end to
    ``_RESUME_REACH_PX`` (or ``room_px``, the distance to the image border), in a fan of
    directions (a curved seam leaves a straight line: +-16 deg around the seam's chord covers
    a radius down to about the reach), for a run of at least ``_RESUME_RUN_PX`` of profiles
    that fit a gap of about the same width close to the line, between the same sheets (their
    levels within 35 % of those just before the end). A sheet border has the table beyond it;
    a tack weld or a spatter ball has the same joint beyond it. Returns the measured centres of
    the longest such run (M, 2) px, in order away from the end.
    """
    p = DetectParams()  # the defaults: what a gap profile is does not depend on a caller's tuning
    reach = min(_RESUME_REACH_PX, room_px - 6.0)
    if reach < 12.0 + _RESUME_RUN_PX:
        return None
    ks = np.arange(12.0, reach, p.step_px)
    need = int(np.ceil(_RESUME_RUN_PX / p.step_px))
    dirs = []
    for a in np.radians(_FAN_DEG):
        c, s = np.cos(a), np.sin(a)
        dirs.append(np.array([c * tang[0] - s * tang[1], s * tang[0] + c * tang[1]]))
    # The sheets on each side, read just before the end: beyond a patch the same sheets go on;
    # beyond a sheet border a valley on the table (a slot, a plate edge) has other sides.
    kb = np.arange(16.0, 80.0, p.step_px)
    pb = end_pt - np.outer(kb, tang)
    fb = fit_at(grey, lut, pb, np.tile([-tang[1], tang[0]], (len(kb), 1)), p)
    if int(fb["valid"].sum()) < 4:
        return None
    sides = np.array([np.median(fb["left"][fb["valid"]]), np.median(fb["right"][fb["valid"]])])
    ok = np.zeros((len(dirs), len(ks)), bool)
    centres = np.zeros((len(dirs), len(ks), 2))
    # Every third profile first: a run of ``need`` (>= 9) profiles holds three consecutive ones
    # of them, a run of 4 to the border one; only the directions that show that are fitted in
    # full (the profiles are fitted independently, so the result is the same, at a third of the
    # cost where nothing goes on beyond the end, the usual case).
    coarse = np.arange(0, len(ks), 3)
    ok[:, coarse], centres[:, coarse] = _resume_fit(grey, lut, end_pt, dirs, ks[coarse], w_med,
                                                    sides, p)
    near_border = reach < _RESUME_REACH_PX
    keep = [i for i in range(len(dirs))
            if max((b - a for a, b in runs_of(ok[i, coarse])), default=0) >= 3
            or (near_border and ok[i, coarse[coarse >= len(ks) - 4]].any())]
    rest = np.setdiff1d(np.arange(len(ks)), coarse)
    if keep and len(rest):
        sub = [dirs[i] for i in keep]
        o, c = _resume_fit(grey, lut, end_pt, sub, ks[rest], w_med, sides, p)
        rows = np.array(keep, dtype=np.intp)
        ok[np.ix_(rows, rest)], centres[np.ix_(rows, rest)] = o, c
    ok[[i for i in range(len(dirs)) if i not in keep]] = False
    best: tuple[int, F64] | None = None
    for row, cen in zip(ok, centres, strict=True):
        runs = runs_of(row)
        if not runs:
            continue
        a, b = max(runs, key=lambda r: r[1] - r[0])
        n = b - a
        # A gap seen again up to the image border needs less length: there is no more to see.
        la, lb = runs[-1]
        if (reach < _RESUME_REACH_PX and lb == len(ks) and (lb - la) * p.step_px >= 16
                and n < need):
            (a, b), n = runs[-1], need
        run = cen[a:b]
        if n >= need and (best is None or n > best[0]) and _continues(run, end_pt, tang):
            best = (n, run)
    return None if best is None else np.asarray(best[1])


def _resume_fit(grey: NDArray[np.uint8], lut: F64, end_pt: F64, dirs: list[F64], ks: F64,
                w_med: float, sides: F64, p: DetectParams) -> tuple[NDArray[np.bool_], F64]:
    """Per direction and distance of :func:`gap_resumes`: a gap there, and its centre (px).

    A gap: the profile fits a gap of about ``w_med`` px close to the line, between sheets of
    about the levels ``sides`` (left, right: linear radiance).
    """
    pts = np.vstack([end_pt + np.outer(ks, d) for d in dirs])
    nrm = np.vstack([np.tile([-d[1], d[0]], (len(ks), 1)) for d in dirs])
    fit = fit_at(grey, lut, pts, nrm, p)
    off = np.einsum("kd,kd->k", fit["centre"] - pts, nrm)
    ok = (fit["valid"] & (np.abs(off) < 8.0) & (fit["width"] < 2.0 * w_med + 2.0)
          & (fit["width"] > 0.4 * w_med - 1.0)
          & (np.abs(fit["left"] - sides[0]) <= 0.35 * sides[0])
          & (np.abs(fit["right"] - sides[1]) <= 0.35 * sides[1]))
    return ok.reshape(len(dirs), len(ks)), fit["centre"].reshape(len(dirs), len(ks), 2)


def _continues(run: F64, end_pt: F64, tang: F64) -> bool:
    """Whether ``run`` (px, outward) continues the seam ending at ``end_pt`` along ``tang``.

    Close to the seam's line (lateral offset at most 6 px + 15 % of the distance: a curve of
    radius 500 px stays inside over 250 px) and in about its direction (20 deg): a line
    parallel to the seam beside it (a pen line beside the joint, the joint beside a pen line)
    is another line, not the same gap beyond a patch.
    """
    nrm = np.array([-tang[1], tang[0]])
    rel = run - end_pt
    along, lat = rel @ tang, rel @ nrm
    if np.any(np.abs(lat) > 6.0 + 0.15 * np.maximum(along, 0.0)):
        return False
    d = run[-1] - run[0]
    return bool(d @ tang > np.cos(np.radians(20.0)) * np.linalg.norm(d))


def _border_crossing(e_pt: F64, tang: F64, W: int, H: int, default: float) -> float:
    """Distance along ``tang`` from ``e_pt`` (inside the image) to the image border (px)."""
    ts = []
    for lo, hi, x, d in ((-0.5, W - 0.5, e_pt[0], tang[0]), (-0.5, H - 0.5, e_pt[1], tang[1])):
        if d > 1e-9:
            ts.append((hi - x) / d)
        elif d < -1e-9:
            ts.append((lo - x) / d)
    return float(min(ts)) if ts else default
