"""Whether the gap goes on beyond where it stopped: a covered patch on the joint, not its end.

A tack weld, a spatter ball, slag or a marker ring on the joint stops the gap the profiles see
as a sheet border does; beyond a patch the same gap, between the same sheets, is seen again.
:func:`gap_resumes` looks for it (used by :mod:`controller.vision.seam_ends` at each end of a
seam). Pixels are (u, v) in the distorted image.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from controller.vision.seam_params import F64, DetectParams, runs_of
from controller.vision.seam_profiles import fit_at

_RESUME_REACH_PX = 260.0  # longest covered stretch looked across (a tack weld ~5-12 mm)
RESUME_RUN_PX = 40.0  # the gap must be seen again over this length, in one run
_FAN_DEG = tuple(float(a) for a in range(-16, 17, 4))  # 4 deg: +-8 px at 115 px
#: Slack (px per px along) for the noise in the seam's and the run's directions (~2 deg).
_TURN_SLACK = 0.04


def gap_resumes(grey: NDArray[np.uint8], lut: F64, end_pt: F64, tang: F64, w_med: float,
                room_px: float) -> F64 | None:
    """Where the gap (median width ``w_med`` px) is seen again beyond ``end_pt`` (px), or None.

    Looks along ``tang`` (unit, pointing out of the seam) from 12 px past the end to
    ``_RESUME_REACH_PX`` (or ``room_px``, the distance to the image border), in a fan of
    directions (a curved seam leaves a straight line: +-16 deg around the seam's chord covers
    a radius down to about the reach), for a run of at least ``RESUME_RUN_PX`` of profiles
    that fit a gap of about the same width close to the line, between the same sheets (their
    levels within 35 % of those just before the end). A sheet border has the table beyond it;
    a tack weld or a spatter ball has the same joint beyond it. Returns the measured centres of
    the longest such run (M, 2) px, in order away from the end.
    """
    p = DetectParams()  # the defaults: what a gap profile is does not depend on a caller's tuning
    reach = min(_RESUME_REACH_PX, room_px - 6.0)
    if reach < 12.0 + RESUME_RUN_PX:
        return None
    ks = np.arange(12.0, reach, p.step_px)
    need = int(np.ceil(RESUME_RUN_PX / p.step_px))
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
    # cost where nothing goes on beyond the end, the usual case). Three consecutive third
    # profiles hold a sixth one: the sixth ones (and the third ones near the border) are fitted
    # first, the other third ones only along directions where one of those fits.
    coarse = np.arange(0, len(ks), 3)
    near_border = reach < _RESUME_REACH_PX
    tail = coarse[coarse >= len(ks) - 4]  # the third profiles next to the border
    first = np.union1d(np.arange(0, len(ks), 6), tail if near_border else coarse[:0])
    ok[:, first], centres[:, first] = _resume_fit(grey, lut, end_pt, dirs, ks[first], w_med,
                                                  sides, p)
    seen = [i for i in range(len(dirs)) if ok[i, first].any()]
    second = np.setdiff1d(coarse, first)
    if seen and len(second):
        o, c = _resume_fit(grey, lut, end_pt, [dirs[i] for i in seen], ks[second], w_med, sides,
                           p)
        rows = np.array(seen, dtype=np.intp)
        ok[np.ix_(rows, second)], centres[np.ix_(rows, second)] = o, c
    keep = [i for i in range(len(dirs))
            if max((b - a for a, b in runs_of(ok[i, coarse])), default=0) >= 3
            or (near_border and ok[i, tail].any())]
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
    radius 500 px stays inside over 250 px), in about its direction (20 deg), and turned toward
    the side it lies on by as much as its offset needs (below): a line parallel to the seam
    beside it (a pen line beside the joint, the joint beside a pen line) is another line, not
    the same gap beyond a patch.
    """
    nrm = np.array([-tang[1], tang[0]])
    rel = run - end_pt
    along, lat = rel @ tang, rel @ nrm
    a = np.maximum(along, 0.0)
    if np.any(np.abs(lat) > 6.0 + 0.15 * a):
        return False
    d = run[-1] - run[0]
    if not d @ tang > np.cos(np.radians(20.0)) * np.linalg.norm(d):
        return False
    # A seam that curves away from its line beyond a patch turns as it goes: ``a`` px on, it
    # lies aside by at most ``a`` times the run's turn (a circle leaves its tangent by half of
    # that; ``tang`` may be a chord over the stretch before the end, already turned, and the
    # bound still holds). A line beside it that runs parallel has the offset without the turn:
    # a pen line fading out beside the joint, whose end would be bridged onto the joint 15-30
    # px aside and take the joint's end for its own.
    u = _direction(run, tang)
    turn = float(np.arctan2(u @ nrm, u @ tang))  # rad, toward +nrm
    allow = 6.0 + _TURN_SLACK * a + a * np.maximum(0.0, turn * np.sign(lat))
    return bool(np.all(np.abs(lat) <= allow))


def _direction(run: F64, tang: F64) -> F64:
    """Unit direction of the line fitted to ``run`` (principal axis), oriented along ``tang``."""
    c = run - run.mean(axis=0)
    u = np.linalg.svd(c, full_matrices=False)[2][0]
    return u if u @ tang >= 0 else -u
