"""Valley paths through a whole image: the best-supported curves along each main direction.

The working image's valley response (:mod:`controller.vision.seam_valley`) is rotated so that one
main direction runs down the rows, and a dynamic programme finds the path of the highest total
*gain* (response minus a bias, capped), moving at most one column per row (within 45 degrees of
the direction), that may start and stop anywhere (a best-scoring sub-path, as in local sequence
alignment). A stretch where the gap is covered (a tack weld, spatter, glare: no valley, gain
``-bias`` per row) is crossed when the gap on both sides pays for it, so the path bridges it; a
path stops where the valley stops for good (a sheet border, the image border, the end of a pen
line). A second path is found with the first one's neighbourhood masked out.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from controller.vision.seam_valley import F32, rotate_to_rows

F64 = NDArray[np.float64]
_OUTSIDE = -1.0  # gain outside the image: paths stop at the image border


@dataclass
class ValleyPath:
    """One path in working-image px: (u, v) points every row of the rotated canvas, its score."""

    points: F64  # (N, 2) working px, ordered
    resp: F64  # (N,) valley response along the path
    score: float
    theta: float  # main direction it was found along (rad)
    rows: F64  # (N,) the path in the rotated canvas: one column per row
    cols: F64
    to_image: F64  # (2, 3) affine from the canvas (col, row) to working px (u, v)


def find_paths(resp: F32, thetas: list[float], bias: float, cap: float,
               per_direction: int = 2, shift_pen: float = 0.02,
               mask_px: int = 6) -> list[ValleyPath]:
    """Up to ``per_direction`` best paths along each of ``thetas``, strongest first overall."""
    out: list[ValleyPath] = []
    for th in thetas:
        rot, Minv = rotate_to_rows(resp, th, fill=np.nan)
        outside = np.isnan(rot)
        gain = np.minimum(np.nan_to_num(rot, nan=0.0), cap) - bias
        gain[outside] = _OUTSIDE
        for _ in range(per_direction):
            rows, cols, score = _best_subpath(gain, shift_pen)
            if len(rows) < 4 or score <= 0:
                break
            canvas = np.column_stack([cols, rows]).astype(np.float64)
            pts = canvas @ Minv[:, :2].T + Minv[:, 2]
            r_on = rot[rows, cols]
            out.append(ValleyPath(pts, np.nan_to_num(r_on.astype(np.float64)), float(score), th,
                                  rows.astype(np.float64), cols.astype(np.float64),
                                  np.asarray(Minv, np.float64)))
            for r, c in zip(rows.tolist(), cols.tolist(), strict=True):
                gain[r, max(c - mask_px, 0):c + mask_px + 1] = -bias
    out.sort(key=lambda p: -p.score)
    return out


def robust_line(rows: F64, cols: F64, seen: NDArray[np.bool_], win: int, tol: float,
                out_win: int | None = None) -> tuple[F64, NDArray[np.bool_]]:
    """``cols(rows)`` smoothed, from the ``seen`` samples that agree with a smooth line.

    Three rounds: a local quadratic (Savitzky-Golay) over ``win`` samples through the kept
    samples (the others interpolated), then samples further than ``tol`` (or three median
    deviations) from it dropped. The kept samples, interpolated across the dropped ones, are
    smoothed over ``out_win`` samples (default ``win``). A path that wandered off along a dark
    feature where the gap is covered comes back to the continuation of the gap on both sides.
    Returns the smoothed ``cols`` and which samples were kept.
    """
    from scipy.signal import savgol_filter

    keep = seen.copy()
    n = len(rows)
    w = min(win, (n - 1) // 2 * 2 + 1)
    for _ in range(3):
        if keep.sum() < 4 or w < 5:
            break
        sm = savgol_filter(np.interp(rows, rows[keep], cols[keep]), w, 2)
        dev = np.abs(cols - sm)
        keep = seen & (dev <= max(tol, 3.0 * float(np.median(dev[keep]))))
    if keep.sum() < 2:
        return cols.copy(), keep
    filled = np.interp(rows, rows[keep], cols[keep])
    wo = min(out_win or win, (n - 1) // 2 * 2 + 1)
    return np.asarray(savgol_filter(filled, wo, 2) if wo >= 5 else filled), keep


def _best_subpath(gain: NDArray[np.floating],
                  pen: float) -> tuple[NDArray[np.int64], NDArray[np.int64], float]:
    """Rows, columns and total gain of the best path down the rows (start and stop anywhere).

    A path steps to the same column or one beside it (costing ``pen``) from row to row, or starts
    afresh where everything above would add nothing.
    """
    R, C = gain.shape
    S = np.empty((R, C), np.float32)
    prev = np.zeros(C, np.float32)
    best = np.full(C, -1e9, np.float32)  # the better neighbour above, then the best way in
    pen32 = np.float32(pen)
    for r in range(R):
        if C > 1:
            np.maximum(prev[:-2], prev[2:], out=best[1:-1])
            best[0], best[-1] = prev[1], prev[-2]
            best -= pen32
        else:
            best[0] = -1e9  # one column: no neighbour
        np.maximum(best, prev, out=best)
        np.maximum(best, 0.0, out=best)
        np.add(best, gain[r], out=S[r])
        prev = S[r]
    r0, c0 = np.unravel_index(int(np.argmax(S)), S.shape)
    r, c = int(r0), int(c0)
    score = float(S[r, c])
    rows, cols = [r], [c]
    # Back along the path: at each cell, the step the forward pass took (the same column first,
    # then the left, then the right one on a tie), until a fresh start.
    while r > 0:
        up = S[r - 1]
        came = [(up[c], 0)]
        if c > 0:
            came.append((up[c - 1] - pen32, -1))
        if c < C - 1:
            came.append((up[c + 1] - pen32, 1))
        m = max(v for v, _ in came)
        if m <= 0:
            break
        c += next(d for v, d in came if v == m)
        r -= 1
        rows.append(int(r))
        cols.append(int(c))
    return np.asarray(rows[::-1]), np.asarray(cols[::-1]), score
