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

A slotted or striped table gives a family of parallel lines: a straight line with three or more
others parallel to it, a pitch away and apart from each other, is one of them. One or two are
not enough: real photographs of a ground joint (../shared/data/real-seams) show straight
valleys parallel to the joint on both sides (the edges of the ground strips, grinding marks) at
the distances of a table's slots. A straight joint laid square on a slotted table with three
slots in view beside the sheets is refused by this: by its geometry alone it is one of them.
"""

from __future__ import annotations

from collections.abc import Callable

import cv2
import numpy as np
from numpy.typing import NDArray

from controller.geometry.camera_model import CameraModel
from controller.vision.seam_params import F64, Candidate, DetectParams

#: Largest angle (deg) between two lines of one family of the grid: parallel on the table, they
#: converge in the image under perspective (up to ~11 deg seen 1000-2000 px apart).
PARALLEL_DEG = 12.0
#: Smallest angle (deg) between the grid line and the lines crossing it.
CROSS_DEG = 30.0
#: A crossing line must reach within this distance (px) of the candidate, inside its extent.
TOUCH_PX = 30.0

#: A straight line parallel to this many others, each a table's pitch away (``pattern_offset_px``
#: or more) and apart from each other, is one of a family: a slotted or striped table. Two are
#: not enough: the two edges of the ground strips beside a joint (../shared/data/real-seams) give
#: a straight joint one parallel line on each side, at about the distance of a table's slots.
FAMILY_LINES = 3
#: Parallel segments closer than this (px, across) are one line seen as several.
SAME_LINE_PX = 40.0

Line = tuple[F64, F64, float, float]  # point, unit direction, extent along it (min, max), px
Straighten = Callable[[F64], F64]  # image px (N, 2) -> undistorted px of the same camera


def straight_lines(valleys: NDArray[np.uint8], factor: int, p: DetectParams) -> list[Line]:
    """Straight valley segments of the search image, full-res px, as (point, dir, s0, s1).

    ``valleys``: the coarse search's valley mask (uint8 0/1, the image shrunk by ``factor``).
    Segments by the probabilistic Hough transform (``cv2.HoughLinesP``), at least
    ``p.min_length_px`` long: lines crossing each other are found whole, where the connected
    components of the mask would join them into one blob.
    """
    min_len = p.min_length_px / factor
    segs = cv2.HoughLinesP(valleys, 1.0, np.pi / 180, int(0.6 * min_len),
                           minLineLength=min_len, maxLineGap=3.0)
    out: list[Line] = []
    for x0, y0, x1, y1 in ([] if segs is None else segs.reshape(-1, 4)):
        a, b = np.array([x0, y0], np.float64), np.array([x1, y1], np.float64)
        if not _a_line_in(valleys, a, b):
            continue
        a, b = (a + 0.5) * factor - 0.5, (b + 0.5) * factor - 0.5
        L = float(np.linalg.norm(b - a))
        out.append(((a + b) / 2, (b - a) / L, -L / 2, L / 2))
    return out


def _a_line_in(valleys: NDArray[np.uint8], a: F64, b: F64) -> bool:
    """Whether the mask holds a line from ``a`` to ``b`` (px of the mask), not a textured patch.

    A Hough segment also runs through a patch of rust or pitting where the mask is dense:
    the line must be set on at least 70 % of its length (at its best shift of up to 1 px
    across) and on at least 40 points more in 100 than its surroundings 4 px to either side.
    """
    H, W = valleys.shape
    L = float(np.linalg.norm(b - a))
    t = np.linspace(0.0, 1.0, max(2, int(L) + 1))[:, None]
    P = a + t * (b - a)
    n = np.array([a[1] - b[1], b[0] - a[0]]) / max(L, 1e-9)
    shifts = np.array([-1.0, 0.0, 1.0, -4.0, 4.0])
    Q = np.rint(P[None, :, :] + shifts[:, None, None] * n).astype(np.int64)  # (5, N, 2)
    share = valleys[np.clip(Q[..., 1], 0, H - 1), np.clip(Q[..., 0], 0, W - 1)].mean(axis=1)
    on = float(share[:3].max())
    around = float(share[3:].mean())
    return on >= 0.7 and on - around >= 0.4


def mark_table_lines(cands: list[Candidate], lines: Callable[[], list[Line]],
                     p: DetectParams, straighten: Straighten | None = None) -> None:
    """Reject (``why_rejected``) each candidate of ``cands`` that is a line of a table's grid.

    ``lines``: gives the straight lines of the image (:func:`straight_lines`), called only when a
    candidate is straight (most joints are not: no Hough transform for them). ``straighten``:
    image px (N, 2) to undistorted px of the same camera (``None``: a lens without distortion).
    A line of the table is straight on the table; the lens bends it in the image, by up to a few
    px over a long line near the image border (more than ``p.straight_px``), so straightness is
    judged on the undistorted centreline. A candidate whose centreline (refined, else coarse) is
    straight is a grid line when

    - one of ``lines`` crosses it (at :data:`CROSS_DEG` or more, reaching within
      :data:`TOUCH_PX` of it inside its extent), and a second line runs at least
      ``p.pattern_offset_px`` away parallel (within :data:`PARALLEL_DEG`) to it or to the
      crossing one; or
    - a line runs parallel to it at least ``p.pattern_offset_px`` away, and two lines parallel
      to each other that far apart run across its direction: it is aligned with one family of a
      grid whose other family is in view (a piece of a grid line in a corner of the image, the
      other family seen elsewhere); or
    - :data:`FAMILY_LINES` or more lines run parallel to it, each ``p.pattern_offset_px`` or more
      from it and more than :data:`SAME_LINE_PX` from each other (a slotted table).
    """
    cos_cross = np.cos(np.radians(CROSS_DEG))
    for c in cands:
        pts = c.points if c.points is not None else c.polyline
        if c.why_rejected or len(pts) < 3:
            continue
        if _line_of(pts if straighten is None else straighten(pts), p.straight_px) is None:
            continue
        # The line itself in image px, where the lines of the image (Hough) are.
        line = _line_of(pts, np.inf)
        assert line is not None
        m, d, s0, s1 = line
        touching: list[Line] = []
        across: list[Line] = []
        for ln in lines():
            m2, d2, t0, t1 = ln
            if abs(float(d @ d2)) > cos_cross:
                continue
            # Where the two lines meet, along each of them.
            s, t = np.linalg.solve(np.column_stack([d, -d2]), m2 - m)
            across.append(ln)
            if s0 - TOUCH_PX <= s <= s1 + TOUCH_PX and t0 - TOUCH_PX <= t <= t1 + TOUCH_PX:
                touching.append(ln)
        twins = _apart([line], lines(), p.pattern_offset_px)
        why = ""
        if touching and (twins or _apart(touching, touching, p.pattern_offset_px)):
            why = "crossed by a straight dark line, with another a pitch away"
        elif twins and _apart(across, across, p.pattern_offset_px):
            why = "aligned with one family of a grid whose other family is in view"
        elif len(_distinct(_offsets(line, lines(), p.pattern_offset_px))) >= FAMILY_LINES:
            why = (f"parallel to {FAMILY_LINES} or more straight lines a table's pitch away (a "
                   "slotted or striped table)")
        if why:
            c.why_rejected = f"a straight line {why}: a line of the table's grid, not a joint"
            c.rival = False


def straightener(camera: CameraModel, x0: int = 0, y0: int = 0) -> Straighten:
    """A function: image px (N, 2) of ``camera`` to undistorted full-image px.

    ``x0, y0``: the corner of the region of interest the px are counted from. A line straight on
    the table is straight in undistorted px.
    """
    K = camera.K

    def straighten(P: F64) -> F64:
        n = camera.pixels_to_normalized(P + [x0, y0])
        return np.asarray(n * [K[0, 0], K[1, 1]] + [K[0, 2], K[1, 2]], dtype=np.float64)
    return straighten


def _offsets(line: Line, b: list[Line], offset_px: float) -> list[float]:
    """Signed distances (px, across ``line``) of the lines of ``b`` parallel to it.

    Only those at least ``offset_px`` away.
    """
    cos_par = np.cos(np.radians(PARALLEL_DEG))
    m, d, _, _ = line
    n = np.array([-d[1], d[0]])
    return [float((m2 - m) @ n) for m2, d2, _, _ in b
            if abs(float(d @ d2)) >= cos_par and abs(float((m2 - m) @ n)) >= offset_px]


def _distinct(offsets: list[float]) -> list[float]:
    """``offsets`` (px) with those within :data:`SAME_LINE_PX` of the previous one merged.

    The Hough transform gives one dark line as several segments.
    """
    out: list[float] = []
    for x in sorted(offsets):
        if not out or x - out[-1] > SAME_LINE_PX:
            out.append(x)
    return out


def _apart(a: list[Line], b: list[Line], offset_px: float) -> list[float]:
    """Distances >= ``offset_px`` between a line of ``a`` and a line of ``b`` parallel to it."""
    return [abs(x) for line in a for x in _offsets(line, b, offset_px)]


def _line_of(P: F64, straight_px: float) -> Line | None:
    if not np.all(np.isfinite(P)):
        return None  # a point the lens model could not undistort: no judgement
    m = P.mean(axis=0)
    _, _, vt = np.linalg.svd(P - m, full_matrices=False)
    dev = (P - m) @ vt[1]
    if float(np.sqrt(np.mean(dev**2))) > straight_px:
        return None
    along = (P - m) @ vt[0]
    return m, vt[0], float(along.min()), float(along.max())
