"""Would the other view confirm a line one view held back? A pair-level rescue, measured.

Usage (from the repository root, on the render cache of ``bench.bench_detect``)::

    .venv/bin/python -m bench.detect_rescue [--part tuning|heldout] [--pairs 150]
        [--pen-pairs 50] [--jobs 2] [--out bench/out/rescue.json]

The cycle welds a pair only when every view returns the seam on its own. Where one view (A)
returns a seam and the other (B) is refused with :class:`SeamNotFound` (no rival, no ambiguity:
only lines too weak or ending wrongly), B's held-back lines are tried with A's seam in 3D
(``controller.stereo.locate.locate_seam``, as the cycle with ``clip_unseen_ends``; an end of B's
line that fades out inside a sheet counts as one B does not see). A line of B is tried when it
passed its checks or was refused only for fading out inside a sheet, reaches a border at one end
at least (a line fading out at both is a mark), and would be confident without its ends' caps
(``rate_confidence`` with its ends read as borders, no rival: at least ``min_confidence``): the
view saw the line clearly, only how it ends is in doubt. The pair is *rescued* when exactly one
such line locates with A's seam within the quality limits; it is then scored against the truth
as ``bench.bench_detect`` scores pairs (located, partial, wrong).

Prints the rescued pairs by their result and by what A's own seam was (found or wrong); writes
the rows as JSON. Not in the cycle (README, *Measured and not kept, twenty-fourth session*): on
2026-12-07 it located 20 more pairs of the tuning part's 500 and 11 of the held-out part's 325,
and made 2 and 3 wrong 3D seams, every one where A's own seam was wrong (an end read past a
rounded corner in both views, a shadow band in both, two different lines: 33 mm off). Two views
detected independently are the check; a rescued pair is only as right as one view.

The cycle has had a stricter form of it since the twenty-seventh session
(``controller.cell.other_view``, measured by ``bench.bench_detect``'s pairs): every end the
returning view reads as the joint's end must be where the 3D seam ends (within 0.5 mm of its
ray), B's lines are those measured by gap profiles (no valley paths), an ambiguous B is tried
too, and a seam is not cut where B's line fades out inside its image. This probe stays as the
measurement of the looser rule the README reports.
"""

from __future__ import annotations

import collections
import contextlib
import dataclasses
from typing import Any

import numpy as np

from bench.bench_detect import _detect, _locate
from bench.detect_cases import load_case, view_truth
from bench.detect_funnel import on_joint
from bench.detect_probe import distinct_lines, run_probe
from bench.detect_score import score_view
from controller.errors import SeamguideError, SeamNotFound
from controller.geometry.camera_model import default_camera
from controller.vision.seam_decision import rate_confidence
from controller.vision.seam_detect import detect_seam
from controller.vision.seam_params import OPEN_END, Candidate, DetectParams

#: The sets read and their default pairs (wide: per difficulty).
PAIRS = {"wide": 150, "pen": 50}
#: A detector end kind as locating takes it: an end fading out inside a sheet is not seen.
AS_SEEN = {"sheet border": "joint_end", "unsure sheet border": "joint_end",
           "image border": "image_border", "open": "image_border"}


def held_back(stages: list[list[Candidate]], p: DetectParams) -> list[Candidate]:
    """The distinct lines of a refused view's ``stages`` worth trying with another view.

    Passed its checks or refused only for an open end; not open at both ends; no covered end;
    at least ``p.min_confidence`` with its ends read as borders and no rival.
    """
    lines = distinct_lines(
        c for cands in stages for c in cands
        if c.points is not None and (not c.why_rejected or c.refused == OPEN_END)
        and not all(k == "open" for k in c.end_kinds) and all(k in AS_SEEN for k in c.end_kinds))
    return [c for c in lines if rate_confidence(
        dataclasses.replace(c, end_kinds=("sheet border", "sheet border")), 0.0, p)[0]
        >= p.min_confidence]


def run_case(case: tuple[str, str, str, int]) -> list[dict[str, Any]]:
    """The pair of a cached case, if one view returned and the other was refused: the rescue."""
    cam = default_camera()
    imgs, z = load_case(case)
    if len(imgs) != 2:
        return []
    got = [_detect("ours", img, cam) for img in imgs]
    returned = [r["result"] == "returned" for r in got]
    if sum(returned) != 1:
        return []
    a = returned.index(True)
    b = 1 - a
    if not got[b]["error"].startswith(SeamNotFound.__name__):
        return []  # an ambiguous view said there are two lines: not for the other to choose
    truth_a = view_truth(z, a, imgs[a])
    ra = got[a]
    a_result = score_view(ra["points"], truth_a, ra["kinds"])["result"]
    stages: list[list[Candidate]] = []
    with contextlib.suppress(SeamguideError):
        detect_seam(imgs[b], camera=cam, trace=stages)
    truth_b = np.asarray(view_truth(z, b)["seam_px"], np.float64)
    tried = []
    for c in held_back(stages, DetectParams()):
        assert c.points is not None and c.width is not None
        curves: list[Any] = [None, None]
        widths: list[Any] = [None, None]
        kinds: list[Any] = [None, None]
        bands: list[Any] = [None, None]
        curves[a], widths[a], kinds[a], bands[a] = (ra["points"], ra["width_px"],
                                                    tuple(ra["kinds"]), ra["band"])
        curves[b], widths[b] = c.points, float(np.median(c.width))
        kinds[b] = tuple(AS_SEEN[k] for k in c.end_kinds)
        res = _locate(z, curves, widths, kinds, cam, clip=True, bands=bands)
        if res["result"] != "refused":
            tried.append((c, res))
    row: dict[str, Any] = {"case": list(case), "a": a, "a_result": a_result,
                           "b_error": got[b]["error"][:160], "lines": len(tried)}
    if len(tried) == 1:
        c, res = tried[0]
        row.update(result=res["result"], b_on_joint=bool(on_joint(c.points, truth_b)),
                   b_ends=list(c.end_kinds), max_mm=round(float(res["max_mm"]), 2))
    else:
        row["result"] = "none" if not tried else "several"
    return [row]


def table(rows: list[dict[str, Any]]) -> str:
    """Markdown: the pairs with one view refused, by A's own result and the rescue's."""
    count = collections.Counter((r["a_result"], r["result"]) for r in rows)
    out = [f"{len(rows)} pairs with one view returned and the other refused (no ambiguity):", "",
           "| A's own seam | rescue: located | partial | wrong | several lines | none |",
           "|---|---|---|---|---|---|"]
    for a in sorted({k[0] for k in count}):
        out.append(f"| {a} | " + " | ".join(str(count[(a, r)]) for r in
                                            ("located", "partial", "wrong", "several", "none"))
                   + " |")
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    """Detect the cached pairs, print the table, write the rows; 0, or 1 if none is cached."""
    return run_probe(argv, __doc__.splitlines()[0], PAIRS, "bench/out/rescue.json",
                     "detect_rescue", run_case, table)


if __name__ == "__main__":
    raise SystemExit(main())
