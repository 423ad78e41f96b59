"""Tuning of the seam detector and the record of one seam candidate as it goes through the steps.

:class:`DetectParams` is public (re-exported by :mod:`controller.vision.seam_detect`);
:class:`Candidate`
is filled in by the coarse search (:mod:`controller.vision.seam_coarse`), the centreline
(:mod:`controller.vision.seam_centreline`) and read by the decision
(:mod:`controller.vision.seam_decision`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]


def runs_of(mask: NDArray[np.bool_]) -> list[tuple[int, int]]:
    """The runs of set samples of a 1-D ``mask``: ``[(start, end), ...]``, ``end`` exclusive.

    The runs of ``~mask`` are its holes (including those touching either end).
    """
    m = np.concatenate([[0], np.asarray(mask).astype(np.int8), [0]])
    d = np.diff(m)
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist(),
                    strict=True))


@dataclass(frozen=True)
class DetectParams:
    """Tuning of :func:`detect_seam` (pixel values at full resolution unless named ``coarse``).

    The pixel scales are for a 2272x1704 camera at 350-450 mm (6-8 px/mm);
    :func:`controller.vision.seam_scale.params_for_scale` sets them for another working distance.

    ``gamma``: camera response used to linearise grey levels (1.0 for a linear camera).
    ``coarse_factor``: shrink factor of the search image (0: automatic, ~560 px wide).
    ``valley_r_coarse``: distance (coarse px) from the valley centre to where both sides are read;
    ``valley_r_px``: with an automatic ``coarse_factor``, the search image is shrunk enough that
    this reaches at least ``valley_r_px`` full-resolution px, beyond a wide gap's edges (0: no
    minimum; set from the working distance by
    :func:`controller.vision.seam_scale.params_for_scale`).
    ``min_depth``: relative valley depth that marks a candidate pixel (0..1).
    ``min_length_px``: shortest candidate kept (px along the curve); ``piece_length_px``: shortest
    piece of valley kept to be joined with others that continue it across at most
    ``piece_join_px`` (a faint gap breaks up where it dips under ``min_depth``).
    ``step_px``: spacing of the refinement profiles along the seam; ``half_width_px``: half
    length of each profile. ``max_gap_px``: widest gap accepted. ``ambiguity_ratio``: a second
    candidate at least this strong relative to the best makes the result ambiguous.
    ``min_confidence``: below this the detection is refused (:class:`SeamNotFound`); an open end
    caps the confidence at 0.45, so a seam not seen to a border is refused by default.
    ``smaller``: when the search finds no seam, search the image shrunk by 2 and keep a seam
    found there only where the gap is soft at full size and the same seam is found shrunk by 3
    (:mod:`controller.vision.seam_smaller`: a close-up's wide, defocused gap).
    ``grain``: refuse a seam the sheets' grain runs on across, over one edge of its dark band (a
    shadow beside the gap) or over the whole line (one surface on both sides: a pen line, a
    slot; :mod:`controller.vision.seam_grain`); off on the image shrunk, whose pixels average
    the grain away.
    ``carry``: carry the returned seam's image-border ends on to the image edge
    (:func:`controller.vision.seam_edge_ends.carry_to_edge`); off on the image shrunk, whose
    seam is compared as read with the lines the full-size search saw
    (:func:`controller.vision.seam_smaller.one_of`).
    ``robust``: when no candidate of the profile model passes, look for the seam as a whole-image
    valley path (:mod:`controller.vision.seam_robust`: ragged, wide, covered or dark gaps).
    ``straight_px``: a line whose points lie within this RMS distance of their principal axis is
    straight; ``pattern_offset_px``: how far apart two parallel lines of a table's grid are at
    least (:mod:`controller.vision.seam_pattern`; 25 mm at 8 px/mm, farther than a pen line
    beside a joint).
    ``max_band_px``: widest dark band (median over the seam, px) taken for the gap (0: no limit).
    Set only where the job states its gap (:func:`controller.vision.seam_scale.params_for_scale`
    with ``limit_band``): a band wider than that gap can be is the gap and a shadow or a mark
    beside it, whose middle is off the gap's, and is refused, not returned. ``min_gap_px``:
    the job's narrowest gap (px, 0: not stated); a darker core narrower than that inside the
    band is the floor beside a cut face, not the gap beside a shadow
    (:mod:`controller.vision.seam_shadow`).
    ``hint_tol_px``: with a nominal seam (``detect_seam(hint=...)``: the job's nominal line seen
    in the view, or ``seamguide detect --hint``), a candidate whose mean distance from it is
    this or more (px of the image) is never returned (it still counts as a rival): how far the
    real seam may lie from the nominal one (the fixture's and the part's tolerance at the view's
    scale; the job's ``seam.line_tolerance_mm``).
    """

    gamma: float = 2.2
    coarse_factor: int = 0
    valley_r_coarse: int = 3
    valley_r_px: float = 0.0
    min_depth: float = 0.2
    min_length_px: float = 300.0
    step_px: float = 4.0
    half_width_px: float = 14.0
    profile_step_px: float = 1.0
    fit_iterations: int = 7
    max_gap_px: float = 16.0
    min_profile_depth: float = 0.25
    bridge_px: float = 200.0
    join_px: float = 200.0
    piece_length_px: float = 100.0
    piece_join_px: float = 48.0
    ambiguity_ratio: float = 0.6
    min_confidence: float = 0.5
    max_candidates: int = 4
    robust: bool = True
    smaller: bool = True
    grain: bool = True
    carry: bool = True
    straight_px: float = 2.5
    pattern_offset_px: float = 200.0
    max_band_px: float = 0.0
    min_gap_px: float = 0.0
    hint_tol_px: float = 60.0


#: Refusals a later rule reads again (``Candidate.refused``); ``why_rejected`` says them to people.
#: An end fades out inside a sheet.
OPEN_END = "open end"
#: An end stops at a covered patch (a tack weld, spatter) with the gap going on beyond it.
COVERED_END = "covered end"
#: A valley path turns across an unseen stretch: it joins two different lines.
JOINED_LINES = "joined lines"


@dataclass
class Candidate:
    """One seam candidate: the coarse polyline, then the refined centreline and its scores."""

    polyline: F64  # ordered coarse centreline, full-res px
    coarse_score: float
    length_px: float
    points: F64 | None = None
    width: F64 | None = None
    depth: float = 0.0
    valid_frac: float = 0.0
    resid: float = 0.0
    score: float = 0.0
    end_kinds: tuple[str, str] = ("open", "open")
    bridged: NDArray[np.bool_] | None = None  # per point of ``points``: interpolated, not seen
    # Where a shadow band was split off (seam_shadow): the whole dark band's centreline (per
    # point of ``points``) and median width (px), the reading if the lighter part is a cut face.
    band_points: F64 | None = None
    band_width: float | None = None
    stats: dict[str, float] = field(default_factory=dict)
    rival: bool = False  # rejected, but its line may be the joint: still makes others ambiguous
    way: str = "profiles"  # or "valley path" (controller.vision.seam_robust)
    why_rejected: str = ""
    refused: str = ""  # OPEN_END, COVERED_END, JOINED_LINES; "" for any other refusal


@dataclass
class Tee:
    """A T-corner among the candidates (:mod:`controller.vision.seam_tee`).

    ``stem`` ends (its end ``end``, 0 or 1) on ``bar``, which runs on past it both ways;
    ``along``: the other candidates lying along the T (a path that turned at it), no lines of
    their own.
    """

    stem: Candidate
    end: int
    bar: Candidate
    along: list[Candidate] = field(default_factory=list)
