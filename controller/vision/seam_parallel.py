"""A second valley running parallel to a seam that leaves the image at both ends.

A pen or soapstone line drawn parallel to the joint (fitters mark offsets 3-20 mm beside it) and
the joint itself are both thin dark lines; where each runs out of the image at both ends, how
they end cannot tell them apart, and the detector may take either (or only one of them is among
its candidates at all: a wide gap the profile model does not fit, a faint pen line). Across the
returned line, the straightened strip of the image (``p.pattern_offset_px`` each side, a row
every 12 px along the line) is read for valleys at every offset: a line seen as a valley on
about as many rows as the returned line itself, at a constant offset beside it, is a second
candidate for the joint, and the choice is refused (:func:`parallel_valley`,
:func:`no_parallel_valley`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from controller.errors import AmbiguousSeam
from controller.vision.seam_decision import GIVE_ROI, summary_px
from controller.vision.seam_params import F64, Candidate, DetectParams
from controller.vision.seam_profiles import bilinear, resample

#: Relative depth (darker side minus centre, over the darker side) of a valley at an offset.
DIP_REL = 0.15
#: Distances (px) from a valley's centre to where its sides are read: thin to wide lines.
SIDES_PX = (3, 6, 12)
#: Nearest offset (px) looked at: nearer, the gap's own edges, a shadow band or a cut face.
MIN_OFFSET_PX = 10.0
#: A parallel valley counts when seen on this share of the rows, and on at least
#: ``OWN_SHARE`` of the share the returned line itself is seen on.
MIN_SHARE = 0.5
OWN_SHARE = 0.9
#: The comparison says something only where the returned line is itself a valley on this share
#: of the rows: a ragged, rusty or tack-welded gap is seen so on fewer, a ground strip's edge
#: beside it on more (real photograph 1_x3: 39 % against 68 %, a joint).
MIN_OWN = 0.5
_WOBBLE = 2  # px: a hand-drawn line wanders; its valley is looked for within this of an offset
_ROW_PX = 12.0  # px between the rows read across the seam (a share of rows needs no more)


def parallel_valley(grey: NDArray[np.uint8], lut: F64, points: F64, width_px: float,
                    p: DetectParams) -> tuple[float, float, float] | None:
    """(offset px, its share of rows, the line's own share) of a valley parallel to ``points``.

    ``points``: the returned seam (px, the searched image's frame); ``width_px`` its gap width.
    Offsets from ``max(MIN_OFFSET_PX, width_px)`` to ``p.pattern_offset_px`` on either side;
    None when no valley there is seen on ``MIN_SHARE`` of the rows and on ``OWN_SHARE`` of the
    share of rows the line itself shows a valley on (within 3 px of it), or when the line itself
    is seen so on under ``MIN_OWN`` of them.
    """
    pts, nrm = resample(points, _ROW_PX, extend=0.0)
    pad = max(SIDES_PX)
    reach = float(p.pattern_offset_px)
    off = np.arange(-reach - pad, reach + pad + 0.5, 1.0)
    U = pts[:, 0:1] + nrm[:, 0:1] * off[None, :]
    V = pts[:, 1:2] + nrm[:, 1:2] * off[None, :]
    val, inside = bilinear(grey, lut, U, V)
    val = np.where(inside, val, np.nan)
    n = len(off)
    centre = val[:, pad:n - pad]
    rel = np.full(centre.shape, -np.inf)
    for k in SIDES_PX:
        side = np.fmin(val[:, pad - k:n - pad - k], val[:, pad + k:n - pad + k])
        rel = np.fmax(rel, (side - centre) / np.maximum(side, 1e-6))
    o = off[pad:n - pad]
    seen = np.isfinite(rel)
    rows = seen.sum(axis=0)
    share = np.where(rows > 0, np.sum((rel > DIP_REL) & seen, axis=0) / np.maximum(rows, 1), 0.0)
    # (Columns seen on few rows, near the image border, say little.)
    share = np.where(rows >= 0.5 * len(pts), share, 0.0)
    wide = np.lib.stride_tricks.sliding_window_view(
        np.pad(share, _WOBBLE), 2 * _WOBBLE + 1).max(axis=1)
    own = float(wide[np.abs(o) <= 3.0].max())
    far = (np.abs(o) >= max(MIN_OFFSET_PX, width_px)) & (np.abs(o) <= reach)
    if not far.any():
        return None
    score = np.where(far, wide, -1.0)
    j = int(np.argmax(score))
    best = float(wide[j])
    if own >= MIN_OWN and best >= MIN_SHARE and best >= OWN_SHARE * own:
        # The line's offset: the middle of the run of offsets as good as the best.
        a, b = j, j
        while a > 0 and score[a - 1] >= best:
            a -= 1
        while b + 1 < len(score) and score[b + 1] >= best:
            b += 1
        return float(0.5 * (o[a] + o[b])), best, own
    return None


def no_parallel_valley(sub: NDArray[np.uint8], lut: F64, best: Candidate, p: DetectParams,
                       x0: int, y0: int) -> None:
    """Raise :class:`AmbiguousSeam` if ``best`` leaves the image at both ends beside a line.

    The line: a second valley (:func:`parallel_valley`), wherever it lies: a nominal seam does
    not set it aside, as it sets no rival aside (``seam_detect.outside_corridor``).
    """
    if best.points is None or any(k != "image border" for k in best.end_kinds):
        return
    width = float(np.median(best.width)) if best.width is not None else 0.0
    found = parallel_valley(sub, lut, best.points, width, p)
    if found is not None:
        off, share, own = found
        raise AmbiguousSeam(
            f"a second line runs parallel to the seam candidate, {abs(off):.0f} px beside it, "
            f"seen as a valley along {100 * share:.0f} % of it (the candidate: {100 * own:.0f} "
            "%); both leave the image at both ends, so how they end cannot tell which is the "
            "joint (a pen or soapstone line drawn beside it looks like it); refusing to choose: "
            + GIVE_ROI, best_px=summary_px(best, x0, y0),
            parallel_offset_px=round(off, 1))
