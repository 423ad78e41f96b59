"""Rays, N-view triangulation and the distances used to judge it.

All 3D quantities in the base frame, mm; pixels as in :mod:`controller.geometry.camera_model`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

F64 = NDArray[np.float64]


def triangulate_rays(origins: F64, directions: F64, valid: NDArray[np.bool_] | None = None
                     ) -> tuple[F64, F64, F64]:
    """Least-squares intersection of V rays for each of N points.

    ``origins`` (V, 3), ``directions`` (V, N, 3) unit vectors; ``valid`` (V, N) says which rays
    take part (at least two per point, else NaN). Returns (points (N, 3) mm, RMS distance of the
    point to its rays (N,) mm — half the ray gap for two views —, largest angle between its rays
    (N,) degrees).
    """
    V, N, _ = directions.shape
    if valid is None:
        valid = np.ones((V, N), dtype=bool)
    w = valid.astype(np.float64)
    A = np.zeros((N, 3, 3))
    b = np.zeros((N, 3))
    eye = np.eye(3)
    for k in range(V):
        d = np.nan_to_num(directions[k])
        P = eye[None] - d[:, :, None] * d[:, None, :]
        A += w[k][:, None, None] * P
        b += w[k][:, None] * (P @ origins[k])
    count = valid.sum(axis=0)
    ok = count >= 2
    det = np.linalg.det(A)
    ok &= np.abs(det) > 1e-12
    X = np.full((N, 3), np.nan)
    if np.any(ok):
        X[ok] = np.linalg.solve(A[ok], b[ok][:, :, None])[:, :, 0]
    sq = np.zeros(N)
    for k in range(V):
        d = np.nan_to_num(directions[k])
        r = X - origins[k]
        perp = r - np.einsum("ij,ij->i", r, d)[:, None] * d
        sq += w[k] * np.einsum("ij,ij->i", perp, perp)
    rms = np.sqrt(sq / np.maximum(count, 1))
    rms[~ok] = np.nan
    angle = np.zeros(N)
    for i in range(V):
        for j in range(i + 1, V):
            both = valid[i] & valid[j]
            c = np.clip(np.einsum("ij,ij->i", np.nan_to_num(directions[i]),
                                  np.nan_to_num(directions[j])), -1, 1)
            angle = np.where(both, np.maximum(angle, np.degrees(np.arccos(c))), angle)
    angle[~ok] = np.nan
    return X, rms, angle


def ray_gap(o1: F64, d1: F64, o2: F64, d2: F64) -> float:
    """Shortest distance (mm) between two rays (unit directions); parallel rays: their spacing."""
    n = np.cross(d1, d2)
    nn = float(np.linalg.norm(n))
    if nn < 1e-12:
        r = o2 - o1
        return float(np.linalg.norm(r - np.dot(r, d1) * d1))
    return float(abs(np.dot(o2 - o1, n)) / nn)


class PolylineDistance:
    """Distance from points to an ordered polyline (same units as its vertices, e.g. px)."""

    def __init__(self, vertices: F64) -> None:
        self.v = np.asarray(vertices, dtype=np.float64)
        self.tree = cKDTree(self.v)

    def __call__(self, points: F64) -> F64:
        """Shortest distance of each (N, 2) point to the polyline; NaN points give NaN."""
        p = np.asarray(points, dtype=np.float64)
        out = np.full(len(p), np.nan)
        ok = np.all(np.isfinite(p), axis=1)
        if not np.any(ok) or len(self.v) < 2:
            return out
        q = p[ok]
        _, idx = self.tree.query(q)
        best = np.full(len(q), np.inf)
        for off in (-1, 0):
            i = np.clip(idx + off, 0, len(self.v) - 2)
            a, b = self.v[i], self.v[i + 1]
            ab = b - a
            L2 = np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-18)
            s = np.clip(np.einsum("ij,ij->i", q - a, ab) / L2, 0.0, 1.0)
            d = np.linalg.norm(q - (a + s[:, None] * ab), axis=1)
            best = np.minimum(best, d)
        out[ok] = best
        return out


def resample_polyline(xy: F64, spacing: float) -> F64:
    """Resample an ordered polyline at (about) equal arc-length ``spacing``, keeping both ends."""
    p = np.asarray(xy, dtype=np.float64)
    seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    if s[-1] <= 0:
        return p[:1].copy()
    n = max(2, int(np.ceil(s[-1] / spacing)) + 1)
    target = np.linspace(0.0, s[-1], n)
    return np.column_stack([np.interp(target, s, p[:, k]) for k in range(p.shape[1])])
