"""The ends of a located seam: which views see them, and what to do where none does.

An end of the 3D seam is *seen* by a view when that view's curve ends there at a ``joint_end``
(a real end of the joint: a sheet border, a plate corner) and the 3D end projects onto it. An end
is *unseen* when the seam runs out of every image there, or out of the stereo overlap (one view
cuts it at its border before the other view's joint end): nothing then says where the joint
really ends, so the seam could be longer than what would be welded. Such an end is refused, or,
when the job allows it (``[seam] clip_unseen_ends``), the seam is clipped to the job's nominal
seam region there (:func:`clip_to_region`) and kept off the images' borders, where a curve's
last pixels are its least sure (:func:`trim_to_margin`); ``quality["ends"]`` records which, per
end.

An end seen by only one view is not extended by that view's ray alone (no monocular depth): the
3D seam ends where both views see it, and that end counts as unseen. The stretch of the reference
view's curve beyond it lies outside another view's image: it does not count against the share of
the curve the views matched (:func:`overlap_coverage`), whose limit is for views that see
different lines, not for a seam leaving one image earlier than the other.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]

JOINT_END = "joint_end"
IMAGE_BORDER = "image_border"

#: A view's joint end must lie this close (px) to the 3D end's projection to count as seeing it.
END_MATCH_PX = 12.0


def view_end_cut(view: Any, curve: F64, index: int, margin_px: float) -> bool:
    """True when the view's curve end ``index`` (0 or -1) is not an end of the joint.

    With the detector's end kinds: an ``image_border`` end; without: an end within ``margin_px``
    of the image border.
    """
    kinds = getattr(view, "end_kinds", None)
    if kinds is not None:
        return bool(kinds[0 if index == 0 else 1] == IMAGE_BORDER)
    return not bool(view.camera.in_image(curve[index][None], margin_px)[0])


def judge_ends(views: list[Any], curves: list[F64], dense: F64,
               margin_px: float) -> list[dict[str, Any]]:
    """Per end of ``dense`` (start, end): the views that see it and why the others do not.

    ``ray_gap_mm`` is the worst distance of a seeing view's end ray from the 3D end. Where no view
    cuts the end at its image border, every view's end is a real end of the joint and all of them
    count, however far apart: a wrong calibration or a detection that stopped short then shows as
    a large gap (judged by ``max_endpoint_gap_mm``), never as an unseen end.
    """
    out = []
    for which, end3d in (("start", dense[0]), ("end", dense[-1])):
        near, cut = [], []
        for v, c in zip(views, curves, strict=True):
            uv = v.camera.project(end3d[None], v.T_base_cam)[0]
            d = np.linalg.norm(c[[0, -1]] - uv, axis=1)
            i = int(np.argmin(d))
            if view_end_cut(v, c, 0 if i == 0 else -1, margin_px):
                cut.append(v.name)
            else:
                near.append((v, c[[0, -1]][i], float(d[i])))
        seen = near if not cut else [t for t in near if t[2] <= END_MATCH_PX]
        not_seen = [f"{n}: the seam runs out of the image" for n in cut]
        not_seen += [f"{v.name}: its joint end lies {d:.0f} px beyond where the seam leaves "
                     f"the other views" for v, _, d in near if cut and d > END_MATCH_PX]
        gap = 0.0
        for v, px, _ in seen:
            o, ray = v.camera.pixel_rays(px[None], v.T_base_cam)
            r = end3d - np.asarray(o).reshape(-1, 3)[0]
            gap = max(gap, float(np.linalg.norm(r - np.dot(r, ray[0]) * ray[0])))
        out.append({"end": which, "status": "seen" if seen else "unseen",
                    "seen_by": [v.name for v, _, _ in seen], "not_seen": not_seen,
                    "ray_gap_mm": gap})
    return out


def clip_to_region(dense: F64, region: tuple[F64, float],
                   unseen: list[dict[str, Any]]) -> tuple[F64, tuple[int, int]]:
    """``dense`` clipped to the nominal sphere (centre mm, radius mm) at its ``unseen`` ends.

    Returns the clipped points and the kept index range [start, stop) into ``dense``; marks each
    unseen end ``clipped`` with the length cut off (mm). Seen ends are never cut.
    """
    centre, radius = np.asarray(region[0], dtype=np.float64), float(region[1])
    a, b, cuts = _cut_ends(dense, np.linalg.norm(dense - centre, axis=1) <= radius, unseen)
    for e, cut in zip(unseen, cuts, strict=True):
        e["clipped_mm"] = cut
        e["status"] = "clipped"
    return dense[a:b], (a, b)


def trim_to_margin(dense: F64, views: list[Any], clipped: list[dict[str, Any]],
                   margin_px: float) -> tuple[F64, tuple[int, int]]:
    """``dense`` (N, 3) mm cut back at its ``clipped`` ends to where every view sees it inside.

    At an end no view sees, the seam runs to a view's image border, and a detected curve's last
    pixels there are its least sure (its profiles and the sheets beside it are cut by the border,
    the end is extrapolated to it): in the simulator's pairs the 3D error there grew to 1.3 mm
    within a few px of a border, against 0.1-0.2 mm farther in. Each clipped end is cut back to
    the first point that projects at least ``margin_px`` inside every view's image (the margin
    within which a curve's end counts as cut by the border), the cut added to its
    ``clipped_mm`` and recorded as ``border_trimmed_mm``. Seen ends are never cut. Returns the
    points kept and their index range [start, stop) into ``dense``.
    """
    inside = np.ones(len(dense), dtype=bool)
    for v in views:
        inside &= v.camera.in_image(v.camera.project(dense, v.T_base_cam), margin_px)
    a, b, cuts = _cut_ends(dense, inside, clipped)
    for e, cut in zip(clipped, cuts, strict=True):
        if cut > 0.0:
            e["border_trimmed_mm"] = cut
            e["clipped_mm"] = float(e.get("clipped_mm", 0.0)) + cut
    return dense[a:b], (a, b)


def _cut_ends(dense: F64, keep: NDArray[np.bool_],
              ends: list[dict[str, Any]]) -> tuple[int, int, list[float]]:
    """Index range [a, b) of ``dense`` (N, 3) mm with each of ``ends`` cut back to ``keep``.

    Each named end ("start" or "end") loses its points up to the first one ``keep`` holds (at
    least 2 points are kept). Also returns the length cut off at each of ``ends`` (mm).
    """
    a, b = 0, len(dense)
    step = np.linalg.norm(np.diff(dense, axis=0), axis=1)
    cuts = []
    for e in ends:
        if e["end"] == "start":
            while a < b - 2 and not keep[a]:
                a += 1
            cuts.append(float(step[:a].sum()))
        else:
            while b > a + 2 and not keep[b - 1]:
                b -= 1
            cuts.append(float(step[b - 1:].sum()))
    return a, b, cuts


def unseen_ends_problem(unseen: list[dict[str, Any]]) -> str:
    """The refusal for ends no view sees (the job does not allow clipping), naming the views."""
    parts = [f"its {e['end']} ({'; '.join(e['not_seen'])})" for e in unseen]
    return (f"no view sees where the seam ends at {' and '.join(parts)}: the seam could be "
            f"longer than what would be welded. Move the views so that every end of the seam is "
            f"in the images, or let the job weld what the views see inside its nominal region "
            f"([seam] clip_unseen_ends = true)")


def overlap_coverage(s_ref: F64, first: int, last: int,
                     ends: list[dict[str, Any]]) -> tuple[float, float]:
    """(share of the stereo overlap matched, share of the whole reference curve matched).

    ``s_ref``: arc length (px) at each sample of the reference view's curve; ``first``, ``last``:
    the first and last sample matched in the other views; ``ends``: :func:`judge_ends` of the
    3D seam (start, end). Where no view sees an end (some view's curve runs out of its image
    there), the reference curve's stretch beyond the last matched sample lies outside another
    view's image, not missed by it: it is left out of the share. That end is refused or clipped
    (``clip_unseen_ends``) by its own rule, and the stretch is never welded. Elsewhere an
    unmatched stretch at an end counts against the share (the views may see different lines).
    """
    matched = float(s_ref[last] - s_ref[first])
    total = float(s_ref[-1])
    unseen = {e["end"] for e in ends if not e["seen_by"]}
    lo = float(s_ref[first]) if "start" in unseen else 0.0
    hi = float(s_ref[last]) if "end" in unseen else total
    return matched / max(hi - lo, 1e-9), matched / max(total, 1e-9)
