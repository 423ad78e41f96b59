"""Where the joint is lost: for each refused view, the stage and the verdict on the joint's line.

Usage (from the repository root, on the render cache of ``bench.bench_detect``)::

    .venv/bin/python -m bench.detect_funnel [--part tuning|heldout] [--pairs 50] [--pen-pairs 25]
        [--tee-pairs 0] [--rough-pairs 0] [--strip-pairs 0] [--jobs 2] [--out bench/out/funnel.json]

A refusal's message names the candidates' reasons, but not which of them was the joint. Here each
view of the wide and pen sets (and of those asked for) is detected again with
``detect_seam(trace=...)``, which hands over every list of candidates a choice was made over (the
first way's, with the finer grid's, the valley paths'). A candidate *is the joint* when its points
lie within :data:`NEAR_PX` (median) of the true centreline and it covers :data:`COVER_SHARE` of it.
Each refused view is put in the first stage where the joint was a candidate, with that candidate's
verdict (its reason with the numbers taken out; or, where it passed every check, "too weak" when
even without a rival its confidence is under ``min_confidence``, else "refused for a rival"); or "no
candidate on the joint", followed, where a candidate's coarse polyline ran along the joint (a search
saw it; its refined line went beside it, or it was set aside), by that candidate's verdict
(:func:`coarse_along`). Where that candidate has ends read as open (fading out inside a sheet), how
far short of the true end each lies, along the truth, or that it lies past it (:func:`open_ends`),
binned by the true end's kind. For each view with no candidate on the joint, what the first way's
coarse search and the profiles see along the true line (:mod:`bench.detect_unseen`: not seen, seen
in pieces, seen whole; profiles fitting or not), a third table. Prints the tables (markdown; the
first counts each verdict by look family) and writes the rows (with each view's look family and gap
width) as JSON.

The default part is ``tuning``, as for ``bench.detect_gallery``: reading the held-out part's
failures one by one is how a rule gets fitted to it.
"""

from __future__ import annotations

import collections
import re
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from bench.detect_cases import load_case, view_truth
from bench.detect_probe import run_probe
from bench.detect_score import dist_to_polyline
from bench.detect_unseen import unseen_readings, unseen_table
from controller.errors import SeamguideError
from controller.geometry.camera_model import default_camera
from controller.vision.seam_centreline import TOO_WIDE
from controller.vision.seam_decision import rate_confidence
from controller.vision.seam_detect import detect_seam
from controller.vision.seam_params import Candidate, DetectParams

NEAR_PX = 4.0  # median distance (px) of a candidate's points from the true centreline
COVER_SHARE = 0.5  # share of the true centreline within 6 px of the candidate
# A coarse polyline (the search grid is 4 px) is along the joint within twice as much: median
# distance, and the share covered within COARSE_COVER_PX.
COARSE_NEAR_PX = 8.0
COARSE_COVER_PX = 10.0
STAGES = ("first way", "finer grid", "valley paths")
#: The sets read and their default pairs (wide: per difficulty). The T-corner close-ups, the rough
#: look and the ground strips are read when asked (``--tee-pairs 25``: the close-ups' T-corners,
#: the look of the held-back robot seam camera's images).
PAIRS = {"wide": 50, "pen": 25, "tee": 0, "rough": 0, "strip": 0}


def on_joint(points: NDArray[np.float64] | None, truth_px: NDArray[np.float64],
             near_px: float = NEAR_PX, cover_px: float = 6.0) -> bool:
    """Whether a candidate's points (N, 2) px lie on the true centreline (M, 2) px: within
    ``near_px`` (median, default :data:`NEAR_PX`) of it and covering :data:`COVER_SHARE` of it
    (to ``cover_px``)."""
    if points is None or len(points) < 2 or len(truth_px) < 2:
        return False
    # The scorer's distance (bench.detect_score), so that "on the joint" means what it does there.
    d_to_truth = dist_to_polyline(points, truth_px)
    d_to_cand = dist_to_polyline(truth_px, points)
    return bool(np.median(d_to_truth) < near_px and np.mean(d_to_cand < cover_px) >= COVER_SHARE)


def _reason(text: str) -> str:
    """A rejection reason with its numbers taken out, cut at its first parenthesis; a band
    wider than the scale's widest gap (``seam_centreline.TOO_WIDE``) said after it."""
    short = re.sub(r"-?\d+(\.\d+)?", "#", text.split(" (")[0]).strip()
    return short + (f": a band {TOO_WIDE}" if TOO_WIDE in text else "")


