"""Lines of the table, not joints: a straight valley in a grid of straight valleys.

A table engraved with a grid (the usual 50 or 100 mm squares of a welding table) shows long,
straight, thin dark lines, as dark and as thin as a gap, running under the sheets and out of the
image: locally each one is a valley with the same surface on both sides, which the profile model
cannot tell from a joint. What tells a grid line from a joint is the grid around it: a straight
line of the other family crosses it (the crossing lines pass under the sheets, so often only one
is seen reaching it), and a second line runs a pitch away parallel to it or to the crossing one.
A joint is a curve, or a line on the sheets that the lines of the table do not reach: they stop
at the sheets' borders. ``DetectParams.pattern_offset_px`` (25 mm at the default scale) keeps a
fitter's pen line, 3-20 mm beside a joint, from counting as the parallel line.

Not used: "another straight line parallel to it" alone (a slot table's slots). Real photographs
of a ground joint (../shared/data/real-seams) show straight valleys parallel to the joint on
both sides (the edges of the ground strips, grinding marks) at the distances of a table's
slots, so that rule refused joints; thin slots (the tuning part's slotted table) stay a source
of wrong seams.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from controller.vision.seam_params import F64, Candidate, DetectParams

#: Largest angle (deg) between two lines of one family of the grid: parallel on the table, they
#: converge in the image under perspective (up to ~11 deg seen 1000-2000 px apart).
PARALLEL_DEG = 12.0
#: Smallest angle (deg) between the grid line and the lines crossing it.
CROSS_DEG = 30.0
#: A crossing line must reach within this distance (px) of the candidate, inside its extent.
TOUCH_PX = 30.0

Line = tuple[F64, F64, float, float]  # point, unit direction, extent along it (min, max), px


def straight_lines(valleys: NDArray[np.uint8], factor: int, p: DetectParams) -> list[Line]:
    """Straight valley segments of the search image, full-res px, as (point, dir, s0, s1).

    ``valleys``: the coarse search's valley mask (uint8 0/1, the image shrunk by ``factor``).
    Segments by the probabilistic Hough transform (``cv2.HoughLinesP``), at least
    ``p.min_length_px`` long: lines crossing each other are found whole, where the connected
    components of the mask would join them into one blob.
    """
    min_len = p.min_length_px / factor
    segs = cv2.HoughLinesP(valleys, 1.0, np.pi / 360, int(0.6 * min_len),
                           minLineLength=min_len, maxLineGap=3.0)
    out: list[Line] = []
    for x0, y0, x1, y1 in ([] if segs is None else segs.reshape(-1, 4)):
        a = (np.array([x0, y0], np.float64) + 0.5) * factor - 0.5
        b = (np.array([x1, y1], np.float64) + 0.5) * factor - 0.5
        L = float(np.linalg.norm(b - a))
        out.append(((a + b) / 2, (b - a) / L, -L / 2, L / 2))
    return out


def mark_table_lines(cands: list[Candidate], lines: list[Line], p: DetectParams) -> None:
    """Reject (``why_rejected``) each candidate of ``cands`` that is a line of a table's grid.

    ``lines``: the straight coarse lines of the image (:func:`straight_lines`). A candidate is a
    grid line when its centreline (refined, else coarse) is straight, one of ``lines`` crosses it
    (at :data:`CROSS_DEG` or more, reaching within :data:`TOUCH_PX` of it inside its extent), and
    either another runs parallel to it (within :data:`PARALLEL_DEG`) at least
    ``p.pattern_offset_px`` away or a second crossing line runs parallel to the first that far
    from it: the two families of a grid.
    """
    cos_cross = np.cos(np.radians(CROSS_DEG))
    cos_par = np.cos(np.radians(PARALLEL_DEG))
    for c in cands:
        pts = c.points if c.points is not None else c.polyline
        if c.why_rejected or len(pts) < 3:
            continue
        line = _line_of(pts, p.straight_px)
        if line is None:
            continue
        m, d, s0, s1 = line
        crossing: list[tuple[F64, F64]] = []
        for m2, d2, t0, t1 in lines:
            if abs(float(d @ d2)) > cos_cross:
                continue
            # Where the two lines meet, along each of them.
            A = np.column_stack([d, -d2])
            s, t = np.linalg.solve(A, m2 - m)
            if s0 - TOUCH_PX <= s <= s1 + TOUCH_PX and t0 - TOUCH_PX <= t <= t1 + TOUCH_PX:
                crossing.append((m2, d2))
        n = np.array([-d[1], d[0]])
        twins = [abs(float((m2 - m) @ n)) for m2, d2, _, _ in lines
                 if abs(float(d @ d2)) >= cos_par]
        twins = [x for x in twins if x >= p.pattern_offset_px]
        pitches = [abs(float((b[0] - a[0]) @ np.array([-a[1][1], a[1][0]])))
                   for i, a in enumerate(crossing) for b in crossing[i + 1:]
                   if abs(float(a[1] @ b[1])) >= cos_par]
        pitches = [x for x in pitches if x >= p.pattern_offset_px]
        if crossing and (twins or pitches):
            c.why_rejected = (f"a straight line crossed by {len(crossing)} straight dark line(s)"
                              + (f", with another one parallel to it {min(twins):.0f} px away"
                                 if twins else f" {min(pitches):.0f} px apart")
                              + ": a line of the table's grid, not a joint")
            c.rival = False


def _line_of(P: F64, straight_px: float) -> Line | None:
    m = P.mean(axis=0)
    _, _, vt = np.linalg.svd(P - m, full_matrices=False)
    dev = (P - m) @ vt[1]
    if float(np.sqrt(np.mean(dev**2))) > straight_px:
        return None
    along = (P - m) @ vt[0]
    return m, vt[0], float(along.min()), float(along.max())
