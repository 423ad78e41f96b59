"""Every candidate the detector looked at in one cached view, and how each open end was read.

Usage (from the repository root, on the render cache of ``bench.bench_detect``)::

    .venv/bin/python -m bench.detect_trace SET DIFFICULTY SEED VIEW [--part tuning|heldout]
        [--ends] [--scales]

e.g. ``.venv/bin/python -m bench.detect_trace wide easy 10029 1 --ends``. Prints the truth (the
joint's ends and their kinds, the gap's width, the look family, covered spans), the detector's
verdict, then each list of candidates it chose from (``detect_seam(trace=...)``: the first
way's, with the finer grid's, the valley paths'), one line per candidate: ``J`` where it is the
joint (:func:`bench.detect_funnel.on_joint`), its way, length, score, depth, share of good
profiles, end kinds, median distance from the true centreline, end points, whether it is a
rival and why it was refused. With ``--ends``, each end of the joint's candidate read as
``open`` is read again as :mod:`controller.vision.seam_ends` reads it: the steps found on the
five lines along the seam (two each side of the gap and its centreline, px along from the end),
the border line they give (where it meets the centreline, which sides step), the end read
(:func:`controller.vision.seam_ends.end_offset`) and whether a wedge of table is read there.
With ``--scales``, the seam the search reads on the image shrunk by each factor the look at
the image shrunk uses (:func:`shrunk_readings`; that look is not traced otherwise).

What :mod:`bench.detect_funnel` counts over a part, this shows for one view. The default part is
``tuning``: reading the held-out part's failures one by one is how a rule gets fitted to it.
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from bench.detect_cases import case_cached, load_case, view_truth
from bench.detect_funnel import STAGES, joint_candidate, on_joint
from bench.detect_score import dist_to_polyline, score_view
from controller.errors import SeamguideError
from controller.geometry.camera_model import default_camera
from controller.vision import seam_detect, seam_smaller
from controller.vision.seam_border import border_line
from controller.vision.seam_detect import detect_seam
from controller.vision.seam_ends import end_lines, end_offset
from controller.vision.seam_params import F64, Candidate, DetectParams
from controller.vision.seam_profiles import linear_lut
from controller.vision.seam_wedge import wedge_end


def candidate_line(c: Candidate, truth_px: F64) -> str:
    """One line about candidate ``c`` against the true centreline (px)."""
    P = c.points if c.points is not None else c.polyline
    md = float(np.median(dist_to_polyline(P, truth_px))) if len(P) > 1 else float("nan")
    mark = "J" if on_joint(P, truth_px) else " "  # as joint_candidate says it
    return (f"{mark} {c.way:<11.11} {c.length_px:5.0f} px  score {c.score:7.1f}  depth "
            f"{c.depth:.2f}  good {c.valid_frac:.2f}  ends {c.end_kinds[0]} / {c.end_kinds[1]}  "
            f"{md:4.0f} px off  {np.round(P[0]).astype(int).tolist()} -> "
            f"{np.round(P[-1]).astype(int).tolist()}{'  rival' if c.rival else ''}"
            f"{'  | ' + c.why_rejected if c.why_rejected else ''}")


def ends_to_read(c: Candidate) -> list[int]:
    """The ends (0, 1) of ``c`` read as open, to read again; none when ``c`` was refused
    before its ends were read (no points: its end kinds are the unread default, as
    :func:`bench.detect_funnel.open_ends` skips them)."""
    if c.points is None:
        return []
    return [end for end in (0, 1) if c.end_kinds[end] == "open"]


def end_reading(grey: NDArray[np.uint8], c: Candidate, end: int, p: DetectParams
                ) -> dict[str, Any]:
    """The open end ``end`` (0 or 1) of ``c`` read again (:func:`seam_ends.end_offset`).

    ``steps``: per line beside the gap (offsets across, px) the lasting steps' positions along
    the seam (px from the end, outward > 0); ``border``: where the border line they give meets
    the centreline (px along, or None) and which sides step; ``end``: (px along, kind) as read
    at the end point; ``wedge``: px along where a wedge of table is read, or None.
    """
    P = c.points if c.points is not None else c.polyline
    Q = P if end == 1 else P[::-1]
    e_pt = Q[-1]
    tang = Q[-1] - Q[max(0, len(Q) - 6)]
    tang = tang / (np.linalg.norm(tang) + 1e-12)
    w = float(np.median(c.width)) if c.width is not None and len(c.width) else 3.0
    lut = linear_lut(p.gamma)
    offs, marked = end_lines(grey, lut, e_pt, tang, w)
    steps = [[k for k, lasting in m if lasting] for m in marked]
    line = border_line(offs, steps, w)
    k, kind, _ = end_offset(grey, lut, e_pt, tang, w)
    return {"at_px": e_pt.round(1).tolist(), "width_px": round(w, 1),
            "steps": {round(o, 1): [round(s, 1) for s in st]
                      for o, st in zip(offs, steps, strict=True)},
            "border": (None if line.k is None else round(line.k, 1), line.sides, line.unsure),
            "end": (round(k, 1), kind), "wedge": wedge_end(grey, lut, e_pt, tang, w)}


def shrunk_readings(grey: NDArray[np.uint8], truth: dict[str, Any],
                    p: DetectParams | None = None) -> list[str]:
    """One line per shrink factor the look at the image shrunk reads the seam at
    (:mod:`controller.vision.seam_smaller`: ``SCALE``, ``CONFIRM``, ``ALT_CONFIRM``): the
    seam the detector's search finds on ``grey`` shrunk by it, scored against ``truth``
    (:func:`bench.detect_score.score_view`), or that it finds none. What the look then keeps
    (the full-size blur, the confirmation) is :func:`seam_smaller.smaller_look`'s."""
    p = p or DetectParams()
    lines = []
    for f in (seam_smaller.SCALE, seam_smaller.CONFIRM, *seam_smaller.ALT_CONFIRM):
        det = seam_smaller._found_at(grey, float(f), None, p, seam_detect.search, None)
        if det is None:
            lines.append(f"shrunk by {f:g}: no seam found")
            continue
        sc = score_view(det.points_px, truth, list(det.end_kinds))
        why = f" ({sc['why']})" if "why" in sc else ""
        lines.append(f"shrunk by {f:g}: {sc['result']}{why}, ends {det.end_kinds[0]} / "
                     f"{det.end_kinds[1]}, confidence {det.confidence:.2f}, "
                     f"{sc.get('rms', float('nan')):.1f} px RMS")
    return lines