def where_lost(stages: list[list[Candidate]], truth_px: NDArray[np.float64]) -> tuple[str, str]:
    """(stage, verdict) of the first stage whose candidates include the joint's line.

    ``stages``: the candidate lists of ``detect_seam(trace=...)`` in order (:data:`STAGES`),
    full-image px (the detection was run without a region of interest). The second holds the
    first's candidates again with the finer grid's added.
    """
    return _lost_at(joint_candidate(stages, truth_px), stages, truth_px)


def _lost_at(found: tuple[str, Candidate] | None, stages: list[list[Candidate]],
             truth_px: NDArray[np.float64]) -> tuple[str, str]:
    """(stage, verdict) from :func:`joint_candidate`'s answer; where none is the joint, whether
    the coarse search had a line along it (:func:`coarse_along`) and that line's verdict."""
    if found is None:
        along = coarse_along(stages, truth_px)
        if along is None:
            return "none", "no candidate on the joint"
        return "none", f"no candidate on the joint; a coarse line along it: {_verdict(along)}"
    return found[0], _verdict(found[1])


def coarse_along(stages: list[list[Candidate]], truth_px: NDArray[np.float64]
                 ) -> Candidate | None:
    """The strongest candidate whose coarse polyline runs along the joint (:data:`COARSE_NEAR_PX`
    median, :data:`COVER_SHARE` of it within :data:`COARSE_COVER_PX`) when none is the joint:
    a search (the coarse grid, the finer grid, the valley paths) saw the joint there, and what
    it became (a line refined beside it, a piece, a table line) is that candidate's verdict.
    None: no search handed on a line along it (the coarse grid hands on
    ``DetectParams.max_candidates``)."""
    along = [c for cands in stages for c in cands
             if on_joint(c.polyline, truth_px, COARSE_NEAR_PX, COARSE_COVER_PX)]
    return max(along, key=lambda k: k.coarse_score) if along else None


def joint_candidate(stages: list[list[Candidate]], truth_px: NDArray[np.float64]
                    ) -> tuple[str, Candidate] | None:
    """The first stage (:data:`STAGES`) whose candidates include the joint's line, and the
    strongest such candidate; None when no stage has one."""
    for name, cands in zip(STAGES, stages, strict=False):
        joint = [c for c in cands
                 if on_joint(c.points if c.points is not None else c.polyline, truth_px)]
        if joint:
            return name, max(joint, key=lambda k: k.score)
    return None


#: Bins (px, upper bounds) of how far an open end lies short of the true end, along the truth.
SHORT_BINS = (8.0, 20.0, 50.0, 150.0)


def open_ends(c: Candidate, truth_px: NDArray[np.float64], truth_kinds: list[str]
              ) -> list[dict[str, Any]]:
    """Each end of the joint's candidate ``c`` read as open (fading out inside a sheet): how far
    short of the true end nearer it it lies (px along the true centreline, from the end's
    nearest point on it; negative: past the true end, along the truth's course there) and that
    end's kind (``joint_end`` or ``image_border``). A candidate refused before its ends were read
    (no points: no long run of gap profiles, a table's line) has none: its ``end_kinds`` are the
    unread default."""
    if c.points is None:
        return []
    pts = c.points
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(truth_px, axis=0), axis=1))])
    out = []
    for k, e in ((0, pts[0]), (1, pts[-1])):
        if c.end_kinds[k] != "open":
            continue
        j = int(np.argmin(np.linalg.norm(truth_px - e, axis=1)))
        te = 0 if s[j] <= s[-1] / 2 else 1
        short = s[j] if te == 0 else s[-1] - s[j]
        if short == 0.0:
            # Nearest the true end itself: past it (negative) by as far as it lies out along the
            # truth's course there, or at it.
            end, inner = (truth_px[0], truth_px[1]) if te == 0 else (truth_px[-1], truth_px[-2])
            out_dir = (end - inner) / max(float(np.linalg.norm(end - inner)), 1e-12)
            past = float((e - end) @ out_dir)
            short = -past if past > 0.0 else 0.0
        out.append({"short_px": round(float(short), 1), "truth_kind": truth_kinds[te]})
    return out


