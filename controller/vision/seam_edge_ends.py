"""An end called the image border must show the gap running on to the image's edge.

A seam that leaves the image is returned with an ``image_border`` end where its centreline last
fitted, up to a profile's length inside the image. But the end rules also call an end the image
border where something stops the gap close to the edge and nothing beyond can be read (a step
within ``seam_ends._VERIFY_PX`` of the edge: a tack weld, a sheet border near the edge). On the
simulator's extended tuning part every seam returned with such an end more than 12 px inside
the image was wrong (README, *A lead, not built*); on the real photographs the gap visibly runs
on to the edge from ends 12-20 px inside it. So between the end and the edge the gap must be
seen: a valley, the centre darker than both sides, on at least a third of the profiles across
the seam's course. Where it is not, the line stops before the edge: the candidate is rejected
(it stays a rival: it may be the seam with its end misread).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from controller.vision.seam_ends import _border_crossing
from controller.vision.seam_params import F64, Candidate
from controller.vision.seam_profiles import bilinear

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
                     ) -> tuple[float, float | None]:
    """(distance px, share) from the last point of ``pts`` (K, 2 px, in order) to the image edge.

    The course is the chord over the last 30 px of ``pts``, carried straight on; profiles every
    2 px from 2 px past the end to 1 px before the edge, each ``width_px`` / 2 + 8 px to either
    side. ``share``: of the profiles wholly inside the image, those that show the gap
    (:data:`DIP`); None where there are none.
    """
    H, W = grey.shape
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
    j = min(int(np.searchsorted(s, s[-1] - _TANGENT_PX)), len(pts) - 2)
    tang = pts[-1] - pts[j]
    tang = tang / (np.linalg.norm(tang) + 1e-12)
    nrm = np.array([-tang[1], tang[0]])
    dist = _border_crossing(pts[-1], tang, W, H, 0.0)
    w = max(width_px, 1.5)
    os_ = np.arange(-(w / 2 + 8.0), w / 2 + 8.0 + 1e-9, 0.5)
    core, left, right = np.abs(os_) <= w / 2 + 1.0, os_ <= -(w / 2 + 4.0), os_ >= w / 2 + 4.0
    # The profile averaged over 2 px before its darkest point is taken: the minimum of single
    # samples finds a dip in the noise of a dark table.
    box = np.ones(4)  # 2 px
    box /= box.sum()
    seen = []
    for k in np.arange(_STEP_PX, dist - 1.0, _STEP_PX):
        q = pts[-1] + k * tang + np.outer(os_, nrm)
        val, inside = bilinear(grey, lut, q[:, 0], q[:, 1])
        if not inside.all():
            continue
        side = min(float(np.median(val[left])), float(np.median(val[right])))
        smooth = np.convolve(val, box, mode="same")
        seen.append(float(smooth[core].min()) < DIP * side)
    return dist, (float(np.mean(seen)) if seen else None)


def reject_ends_short_of_edge(grey: NDArray[np.uint8], lut: F64, cands: list[Candidate]) -> None:
    """Reject (as rivals) candidates with an image-border end the gap is not seen to leave from.

    ``grey``: the image searched (ROI px, as the candidates' points). An ``"image border"`` end
    more than :data:`EDGE_CHECK_PX` inside the image must show the gap on at least
    :data:`SEEN_SHARE` of the profiles between it and the edge (:func:`gap_seen_to_edge`).
    """
    for c in cands:
        pts = c.points if c.points is not None else c.polyline
        if c.why_rejected or pts is None or len(pts) < 3:
            continue
        w = float(np.median(c.width)) if c.width is not None and len(c.width) else 3.0
        for end, kind in enumerate(c.end_kinds):
            if kind != "image border":
                continue
            dist, share = gap_seen_to_edge(grey, lut, pts if end == 1 else pts[::-1], w)
            if dist > EDGE_CHECK_PX and share is not None and share < SEEN_SHARE:
                c.why_rejected = (f"its end at the image border lies {dist:.0f} px inside the "
                                  f"image and the gap is seen on only {100 * share:.0f} % of the "
                                  "way to the edge: the line stops before it (a tack weld, a "
                                  "sheet border near the edge) or is not the seam")
                c.rival = True
                break
