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

from controller.poses import invert

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
                 min_angle_deg: float = 8.0, along_tol: float = 4e-4) -> CurveMatch:
    """Match reference curve samples (N, 2) to an ordered polyline (M, 2) in another view.

    Both inputs are normalised undistorted coordinates of ordered polylines. A sample whose
    epipolar line runs within ``along_tol`` (normalised units, about 1 px) of a stretch of the
    other curve longer than ``tan(min_angle_deg)``-worth is degenerate even without a crossing.
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
    # crossing angle: between the line direction (-b, a) and the segment direction
    sin_angle = np.abs(np.einsum("ij,ij->i", lines[rows, :2], seg_unit[segs]))
    angle_all = np.degrees(np.arcsin(np.clip(sin_angle, 0.0, 1.0)))

    t = np.full(n, np.nan)
    angle = np.zeros(n)
    counts = np.bincount(rows, minlength=n)
    ambiguous = counts > 1
    single = counts == 1
    first = np.searchsorted(rows, np.arange(n))
    idx_single = first[single]
    t[single] = t_all[idx_single]
    angle[single] = angle_all[idx_single]
    if np.any(ambiguous):
        known = np.flatnonzero(single & (angle > min_angle_deg))
        for i in np.flatnonzero(ambiguous):
            cand = slice(first[i], first[i] + counts[i])
            if known.size >= 2:
                pred = float(np.interp(i, known, t[known]))
            elif known.size == 1:
                pred = float(t[known[0]])
            else:
                pred = float(np.median(t_all[cand]))
            k = first[i] + int(np.argmin(np.abs(t_all[cand] - pred)))
            t[i], angle[i] = t_all[k], angle_all[k]
    degenerate = np.isfinite(t) & (angle < min_angle_deg)
    # The curve lying along the line itself (no sign change at all): count near vertices.
    near = (np.abs(f) < along_tol).sum(axis=1)
    degenerate |= near > max(5, len(xy_other) // 20)
    return CurveMatch(t=t, angle_deg=angle, degenerate=degenerate, ambiguous=ambiguous)


def point_on_polyline(xy: F64, t: F64) -> F64:
    """Points at fractional indices ``t`` along polyline ``xy`` (NaN stays NaN)."""
    out = np.full((len(t), 2), np.nan)
    ok = np.isfinite(t)
    tt = np.clip(t[ok], 0, len(xy) - 1)
    i = np.minimum(np.floor(tt).astype(int), len(xy) - 2)
    a = (tt - i)[:, None]
    out[ok] = xy[i] * (1 - a) + xy[i + 1] * a
    return out
