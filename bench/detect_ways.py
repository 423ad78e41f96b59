"""One case's views detected one way, scored, and the pair located: what the benchmarks that
compare ways of detecting (``bench.bench_detect_job_gap``, ``bench.bench_detect_nominal``) share.

A *way* gives each view its detector parameters and nominal seam (``setting(i, truth)`` ->
``(DetectParams or None, hint px or None)``). Views are scored by ``bench.detect_score`` and
counted as ``seamguide detect`` answers (``bench_detect.single_view``); the pair is located as
``bench.bench_detect`` locates it (no clipping), so the counts compare with its report.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from bench.bench_detect import _detect, _locate, single_view
from bench.detect_cases import view_truth
from bench.detect_score import score_view

Setting = Callable[[int, dict[str, Any]], tuple[Any, Any]]


def detect_one_way(imgs: list[np.ndarray], z: dict[str, Any], cam: Any,
                   setting: Setting) -> dict[str, Any]:
    """``{"views": [...], "pair": result}`` of one case's images ``imgs`` (truth ``z``)."""
    views, curves, widths, kinds, bands = [], [], [], [], []
    for i, img in enumerate(imgs):
        truth = view_truth(z, i)
        truth["image_size"] = (img.shape[1], img.shape[0])
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
        out["pair"] = (_locate(z, curves, widths, kinds, cam, bands=bands)["result"]
                       if len(curves) == 2 else "refused")
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
    return out
