"""The published stereo methods, ported to Python for the side-by-side benchmark.

Both take the seam as each camera saw it. The published MATLAB prototype fitted a degree-7
polynomial y(x) to the detected seam pixels of each image and then either

* ``epipolar_poly7``: intersected the epipolar line of each sample of curve 1 with the polynomial of
  image 2 (one root per line, taken nearest the previous one; no undistortion; no handling of
  stretches along the epipolar lines), then took the midpoint of the two rays; or
* ``closest_rays``: for each sample of curve 1 searched all samples of curve 2 for the pair of rays
  with the smallest gap, and took its midpoint (slow and noisy).

Coordinates: pixels in, 3D points in the base frame (mm) out. Neither method undistorts, as in the
publication (its camera model was pinhole); the lens distortion of the simulated camera is part of
the error they show.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from controller.geometry.camera_model import CameraModel
from controller.geometry.poses import invert

F64 = NDArray[np.float64]


def poly7_curve(px: F64, n: int = 400) -> F64:
    """Fit y = p7(x) to the seam pixels (u, v) and sample it at ``n`` x values over their range."""
    u, v = px[:, 0], px[:, 1]
    scale = max(float(np.ptp(u)), 1.0)
    c = np.polyfit((u - u.mean()) / scale, v, 7)
    us = np.linspace(u.min(), u.max(), n)
    return np.column_stack([us, np.polyval(c, (us - u.mean()) / scale)])


def _rays_pinhole(cam: CameraModel, uv: F64, T_base_cam: F64) -> tuple[F64, F64]:
    x = (uv[:, 0] - cam.cx) / cam.fx
    y = (uv[:, 1] - cam.cy) / cam.fy
    d = np.column_stack([x, y, np.ones(len(uv))])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return T_base_cam[:3, 3].copy(), d @ T_base_cam[:3, :3].T


def _midpoints(o1: F64, d1: F64, o2: F64, d2: F64) -> F64:
    w0 = o1 - o2
    a = np.einsum("ij,ij->i", d1, d1)
    b = np.einsum("ij,ij->i", d1, d2)
    c = np.einsum("ij,ij->i", d2, d2)
    d = np.einsum("ij,ij->i", d1, w0)
    e = np.einsum("ij,ij->i", d2, w0)
    den = a * c - b * b
    den = np.where(np.abs(den) < 1e-12, np.nan, den)
    s = (b * e - c * d) / den
    t = (a * e - b * d) / den
    return 0.5 * ((o1 + s[:, None] * d1) + (o2 + t[:, None] * d2))


def epipolar_poly7(cam: CameraModel, px1: F64, T1: F64, px2: F64, T2: F64, n: int = 400) -> F64:
    """3D seam points (mm) by intersecting epipolar lines with the other image's polynomial."""
    c1, c2 = poly7_curve(px1, n), poly7_curve(px2, 4 * n)
    K = cam.K
    Kinv = np.linalg.inv(K)
    T21 = invert(T2) @ T1
    R, t = T21[:3, :3], T21[:3, 3]
    tx = np.array([[0, -t[2], t[1]], [t[2], 0, -t[0]], [-t[1], t[0], 0]])
    F = Kinv.T @ tx @ R @ Kinv
    h1 = np.column_stack([c1, np.ones(len(c1))])
    lines = h1 @ F.T
    h2 = np.column_stack([c2, np.ones(len(c2))])
    f = lines @ h2.T
    out = np.full((len(c1), 2), np.nan)
    prev = None
    for i in range(len(c1)):
        s = np.flatnonzero(f[i, :-1] * f[i, 1:] <= 0)
        if s.size == 0:
            continue
        j = s[np.argmin(np.abs(s - prev))] if prev is not None else s[0]
        a = f[i, j] / (f[i, j] - f[i, j + 1])
        out[i] = c2[j] * (1 - a) + c2[j + 1] * a
        prev = j
    ok = np.isfinite(out[:, 0])
    o1, d1 = _rays_pinhole(cam, c1[ok], T1)
    o2, d2 = _rays_pinhole(cam, out[ok], T2)
    P = _midpoints(np.broadcast_to(o1, d1.shape), d1, np.broadcast_to(o2, d2.shape), d2)
    return P[np.all(np.isfinite(P), axis=1)]


def closest_rays(cam: CameraModel, px1: F64, T1: F64, px2: F64, T2: F64, n: int = 300) -> F64:
    """3D seam points (mm): per sample of curve 1, the closest ray among all samples of curve 2."""
    c1, c2 = poly7_curve(px1, n), poly7_curve(px2, 3 * n)
    o1, d1 = _rays_pinhole(cam, c1, T1)
    o2, d2 = _rays_pinhole(cam, c2, T2)
    n12 = np.cross(d1[:, None, :], d2[None, :, :])  # (N, M, 3)
    nn = np.linalg.norm(n12, axis=2)
    gap = np.abs(np.einsum("ijk,k->ij", n12, o2 - o1)) / np.maximum(nn, 1e-12)
    j = np.argmin(gap, axis=1)
    return _midpoints(np.broadcast_to(o1, d1.shape), d1, np.broadcast_to(o2, d1.shape), d2[j])
