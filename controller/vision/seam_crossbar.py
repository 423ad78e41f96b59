"""The seam chosen may be a T-corner's crossbar: a long line ends on it from one side.

At a T-corner two gaps meet: the joint (the stem) ends on the crossbar, a gap from border to
border between the two sheets and a third plate (README, *A look the held-back close-ups have*).
:mod:`controller.vision.seam_tee` chooses the stem where it passes or fails only at the end where
it meets the crossbar. A ragged, wide stem fails elsewhere too (no long run of gap profiles, a
path joining two lines), and then the crossbar alone passes and was returned, a wrong seam at
high confidence (tee hard tuning 60037 view 1 at 0.93). :func:`no_stem_on` refuses that choice:
a line the search saw, long enough to be a seam itself, whatever it was refused for, ends on the
seam chosen from one side, away from the seam's ends, at :data:`controller.vision.seam_tee.
MIN_ANGLE_DEG` or more, and does not go on across it. Of the two joints a T-corner shows, the
view is of the stem (``seam_tee``); it was not measured, so nothing is returned. A job's nominal
seam line chooses (the check is not made then), or a ``--roi`` around the joint meant.

A line that crosses the seam (a pen line drawn across the joint), a mark or a tack weld beside
it (short, or no line at all: the dark body of a bead made the valleys of a first, valley-based
version of this check on four of the nine real photographs), and a sheet border meeting the
seam at its end are not such a line.
"""

from __future__ import annotations

import numpy as np

from controller.errors import AmbiguousSeam
from controller.vision.seam_coarse import nearest_px
from controller.vision.seam_decision import GIVE_ROI, arc_length, points_summary, summary_px
from controller.vision.seam_params import F64, Candidate, DetectParams
from controller.vision.seam_tee import MIN_ANGLE_DEG

#: A stem is at least this many times the shortest seam kept (``p.min_length_px``) long.
STEM_LENGTHS = 2.0
REACH_PX = 25.0  # its end within this of the seam's gap edge
END_PX = 60.0  # and meets the seam this far or more from the seam's ends (px along it)
ACROSS_SHARE = 0.1  # at most this share of its points lie on the seam's other side
AWAY_PX = 6.0  # a line closer than this to the seam (median) is the seam itself


def stem_on(best: F64, width_px: float, line: F64) -> tuple[F64, float] | None:
    """Where ``line`` (N, 2, px) ends on the seam ``best`` (K, 2, px) from one side, or None.

    ``width_px``: the seam's gap width. Returns the point of the seam it meets (px) and the
    angle between them there (deg).
    """
    s = arc_length(best)
    for end, inner in ((line[0], line[min(len(line) - 1, 15)]),
                       (line[-1], line[max(0, len(line) - 16)])):
        d = np.linalg.norm(best - end, axis=1)
        j = int(np.argmin(d))
        if d[j] > width_px / 2 + REACH_PX or min(s[j], s[-1] - s[j]) < END_PX:
            continue
        t = best[min(j + 3, len(best) - 1)] - best[max(j - 3, 0)]
        t = t / (np.linalg.norm(t) + 1e-12)
        u = end - inner
        u = u / (np.linalg.norm(u) + 1e-12)
        angle = float(np.degrees(np.arccos(min(1.0, abs(float(t @ u))))))
        if angle < MIN_ANGLE_DEG:
            continue
        nrm = np.array([-t[1], t[0]])
        own_side = np.sign(float((inner - best[j]) @ nrm))
        across = float(np.mean(np.sign((line - best[j]) @ nrm) == -own_side))
        if across <= ACROSS_SHARE:
            return best[j], angle
    return None


def no_stem_on(points: F64, width_px: float, cands: list[Candidate], p: DetectParams,
               x0: int, y0: int) -> None:
    """Raise :class:`AmbiguousSeam` where a long line of ``cands`` ends on the seam chosen.

    ``points`` (K, 2) and ``width_px``: the seam chosen; ``cands``: every candidate the search
    looked at. All in px of the region searched, offset by ``x0``, ``y0`` in the image.
    """
    for c in cands:
        line = c.points if c.points is not None else c.polyline
        if line is None or len(line) < 3 or c.length_px < STEM_LENGTHS * p.min_length_px:
            continue
        if float(np.median(nearest_px(line, points)[0])) < AWAY_PX:
            continue  # the seam itself, or a piece of it
        found = stem_on(points, width_px, line)
        if found is not None:
            at, angle = found
            raise AmbiguousSeam(
                f"a line {c.length_px:.0f} px long ends on the seam candidate at "
                f"{(at + [x0, y0]).round(0).tolist()} px from one side, at {angle:.0f} deg: a "
                f"T-corner, whose joint is the line ending there (not measured: "
                f"{c.why_rejected or 'weaker'}) and the candidate its crossbar, or a mark drawn "
                f"up to the joint; refusing to choose: " + GIVE_ROI,
                best_px=points_summary(points, x0, y0), second_px=summary_px(c, x0, y0))
