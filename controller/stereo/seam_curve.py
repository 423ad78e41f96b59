"""A smooth 3D seam curve through triangulated points, resampled with true end points.

The curve is parametrised by the arc length of the seam in the reference image, which is monotonic
and nearly noise-free, rather than by the 3D chord length of noisy points. Each coordinate is a
least-squares cubic B-spline with evenly spaced knots (scipy's ``make_lsq_spline``; its
``make_smoothing_spline`` chooses the smoothing by a GCV search written in Python that took
0.5 s per coordinate and sometimes interpolated the noise), so the curve follows any shape
without the end curl of a high-degree polynomial.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.interpolate import make_lsq_spline

from controller.errors import ConfigError

F64 = NDArray[np.float64]


def smooth_curve(param: F64, points: F64, knot_spacing: float = 30.0) -> F64:
    """Smooth (N, 3) ``points`` ordered by strictly increasing ``param``; same shape out.

    A least-squares cubic B-spline per coordinate with interior knots every ``knot_spacing``
    (in units of ``param``, e.g. px of reference-image arc length): fast, follows any shape, and
    its bandwidth is set by the knot spacing rather than a fitted polynomial degree.
    """
    p = np.asarray(param, dtype=np.float64)
    X = np.asarray(points, dtype=np.float64)
    k = 3
    span = p[-1] - p[0]
    n_inner = int(span // knot_spacing)
    if len(p) < 2 * (k + 1) or n_inner < 1:
        return _polyfit_smooth(p, X)
    inner = np.linspace(p[0], p[-1], n_inner + 2)[1:-1]
    t = np.concatenate([[p[0]] * (k + 1), inner, [p[-1]] * (k + 1)])
    try:
        out = np.asarray(make_lsq_spline(p, X, t, k=k)(p))
    except (ValueError, np.linalg.LinAlgError):
        out = np.full_like(X, np.nan)
    if not np.all(np.isfinite(out)):
        # Schoenberg-Whitney fails where samples are missing between knots (degenerate gaps):
        # older scipy raised, scipy 1.17 returns NaN. Fall back to fewer knots.
        return smooth_curve(p, X, knot_spacing * 2) if n_inner > 1 else _polyfit_smooth(p, X)
    return out


def _polyfit_smooth(p: F64, X: F64) -> F64:
    """Very short curves: a quadratic (or line) in the parameter."""
    deg = min(2, len(p) - 1)
    coef = np.polyfit(p, X, deg)
    return np.column_stack([np.polyval(coef[:, j], p) for j in range(X.shape[1])])


def arc_length(points: F64) -> F64:
    """Cumulative arc length (mm) along an ordered (N, 3) polyline, starting at 0."""
    seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
    return np.concatenate([[0.0], np.cumsum(seg)])


def resample_curve(points: F64, spacing_mm: float | None = 2.0, count: int | None = None) -> F64:
    """Resample an ordered dense polyline at equal arc length, keeping both end points exactly.

    Give ``spacing_mm`` (the last interval is made equal by rounding the count) or ``count``.
    """
    s = arc_length(points)
    length = float(s[-1])
    if count is None:
        if spacing_mm is None or spacing_mm <= 0:
            raise ConfigError(f"weld point spacing must be positive mm, got {spacing_mm}")
        count = max(2, int(round(length / spacing_mm)) + 1)
    if count < 2:
        raise ConfigError(f"weld point count must be at least 2, got {count}")
    target = np.linspace(0.0, length, count)
    return np.column_stack([np.interp(target, s, points[:, k]) for k in range(3)])


def end_bend_mm(points: F64, tip_mm: float = 1.5, reach_mm: float = 10.0) -> list[float | None]:
    """How far each end of a 3D seam (N, 3) mm leaves its own course: [start, end] mm or None.

    Per end, a quadratic in arc length is fitted (per coordinate) to the points between
    ``tip_mm`` and ``reach_mm`` from that end and extrapolated over the last ``tip_mm``; the
    value is the largest distance of those last points from it. A joint does not turn off its
    course in its last millimetre; a seam that does took a detection artefact at its end in
    one view (a curve's last pixels off the gap across the seam move the triangulated end along
    the other view's rays, which no ray gap shows). None where fewer than 5 points fit or no
    point lies within ``tip_mm`` of the end.
    """
    P = np.asarray(points, dtype=np.float64)
    s = arc_length(P)
    out: list[float | None] = []
    for d in (s, s[-1] - s):
        fit, tip = (d > tip_mm) & (d < reach_mm), d <= tip_mm
        if fit.sum() < 5 or not tip.any():
            out.append(None)
            continue
        coef = np.polyfit(d[fit], P[fit], 2)  # (3, 3): one quadratic per coordinate
        pred = np.column_stack([np.polyval(coef[:, k], d[tip]) for k in range(3)])
        out.append(float(np.max(np.linalg.norm(P[tip] - pred, axis=1))))
    return out
