"""The detector's pixel scales from the working distance: px per mm and the expected gap in mm.

:class:`~controller.vision.seam_params.DetectParams` holds fixed pixel scales tuned for a
2272x1704 camera (fx ~2840 px) at 350-450 mm, about 6-8 px/mm: a gap up to 16 px wide, profiles
14 px to each side, seams of at least 300 px. A close-up camera sees a 1 mm gap 20-25 px wide (too
wide for those profiles), a far one sees a whole seam shorter than 300 px. Where the calibration
and the job give the working distance ``Z`` (mm, along the optical axis), the scale is
``px_per_mm = fx / Z`` (:func:`px_per_mm_at`) and :func:`params_for_scale` sets the scales that
follow from it. The floors are the defaults: the scales only grow with a wider gap, so what the
defaults reject as noise at their own distance is still rejected; only the shortest seam kept
shrinks, down to :data:`MIN_LENGTH_FLOOR_PX`, when the whole seam is short in the image. One
exception, on the job's word: where the job states its gap, a dark band wider than that gap, a
shadow and blur can make it is refused (``max_band_px``): it is the gap with a shadow or a mark
beside it, and its middle is off the gap's; and a darker core narrower than its narrowest gap
is not split off as a gap beside a shadow (``min_gap_px``).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from numpy.typing import ArrayLike

from controller.errors import InputError
from controller.vision.seam_params import DetectParams

#: Expected gap (mm) when the job says nothing: a hairline to 1.2 mm, the gaps the defaults were
#: tuned on. At the defaults' distances (6-8 px/mm) it gives the defaults' scales, so a job that
#: does not say its gap is detected as the benchmark measures; a close-up view still gets longer
#: profiles (a 1.2 mm gap is 24 px at 20 px/mm). A wider gap range loosens the search at every
#: distance (wider dark lines, pen lines, accepted as gaps): give it only when the joint has it.
DEFAULT_GAP_MM: tuple[float, float] = (0.1, 1.2)
#: A lopsided shadow band beside the gap (the plate edge's) widens the dark band by this share.
SHADOW_SHARE = 0.25
#: Blur (px) on the gap's two edges together: a defocused edge darkens about 1 px outside it.
BLUR_PX = 2.0
#: Sheet (px) the profile reads beyond the dark band on each side, for the sheets' levels.
SIDE_PX = 6.0
#: The shortest seam kept is at most this share of the seam's expected length in the image.
LENGTH_SHARE = 0.5
#: The shortest seam kept never goes under this (px): shorter valleys are scratches and noise.
MIN_LENGTH_FLOOR_PX = 100.0
#: Two lines of a table's grid are at least this far apart (mm): farther than a fitter's pen
#: line beside a joint (3-20 mm), closer than a welding table's pitch (50-100 mm).
GRID_PITCH_MM = 25.0


def check_gap_mm(gap_mm: ArrayLike, name: str = "gap_mm") -> tuple[float, float]:
    """``gap_mm`` as (lo, hi) mm, or :class:`InputError` naming ``name`` and what to give.

    Both finite, ``0 <= lo <= hi``, ``hi`` positive and under 50 mm (a butt joint's gap).
    """
    try:
        lo, hi = (float(v) for v in np.asarray(gap_mm, dtype=np.float64).reshape(-1))
    except (TypeError, ValueError) as err:
        raise InputError(f"{name} = {gap_mm!r}: give two numbers [min, max] in mm, e.g. "
                         "[0.1, 2.0]") from err
    if not (math.isfinite(lo) and math.isfinite(hi)) or lo < 0 or hi <= 0 or lo > hi:
        raise InputError(f"{name} = [{lo:g}, {hi:g}]: give the narrowest and the widest gap in "
                         "mm, 0 <= min <= max and max > 0, e.g. [0.1, 2.0]")
    if hi > 50.0:
        raise InputError(f"{name} = [{lo:g}, {hi:g}]: a gap over 50 mm is not a butt joint; give "
                         "the gap in mm (not px or um), e.g. [0.1, 2.0]")
    return lo, hi


def params_for_scale(px_per_mm: float, gap_mm: ArrayLike = DEFAULT_GAP_MM, *,
                     seam_length_px: float | None = None, limit_band: bool = False,
                     base: DetectParams | None = None) -> DetectParams:
    """``base`` (default :class:`DetectParams`) with its pixel scales set for ``px_per_mm``.

    ``px_per_mm``: image px per mm on the part at the working distance (``fx / Z``, see
    :func:`px_per_mm_at`); ``gap_mm``: (narrowest, widest) expected gap, mm;
    ``seam_length_px``: the seam's expected length in the image (px; None: not known). With the
    widest gap ``w = gap_mm[1] * px_per_mm`` px, the dark band is
    ``b = (1 + SHADOW_SHARE) * w + BLUR_PX`` px (the gap, a lopsided shadow beside it, blur), and

    - ``max_gap_px`` (widest gap accepted) = ``max(base, b)``;
    - ``half_width_px`` (half length of each profile) = ``max(base, b / 2 + SIDE_PX)``: the
      profile reads both sheets beyond the band;
    - ``valley_r_px`` (coarse search: where both sides of a valley are read, full-res px) =
      ``max(base, b / 2)``: outside the band, so a wide gap is a valley, not two edges;
    - ``min_length_px`` (shortest seam kept) = ``min(base, LENGTH_SHARE * seam_length_px)`` but
      not under :data:`MIN_LENGTH_FLOOR_PX`; ``piece_length_px`` at most that;
    - ``pattern_offset_px`` (closest two lines of a table's grid) =
      ``max(base, GRID_PITCH_MM * px_per_mm)``: a pen line 20 mm beside a close-up joint is not
      a grid's second line;
    - ``max_band_px`` (widest dark band taken for the gap) = ``b`` when ``limit_band`` (the job
      states its gap: a band wider than ``b`` is a shadow or a mark beside the gap, and its
      middle is not the gap's), else ``base``'s (0: no limit). Only this narrows what the
      defaults accept, and only on the job's word: a gap range left at the default
      does not limit the band (a wide gap is still found by the valley paths);
    - ``min_gap_px`` (the narrowest gap) = ``gap_mm[0] * px_per_mm`` when ``limit_band``, else
      ``base``'s: a darker core narrower than that inside a dark band is the floor beside a
      cut face seen in the gap, not a gap beside a shadow (:mod:`seam_shadow` keeps the band).

    Everything else is ``base``'s (the defaults' noise floors: depth, fit, confidence). While
    ``w <= 11.2`` px (the default 1.2 mm gap at up to 9.3 px/mm: fx 2840 px from 305 mm on) the
    result is ``base`` but for ``valley_r_px <= 8``, which a 2272 px wide image's automatic
    coarse factor (4 x 3 px) already reaches, and from 8 px/mm (355 mm) on a larger
    ``pattern_offset_px``. Raises
    :class:`InputError` for a non-positive or non-finite ``px_per_mm`` / ``seam_length_px`` or a
    bad ``gap_mm``.
    """
    p = base or DetectParams()
    s = float(px_per_mm)
    if not math.isfinite(s) or s <= 0:
        raise InputError(f"px_per_mm = {px_per_mm!r}: must be a positive number (fx / working "
                         "distance in mm)")
    lo, hi = check_gap_mm(gap_mm)
    band = (1.0 + SHADOW_SHARE) * hi * s + BLUR_PX
    min_length = p.min_length_px
    if seam_length_px is not None:
        L = float(seam_length_px)
        if not math.isfinite(L) or L <= 0:
            raise InputError(f"seam_length_px = {seam_length_px!r}: must be a positive number")
        min_length = max(min(min_length, LENGTH_SHARE * L), MIN_LENGTH_FLOOR_PX)
    return replace(p,
                   max_gap_px=max(p.max_gap_px, band),
                   half_width_px=max(p.half_width_px, band / 2 + SIDE_PX),
                   valley_r_px=max(p.valley_r_px, band / 2),
                   min_length_px=min_length,
                   piece_length_px=min(p.piece_length_px, min_length),
                   pattern_offset_px=max(p.pattern_offset_px, GRID_PITCH_MM * s),
                   max_band_px=band if limit_band else p.max_band_px,
                   min_gap_px=lo * s if limit_band else p.min_gap_px)


def px_per_mm_at(fx_px: float, T_base_cam: ArrayLike, point_mm: ArrayLike) -> float | None:
    """Image px per mm at ``point_mm`` (base frame, mm) seen from ``T_base_cam`` (mm): ``fx / Z``.

    ``Z`` is the point's depth along the camera's optical axis (mm). None when the point is not
    at least 1 mm in front of the camera (no scale to set).
    """
    T = np.asarray(T_base_cam, dtype=np.float64)
    p = np.asarray(point_mm, dtype=np.float64).reshape(3)
    z = float(T[:3, 2] @ (p - T[:3, 3]))  # the point in the camera frame, its z
    if not math.isfinite(z) or z < 1.0:
        return None
    return float(fx_px) / z
