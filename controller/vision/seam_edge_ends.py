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
dark table is a sheet border (``joint_end``) at the step the end rules stopped at. Any other
such end of the seam returned is where it leaves the image: its centreline is carried on
straight to the edge, where it runs straight enough for that (an end called the image border
lies on it), the stretch where no gap is seen reported as occluded (:func:`carry_to_edge`;
README, *An image-border end on the border*). Where it cannot be carried (the seam bends there)
or is not (the search on the image shrunk), an end left farther inside the image than
:data:`IMAGE_EDGE_PX` is not where the seam leaves the image: as the answer from that image alone
(``seamguide detect``) the seam is refused (:func:`no_end_inside`, :func:`one_image_answer`);
two views (the cycle, ``seamguide locate``) take the 3D end from the view that sees it, or clip.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from controller.errors import SeamNotFound
from controller.vision.seam_decision import arc_length, one_reading, points_summary
from controller.vision.seam_detection import SeamDetection
from controller.vision.seam_ends import border_crossing, darker_than_sheets
from controller.vision.seam_params import F64, Candidate, DetectParams
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
    way = _way_to_edge(grey, lut, pts, width_px)
    seen = way.seen[way.inside]
    return way.dist, (float(np.mean(seen)) if len(seen) else None), way.over_table


@dataclass
class _Way:
    """The way from a seam's last point to the image edge (:func:`_way_to_edge`)."""

    tang: F64  # the course, unit
    dist: float  # px along ``tang`` to the edge
    ks: F64  # px along ``tang`` of the profiles
    seen: NDArray[np.bool_]  # per profile: the gap shows (False where not wholly inside)
    inside: NDArray[np.bool_]  # per profile: wholly inside the image
    over_table: bool


def _way_to_edge(grey: NDArray[np.uint8], lut: F64, pts: F64, width_px: float) -> _Way:
    """:func:`gap_seen_to_edge`'s reading, profile by profile, with the course taken."""
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
    ks = np.arange(_STEP_PX, dist - 1.0, _STEP_PX)
    seen = np.zeros(len(ks), bool)
    inside = np.zeros(len(ks), bool)
    brighter: list[F64] = []
    for i, k in enumerate(ks):
        q = pts[-1] + k * tang + np.outer(os_, nrm)
        val, ins = bilinear(grey, lut, q[:, 0], q[:, 1])
        if not ins.all():
            continue
        inside[i] = True
        m_left, m_right = float(np.median(val[left])), float(np.median(val[right]))
        brighter.append(val[left] if m_left >= m_right else val[right])
        seen[i] = (float(np.convolve(val, box, mode="same")[core].min())
                   < DIP * min(m_left, m_right))
    sheets = sheet_levels(grey, lut, pts[-1], tang, nrm, w)
    over_table = bool(brighter and sheets is not None
                      and darker_than_sheets(np.concatenate(brighter), min(sheets)))
    return _Way(tang, dist, ks, seen, inside, over_table)


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


#: A seam is carried on straight to the edge only where, bent as over its last
#: :data:`BEND_PX`, it would leave the straight course by at most this much there (px).
MAX_BEND_OFF_PX = 1.0
BEND_PX = 120.0


def carry_to_edge(grey: NDArray[np.uint8], lut: F64, c: Candidate,
                  p: DetectParams | None = None) -> None:
    """Carry the returned seam ``c`` on to the image edge from its image-border ends.

    An ``"image border"`` end more than :data:`EDGE_CHECK_PX` inside the image (the end rules
    stopped at a tack weld or spatter near the edge, beyond which nothing can be read) is
    carried on straight along the course of its last 30 px, points every 4 px and the last on
    the edge; each is ``bridged`` (an occluded span) unless the profile nearest it shows the
    gap (:func:`gap_seen_to_edge`). Not where the seam bends: its curvature over the last
    :data:`BEND_PX` would take it more than :data:`MAX_BEND_OFF_PX` off the straight course
    by the edge (the straight stretch would be off the joint; the end stays where it was read).
    Run on the seam chosen only: the carried stretch is not evidence for choosing (a line
    carried across another one would change what the rules read of the two). Not where
    ``p.carry`` is off (the search on the image shrunk).
    """
    if (p is not None and not p.carry) or c.points is None or len(c.points) < 3:
        return
    w = float(np.median(c.width)) if c.width is not None and len(c.width) else 3.0
    for end, kind in enumerate(c.end_kinds):
        if kind != "image border":
            continue
        toward = c.points if end == 1 else c.points[::-1]
        way = _way_to_edge(grey, lut, toward, w)
        if way.dist > EDGE_CHECK_PX and 0.5 * _curvature(toward) * way.dist ** 2 <= \
                MAX_BEND_OFF_PX:
            _carry(c, end, way)


