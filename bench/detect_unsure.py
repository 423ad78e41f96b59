"""Would the seams held back for an unsure end have been right? Candidates capped, scored.

Usage (from the repository root, on the render cache of ``bench.bench_detect``)::

    .venv/bin/python -m bench.detect_unsure [--part tuning|heldout] [--pairs 150]
        [--pen-pairs 50] [--tee-pairs 25] [--rough-pairs 60] [--strip-pairs 20] [--jobs 2]
        [--out bench/out/unsure.json]

A candidate whose end was read as an ``"unsure sheet border"`` (two borders seen equally well
there) is capped at confidence 0.45 (:func:`controller.vision.seam_decision.rate_confidence`),
under ``min_confidence``: it is never returned. Here each view of the sets named is detected
again with ``detect_seam(trace=...)``; every candidate that passed all its checks
(``why_rejected`` empty) with such an end is scored as if it had been returned
(:func:`bench.detect_score.score_view`, an unsure border as a ``joint_end``), once however many
stages listed it. Prints the counts by result and why (a markdown table) and the confidence
each would have had without the cap; writes the rows as JSON. The cap is worth keeping while
most such candidates would be wrong.

The default part is ``tuning``: reading the held-out part's candidates one by one is how a rule
gets fitted to it.
"""

from __future__ import annotations

import collections
import contextlib
from typing import Any

import numpy as np
from numpy.typing import NDArray

from bench.detect_cases import load_case, view_truth
from bench.detect_probe import distinct_lines, run_probe
from bench.detect_score import score_view
from controller.errors import SeamguideError
from controller.geometry.camera_model import default_camera
from controller.vision.seam_decision import base_confidence
from controller.vision.seam_detect import detect_seam
from controller.vision.seam_params import Candidate

#: The sets read and their default pairs (wide: per difficulty).
PAIRS = {"wide": 150, "pen": 50, "tee": 25, "rough": 60, "strip": 20}
#: A detector end kind as ``seamguide detect`` reports it (an unsure border is a joint end).
REPORTED = {"sheet border": "joint_end", "unsure sheet border": "joint_end",
            "image border": "image_border"}


def unsure_rows(stages: list[list[Candidate]], truth: dict[str, Any]) -> list[dict[str, Any]]:
    """One row per distinct candidate of ``stages`` that passed its checks with an unsure end:
    its score against ``truth`` (a view's truth with ``image_size``; result, why, end error in px
    of the distorted image) and its confidence without the cap (0..1)."""
    rows = []
    for c in distinct_lines(c for cands in stages for c in cands
                            if c.points is not None and not c.why_rejected
                            and any(k.startswith("unsure") for k in c.end_kinds)):
        sc = score_view(c.points, truth, [REPORTED.get(k, k) for k in c.end_kinds])
        rows.append({"result": sc["result"], "why": sc.get("why", ""),
                     "end_px": round(float(sc.get("end", np.nan)), 1),
                     "conf_uncapped": round(base_confidence(c), 2)})
    return rows


def run_case(case: tuple[str, str, str, int]) -> list[dict[str, Any]]:
    """:func:`unsure_rows` of each view of a cached case, with the case and view."""
    imgs, z = load_case(case)
    out = []
    for i, img in enumerate(imgs):
        truth = view_truth(z, i, img)
        stages: list[list[Candidate]] = []
        with contextlib.suppress(SeamguideError):  # a refusal still hands over its candidates
            detect_seam(img, camera=default_camera(), trace=stages)
        out += [{"case": list(case), "view": i, **r} for r in unsure_rows(stages, truth)]
    return out


def table(rows: list[dict[str, Any]]) -> str:
    """Markdown: the candidates by result and why, and their uncapped confidence's range."""
    count = collections.Counter((r["result"], r["why"]) for r in rows)
    out = [f"{len(rows)} candidates held back for an unsure end; scored as if returned:", "",
           "| result | why | candidates | uncapped confidence |", "|---|---|---|---|"]
    for (res, why), n in sorted(count.items(), key=lambda kv: -kv[1]):
        conf: NDArray[np.float64] = np.array([r["conf_uncapped"] for r in rows
                                              if (r["result"], r["why"]) == (res, why)])
        out.append(f"| {res} | {why or '-'} | {n} | {conf.min():.2f}-{conf.max():.2f} |")
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    """Detect the cached views, print the table, write the rows; 0, or 1 if none is cached."""
    return run_probe(argv, __doc__.splitlines()[0], PAIRS, "bench/out/unsure.json",
                     "detect_unsure", run_case, table)


if __name__ == "__main__":
    raise SystemExit(main())
