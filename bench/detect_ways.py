"""One case's views detected one way, scored, and the pair located: what the benchmarks that
compare ways of detecting (``bench.bench_detect_job_gap``, ``bench.bench_detect_nominal``) share.

A *way* gives each view its detector parameters and nominal seam (``setting(i, truth)`` ->
``(DetectParams or None, hint px or None)``). Views are scored by ``bench.detect_score`` and
counted as ``seamguide detect`` answers (``bench_detect.single_view``); the pair is located as
``bench.bench_detect`` locates it (no clipping), so the counts compare with its report, and
(``pair_clip``) as a job that clips the ends no view sees, with the way's nominal line held in
3D when it has one (``line3d``).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from bench.bench_detect import _detect, _locate, single_view
from bench.detect_cases import view_truth
from bench.detect_score import score_view

Setting = Callable[[int, dict[str, Any]], tuple[Any, Any]]


def detect_one_way(imgs: list[np.ndarray], z: dict[str, Any], cam: Any,
                   setting: Setting, line3d: tuple[np.ndarray, float] | None = None
                   ) -> dict[str, Any]:
    """``{"views": [...], "pair": result, "pair_clip": result}`` of one case's images ``imgs``
    (truth ``z``); ``line3d``: the job's nominal line (mm) and tolerance (mm) for the clipped
    pair."""
    views, curves, widths, kinds, bands = [], [], [], [], []
    for i, img in enumerate(imgs):
        truth = view_truth(z, i, img)
        params, hint = setting(i, truth)
        r = _detect("ours", img, cam, params, hint=hint)
        if r["result"] == "returned":
            said = r.pop("kinds")
            r.update(score_view(r["points"], truth, said))
            curves.append(r.pop("points"))
            widths.append(r["width_px"])
            bands.append(r["band"])
            kinds.append(tuple(said) if said and len(said) == 2 else None)
        r = single_view(r)
        views.append({k: r.get(k) for k in ("result", "why", "confidence", "error")})
    out: dict[str, Any] = {"views": views}
    if len(imgs) == 2:
        both = len(curves) == 2
        out["pair"] = (_locate(z, curves, widths, kinds, cam, bands=bands)["result"]
                       if both else "refused")
        out["pair_clip"] = (_locate(z, curves, widths, kinds, cam, clip=True, bands=bands,
                                    nominal_line=line3d)["result"] if both else "refused")
    return out


def way_counts(rows: list[dict[str, Any]], way: str) -> dict[str, int]:
    """Counts of one way's views (found / wrong / refused) and pairs (located / partial /
    wrong) over ``rows`` (each with ``row[way]`` from :func:`detect_one_way`)."""
    views = [v for r in rows for v in r[way]["views"]]
    pairs = [r[way]["pair"] for r in rows if "pair" in r[way]]
    out = {k: sum(v["result"] == k for v in views) for k in ("found", "wrong", "refused")}
    out["views"] = len(views)
    out.update(pairs=len(pairs), pairs_located=pairs.count("located"),
               pairs_partial=pairs.count("partial"), pairs_wrong=pairs.count("wrong"))
    clipped = [r[way].get("pair_clip") for r in rows if "pair" in r[way]]
    out.update(clip_located=clipped.count("located"), clip_wrong=clipped.count("wrong"))
    return out


#: Columns every comparison table prints after the way: (header, summary key, width).
VIEW_COLS = [("views", "views", 5), ("found", "found", 5), ("wrong", "wrong", 5)]
PAIR_COLS = [("pairs", "pairs", 5), ("loc", "pairs_located", 4), ("part", "pairs_partial", 4),
             ("wrong", "pairs_wrong", 5), ("cloc", "clip_located", 4),
             ("cwrong", "clip_wrong", 6)]


def write_and_print(out: str, report: dict[str, Any], rows: list[dict[str, Any]], title: str,
                    first: tuple[str, int], way_w: int, extra: list[tuple[str, str, int]]) -> None:
    """Write ``report`` with its ``rows`` to ``out`` (JSON) and print its summary as a table.

    ``report["summary"]``: {part/set: {way: counts}}; ``first``: the first column's header and
    width; ``extra``: the bench's own count columns (header, key, width), printed between the
    views' and the pairs' columns.
    """
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    Path(out).write_text(json.dumps({**report, "rows": rows}, indent=1))
    print(title)
    cols = VIEW_COLS + extra + PAIR_COLS
    print(" ".join([f"{first[0]:{first[1]}s}", f"{'way':{way_w}s}",
                    *(f"{h:>{w}s}" for h, _, w in cols)]))
    for key, by_way in report["summary"].items():
        for w, s in by_way.items():
            print(" ".join([f"{key:{first[1]}s}", f"{w:{way_w}s}",
                            *(f"{s[k]:{n}d}" for _, k, n in cols)]))
