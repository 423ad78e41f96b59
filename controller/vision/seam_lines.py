"""The lines a refused search measured: for another view of the same seam to choose among.

:func:`~controller.vision.seam_detect.detect_seam` refuses a view where no line passes every
check on its own (an end read as fading out inside a sheet, two lines of similar strength, an
end read as unsure). The lines it measured on the way are still measurements: a centreline
followed by gap profiles and ends read on the image. A second view of the same seam that did
find it can say which of them is the joint (its ends must meet that seam's:
:mod:`controller.cell.other_view`). :func:`measured_lines` hands them over. Pixels are (u, v) in
the distorted full image.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from controller.errors import AmbiguousSeam, SeamNotFound
from controller.geometry.camera_model import CameraModel
from controller.vision.seam_detect import checked_roi, detect_seam
from controller.vision.seam_params import F64, Candidate, DetectParams

#: The end readings a measured line keeps (:func:`controller.vision.seam_ends.end_offset`'s words):
#: ``"sheet border"`` (sure), ``"unsure sheet border"``, ``"image border"``, ``"open"`` (the line
#: fades out inside a sheet), ``"covered"`` (a patch on the line with the gap going on beyond).
SURE_END = "sheet border"
IMAGE_END = "image border"
OPEN = "open"


@dataclass(frozen=True)
class MeasuredLine:
    """One line the search measured, and why it did not return it alone.

    Centreline (K, 2) px, median gap width (px), end readings in the order of ``points_px``.
    """

    points_px: F64
    width_px: float
    end_readings: tuple[str, str]
    why_refused: str


def measured_lines(image: NDArray[Any], *, camera: CameraModel | None = None,
                   roi: tuple[int, int, int, int] | None = None,
                   params: DetectParams | None = None,
                   hint: Any = None) -> list[MeasuredLine]:
    """The lines measured by gap profiles in a view the search refuses (full-image px).

    The same search as :func:`detect_seam` (same arguments), traced. Kept: lines the first way
    measured with gap profiles (a whole-image valley path is the weak way: about a third of the
    seams it returns are wrong, README *Valley paths*) and whose ends are not both read as
    fading out inside a sheet (a pen or soapstone line, a scratch). Each line once. Empty where
    the search finds a seam after all (it is deterministic: it does not) or refuses before any
    line is measured. Input errors are raised as :func:`detect_seam` raises them.
    """
    H, W = image.shape[:2]
    x0, y0, _, _ = checked_roi(roi, W, H)
    trace: list[list[Candidate]] = []
    try:
        detect_seam(image, camera=camera, roi=roi, params=params, hint=hint, trace=trace)
        return []
    except (SeamNotFound, AmbiguousSeam):
        pass
    out: list[MeasuredLine] = []
    seen: list[F64] = []
    for look in trace:
        for c in look:
            if c.points is None or len(c.points) < 5 or c.way != "profiles" or \
                    c.end_kinds == (OPEN, OPEN):
                continue
            ends = c.points[[0, -1]]
            if any(np.abs(ends - s).max() < 1.0 for s in seen):
                continue  # (the finer grid hands on the first way's lines again)
            seen.append(ends)
            width = float(np.median(c.width)) if c.width is not None else 0.0
            why = c.why_rejected or ("passed every check alone, refused as too weak or for a rival "
                                     "(the view's refusal says)")
            out.append(MeasuredLine(c.points + [x0, y0], width, c.end_kinds, why))
    return out
