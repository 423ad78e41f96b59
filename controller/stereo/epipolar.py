"""Matching two image curves of the same 3D seam with epipolar geometry.

Works in normalised undistorted camera coordinates, where epipolar lines are straight. For each
sample of the reference curve, its epipolar line in the other view is intersected with the other
curve (every crossing, found by sign changes of the signed distance along the polyline). Where a
line crosses the curve more than once the crossing that keeps the correspondence continuous and
monotonic is kept. Where the curve runs nearly along the epipolar lines (a small crossing angle)
the intersection is ill-conditioned: those samples are flagged ``degenerate`` and left to the curve
refinement, and the caller reports the stretch.

The published methods intersected each epipolar line with a fitted polynomial (one crossing only,
fails along the epipolar direction) or searched all ray pairs for the closest one (slow, noisy).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from controller.geometry.poses import invert

F64 = NDArray[np.float64]


@dataclass(frozen=True)
class CurveMatch:
    """Correspondences from reference-curve samples to the other curve.

    ``t`` is the fractional index into the other polyline (NaN where there is no crossing);
    ``angle_deg`` the crossing angle between the epipolar line and the other curve (0 = tangent);
    ``degenerate`` marks crossings flatter than the limit; ``ambiguous`` marks samples whose line
    crossed the other curve more than once (the continuous crossing was kept).
    """

    t: F64
    angle_deg: F64
    degenerate: NDArray[np.bool_]
    ambiguous: NDArray[np.bool_]


def relative_pose(T_base_cam_ref: F64, T_base_cam_other: F64) -> F64:
    """``T_other_ref``: maps points in the reference camera frame to the other camera frame."""
    return invert(T_base_cam_other) @ T_base_cam_ref


def epipolar_lines(xy_ref: F64, T_other_ref: F64) -> F64:
    """Epipolar lines (N, 3) ``a x + b y + c = 0`` in the other view, normalised coordinates.

    Lines are scaled so that (a, b) is a unit vector: the line value of a point is its signed
    distance in normalised units.
    """
    R, t = T_other_ref[:3, :3], T_other_ref[:3, 3]
    rays = np.column_stack([xy_ref, np.ones(len(xy_ref))]) @ R.T
    lines = np.cross(np.broadcast_to(t, rays.shape), rays)
    norm = np.linalg.norm(lines[:, :2], axis=1, keepdims=True)
    return lines / np.where(norm > 0, norm, 1.0)


def match_curves(xy_ref: F64, xy_other: F64, T_other_ref: F64,
                 min_angle_deg: float = 8.0, along_tol: float = 4e-4,
                 end_tol: float = 1e-9) -> CurveMatch:
    """Match reference curve samples (N, 2) to an ordered polyline (M, 2) in another view.

    Both inputs are normalised undistorted coordinates of ordered polylines. A sample whose
    epipolar line runs within ``along_tol`` (normalised units, about 1 px) of a stretch of the
    other curve longer than ``tan(min_angle_deg)``-worth is degenerate even without a crossing.
    A line within ``end_tol`` (normalised units; rounding, not a tolerance on the data) of an end
    vertex of the other curve meets it there.
    Returns a :class:`CurveMatch` of length N.
    """
    n = len(xy_ref)
    lines = epipolar_lines(xy_ref, T_other_ref)
    other_h = np.column_stack([xy_other, np.ones(len(xy_other))])
    f = lines @ other_h.T  # (N, M) signed distances
    seg_dir = np.diff(xy_other, axis=0)
    seg_len = np.linalg.norm(seg_dir, axis=1)
    seg_unit = seg_dir / np.where(seg_len > 0, seg_len, 1.0)[:, None]
    cross = (f[:, :-1] * f[:, 1:] <= 0) & ((f[:, :-1] != 0) | (f[:, 1:] != 0))
    rows, segs = np.nonzero(cross)
    f0, f1 = f[rows, segs], f[rows, segs + 1]
    frac = f0 / (f0 - f1)
    t_all = segs + frac
    # A line through an end vertex of the other curve, rounding off to the side the curve lies on,
    # shows no sign change: the reference curve's end sample (where both views see the seam end)
    # was left unmatched and every 3D seam ended one sample short. Such a line touches the end.
    last = len(xy_other) - 1
    ends = [(np.flatnonzero((np.abs(f[:, k]) <= end_tol) & ~cross[:, seg]), k, seg)
            for k, seg in ((0, 0), (last, last - 1))]
    rows = np.concatenate([rows] + [r for r, _, _ in ends])
    segs = np.concatenate([segs] + [np.full(len(r), seg) for r, _, seg in ends])
    t_all = np.concatenate([t_all] + [np.full(len(r), float(k)) for r, k, _ in ends])
    order = np.lexsort((t_all, rows))  # grouped by sample, as _resolve_crossings expects
    rows, segs, t_all = rows[order], segs[order], t_all[order]
    # crossing angle: between the line direction (-b, a) and the segment direction
    sin_angle = np.abs(np.einsum("ij,ij->i", lines[rows, :2], seg_unit[segs]))
    angle_all = np.degrees(np.arcsin(np.clip(sin_angle, 0.0, 1.0)))

    t, angle = _resolve_crossings(rows, t_all, angle_all, n)
    counts = np.bincount(rows, minlength=n)
    ambiguous = counts > 1
    degenerate = np.isfinite(t) & (angle < min_angle_deg)
    # The curve lying along the line itself (no sign change at all): count near vertices.
    near = (np.abs(f) < along_tol).sum(axis=1)
    degenerate |= near > max(5, len(xy_other) // 20)
    return CurveMatch(t=t, angle_deg=angle, degenerate=degenerate, ambiguous=ambiguous)


def _resolve_crossings(rows: NDArray[np.intp], t_all: F64, angle_all: F64, n: int,
                       window: int = 15) -> tuple[F64, F64]:
    """One crossing per sample, continuous and monotonic along the other curve.

    Unique crossings are kept; multiple ones are resolved by continuity from resolved neighbours
    within ``window`` samples, else left unmatched.

    Both curves are ordered along the same seam, so the correspondence must run one way: samples
    that still step against the dominant direction are dropped (NaN). A seam seen across the
    baseline gives unique crossings almost everywhere; multiple ones come in pairs near stretches
    that are tangent to the epipolar lines, which are flagged degenerate anyway.
    """
    t = np.full(n, np.nan)
    angle = np.zeros(n)
    if rows.size == 0:
        return t, angle
    counts = np.bincount(rows, minlength=n)
    first = np.searchsorted(rows, np.arange(n))
    single = counts == 1
    t[single] = t_all[first[single]]
    angle[single] = angle_all[first[single]]
    multiple = np.flatnonzero(counts > 1)
    # Forward, then backward: each resolved sample becomes a neighbour for the next one, so long
    # ambiguous stretches are followed by continuity from where the crossing was unique.
    for order in (multiple, multiple[::-1]):
        step = 1 if order is multiple else -1
        for i in order:
            if np.isfinite(t[i]):
                continue
            lo, hi = (i - window, i) if step == 1 else (i + 1, i + window + 1)
            near = np.arange(max(lo, 0), min(hi, n))
            near = near[np.isfinite(t[near])]
            near = near[-2:] if step == 1 else near[:2]
            if near.size == 0:
                continue
            if near.size == 2:
                pred = float(t[near[0]] + (t[near[1]] - t[near[0]]) * (i - near[0])
                             / (near[1] - near[0]))
            else:
                pred = float(t[near[0]])
            cand = slice(first[i], first[i] + counts[i])
            k = first[i] + int(np.argmin(np.abs(t_all[cand] - pred)))
            t[i], angle[i] = t_all[k], angle_all[k]
    ok = np.flatnonzero(np.isfinite(t))
    if ok.size > 1:
        direction = np.sign(np.median(np.diff(t[ok]))) or 1.0
        # Keep the longest run consistent with the direction: drop samples that go backwards
        # relative to both their predecessor and the running extreme.
        running = np.maximum.accumulate(direction * t[ok])
        backwards = direction * t[ok] < running - 1e-9
        t[ok[backwards]] = np.nan
    return t, angle


def point_on_polyline(xy: F64, t: F64) -> F64:
    """Points at fractional indices ``t`` along polyline ``xy`` (NaN stays NaN)."""
    out = np.full((len(t), 2), np.nan)
    ok = np.isfinite(t)
    tt = np.clip(t[ok], 0, len(xy) - 1)
    i = np.minimum(np.floor(tt).astype(int), len(xy) - 2)
    a = (tt - i)[:, None]
    out[ok] = xy[i] * (1 - a) + xy[i + 1] * a
    return out
