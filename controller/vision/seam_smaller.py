"""The seam found on the image shrunk, where the full-size search refuses a wide, soft gap.

The detector's pixel sizes (a gap up to 16 px, profiles 14 px to each side of it, the windows the
ends are read in) are those of a sharp gap a few px wide: a 2272x1704 camera at 350-450 mm. A
close-up shows the gap 13-25 px wide and defocused (edges blurred by a sigma of 2-4 px): the
profiles do not reach the sheets beyond it, the ends' windows are too small for its corners, and
the full-size search refuses it. On the image shrunk by :data:`SCALE` the same gap is 7-13 px
wide with its blur halved: the sizes the defaults were made for. So where the full-size search
finds no seam (or cannot choose between two lines, the wide gap measured in pieces: then only one
of those two is taken, :func:`one_of`), the same search runs on the image shrunk by 2
(``cv2.INTER_AREA``: each pixel the mean of the pixels it covers), and its seam is kept only where

1. **the gap is soft at full size**: the two-edge model fitted across it at full size, on profiles
   reaching past it, finds its edges blurred by a sigma of at least :data:`MIN_BLUR_PX`. A blur
   of sigma 2 px leaves 0.7 % of the contrast at the shrunk image's Nyquist frequency
   (``exp(-2 pi^2 sigma^2 f^2)``, ``f`` = 1/4 cycle per px): the full-size image holds no detail
   the shrunk one lost. A sharp image does (shrunk, a hairline gap beside a shadow or a cut face
   reads as one wide band whose middle is not the gap's): there the full-size refusal stands.
2. **it holds at another scale**: the same search on the image shrunk by :data:`CONFIRM` finds
   the same seam (the same end kinds, each end within :data:`END_AGREE_PX` or, for a gap wider
   than twice that, :data:`END_AGREE_SHARE` of its width, the centrelines within
   :data:`CENTRE_AGREE` of the gap's width, median). A reading that moves with the scale (an
   end read at a different corner, a band read on its other side) is not a measurement. (Four
   close-ups of the tuning part, gaps 20-27 px wide, were read at both scales with centrelines
   0.7-2.6 px apart and one end 8-12 px apart: three where the seam crosses the image border at
   45-60 deg, one at a sheet border; refused while 8 px was asked of every gap.)
   Where that search finds no seam at all (a faint gap drops under the search's thresholds at
   one scale: nothing read there moved), two of the searches shrunk by :data:`ALT_CONFIRM`
   (1.5, 2.5, 4) must find the same seam and none of them a different one.

The kept seam's centreline is measured again at full size along the shrunk search's line
(profiles as wide as its gap asks for, a shadow split off as the full-size search does:
:mod:`controller.vision.seam_shadow`); its ends, their kinds, the occluded spans and the
confidence are the shrunk search's, and a first reason says how it was found (the search's
own reasons after it count px of the shrunk image).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from controller.errors import SeamguideError
from controller.vision.seam_coarse import nearest_px
from controller.vision.seam_decision import JOINT_END, arc_length
from controller.vision.seam_detection import SeamDetection
from controller.vision.seam_ends import moving_line
from controller.vision.seam_params import F64, DetectParams
from controller.vision.seam_pattern import Straighten
from controller.vision.seam_profiles import fit_at, linear_lut, resample
from controller.vision.seam_shadow import split_shadow

SCALE = 2  # the image is searched again shrunk by this
CONFIRM = 3  # and the seam found there must be found shrunk by this too
MIN_BLUR_PX = 2.0  # full-size edge blur (sigma, px) from which shrinking by 2 loses nothing
END_AGREE_PX = 8.0  # the two scales' ends agree within this (full-size px)
END_AGREE_SHARE = 0.5  # or within this share of the gap's width, where that is more
CENTRE_AGREE = 0.25  # and their centrelines within this share of the gap's width (median)
_SIDE_PX = 8.0  # full-size profiles reach this far past the gap's edges
ONE_OF_SHARE = 0.8  # one_of: share of the seam's points along the line
ONE_OF_PX = 6.0  # one_of: along = within half the gap's width, at least this (px)
_MIN_PROFILES = 8  # full-size profiles that must fit the gap to measure it there
#: Where the search shrunk by CONFIRM finds no seam at all, two of these must find the same seam
#: and none a different one (extended tuning part: 4 close-ups found, no wrong seam more).
ALT_CONFIRM = (1.5, 2.5, 4.0)

#: The detector's search on an image: (grey, hint px or None, params, straighten) -> detection.
Look = Callable[[NDArray[np.uint8], F64 | None, DetectParams, Straighten | None], SeamDetection]


def smaller_look(grey: NDArray[np.uint8], hint: F64 | None, p: DetectParams, look: Look,
                 straighten: Straighten | None) -> SeamDetection | None:
    """The seam in ``grey`` as found on it shrunk (module doc), px of ``grey``; None: not found.

    ``hint``: the job's nominal seam (N, 2) px of ``grey`` or None; ``straighten``: ``grey`` px
    to undistorted px (:func:`controller.vision.seam_pattern.straightener`) or None; ``look``:
    the detector's full search (it raises :class:`SeamguideError` when it finds nothing).
    """
    half = _found_at(grey, SCALE, hint, p, look, straighten)
    if half is None:
        return None
    lut = linear_lut(p.gamma)
    full = _measured_at_full_size(grey, lut, half, p)
    if full is None or full.stats["edge_blur_px"] < MIN_BLUR_PX:
        return None
    confirmed = _confirmed(full, lambda f: _found_at(grey, f, hint, p, look, straighten))
    if not confirmed:
        return None
    # The search's own reasons count px of the image it searched: said so before them.
    again = " and ".join(f"{f:g}" for f in confirmed)
    reason = (f"found on the image shrunk by {SCALE} and again by {again}: the gap "
              f"({full.gap_width_px:.0f} px, edges blurred by {full.stats['edge_blur_px']:.1f} px)"
              " is wider and softer than the full-size search measures; the lengths and widths "
              f"below are px of the image shrunk by {SCALE}")
    return replace(full, reasons=[reason, *full.reasons])


def _confirmed(full: SeamDetection, found_at: Callable[[float], SeamDetection | None]
               ) -> list[float]:
    """The shrink factors at which the same seam as ``full`` is found (module doc, point 2).

    [:data:`CONFIRM`], or two or three of :data:`ALT_CONFIRM` where nothing is found at
    :data:`CONFIRM`; [] where it does not hold. ``found_at(f)``: the seam found shrunk by ``f``
    (px of the full image) or None.
    """
    other = found_at(CONFIRM)
    if other is not None:
        return [float(CONFIRM)] if same_seam(full, other) else []
    # Nothing found there is no reading that moved with the scale (a faint close-up gap drops
    # under the search's thresholds at one scale): two other scales must agree, none differ.
    agree: list[float] = []
    for f in ALT_CONFIRM:
        o = found_at(f)
        if o is None:
            continue
        if not same_seam(full, o):
            return []
        agree.append(f)
    return agree if len(agree) >= 2 else []


def same_seam(a: SeamDetection, b: SeamDetection) -> bool:
    """Whether two readings of the seam (px of one image) agree (module doc, point 2)."""
    ea, eb = a.endpoints_px, b.endpoints_px
    kb = b.end_kinds
    if np.linalg.norm(eb[0] - ea[0]) > np.linalg.norm(eb[1] - ea[0]):
        eb, kb = eb[::-1], (kb[1], kb[0])
    if tuple(kb) != tuple(a.end_kinds):
        return False
    end_tol = max(END_AGREE_PX, END_AGREE_SHARE * a.gap_width_px)
    if float(np.max(np.linalg.norm(eb - ea, axis=1))) > end_tol:
        return False
    return bool(np.median(_distances(a.points_px, b.points_px)) <= CENTRE_AGREE * a.gap_width_px)


def one_of(det: SeamDetection, lines: list[F64]) -> bool:
    """Whether ``det`` lies along one of ``lines`` (px of the same image; any point spacing).

    Along: :data:`ONE_OF_SHARE` of its points (every 4th) within ``max(ONE_OF_PX, half its
    gap's width)`` px of the line. Where the full-size search could not choose between two
    lines, the search on the image shrunk may choose, but only between those two
    (:func:`controller.vision.seam_detect.detect_seam`).
    """
    tol = max(ONE_OF_PX, 0.5 * det.gap_width_px)
    return any(len(q) >= 2 and float(np.mean(_distances(det.points_px, q) <= tol)) >= ONE_OF_SHARE
               for q in lines)


def _distances(a: F64, b: F64) -> F64:
    """Distance (px) from each point of ``a`` to the polyline ``b`` (read every px along it)."""
    return np.asarray(nearest_px(a, resample(b, 1.0, extend=0.0)[0])[0], dtype=np.float64)


def _scaled(P: F64, sx: float, sy: float, offset: tuple[float, float] = (0.0, 0.0)) -> F64:
    """Points ``P`` (px) in an image ``sx`` x ``sy`` times as large, moved by ``offset``.

    Pixel centres map as ``(p + 0.5) * s - 0.5``: the shrunk pixel 0 covers pixels 0 and 1,
    centre 0.5.
    """
    return np.asarray((P + 0.5) * [sx, sy] - 0.5 + np.asarray(offset, float), np.float64)


def moved(det: SeamDetection, scale: float | tuple[float, float],
          offset: tuple[float, float]) -> SeamDetection:
    """``det`` in another image's px: ``q = (p + 0.5) * scale - 0.5 + offset``.

    ``scale``: that image's px per px of ``det``'s (x, y), e.g. 2 from an image shrunk by 2
    (pixel centres: the shrunk pixel 0 covers pixels 0 and 1, centre 0.5); ``offset``: where
    ``det``'s image starts in it (a region of interest). Widths and lengths scale by the mean.
    """
    sx, sy = (scale, scale) if isinstance(scale, (int, float)) else scale
    k = (sx + sy) / 2

    def m(P: F64) -> F64:
        return _scaled(P, sx, sy, offset)

    stats: dict[str, Any] = dict(det.stats)
    if "length_px" in stats:
        stats["length_px"] = stats["length_px"] * k
    return replace(det, points_px=m(det.points_px), endpoints_px=m(det.endpoints_px),
                   width_px=det.width_px * k,
                   band_px=None if det.band_px is None else m(det.band_px),
                   band_width_px=None if det.band_width_px is None else det.band_width_px * k,
                   occluded_spans_px=[(a * k, b * k) for a, b in det.occluded_spans_px],
                   stats=stats)


def _found_at(grey: NDArray[np.uint8], f: float, hint: F64 | None, p: DetectParams, look: Look,
              straighten: Straighten | None) -> SeamDetection | None:
    """The detector's seam on ``grey`` shrunk by ``f``, in px of ``grey``; None: none found."""
    H, W = grey.shape
    w, h = max(1, round(W / f)), max(1, round(H / f))
    small = np.asarray(cv2.resize(grey, (w, h), interpolation=cv2.INTER_AREA), dtype=np.uint8)
    sx, sy = W / w, H / h

    def down(P: F64) -> F64:
        return _scaled(P, 1.0 / sx, 1.0 / sy)

    small_straighten = (None if straighten is None
                        else (lambda P: down(straighten(_scaled(P, sx, sy)))))
    # A band limit the job stated (px of the image) is f times fewer px of the shrunk one; so is
    # how far the seam may lie from the nominal one.
    ps = replace(p, max_band_px=p.max_band_px / f, min_gap_px=p.min_gap_px / f,
                 hint_tol_px=p.hint_tol_px / f, smaller=False, grain=False,
                 carry=False)
    try:
        det = look(small, None if hint is None else down(hint), ps, small_straighten)
    except SeamguideError:
        return None
    return moved(det, (sx, sy), (0.0, 0.0))


def _measured_at_full_size(grey: NDArray[np.uint8], lut: F64, det: SeamDetection,
                           p: DetectParams) -> SeamDetection | None:
    """``det`` (found shrunk, px of ``grey``) with its centreline measured on ``grey``.

    Profiles across the line reach :data:`_SIDE_PX` past a gap of its width; where they fit the
    gap (a shadow split off as :func:`split_shadow` does), the line moves by their offsets,
    smoothed along it, held from the last one measured to an end; profiles within their length
    of a ``joint_end`` (where the sheets end they cross the border) are not used. Adds
    ``stats["edge_blur_px"]``: the edges' blur (sigma, median). None: fewer than
    :data:`_MIN_PROFILES` profiles fit.
    """
    P = det.points_px
    w = det.gap_width_px
    s = arc_length(P)
    idx = np.arange(len(P))
    tang = P[np.minimum(idx + 3, len(P) - 1)] - P[np.maximum(idx - 3, 0)]
    tang /= np.linalg.norm(tang, axis=1, keepdims=True) + 1e-12
    nrm = np.column_stack([-tang[:, 1], tang[:, 0]])
    pw = replace(p, max_gap_px=max(p.max_gap_px, 1.6 * w + 2.0),
                 half_width_px=max(p.half_width_px, w / 2 + _SIDE_PX))
    two = fit_at(grey, lut, P, nrm, pw)
    if int(two["valid"].sum()) < _MIN_PROFILES:
        return None
    blur = float(np.median(two["params"][two["valid"], 5]))
    fit, shadow = split_shadow(two, pw)
    reach = pw.half_width_px + 3.0
    away = np.ones(len(P), bool)
    if det.end_kinds[0] == JOINT_END:
        away &= s >= reach
    if det.end_kinds[1] == JOINT_END:
        away &= s <= s[-1] - reach
    off = np.einsum("kd,kd->k", fit["centre"] - P, nrm)
    ok = fit["valid"] & away & (np.abs(off) < max(2.0, w / 4)) & (fit["width"] < 1.6 * w + 1.0)
    if int(ok.sum()) < _MIN_PROFILES:
        return None
    win = min(7, (len(P) - 1) // 2 * 2 + 1)

    def along(v: F64, where: NDArray[np.bool_]) -> F64:
        out = np.interp(s, s[where], v[where])
        return moving_line(out, win) if win >= 3 else out

    pts = P + nrm * along(off, ok)[:, None]
    band, band_w = None, None
    if shadow.get("shadow_split"):
        whole = ok & two["valid"]
        band = P + nrm * along(np.einsum("kd,kd->k", two["centre"] - P, nrm), whole)[:, None]
        band_w = float(np.median(two["width"][whole]))
    stats = {**det.stats, **shadow, "edge_blur_px": blur, "scale": float(SCALE),
             "way": f"{det.stats.get('way', 'profiles')}, image shrunk by {SCALE}"}
    return replace(det, points_px=pts, endpoints_px=np.array([pts[0], pts[-1]]),
                   width_px=np.interp(s, s[ok], fit["width"][ok]), band_px=band,
                   band_width_px=band_w, stats=stats)
