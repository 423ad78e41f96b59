"""A line that ends on another: the stem of a T-corner, and the crossbar it ends at.

At a T-corner the joint between two sheets ends at a third plate lying across its end, beyond a
crossbar gap (README, *A look the held-back close-ups have*). The view shows two lines: the
joint (the stem), which ends at the crossbar, and the crossbar, a gap from border to border as
dark and as wide as the joint and a joint in its own right (between the two sheets and the third
plate). Read alone, both pass: the view was refused as ambiguous, or the crossbar, the longer,
was returned. And the stem's valley path runs on into the crossbar's gap, so its end was read
at the crossbar's far edge, a crossbar's width past where the sheets stop facing each other.

A candidate ends on another (:func:`find_tees`) where, at one of its ends,

- it meets the other's dark band (within half the band's median width plus :data:`MARGIN_PX`
  of its centreline) and, from there, runs on off the band for at most :data:`TAIL_PX` plus the
  band's width (into the crossbar's gap and the plate beyond; a line crossing the other runs
  on), or along the band; it is not mostly the band itself;
- where its end lies past the band, it was not read as a sheet border or the image border
  there (a line that crossed the other and ended at a border of its own is no stem);
- the other runs on past the meeting point both ways by :data:`RUN_ON_PX` or three of its
  widths (a T, not a corner where both lines end), and is a line of its own (:func:`_a_line`:
  not a path joining two lines across an unseen stretch, nor fading out at both ends);
- the two meet at :data:`MIN_ANGLE_DEG` or more (a T, not one line read twice);
- its gap is seen (not bridged) on at least half of its last :data:`APPROACH_PX` before it
  meets the band (a path bridged across the sheet up to a line ends nowhere);
- beyond the other's far edge, along the stem's course, lies a plate: not as dark against the
  sheets as a table is (:func:`_plate_beyond`). Where the sheets end at their outer edge with the
  table beyond, a line along that edge is no crossbar, and the end reading stands.

A stem is a candidate passing so far, or one refused only for how that end was read: fading out
inside a sheet (its path ran on into the third plate) or stopping at a covered patch with a gap
beyond (the crossbar's gap is beyond); its other end must be an end (a border).

Then (:func:`cut_stems`) the stem ends where its course meets the crossbar's near edge: there
the two sheets stop facing each other, so that end is a sheet border (``joint_end``), and a stem
refused only for that end is judged again. And the crossbar, or a path along the T, does not
count as the stem's rival (``seam_decision.choose``): of the two joints a view of a T-corner
shows, the one that ends in it is the one the view is of; the crossbar runs on out of it both
ways. The choice is said in the reasons; a job that means the crossbar gives its nominal seam
region (``hint``) or a ``roi``, which leave the stem out of the search. Where the stem is much
weaker than its crossbar (under ``ambiguity_ratio``), the view is refused as ambiguous.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from controller.vision.seam_decision import arc_length
from controller.vision.seam_ends import darker_than_sheets
from controller.vision.seam_params import (
    COVERED_END,
    F64,
    JOINED_LINES,
    OPEN_END,
    Candidate,
    Tee,
)
from controller.vision.seam_profiles import bilinear, resample
from controller.vision.seam_robust import judge_path
from controller.vision.seam_wedge import sheet_levels

#: The stem's last point may lie this far (px) outside the crossbar's band.
MARGIN_PX = 4.0
#: Besides the crossbar's width, the stem may run this far (px) into or past its band at its
#: end (a valley path runs on across the crossbar's gap into the plate beyond it).
TAIL_PX = 60.0
#: The crossbar runs on at least this far (px; or three of its widths) past the meeting point.
RUN_ON_PX = 60.0
#: The stem meets the crossbar at this angle (deg) or more.
MIN_ANGLE_DEG = 45.0
#: The stem's gap must be seen on half of this many px (px) before it meets the crossbar.
APPROACH_PX = 100.0
#: Near the junction both lines are pulled toward each other: their courses are fitted this many
#: band widths (at least CLEAR_PX) away from it, over FIT_PX of each.
CLEAR_WIDTHS = 1.5
CLEAR_PX = 20.0
FIT_PX = 80.0
#: Beyond the crossbar's far edge, a plate is looked for over this many px.
BEYOND_PX = 30.0
#: The tangents are chords over this many px of each line.
_CHORD_PX = 30.0


def find_tees(grey: NDArray[np.uint8], lut: F64, cands: list[Candidate]) -> list[Tee]:
    """The T-corners of ``cands``: each candidate that ends on another, with the lines along both.

    ``grey``: the image searched (``lut`` its linearisation), ``cands`` in its px. Stems as in
    the module doc; a crossbar may be any line of its own (:func:`_a_line`; a rejected one may
    be a rival). A stem ends on at most one crossbar (the first found, in the order of
    ``cands``).
    """
    out = []
    cache: dict[int, F64] = {}

    def dense(c: Candidate) -> F64:  # each line resampled once, whatever it is paired with
        if id(c) not in cache:
            cache[id(c)] = _dense(c)
        return cache[id(c)]

    for stem in cands:
        if stem.points is None or len(stem.points) < 3:
            continue
        if stem.why_rejected and not _refused_for_an_end(stem):
            continue
        for bar in cands:
            if bar is stem or not _a_line(bar):
                continue
            meeting = _end_on(stem, bar, dense(bar))
            if meeting is None or not _plate_beyond(grey, lut, stem, *meeting, bar, dense(bar)):
                continue
            end = meeting[0]
            if stem.end_kinds[1 - end] in ("open", "covered"):
                continue  # its other end is no end either
            along = [c for c in cands if c is not stem and c is not bar
                     and on_tee(c, stem, bar, dense(stem), dense(bar))]
            out.append(Tee(stem, end, bar, along))
            break
    return out


def on_tee(c: Candidate, stem: Candidate, bar: Candidate, stem_dense: F64,
           bar_dense: F64) -> bool:
    """Whether ``c`` lies along the T of ``stem`` and ``bar`` (a path that turned at the T).

    ``stem_dense``, ``bar_dense``: their centrelines a point every px (:func:`_dense`). 90 % of
    its points within the wider of the two bands' half widths plus :data:`MARGIN_PX` of one or
    the other: it is no line of its own, and no rival to the stem.
    """
    if c.points is None:
        return False
    tol = max(_half_width(stem), _half_width(bar)) + MARGIN_PX
    d = np.minimum(_distance(c.points[::4], stem_dense), _distance(c.points[::4], bar_dense))
    return bool(np.mean(d <= tol) >= 0.9)


def cut_stems(tees: list[Tee]) -> None:
    """End each stem of ``tees`` at its crossbar's near edge; that end becomes a sheet border.

    Near the junction both lines are pulled toward each other (the dark region is wider there),
    so the end is where the stem's course meets the crossbar's: each fitted straight to the
    centreline from :data:`CLEAR_WIDTHS` band widths (or :data:`CLEAR_PX`) away from the
    junction over :data:`FIT_PX`, the stem's course carried to the crossbar's near edge (the
    crossbar's course moved toward the stem by half the crossbar's band width). The stem's
    points within that distance of the junction are replaced by points along its course to that
    end (every 2 px). Every per-point array of the stem follows (``width`` and ``band_points``
    carried on, ``bridged`` false: the gap is seen there) and ``length_px``. A stem refused only
    for how that end was read is judged again.
    """
    for t in tees:
        stem = t.stem
        _settle(stem, t.end, t.bar)
        kinds = list(stem.end_kinds)
        kinds[t.end] = "sheet border"
        stem.end_kinds = (kinds[0], kinds[1])
        if not stem.why_rejected:
            continue
        if stem.way == "valley path":
            judge_path(stem)
        elif _ends_open(stem) == 0:
            stem.why_rejected, stem.rival, stem.refused = "", False, ""


def _settle(stem: Candidate, end: int, bar: Candidate) -> None:
    """Move ``stem``'s end ``end`` to where its course meets ``bar``'s near edge (cut_stems)."""
    assert stem.points is not None
    names = [n for n in ("width", "bridged", "band_points")
             if getattr(stem, n) is not None and len(getattr(stem, n)) == len(stem.points)]
    flip = end == 0
    pts = stem.points[::-1] if flip else stem.points
    arrs = {n: (getattr(stem, n)[::-1] if flip else getattr(stem, n)) for n in names}
    hb = _half_width(bar)
    clear = max(CLEAR_WIDTHS * 2.0 * max(hb, _half_width(stem)), CLEAR_PX)
    dense = _dense(bar)
    first = int(np.flatnonzero(_distance(pts, dense) <= hb + MARGIN_PX)[0])
    k = int(np.argmin(np.linalg.norm(dense - pts[first], axis=1)))
    lo, hi = int(clear), int(clear + FIT_PX)
    side_pts = np.concatenate([dense[max(k - hi, 0):max(k - lo, 0)], dense[k + lo:k + hi]])
    if len(side_pts) < FIT_PX / 2:
        return
    c0, u = _line(side_pts)
    n_s = np.array([-u[1], u[0]])
    if float((pts[0] - c0) @ n_s) < 0:
        n_s = -n_s  # toward the stem's side
    dl = (pts - c0) @ n_s
    course = np.flatnonzero((dl >= hb + clear) & (dl <= hb + clear + FIT_PX))
    course = course[course < first]
    if len(course) < 8:
        return
    q0, v = _line(pts[course])
    if abs(float(v @ n_s)) < np.sin(np.radians(MIN_ANGLE_DEG)):
        return
    edge = q0 + v * (hb - float((q0 - c0) @ n_s)) / float(v @ n_s)
    j = int(course[-1])
    n_new = max(int(np.ceil(np.linalg.norm(edge - pts[j]) / 2.0)), 1)
    new = pts[j] + np.outer(np.arange(1, n_new + 1) / n_new, edge - pts[j])
    out = np.vstack([pts[:j + 1], new])
    for n, arr in arrs.items():
        if n == "band_points":
            tail = new + (arr[j] - pts[j])
        else:
            tail = np.repeat(arr[j:j + 1], n_new, axis=0)
            if n == "bridged":
                tail[:] = False
        arrs[n] = np.concatenate([arr[:j + 1], tail])
    stem.points = out[::-1].copy() if flip else out
    for n, arr in arrs.items():
        setattr(stem, n, arr[::-1].copy() if flip else arr)
    stem.length_px = float(arc_length(stem.points)[-1])


def _line(q: F64) -> tuple[F64, F64]:
    """A straight line fitted to the points ``q`` (K, 2): (a point on it, its unit direction)."""
    c = q.mean(axis=0)
    _, _, vt = np.linalg.svd(q - c, full_matrices=False)
    u = vt[0]
    if float((q[-1] - q[0]) @ u) < 0:
        u = -u
    return c, u


def _a_line(c: Candidate) -> bool:
    """Whether ``c`` may be a crossbar: a line of its own, seen to an end at one end at least.

    Not a path refused for joining two different lines across an unseen stretch, nor a line
    fading out inside a sheet at both ends (a piece of a line, a mark): a scratch ending on the
    joint would take the joint's piece for a crossbar and itself for a stem.
    """
    if c.points is None or len(c.points) < 3 or c.refused == JOINED_LINES:
        return False
    return _ends_open(c) < 2


def _refused_for_an_end(c: Candidate) -> bool:
    """Whether ``c`` was refused only for how an end was read.

    Fading out inside a sheet, or stopping at a covered patch with a gap beyond (at a T, the
    crossbar's gap is beyond); at one end only (:func:`find_tees` asks the other to be an end).
    """
    return c.refused in (OPEN_END, COVERED_END) and _ends_open(c) < 2


def _ends_open(c: Candidate) -> int:
    """How many of ``c``'s ends are no ends: fading out inside a sheet or covered."""
    return sum(k in ("open", "covered") for k in c.end_kinds)


def _end_on(stem: Candidate, bar: Candidate, dense: F64) -> tuple[int, int] | None:
    """Which end of ``stem`` ends on ``bar`` as a T's stem (module doc), or None.

    ``dense``: ``bar``'s centreline a point every px (:func:`_dense`).

    With it, where they meet: the index of the stem's first point within the bar's band (plus
    :data:`MARGIN_PX`), the stem's points ordered toward that end.
    """
    assert stem.points is not None
    hb = _half_width(bar)
    for end in (0, 1):
        p = stem.points if end == 1 else stem.points[::-1]
        kind = stem.end_kinds[end]
        d_end = float(_distance(p[-1:], dense)[0])
        if d_end > hb + MARGIN_PX + TAIL_PX:
            continue
        if d_end > hb + MARGIN_PX and kind in ("sheet border", "image border"):
            continue  # it crossed the bar and ran on to a border of its own
        d = _distance(p, dense)
        near = d <= hb + MARGIN_PX
        if not near.any() or near[0]:
            continue  # it never meets the bar, or starts on it
        first = int(np.flatnonzero(near)[0])
        s = arc_length(p)
        seg = np.diff(s)[first:]
        off = float(seg[~(near[first:-1] & near[first + 1:])].sum())  # after it, off the bar
        along = s[-1] - s[first] - off
        if off > TAIL_PX + 2.0 * hb or s[first] < 0.5 * s[-1]:
            continue  # it runs on far past the bar, or is mostly the bar itself
        if kind == "image border" and along < RUN_ON_PX:
            continue  # it leaves the image, not along the bar
        k = int(np.argmin(np.linalg.norm(dense - p[first], axis=1)))  # the bar's point there
        if _angle_deg(p, s, first, dense, k) < MIN_ANGLE_DEG:
            continue
        if stem.bridged is not None and len(stem.bridged) == len(p):
            seen = ~(stem.bridged if end == 1 else stem.bridged[::-1])
            before = (s >= s[first] - APPROACH_PX) & (s < s[first])
            if before.any() and float(np.mean(seen[before])) < 0.5:
                continue  # bridged up to the bar: where it meets it, nothing was seen
        run_on = max(RUN_ON_PX, 6.0 * hb)
        if k >= run_on and len(dense) - 1 - k >= run_on:
            return end, first
    return None


def _plate_beyond(grey: NDArray[np.uint8], lut: F64, stem: Candidate, end: int, first: int,
                  bar: Candidate, dense: F64) -> bool:
    """Whether a plate lies beyond ``bar`` where ``stem``'s end ``end`` meets it (module doc).

    ``first``: where they meet (:func:`_end_on`); ``dense``: ``bar``'s centreline a point every
    px (:func:`_dense`).

    Read along the stem's course (the chord over its last :data:`_CHORD_PX` before it meets the
    bar's band) over :data:`BEYOND_PX`, starting a band's width past where it meets the band
    (half a band's width past the far edge of a bar crossed square), across as wide as the
    stem's band; a plate where not darker than the sheets before the junction as a dark table is
    (:func:`controller.vision.seam_ends.darker_than_sheets`).
    """
    assert stem.points is not None
    p = stem.points if end == 1 else stem.points[::-1]
    hb, ws = _half_width(bar), 2.0 * _half_width(stem)
    d_first = float(_distance(p[first:first + 1], dense)[0])
    s = arc_length(p)
    j = min(int(np.searchsorted(s, s[first] - _CHORD_PX)), first - 1)
    u = p[first] - p[j]
    u = u / (np.linalg.norm(u) + 1e-12)
    nrm = np.array([-u[1], u[0]])
    sheets = sheet_levels(grey, lut, p[first], u, nrm, ws)
    along = d_first + 2.0 * hb + np.arange(2.0, BEYOND_PX + 0.1, 2.0)
    across = np.linspace(-ws / 2, ws / 2, 5)
    q = (p[first] + along[:, None, None] * u + across[None, :, None] * nrm).reshape(-1, 2)
    val, inside = bilinear(grey, lut, q[:, 0], q[:, 1])
    if sheets is None or inside.sum() < len(q) // 2:
        return False
    return not darker_than_sheets(val[inside], min(sheets))


def _angle_deg(p: F64, s: F64, first: int, dense: F64, k: int) -> float:
    """Angle (deg, 0-90) between ``p`` before its point ``first`` and ``dense`` at its point ``k``.

    ``s``: the arc length along ``p`` (:func:`arc_length`); ``k``: the point of ``dense``
    nearest ``p[first]``.
    """
    j = int(np.searchsorted(s, s[first] - _CHORD_PX))
    a = p[first] - p[min(j, max(first - 1, 0))]
    n = int(_CHORD_PX / 2)
    b = dense[min(k + n, len(dense) - 1)] - dense[max(k - n, 0)]
    cos = abs(float(a @ b)) / (float(np.linalg.norm(a) * np.linalg.norm(b)) + 1e-12)
    return float(np.degrees(np.arccos(min(cos, 1.0))))


def _dense(c: Candidate) -> F64:
    """``c``'s centreline with a point every px of its length."""
    assert c.points is not None
    return resample(c.points, 1.0, extend=0.0)[0]


def _half_width(c: Candidate) -> float:
    """Half the median width (px) of ``c``'s dark band (1.5 px where none was measured)."""
    if c.width is None or not len(c.width):
        return 1.5
    return 0.5 * float(np.median(c.width))


def _distance(p: F64, dense: F64) -> F64:
    """Distance (px) from each point of ``p`` to the nearest point of ``dense``, in chunks."""
    out = np.empty(len(p))
    for i in range(0, len(p), 256):
        q = p[i:i + 256]
        out[i:i + 256] = np.sqrt(((q[:, None, :] - dense[None, :, :]) ** 2).sum(-1).min(axis=1))
    return out