def _curvature(pts: F64) -> float:
    """The curvature (1/px) of ``pts``' last :data:`BEND_PX` of arc: a quadratic in arc length."""
    s = arc_length(pts)
    sel = s >= s[-1] - BEND_PX
    if sel.sum() < 5:
        return 0.0
    t = s[sel] - s[-1]
    coef = np.polyfit(t, pts[sel], 2)  # both coordinates at once: rows t^2, t, 1
    (dx, dy), (ddx, ddy) = coef[1], 2 * coef[0]
    return float(abs(dx * ddy - dy * ddx) / max(np.hypot(dx, dy) ** 3, 1e-12))


def _carry(c: Candidate, end: int, way: _Way) -> None:
    """:func:`carry_to_edge`'s points added at ``c``'s ``end`` (0 first, 1 last) along ``way``.

    The width is held at the end's; a split shadow's band centreline (``band_points``) is
    carried on alongside.
    """
    assert c.points is not None
    n = len(c.points)
    ks = np.append(np.arange(2 * _STEP_PX, way.dist - _STEP_PX, 2 * _STEP_PX), way.dist)
    if len(way.ks):
        near = np.clip(np.searchsorted(way.ks, ks), 0, len(way.ks) - 1)
        unseen = ~way.seen[near]
    else:
        unseen = np.ones(len(ks), bool)
    step = np.outer(ks, way.tang)

    def grow(a: NDArray[Any], more: NDArray[Any]) -> NDArray[Any]:
        return np.concatenate([a, more]) if end == 1 else np.concatenate([more[::-1], a])

    last = c.points[-1] if end == 1 else c.points[0]
    c.points = grow(c.points, last + step)
    bridged = c.bridged if c.bridged is not None else np.zeros(n, bool)
    c.bridged = grow(bridged, unseen)
    if c.width is not None and len(c.width) == n:
        c.width = grow(c.width, np.full(len(ks), c.width[-1] if end == 1 else c.width[0]))
    if c.band_points is not None and len(c.band_points) == n:
        b_last = c.band_points[-1] if end == 1 else c.band_points[0]
        c.band_points = grow(c.band_points, b_last + step)
    c.length_px = float(arc_length(c.points)[-1])


#: Farthest (px) an end called the image border may lie from the edge of the image searched
#: once carried on to it: the contract's ``image_border`` is where the seam leaves the image.
#: The seams returned with such an end left farther inside (the end rules stopped at a step near
#: the edge, and the seam bends there or was read on the image shrunk) were wrong, 8 of 8 over
#: every set of both parts, 33-114 px inside (README, *Twenty-fifth session*).
IMAGE_EDGE_PX = 12.0


def one_image_answer(det: SeamDetection, p: DetectParams,
                     box: tuple[int, int, int, int]) -> None:
    """Raise where the seam ``det`` (full-image px) is no answer from its image alone.

    ``box``: the region searched (x0, y0, x1, y1; the whole image without a region of
    interest). Two readings one image cannot choose from
    (:func:`controller.vision.seam_decision.one_reading`: :class:`AmbiguousSeam`), or an end
    called the image border left inside it (:func:`no_end_inside`: :class:`SeamNotFound`).
    ``seamguide detect`` answers so, and the benchmark's single views; the cycle and
    ``seamguide locate`` take ``det`` as it is and decide with the other view.
    """
    one_reading(det.points_px, det.band_px, p)
    x0, y0, x1, y1 = box
    no_end_inside(det.points_px - [x0, y0], det.end_kinds, (y1 - y0, x1 - x0), x0, y0)


def no_end_inside(points: F64, kinds: tuple[str, str], shape: tuple[int, ...], x0: int,
                  y0: int) -> None:
    """Raise :class:`SeamNotFound` where an image-border end of a seam lies inside the image.

    ``points``: the seam's centreline (px of the region searched, of ``shape`` (H, W), whose
    corner in the image is ``x0, y0``); ``kinds``: its two ends' kinds (first, last; the
    detector's words or the contract's). An image-border end farther than
    :data:`IMAGE_EDGE_PX` from the region's edge is seen neither to end nor to leave the image:
    what stopped it (a tack weld or spatter near the edge, a sheet's end) is not known, and
    welding on to the edge, or stopping there, may be wrong.
    """
    H, W = shape[:2]
    for end, kind in zip((points[0], points[-1]), kinds, strict=True):
        u, v = float(end[0]), float(end[1])
        inside = min(u + 0.5, v + 0.5, W - 0.5 - u, H - 0.5 - v)
        if kind.replace("_", " ") == "image border" and inside > IMAGE_EDGE_PX:
            raise SeamNotFound(
                f"the seam found stops {inside:.0f} px inside the image at "
                f"({u + x0:.0f}, {v + y0:.0f}), where something it cannot see past (a tack weld, "
                "spatter, a sheet's end) lies between it and the image's edge: it is seen "
                "neither to end nor to leave the image; move the view so that the joint's end, "
                "or the seam running on out of the image, is seen",
                best_px=points_summary(points, x0, y0), end_px=[round(u + x0, 1),
                                                                round(v + y0, 1)])