def main(argv: list[str] | None = None) -> int:
    """Print the trace of one cached view; 0, or 1 when the view is not in the cache."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("set", choices=("classic", "wide", "pen", "tee", "rough", "strip"))
    ap.add_argument("difficulty", choices=("easy", "medium", "hard"))
    ap.add_argument("seed", type=int)
    ap.add_argument("view", type=int, choices=(0, 1))
    ap.add_argument("--part", choices=("tuning", "heldout"), default="tuning")
    ap.add_argument("--ends", action="store_true", help="read the joint's open ends again")
    ap.add_argument("--scales", action="store_true",
                    help="the seam read on the image shrunk by each factor of the look at the "
                    "image shrunk (not traced otherwise)")
    a = ap.parse_args(argv)
    case = (a.set, a.difficulty, a.part, a.seed)
    if not case_cached(case):
        print(f"detect_trace: {a.set} {a.difficulty} {a.part} {a.seed} is not in the render "
              "cache: run `.venv/bin/python -m bench.bench_detect --render-only` with the sets "
              "and sizes that include it (the seeds of a part are in bench.detect_cases)",
              file=sys.stderr)
        return 1
    if a.part == "heldout":
        print("(the held-out part: to measure with, not to tune on)")
    imgs, z = load_case(case)
    img = imgs[a.view]
    truth = view_truth(z, a.view, img)
    tp = np.asarray(truth["seam_px"], np.float64)
    print(f"truth: {np.round(tp[0]).astype(int).tolist()} ({truth['end_kinds'][0]}) -> "
          f"{np.round(tp[-1]).astype(int).tolist()} ({truth['end_kinds'][1]}), gap "
          f"{truth['gap_px']:.1f} px, look {truth['family']}, {len(truth['pens'])} pen line(s), "
          f"covered spans {np.round(truth['spans']).astype(int).tolist()}")
    stages: list[list[Candidate]] = []
    try:
        det = detect_seam(img, camera=default_camera(), trace=stages)
        print(f"returned at confidence {det.confidence:.2f}, ends {det.end_kinds[0]} / "
              f"{det.end_kinds[1]}")
    except SeamguideError as err:
        print(f"refused: {err}")
    for name, cands in zip(STAGES, stages, strict=False):
        print(f"== {name}: {len(cands)} candidate(s)")
        for c in cands:
            print("  " + candidate_line(c, tp))
    found = joint_candidate(stages, tp)
    grey = img if img.ndim == 2 else cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    if a.ends and found is not None:
        if found[1].points is None:
            print(f"the joint's candidate ({found[0]}) was refused before its ends were read")
        for end in ends_to_read(found[1]):
            print(f"open end {end} of the joint's candidate ({found[0]}): "
                  f"{end_reading(grey, found[1], end, DetectParams())}")
    if a.scales:
        for line in shrunk_readings(grey, truth):
            print(line)
    return 0


if __name__ == "__main__":
    sys.exit(main())
