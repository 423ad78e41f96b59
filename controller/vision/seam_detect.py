"""Find the weld joint in one image: an ordered sub-pixel centreline with a confidence and reasons.

The joint is a thin dark valley with a sheet on each side, running from one sheet border to the
other. Sheet borders, table holes, marker dots, clutter and glare give edges as strong as the
joint's, so this looks for the *shape*, not for edges:

1. **Coarse search** on the image shrunk by ``coarse_factor`` (box average, so a thin gap stays
   visible as a dip): linearise the grey levels (camera response ``gamma``) and compute, in four
   directions, the *relative valley depth* ``(min(I(p + r n), I(p - r n)) - I(p)) / min(...)``.
   It is high only where both sides are brighter than the centre: a step edge (sheet border), a
   dot or a wide dark band give ~0, and dividing by the local brightness makes it independent of
   uneven light and glare (adaptive rather than a fixed threshold).
2. **Candidates**: connected components of the thresholded depth (pieces of a faint gap that dips
   under the threshold are joined when they continue each other), long ones kept; each becomes an
   ordered polyline by binning its pixels along its principal axis (any orientation in the image;
   the curve must be monotonic along some direction: straight seams, arcs up to a half circle,
   S-curves).
3. **Sub-pixel refinement at full resolution**, only along the candidate: a profile across the
   curve every ``step_px`` pixels, sampled by exact bilinear interpolation of the *linearised*
   image (not ``cv2.remap``, which quantises coordinates to 1/32 px), is fitted by a model of two
   blurred steps (left sheet level, gap floor, right sheet level, centre, width, blur). The centre
   is the midpoint of the two gap edges, which is unbiased when the sheets differ in brightness,
   unlike the darkness centroid (biased toward the darker sheet by up to 0.3 px).
4. **Curve and ends**: the longest run of good profiles (short interruptions by a crossing
   scratch are bridged) gives honest end points; outliers are dropped and the centreline is
   smoothed by a local quadratic (Savitzky-Golay) fit over arc length, which follows any shape
   without the curling of a global polynomial and without shrinking curves.
   A straight candidate in a grid of straight valleys (crossed by one, with another parallel to
   it or to the crossing one), or one of three or more parallel lines a table's pitch apart, is
   a line of the table, set aside before refining and again after, on the refined centreline
   judged straight on the undistorted image (:mod:`controller.vision.seam_pattern`).
5. **Decision**: no candidate that passes -> :class:`SeamNotFound`; two of similar strength ->
   :class:`AmbiguousSeam`; both carry what was seen in ``details``.
6. **Second and third looks** when no candidate passes: the coarse search again with the valley
   depth of a grid twice as fine pooled onto the coarse one (a hairline gap straddling two
   coarse pixels shows half its depth in each and falls apart), keeping only lines at most a
   coarse pixel wide; then the seam as a whole-image valley path (ragged, wide, covered gaps).
7. **The image shrunk** when all of that finds no seam, or cannot choose between two lines: the
   same search on the image shrunk by 2, for a gap wider and softer than the full-size scales (a
   defocused close-up), kept only where the gap is blurred at full size and the search shrunk by
   3 finds the same seam (:mod:`controller.vision.seam_smaller`); after an ambiguity, only if it
   is one of the two lines (:func:`controller.vision.seam_smaller.one_of`).

The steps live in :mod:`controller.vision.seam_coarse` (1, 2), :mod:`.seam_profiles` (3),
:mod:`.seam_centreline` and :mod:`.seam_ends` (4), :mod:`.seam_decision` (5) (all in
``controller.vision``); :mod:`.seam_params` holds the tuning. This module is the public entry.

Pixels are (u, v) = (column, row), origin at the centre of the top-left pixel, in the *distorted*
image (undistort with ``CameraModel.pixels_to_normalized``).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import replace
from typing import Any

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from controller.errors import AmbiguousSeam, InputError, SeamNotFound
from controller.geometry.camera_model import CameraModel
from controller.vision.seam_centreline import refine, scale_advice
from controller.vision.seam_coarse import coarse_candidates, drop_duplicates, mean_dist, share_near
from controller.vision.seam_crossbar import no_stem_on
from controller.vision.seam_decision import (
    IMAGE_BORDER,
    JOINT_END,
    choose,
    orient,
    public_end_kinds,
    spans_of,
)
from controller.vision.seam_detection import SeamDetection
from controller.vision.seam_edge_ends import carry_to_edge, correct_edge_ends
from controller.vision.seam_grain import no_grain_across, no_one_surface
from controller.vision.seam_parallel import no_parallel_valley
from controller.vision.seam_params import F64, OPEN_END, Candidate, DetectParams
from controller.vision.seam_pattern import (
    Straighten,
    mark_table_lines,
    straight_lines,
    straightener,
)
from controller.vision.seam_profiles import linear_lut, resample
from controller.vision.seam_robust import robust_candidates
from controller.vision.seam_smaller import moved, one_of, smaller_look
from controller.vision.seam_tee import cut_stems, find_tees

#: Marks the lines of a table among candidates (seam_pattern.mark_table_lines, bound to an image).
TableCheck = Callable[[list[Candidate]], None]

__all__ = ["IMAGE_BORDER", "JOINT_END", "DetectParams", "SeamDetection", "detect_seam"]


def detect_seam(image: NDArray[Any], *, camera: CameraModel | None = None,
                roi: tuple[int, int, int, int] | None = None, hint: ArrayLike | None = None,
                params: DetectParams | None = None,
                trace: list[list[Candidate]] | None = None) -> SeamDetection:
    """Find the seam in ``image`` (uint8, greyscale HxW or BGR HxWx3) and return its centreline.

    ``camera``: when given, the image size must match it (a wrong-size image is an
    :class:`InputError`). ``roi``: (x0, y0, x1, y1) pixel box to search in (end exclusive).
    ``hint``: a nominal seam polyline (N >= 2 vertices, px; it may run out of the image), the
    job's nominal line seen in this view; a candidate ``p.hint_tol_px`` or more (mean distance)
    from it is never returned, and still counts as a rival (:func:`outside_corridor`).
    Raises :class:`SeamNotFound` (no candidate passes), :class:`AmbiguousSeam` (two candidates
    of similar strength, a second line beside the best one at a pen line's distance, or a long
    line ending on it: a T's crossbar), :class:`InputError` (not a uint8 image, wrong size, bad
    ROI or hint). A refusal where a line's profiles fitted a band wider than ``p.max_gap_px``
    says what to give to measure it (:func:`controller.vision.seam_centreline.scale_advice`).
    ``trace``: when given, every list of candidates a choice is made over is appended to it, in
    order (the first way's; with the finer grid's; the valley paths'), ROI px: what
    ``bench.detect_funnel`` reads to say where a joint was lost (the full-size search only; the
    look at the image shrunk is not traced).
    """
    p = params or DetectParams()
    grey = _as_grey(image)
    H, W = grey.shape
    if camera is not None and (camera.width, camera.height) != (W, H):
        raise InputError(f"image is {W}x{H} px but the calibration is for "
                         f"{camera.width}x{camera.height}; use the calibration of this camera "
                         "(or resize the image back to the calibrated size)",
                         image_size=[W, H], calibration_size=[camera.width, camera.height])
    x0, y0, x1, y1 = checked_roi(roi, W, H)
    sub = grey[y0:y1, x0:x1]
    hint_arr = None if hint is None else _check_hint(hint) - [x0, y0]
    straighten = None if camera is None else straightener(camera, x0, y0)
    traced: list[list[Candidate]] = [] if trace is None else trace
    try:
        return _detect_in(sub, hint_arr, p, straighten, traced, (x0, y0, x1, y1))
    except (SeamNotFound, AmbiguousSeam) as exc:
        if not p.smaller:
            raise scale_advice(exc, traced, p) from None
        # A gap wider and softer than the full-size search measures (a close-up): the same
        # search on the image shrunk (seam_smaller), kept only where it holds at two scales.
        small = smaller_look(sub, hint_arr, p, search, straighten)
        if small is None:
            raise scale_advice(exc, traced, p) from None
        if isinstance(exc, AmbiguousSeam):
            # Two lines the full-size search could not choose between (it measures a close-up's
            # wide gap in pieces): the shrunk search may choose, but only one of those two.
            two = [np.asarray(exc.details[k], np.float64) - [x0, y0]
                   for k in ("best_px", "second_px") if k in exc.details]
            if len(two) < 2 or not one_of(small, two):
                raise scale_advice(exc, traced, p) from None
            why = str(exc).split("; refusing")[0]
            small = replace(small, reasons=[f"at full size: {why}; the search on the image "
                                            "shrunk took this one of the two",
                                            *small.reasons])
        no_one_surface(sub, small, p, x0, y0)  # (not read on the image shrunk: asked here)
        if hint_arr is None:  # the lines the full-size search saw, on the seam read shrunk
            no_stem_on(small.points_px, small.gap_width_px or 3.0,
                       [c for look in traced for c in look], p, x0, y0)
        return moved(small, 1.0, (x0, y0))


def search(sub: NDArray[np.uint8], hint_arr: F64 | None, p: DetectParams,
           straighten: Straighten | None) -> SeamDetection:
    """The detector's search in ``sub`` alone, untraced: results and errors in px of ``sub``.

    What :func:`controller.vision.seam_smaller.smaller_look` runs on the image shrunk.
    """
    return _detect_in(sub, hint_arr, p, straighten, None, None)


def _detect_in(sub: NDArray[np.uint8], hint_arr: F64 | None, p: DetectParams,
               straighten: Straighten | None, trace: list[list[Candidate]] | None,
               box: tuple[int, int, int, int] | None) -> SeamDetection:
    """:func:`detect_seam`'s search in ``sub`` (px of ``sub``, as ``hint_arr``).

    ``sub`` is the region ``box`` (x0, y0, x1, y1) of the image: results and errors in image
    px (None: ``sub`` is the image searched, px of ``sub``).
    """
    x0, y0, x1, y1 = box if box is not None else (0, 0, sub.shape[1], sub.shape[0])
    lut = linear_lut(p.gamma)
    cands, seen, valleys, factor = coarse_candidates(sub, lut, p)
    lines = functools.cache(lambda: straight_lines(valleys, factor, p))
    table = functools.partial(mark_table_lines, lines=lines, p=p, straighten=straighten)
    cands = _refined(sub, lut, cands, table, p)
    details: dict[str, Any] = {"candidates_seen": seen, "roi": [x0, y0, x1, y1]}

    checked: set[int] = set()  # candidates whose image-border ends were looked at already

    def decide(cands: list[Candidate]) -> tuple[Candidate, float, float, list[str]]:
        fresh = [c for c in cands if id(c) not in checked]
        correct_edge_ends(sub, lut, fresh)
        tees = find_tees(sub, lut, cands)
        cut_stems([t for t in tees if id(t.stem) not in checked])
        checked.update(id(c) for c in cands)
        if hint_arr is not None:
            outside_corridor(cands, hint_arr, p)
        if trace is not None:
            trace.append(list(cands))
        return choose(cands, p, details, (x0, y0), tees)

    looked = cands  # every candidate looked at: where a line ends on the one chosen (crossbar)
    try:
        best, ratio, conf, reasons = decide(cands)
    except SeamNotFound as first:
        if not p.robust:
            raise
        both = cands + _hairline_look(sub, lut, cands, table, factor, p)
        try:
            best, ratio, conf, reasons = decide(both)
        except SeamNotFound:
            pass
        else:
            _one_line(sub, lut, best, both, hint_arr, p, x0, y0)
            return _detection(best, ratio, conf, reasons, both, x0, y0)
        # The gap is not the clean two-edge valley the profiles fit (ragged, wide, covered by
        # tack welds, dark and noisy): the seam as a whole-image valley path (seam_robust).
        cands = robust_candidates(sub, lut, p, not_lines=faded_lines(cands))
        looked = both + cands
        table(cands)
        details["first_way"] = str(first)
        best, ratio, conf, reasons = decide(cands)
        reasons.append("found as a whole-image valley path (the two-edge profile model did not "
                       "fit the gap)")
    _one_line(sub, lut, best, looked, hint_arr, p, x0, y0)
    return _detection(best, ratio, conf, reasons, cands, x0, y0)


def _one_line(sub: NDArray[np.uint8], lut: F64, best: Candidate, looked: list[Candidate],
              hint: F64 | None, p: DetectParams, x0: int, y0: int) -> None:
    """Refuse ``best`` where a parallel line, the sheets' grain or a T-stem makes it doubtful.

    The second is not asked where the job's nominal seam line (``hint``) chose ``best``. A
    ``best`` kept has its image-border ends carried on to the edge (``carry_to_edge``).
    """
    no_parallel_valley(sub, lut, best, p, x0, y0)
    no_grain_across(sub, lut, best, p, x0, y0)
    if hint is None and best.points is not None:
        no_stem_on(best.points, float(np.median(best.width)) if best.width is not None else 3.0,
                   looked, p, x0, y0)
    carry_to_edge(sub, lut, best, p)


def outside_corridor(cands: list[Candidate], hint: F64, p: DetectParams) -> None:
    """Refuse the candidates lying ``p.hint_tol_px`` or more (mean) from the nominal seam.

    None of them is returned: one that passed is refused for where it lies. They stay in the
    list, judged as without a nominal seam (a T's crossbar still ends its stem there:
    seam_tee), and each stays a rival, or becomes one if it had passed: a line anywhere in the
    view as strong as the seam chosen near the nominal one still makes that choice doubtful. A
    nominal seam never turns a refusal into a seam: on the benchmark's held-out views, letting
    far lines stop counting as rivals returned as many wrong seams as found ones, and on a real
    photograph (1_x5 of ../shared/data/real-seams, the ground strip's edge line set aside) a
    wrong one (README, *A nominal seam line*).
    """
    for c in cands:
        d = mean_dist(c.points if c.points is not None else c.polyline, hint)
        if d < p.hint_tol_px:
            continue
        if not c.why_rejected:
            c.rival = True
            c.why_rejected = (f"line {d:.0f} px (mean) from the nominal seam, where the seam may "
                              f"lie at most {p.hint_tol_px:.0f} px from it")


def faded_lines(cands: list[Candidate]) -> list[F64]:
    """The centrelines (px) of ``cands`` seen to fade out inside a sheet at an end.

    Also where the other end stopped at a patch with the line going on beyond it: that end
    says nothing of what the line is, the open one does (a pen line, a scratch). A valley path
    along one of them is not a seam (:func:`controller.vision.seam_robust.robust_candidates`).
    """
    return [c.points for c in cands if c.points is not None
            and (c.refused == OPEN_END or "open" in c.end_kinds)]


def _refined(sub: NDArray[np.uint8], lut: F64, cands: list[Candidate], table: TableCheck,
             p: DetectParams) -> list[Candidate]:
    """Coarse candidates refined (table lines set aside, pieces of one seam once).

    ``table(cands)``: marks the lines of a table's grid among ``cands``
    (:func:`controller.vision.seam_pattern.mark_table_lines`).
    """
    # Lines of the table are set aside before refining, so that they do not use up the
    # candidates refined (max_candidates) nor make the joint look ambiguous; and again after,
    # on the refined centreline: a long line is straight enough to judge only at full resolution.
    table(cands)
    aside = [c for c in cands if c.why_rejected]
    cands = [c for c in cands if not c.why_rejected]
    cands = cands[: p.max_candidates]
    done: list[Candidate] = []
    for c in cands:
        # A piece of a seam already refined across its covered patches is that seam again.
        if any(k.points is not None and not k.why_rejected
               and share_near(c.polyline, k.points, 6.0) >= 0.8 for k in done):
            continue
        refine(sub, lut, c, p)
        done.append(c)
    table(done)
    return drop_duplicates(done) + aside


def _hairline_look(sub: NDArray[np.uint8], lut: F64, cands: list[Candidate], table: TableCheck,
                   factor: int, p: DetectParams) -> list[Candidate]:
    """The lines a grid twice as fine gives that the coarse one (``cands``) did not, refined.

    Those the coarse grid gave keep their verdicts (and stay rivals) and are not refined again.
    A line wider than a coarse pixel is refused: the finer grid is for gaps about one coarse
    pixel wide; a wider line was seen on the coarse grid already and refused there.
    """
    seen_lines = [k.polyline for k in cands] + [k.points for k in cands if k.points is not None]
    new = [c for c in coarse_candidates(sub, lut, p, fine=True)[0]
           if not any(share_near(c.polyline, q, 6.0) >= 0.8 for q in seen_lines)]
    fine = _refined(sub, lut, new, table, p)
    for c in fine:
        if c.width is not None and float(np.median(c.width)) > factor:
            # Whatever else it was refused for: the coarse grid's verdict on it stands, and a
            # duplicate of a line it judged is no rival either.
            c.why_rejected = (f"line {float(np.median(c.width)):.1f} px wide found only on the "
                              "finer search grid")
            c.rival, c.refused = False, ""
    return fine


def _detection(best: Candidate, ratio: float, conf: float, reasons: list[str],
               cands: list[Candidate], x0: int, y0: int) -> SeamDetection:
    """The chosen candidate as a :class:`SeamDetection` in full-image px, oriented."""
    assert best.points is not None and best.width is not None
    pts0 = best.points + [x0, y0]
    pts = orient(pts0)
    flipped = pts is not pts0
    band = None if best.band_points is None else best.band_points + [x0, y0]
    if band is not None and flipped:
        band = band[::-1]
    width = best.width[::-1] if flipped else best.width
    kinds = public_end_kinds(best.end_kinds)
    bridged = best.bridged if best.bridged is not None else np.zeros(len(pts), bool)
    if flipped:
        kinds, bridged = (kinds[1], kinds[0]), bridged[::-1]
    stats = {"length_px": float(np.sum(np.linalg.norm(np.diff(pts, axis=0), axis=1))),
             "valid_fraction": float(best.valid_frac), "relative_depth": float(best.depth),
             "fit_residual": float(best.resid), "second_best_ratio": float(ratio),
             "candidates": len(cands), "way": best.way}
    return SeamDetection(points_px=pts, confidence=conf, reasons=reasons,
                         endpoints_px=np.array([pts[0], pts[-1]]), width_px=width, stats=stats,
                         end_kinds=kinds, occluded_spans_px=spans_of(pts, bridged),
                         band_px=band, band_width_px=best.band_width if band is not None else None)


def _as_grey(image: NDArray[Any]) -> NDArray[np.uint8]:
    img = np.asarray(image)
    if img.dtype != np.uint8:
        raise InputError(f"detect_seam needs a uint8 image, got dtype {img.dtype}; load 8-bit "
                         "images (controller.vision.image_io.load_image)")
    if img.ndim == 3 and img.shape[2] == 3:
        return np.asarray(cv2.cvtColor(img, cv2.COLOR_BGR2GRAY), dtype=np.uint8)
    if img.ndim == 3 and img.shape[2] == 1:
        return img[:, :, 0]
    if img.ndim != 2:
        raise InputError(f"detect_seam needs a greyscale (H, W) or BGR (H, W, 3) image, got "
                         f"shape {img.shape}")
    if min(img.shape) < 32:
        raise InputError(f"image {img.shape[1]}x{img.shape[0]} px is too small to hold a seam "
                         "(at least 32 px each way)")
    return img


def _check_hint(hint: ArrayLike) -> F64:
    """The nominal seam polyline ``hint`` (px) with a point every 2 px.

    Distances to it are read at its points; a hint that cannot be one is an :class:`InputError`
    saying what is wrong with it.
    """
    try:
        h = np.asarray(hint, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise InputError(f"nominal seam (hint) must be a list of [u, v] px, got {hint!r}") from err
    if h.ndim != 2 or h.shape[1] != 2 or len(h) < 2 or not np.all(np.isfinite(h)):
        raise InputError(f"nominal seam (hint) must be two or more finite [u, v] px, got an "
                         f"array of shape {h.shape}")
    if float(np.sum(np.linalg.norm(np.diff(h, axis=0), axis=1))) < 10.0:
        raise InputError("nominal seam (hint) is under 10 px long: give its vertices along the "
                         "seam, in px of the image")
    return resample(h, 2.0, extend=0.0)[0]


def checked_roi(roi: Any, W: int, H: int) -> tuple[int, int, int, int]:
    """The region searched (x0, y0, x1, y1; end exclusive) of a W x H image: ``roi`` clipped."""
    if roi is None:
        return 0, 0, W, H
    try:
        x0, y0, x1, y1 = (int(v) for v in roi)
    except (TypeError, ValueError) as err:
        raise InputError(f"roi must be four integers x0,y0,x1,y1, got {roi!r}") from err
    x0, y0 = max(x0, 0), max(y0, 0)
    x1, y1 = min(x1, W), min(y1, H)
    if x1 - x0 < 32 or y1 - y0 < 32:
        raise InputError(f"roi {list(roi)} leaves {max(x1 - x0, 0)}x{max(y1 - y0, 0)} px of the "
                         f"{W}x{H} image; give a box of at least 32x32 px inside the image")
    return x0, y0, x1, y1