def _verdict(c: Candidate) -> str:
    """Why the joint's candidate ``c`` was not returned: its rejection, or at the decision."""
    if c.why_rejected:
        return _reason(c.why_rejected)
    conf, _ = rate_confidence(c, 0.0)  # as strong as it can be: no rival
    if conf < DetectParams().min_confidence:
        unsure = any(k.startswith("unsure") for k in c.end_kinds)
        return "passed, too weak" + (" (an end read as unsure)" if unsure else "")
    return "passed, refused for a rival"


def run_case(case: tuple[str, str, str, int]) -> list[dict[str, Any]]:
    """Each view of a cached case: detected with a trace, and where its joint was lost."""
    cam = default_camera()
    imgs, z = load_case(case)
    rows = []
    for i, img in enumerate(imgs):
        truth = view_truth(z, i)
        stages: list[list[Candidate]] = []
        try:
            detect_seam(img, camera=cam, trace=stages)
        except SeamguideError:
            tp = np.asarray(truth["seam_px"], np.float64)
            found = joint_candidate(stages, tp)  # where_lost's search, once for both uses
            stage, verdict = _lost_at(found, stages, tp)
            ends = [] if found is None else open_ends(found[1], tp, truth["end_kinds"])
            # No candidate on the joint: what the coarse search and the profiles see along it.
            unseen = None if found is not None else unseen_readings(
                img if img.ndim == 2 else cv2.cvtColor(img, cv2.COLOR_BGR2GRAY), tp)
        else:
            stage, verdict, ends, unseen = "returned", "", [], None
        rows.append({"case": list(case), "view": i, "stage": stage, "verdict": verdict,
                     "family": truth["family"], "open_ends": ends, "unseen": unseen,
                     "gap_px": float(truth["gap_px"])})
    return rows


def table(rows: list[dict[str, Any]]) -> str:
    """Markdown: refused views per (stage, verdict), most first, by look family (the rows'
    ``family``), with up to 3 examples."""
    refused = [r for r in rows if r["stage"] != "returned"]
    count = collections.Counter((r["stage"], r["verdict"]) for r in refused)
    looks = sorted({r.get("family", "?") for r in refused})
    out = [f"{len(refused)} of {len(rows)} views refused; where the joint was lost:", "",
           "| stage | verdict on the joint's line | views | " + " | ".join(looks) + " | e.g. |",
           "|---" * (4 + len(looks)) + "|"]
    for (stage, verdict), n in count.most_common():
        these = [r for r in refused if (r["stage"], r["verdict"]) == (stage, verdict)]
        by_look = collections.Counter(r.get("family", "?") for r in these)
        ex = [f"{r['case'][1]} {r['case'][3]} v{r['view']}" for r in these][:3]
        out.append(f"| {stage} | {verdict} | {n} | "
                   + " | ".join(str(by_look[k]) for k in looks) + f" | {', '.join(ex)} |")
    ends = [e for r in refused for e in r.get("open_ends", [])]
    if ends:
        heads = ["past it", f"<= {SHORT_BINS[0]:.0f} px"] + [
            f"{a:.0f}-{b:.0f} px" for a, b in zip(SHORT_BINS, SHORT_BINS[1:], strict=False)] + [
            f"> {SHORT_BINS[-1]:.0f} px"]
        out += ["", "Ends of the joint's line read as open (fading out inside a sheet), by how far "
                "short of the true end they lie (along it), or past it:", "",
                "| true end | " + " | ".join(heads) + " |", "|---" * (len(heads) + 1) + "|"]
        for kind in sorted({e["truth_kind"] for e in ends}):
            short = [e["short_px"] for e in ends if e["truth_kind"] == kind]
            # (Column 0: past the true end; the bins of how far short follow.)
            per_bin = np.bincount([0 if v < 0 else 1 + int(np.searchsorted(SHORT_BINS, v))
                             for v in short], minlength=len(heads))
            out.append(f"| {kind} | " + " | ".join(str(int(x)) for x in per_bin) + " |")
    return "\n".join(out)


def report(rows: list[dict[str, Any]]) -> str:
    """Both tables: where the joint was lost, and what is seen along it where no candidate was."""
    return table(rows) + "\n\n" + unseen_table(rows)


def main(argv: list[str] | None = None) -> int:
    """Detect the cached views of one part, print the table, write the rows; 0, or 1 if none."""
    return run_probe(argv, __doc__.splitlines()[0], PAIRS, "bench/out/funnel.json",
                     "detect_funnel", run_case, report, chunksize=1)


if __name__ == "__main__":
    raise SystemExit(main())
