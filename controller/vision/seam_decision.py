"""The decision on the best candidate: its confidence and the reasons, and how it is reported."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from controller.errors import AmbiguousSeam, SeamNotFound
from controller.vision.seam_coarse import nearest_px
from controller.vision.seam_params import F64, Candidate, DetectParams, Tee, runs_of

JOINT_END = "joint_end"
IMAGE_BORDER = "image_border"
#: What an ambiguous refusal asks for. A box around the joint leaves the other line out; on the
#: views refused so the seam found inside such a box was as often wrong as right (README, *A
#: nominal seam line*): the person who draws the box checks the seam it gives.
GIVE_ROI = ("give a --roi around the joint (the --overlay picture draws the lines) and check "
            "the seam found there on the picture")


def choose(cands: list[Candidate], p: DetectParams, details: dict[str, Any],
           offset: tuple[int, int], tees: list[Tee] | None = None
           ) -> tuple[Candidate, float, float, list[str]]:
    """The best of ``cands`` (refined), the next one's score ratio, its confidence and reasons.

    ``tees``: the T-corners among ``cands`` (:func:`controller.vision.seam_tee.find_tees`):
    neither a crossbar nor a line along the T is its stem's rival, a stem at least
    ``p.ambiguity_ratio`` as strong as its crossbar is chosen over it, and a weaker one makes
    the crossbar ambiguous.

    Raises :class:`SeamNotFound` (none passes, the best is too weak or fades out inside a sheet)
    or :class:`AmbiguousSeam` (two of similar strength, or a second line running beside the best
    at a pen line's distance); ``details`` (with the reasons of the
    rejected candidates added) go into the error. ``offset`` (x0, y0): ROI corner, for messages.
    """
    _mark_too_wide(cands, p)
    good = sorted([c for c in cands if not c.why_rejected], key=lambda c: -c.score)
    rejected = [c.why_rejected for c in cands if c.why_rejected]
    details = {**details, "rejected": rejected}
    x0, y0 = offset
    if not good:
        # The same reason once, with how many candidates gave it (the lines of a table's grid).
        said = [f"{r} (x{rejected.count(r)})" if rejected.count(r) > 1 else r
                for r in dict.fromkeys(rejected)]
        # The strongest lines looked at, to draw with why each was refused.
        shown = sorted(cands, key=lambda c: (-c.score, -c.coarse_score))[:LOOKED_AT_SHOWN]
        raise SeamNotFound(
            f"no weld seam found in the image ({len(cands)} candidate(s) looked at: "
            + ("; ".join(said) or "no thin dark valley long enough")
            + "); check that the joint is in view, in focus and lit, or give a --roi",
            **details, looked_at_px=[summary_px(c, x0, y0) for c in shown],
            looked_at_why=[c.why_rejected for c in shown])
    best = good[0]
    stems = [t.stem for t in tees or [] if t.bar is best and not t.stem.why_rejected]
    if stems:
        stem = max(stems, key=lambda c: c.score)
        if stem.score < p.ambiguity_ratio * best.score:
            # The best runs across the end of a line that passes too: a T-corner, whose stem is
            # the seam such a view is of (seam_tee), but too weak to be taken for sure.
            raise AmbiguousSeam(
                f"a line ends on the best seam candidate, as at a T-corner (score "
                f"{best.score:.0f} vs {stem.score:.0f}): the seam may be the line that ends there; "
                "refusing to choose: " + GIVE_ROI,
                best_px=summary_px(best, x0, y0), second_px=summary_px(stem, x0, y0),
                **details)
        best = stem
    tee = next((t for t in tees or [] if t.stem is best), None)
    not_rivals = [best] + ([] if tee is None else [tee.bar, *tee.along])
    rivals = sorted([c for c in good + [c for c in cands if c.why_rejected and c.rival]
                     if not any(c is k for k in not_rivals)],
                    key=lambda c: -c.score)
    second = rivals[0] if rivals else None
    # A best of score 0 (a measure of the candidate at 0: none of the detector's ways passes
    # such a candidate today) has every rival as strong as itself, not a division by zero.
    ratio = (0.0 if second is None else second.score / best.score if best.score > 0 else 1.0)
    if second is not None and ratio >= p.ambiguity_ratio:
        what = ("two seam candidates of similar strength" if ratio <= 1.0 else
                "a line stronger than the best seam candidate, rejected")
        if second.why_rejected:  # a rival refused for what it is, or where (a nominal seam)
            what += ("" if ratio > 1.0 else ", the second rejected") + f" ({second.why_rejected})"
        raise AmbiguousSeam(
            f"{what} (score {best.score:.0f} vs {second.score:.0f}, ratio {ratio:.2f}); "
            "refusing to choose: " + GIVE_ROI,
            best_px=summary_px(best, x0, y0),
            second_px=summary_px(second, x0, y0), **details)
    beside = _line_beside(best, good[1:], p)
    if beside is not None:
        other, dist = beside
        raise AmbiguousSeam(
            f"a second line runs beside the seam candidate, {dist:.0f} px from it along most of "
            f"its length (score {best.score:.0f} vs {other.score:.0f}): a pen or soapstone line "
            "drawn parallel to the joint looks like it; refusing to choose: " + GIVE_ROI,
            best_px=summary_px(best, x0, y0),
            second_px=summary_px(other, x0, y0), **details)
    conf, reasons = rate_confidence(best, ratio, p)
    if tee is not None:
        reasons.append(f"ends at a T-corner: a line crossing its end runs on past it both ways "
                       f"(score {tee.bar.score:.0f}), the seam taken is the one ending there "
                       "(for the crossing line, give its nominal seam region)")
    if "open" in best.end_kinds or "covered" in best.end_kinds:
        # A point inside a sheet is never returned as an end, at any confidence threshold.
        raise SeamNotFound("best seam candidate fades out inside a sheet at one end (a joint "
                           "ends at a sheet border or leaves the image): "
                           + "; ".join(reasons), confidence=conf, reasons=reasons, **details,
                           best_px=summary_px(best, x0, y0))
    if conf < p.min_confidence:
        raise SeamNotFound(f"best seam candidate too weak (confidence {conf:.2f}): "
                           + "; ".join(reasons), confidence=conf, reasons=reasons, **details,
                           best_px=summary_px(best, x0, y0))
    return best, ratio, conf, reasons


def _mark_too_wide(cands: list[Candidate], p: DetectParams) -> None:
    """Reject candidates whose dark band (median width, px) is wider than ``p.max_band_px``.

    Such a band is the gap and a shadow (or a mark) beside it as dark as the gap: one view
    cannot tell which part is the gap, and the band's middle lies up to half the shadow's width
    off it (README, seam vision). A rejected band stays a rival: a weaker line elsewhere is not
    returned in its place.
    """
    if p.max_band_px <= 0:
        return
    for c in cands:
        if c.why_rejected or c.width is None or not len(c.width):
            continue
        w = float(np.median(c.width))
        if w > p.max_band_px:
            c.why_rejected = (f"dark band {w:.1f} px wide where the job's gap makes at most "
                              f"{p.max_band_px:.1f} px (a shadow or a mark beside the gap, or "
                              "a wider gap than the job's seam.gap_mm says)")
            c.rival = True


#: A line beside the best candidate makes the choice ambiguous from this share of the best's
#: score on: lower than the ambiguity ratio (for lines anywhere), because the joint and a pen
#: line beside it are told apart only by how they end, which is where the detector errs.
BESIDE_SCORE = 0.4
#: Beside: this share of the line's points lies 10 px to ``pattern_offset_px`` from the best.
BESIDE_SHARE = 0.7


def _line_beside(best: Candidate, others: list[Candidate],
                 p: DetectParams) -> tuple[Candidate, float] | None:
    """An accepted candidate running beside ``best`` at a pen line's distance, and how far (px).

    Beside: at least :data:`BESIDE_SHARE` of its points lie 10 px to ``p.pattern_offset_px``
    (25 mm at the default scale: a fitter's pen line is drawn 3-20 mm beside the joint) from
    ``best``'s centreline, and its score is at least :data:`BESIDE_SCORE` of ``best``'s.
    """
    if best.points is None:
        return None
    for c in others:
        if c.points is None or c.score < BESIDE_SCORE * best.score:
            continue
        d, _ = nearest_px(c.points, best.points)
        near = (d >= 10.0) & (d <= p.pattern_offset_px)
        if float(np.mean(near)) >= BESIDE_SHARE:
            return c, float(np.median(d[near]))
    return None


#: A returned seam's confidence falls with its dark band's width, from WIDE_KNEE times the widest
#: gap the scale accepts (``max_gap_px``; 6 of the defaults' 16 px) on, by WIDE_SLOPE per
#: ``max_gap_px`` of width (3 % per px at the defaults), down to WIDE_FLOOR. Why: the wider the
#: band, the more room for a shadow, the far sheet's cut face or a ragged edge inside it, which
#: one image cannot tell from the gap (README, *Confidence and the band's width*): of the
#: extended tuning part's returned seams (1000 views, 2026-12-05), 5 % of those under 8 px were
#: wrong, 32 % of those wider (held-out part: 9 % and 29 %).
WIDE_KNEE = 0.375
WIDE_SLOPE = 0.48
WIDE_FLOOR = 0.6


def width_factor(width_px: float, p: DetectParams) -> float:
    """Confidence factor (WIDE_FLOOR..1) of a dark band ``width_px`` wide (median, px)."""
    share = width_px / max(p.max_gap_px, 1e-6)
    return float(np.clip(1.0 - WIDE_SLOPE * (share - WIDE_KNEE), WIDE_FLOOR, 1.0))


def base_confidence(c: Candidate) -> float:
    """What a candidate's confidence (0..1) starts from, before its fit, rival, width and ends.

    The share of its line measured (full at 90 %) times its relative gap depth (full at 0.4).
    """
    return float(min(1.0, c.valid_frac / 0.9) * min(1.0, c.depth / 0.4))


def rate_confidence(c: Candidate, ratio: float,
                    p: DetectParams | None = None) -> tuple[float, list[str]]:
    """Confidence 0..1 of ``c`` (``ratio``: next candidate's score over its own) and why.

    ``p``: the detector's parameters, for the band width's factor (:func:`width_factor`;
    default :class:`DetectParams`).
    """
    p = p or DetectParams()
    if c.way == "profiles":
        reasons = [f"thin dark valley {c.length_px:.0f} px long with a sheet on each side",
                   f"{100 * c.valid_frac:.0f} % of cross-profiles fit two gap edges",
                   f"relative gap depth {c.depth:.2f}, fit residual {100 * c.resid:.1f} % of "
                   "depth"]
    else:
        reasons = [f"dark valley path {c.length_px:.0f} px long through the whole image",
                   f"a valley on {100 * c.valid_frac:.0f} % of it (covered stretches bridged)",
                   f"relative gap depth {c.depth:.2f}"]
    conf = (base_confidence(c) * max(0.0, 1.0 - max(0.0, c.resid - 0.05) * 4)
            * (1.0 - 0.5 * ratio))
    if c.width is not None and len(c.width):
        w = float(np.median(c.width))
        f = width_factor(w, p)
        if f < 1.0:
            conf *= f
            reasons.append(f"dark band {w:.1f} px wide: a shadow or cut face inside it would "
                           "move the gap's middle (with the working distance and the job's gap, "
                           "detect --distance-mm Z --gap-mm LO HI, it is judged at that scale)")
    n_open = sum(k == "open" for k in c.end_kinds)
    reasons.append(f"ends at: {c.end_kinds[0]}, {c.end_kinds[1]}")
    if n_open:
        # A joint runs from border to border: an open end means part of it is not seen, or the
        # line is a mark, not a joint. Never report that with high confidence.
        conf = min(conf * 0.6, 0.45)
        reasons.append("one end fades out inside a sheet: the seam may continue unseen")
    if any(k.startswith("unsure") for k in c.end_kinds):
        # Where the seam meets the border is not clear: an end point off by more than a few px
        # would put the weld's start or stop in the wrong place.
        conf = min(conf * 0.6, 0.45)
        reasons.append("two sheet borders seen equally well at one end: the end point is unsure")
    if ratio > 0:
        reasons.append(f"next candidate {100 * ratio:.0f} % as strong")
    else:
        reasons.append("no other candidate")
    return float(np.clip(conf, 0.0, 1.0)), reasons


#: A refusal with no candidate passing reports this many of the strongest lines it looked at.
LOOKED_AT_SHOWN = 3
#: A refused candidate is reported as its centreline with a point about every this many px:
#: enough to draw it over the image (a curve's bends kept) and short in a cycle record.
SUMMARY_STEP_PX = 40.0


def summary_px(c: Candidate, x0: int, y0: int) -> list[list[float]]:
    """``c``'s centreline in image px (ROI offset ``x0, y0`` added), for a report or a picture.

    Its first and last point, and a point about every :data:`SUMMARY_STEP_PX` px of arc length
    between them.
    """
    return points_summary(c.points if c.points is not None else c.polyline, x0, y0)


def points_summary(pts: F64, x0: int, y0: int) -> list[list[float]]:
    """A centreline ``pts`` (px) as :func:`summary_px` reports it, ``x0, y0`` added."""
    s = arc_length(pts)
    n = max(2, int(np.ceil(s[-1] / SUMMARY_STEP_PX)) + 1)
    idx = np.unique(np.searchsorted(s, np.linspace(0.0, s[-1], n)).clip(0, len(pts) - 1))
    return np.round(pts[idx] + [x0, y0], 1).tolist()


def orient(pts: F64) -> F64:
    """``pts`` ordered from the end nearer the left border (the top one for a vertical seam).

    Returns ``pts`` itself when it is already in that order, else a reversed copy.
    """
    d = pts[-1] - pts[0]
    if abs(d[0]) >= abs(d[1]):
        return pts if d[0] >= 0 else pts[::-1].copy()
    return pts if d[1] >= 0 else pts[::-1].copy()


def public_end_kinds(kinds: tuple[str, str]) -> tuple[str, str]:
    """The internal end kinds ("sheet border", "image border", ...) as the contract's words.

    Only ends the detector returns are mapped: an "open" end (a line fading out inside a sheet)
    is refused before this and is an error here.
    """
    out = []
    for k in kinds:
        if k == "image border":
            out.append(IMAGE_BORDER)
        elif k.endswith("sheet border"):
            out.append(JOINT_END)
        else:
            raise ValueError(f"end kind {k!r} cannot be returned")
    return out[0], out[1]


def arc_length(pts: F64) -> F64:
    """Cumulative arc length (px) along ``pts`` (K, 2), 0 at the first point."""
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])


def spans_of(pts: F64, mask: NDArray[np.bool_]) -> list[tuple[float, float]]:
    """Arc-length ranges (px from the first point of ``pts``) of the runs where ``mask`` is set.

    Each run is widened to the neighbouring seen points (the gap was last seen there).
    """
    s = arc_length(pts)
    out: list[tuple[float, float]] = []
    for a, b in runs_of(mask):
        lo, hi = float(s[max(a - 1, 0)]), float(s[min(b, len(s) - 1)])
        if out and lo <= out[-1][1]:
            out[-1] = (out[-1][0], hi)  # two runs around one seen point: one patch
        else:
            out.append((lo, hi))
    return out


def one_reading(points_px: F64, band_px: F64 | None, p: DetectParams) -> None:
    """Raise :class:`AmbiguousSeam` where one image holds two readings and nothing says which.

    ``points_px`` (K, 2) is the centreline of a dark band's darker core taken as the gap beside a
    shadow, ``band_px`` (K, 2, point for point) the whole band's: the seam if the lighter part is
    the far sheet's cut face seen inside a wide gap (:mod:`controller.vision.seam_shadow`). One
    image cannot tell them apart (the simulator's wide scenes, 2026-12-04: of 16 split views the
    core was the gap in 10, the band in 6); two views can (:mod:`controller.stereo.band_check`),
    and so can a job that states its gap (``p.min_gap_px`` > 0: a core narrower than the
    narrowest gap was not split off). For a single-image answer (``seamguide detect``) without
    either, the split is a refusal naming both lines, not a guess.
    """
    if band_px is None or p.min_gap_px > 0:
        return
    off = float(np.median(np.linalg.norm(band_px - points_px, axis=1)))
    raise AmbiguousSeam(
        f"the dark band across the seam has a darker core on one side: either the gap beside a "
        f"shadow (the core's middle) or a wide gap with the far sheet's cut face seen inside it "
        f"(the whole band's middle, {off:.1f} px away); one image cannot tell which. Locate the "
        f"seam from two views (seamguide locate decides in 3D), or give the expected gap "
        f"(--calibration C --distance-mm Z --gap-mm LO HI)", offset_px=round(off, 2))
