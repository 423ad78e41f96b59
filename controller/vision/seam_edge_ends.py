"""An end called the image border beyond which the sheets end is a sheet border, not the image's.

A seam that leaves the image is returned with an ``image_border`` end where its centreline last
fitted, up to a profile's length inside the image. But the end rules also call an end the image
border where something stops the gap close to the edge and nothing beyond it can be read (a step
within ``seam_ends._VERIFY_PX`` of the edge). That is right for a tack weld over the joint at
the edge (the seam leaves the image under it: the dry run's ``tack_open`` seams) and wrong for a
sheet border near the edge (README, *A lead, built since*: every seam returned with such an end
more than 12 px inside the image on the simulator's extended tuning part was wrong). Between
the end and the edge the two differ: beyond a sheet border lies the table, no gap and darker
than the sheets; over a tack weld the bead or the sheets go on. An end more than 8 px inside
the image whose way to the edge shows the gap on under a third of its profiles and lies over a
dark table is a sheet border (``joint_end``) at the step the end rules stopped at.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from controller.vision.seam_decision import arc_length
from controller.vision.seam_ends import border_crossing, darker_than_sheets
from controller.vision.seam_params import F64, Candidate
from controller.vision.seam_profiles import bilinear
from controller.vision.seam_wedge import sheet_levels

#: Ends closer to the image edge than this (px) are not checked: too few profiles between.
EDGE_CHECK_PX = 8.0
#: A profile shows the gap where, averaged over 2 px, its darkest point within half the gap + 1 px
#: of the course is under this share of the darker side (read 4-8 px beyond the gap's edges), in
#: linear light.
DIP = 0.85
#: The gap must be seen on at least this share of the profiles between the end and the edge.
SEEN_SHARE = 1.0 / 3.0
_STEP_PX = 2.0
_TANGENT_PX = 30.0


def gap_seen_to_edge(grey: NDArray[np.uint8], lut: F64, pts: F64, width_px: float
                     ) -> tuple[float, float | None, bool]:
    """(distance px, share, over the table) from the last point of ``pts`` to the image edge.

    ``pts``: (K, 2) px in order. The course is the chord over the last 30 px of ``pts``, carried
    straight on; profiles every 2 px from 2 px past the end to 1 px before the edge, each
    ``width_px`` / 2 + 8 px to either side. ``share``: of the profiles wholly inside the image,
    those that show the gap (:data:`DIP`); None where there are none. ``over the table``: the
    brighter side of those profiles is darker than the darker sheet before the end
    (:func:`controller.vision.seam_wedge.sheet_levels`), as
    :func:`controller.vision.seam_ends.darker_than_sheets` judges a dark table.
    """
    H, W = grey.shape
    s = arc_length(pts)
    j = min(int(np.searchsorted(s, s[-1] - _TANGENT_PX)), len(pts) - 2)
    tang = pts[-1] - pts[j]
    tang = tang / (np.linalg.norm(tang) + 1e-12)
    nrm = np.array([-tang[1], tang[0]])
    dist = border_crossing(pts[-1], tang, W, H, 0.0)
    w = max(width_px, 1.5)
    os_ = np.arange(-(w / 2 + 8.0), w / 2 + 8.0 + 1e-9, 0.5)
    core, left, right = np.abs(os_) <= w / 2 + 1.0, os_ <= -(w / 2 + 4.0), os_ >= w / 2 + 4.0
    # The profile averaged over 2 px before its darkest point is taken: the minimum of single
    # samples finds a dip in the noise of a dark table.
    box = np.ones(4) / 4.0
    seen: list[bool] = []
    brighter: list[F64] = []
    for k in np.arange(_STEP_PX, dist - 1.0, _STEP_PX):
        q = pts[-1] + k * tang + np.outer(os_, nrm)
        val, inside = bilinear(grey, lut, q[:, 0], q[:, 1])
        if not inside.all():
            continue
        m_left, m_right = float(np.median(val[left])), float(np.median(val[right]))
        brighter.append(val[left] if m_left >= m_right else val[right])
        seen.append(float(np.convolve(val, box, mode="same")[core].min())
                    < DIP * min(m_left, m_right))
    sheets = sheet_levels(grey, lut, pts[-1], tang, nrm, w)
    over_table = bool(brighter and sheets is not None
                      and darker_than_sheets(np.concatenate(brighter), min(sheets)))
    return dist, (float(np.mean(seen)) if seen else None), over_table


def correct_edge_ends(grey: NDArray[np.uint8], lut: F64, cands: list[Candidate]) -> None:
    """Call a sheet border what was read as the image border with the table beyond it.

    ``grey``: the image searched (ROI px, as the candidates' points). An ``"image border"`` end
    more than :data:`EDGE_CHECK_PX` inside the image, where the way to the edge shows the gap on
    fewer than :data:`SEEN_SHARE` of its profiles and lies over a dark table
    (:func:`gap_seen_to_edge`), is where the sheets end: its kind becomes ``"sheet border"``
    (``joint_end``), the point stays (the step the end rules stopped at).
    """
    for c in cands:
        pts = c.points if c.points is not None else c.polyline
        if c.why_rejected or pts is None or len(pts) < 3:
            continue
        w = float(np.median(c.width)) if c.width is not None and len(c.width) else 3.0
        kinds = list(c.end_kinds)
        for end, kind in enumerate(kinds):
            if kind != "image border":
                continue
            dist, share, over_table = gap_seen_to_edge(grey, lut,
                                                       pts if end == 1 else pts[::-1], w)
            if (dist > EDGE_CHECK_PX and share is not None and share < SEEN_SHARE
                    and over_table):
                kinds[end] = "sheet border"
        c.end_kinds = (kinds[0], kinds[1])
