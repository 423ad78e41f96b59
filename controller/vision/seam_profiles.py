"""Sub-pixel profiles across the seam at full resolution: sampling and the two-edge gap model.

A profile across the curve is sampled by exact bilinear interpolation of the *linearised* image
(not ``cv2.remap``, which quantises coordinates to 1/32 px) and fitted by a model of two blurred
steps (left sheet level, gap floor, right sheet level, centre, width, blur) by Levenberg-Marquardt,
all profiles at once. The centre is the midpoint of the two gap edges, unbiased when the sheets
differ in brightness (the darkness centroid is biased toward the darker sheet by up to 0.3 px).
:func:`track_on` follows a faint stretch of the gap past the coarse candidate's end.
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from controller.vision.scipy_equivalents import norm_cdf_pdf
from controller.vision.seam_params import F64, DetectParams


def linear_lut(gamma: float) -> F64:
    """Grey level (0..255) -> linear radiance (0..1) for a camera response of ``gamma``."""
    return np.asarray((np.arange(256, dtype=np.float64) / 255.0) ** gamma, dtype=np.float64)


def resample(poly: F64, step: float, extend: float) -> tuple[F64, F64]:
    """Points every ``step`` px along ``poly`` (extended by ``extend`` px at both ends), normals."""
    seg = np.linalg.norm(np.diff(poly, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    # Smooth tangents from a chord over ~10 px.
    t0 = poly[min(len(poly) - 1, 6)] - poly[0]
    t1 = poly[-1] - poly[max(0, len(poly) - 7)]
    t0 /= np.linalg.norm(t0) + 1e-12
    t1 /= np.linalg.norm(t1) + 1e-12
    q = np.arange(-extend, s[-1] + extend + 1e-9, step)
    pts = np.column_stack([np.interp(q, s, poly[:, 0]), np.interp(q, s, poly[:, 1])])
    lo, hi = q < 0, q > s[-1]
    pts[lo] = poly[0] + np.outer(q[lo], t0)
    pts[hi] = poly[-1] + np.outer(q[hi] - s[-1], t1)
    k = max(2, int(round(8 / step)))
    tang = np.empty_like(pts)
    idx = np.arange(len(pts))
    a, b = np.clip(idx - k, 0, len(pts) - 1), np.clip(idx + k, 0, len(pts) - 1)
    tang = pts[b] - pts[a]
    tang /= np.linalg.norm(tang, axis=1, keepdims=True) + 1e-12
    normal = np.column_stack([-tang[:, 1], tang[:, 0]])
    return pts, normal


def bilinear(grey: NDArray[np.uint8], lut: F64, u: F64, v: F64) -> tuple[F64, NDArray[np.bool_]]:
    """Linearised image at (``u``, ``v``) by exact bilinear interpolation; which are inside."""
    H, W = grey.shape
    inside = (u >= 0) & (u <= W - 1) & (v >= 0) & (v <= H - 1)
    uc = np.clip(u, 0, W - 1.000001)
    vc = np.clip(v, 0, H - 1.000001)
    u0 = np.floor(uc).astype(np.int64)
    v0 = np.floor(vc).astype(np.int64)
    fu, fv = uc - u0, vc - v0
    i00 = lut[grey[v0, u0]]
    i01 = lut[grey[v0, u0 + 1]]
    i10 = lut[grey[v0 + 1, u0]]
    i11 = lut[grey[v0 + 1, u0 + 1]]
    val = (i00 * (1 - fu) + i01 * fu) * (1 - fv) + (i10 * (1 - fu) + i11 * fu) * fv
    return val, inside


def _model(x: F64, prm: F64) -> tuple[F64, F64]:
    """Two blurred steps: value (K, S) and Jacobian (K, S, 6) for (L, R, F, c, w, s)."""
    L, R, F, c, w, s = (prm[:, i:i + 1] for i in range(6))
    s = np.maximum(s, 0.15)
    z1 = (-(x - c) - w / 2) / s
    z2 = ((x - c) - w / 2) / s
    P1, g1 = norm_cdf_pdf(z1)
    P2, g2 = norm_cdf_pdf(z2)
    val = F + (L - F) * P1 + (R - F) * P2
    J = np.empty(val.shape + (6,))
    J[..., 0] = P1
    J[..., 1] = P2
    J[..., 2] = 1 - P1 - P2
    J[..., 3] = ((L - F) * g1 - (R - F) * g2) / s
    J[..., 4] = (-(L - F) * g1 - (R - F) * g2) / (2 * s)
    J[..., 5] = (-(L - F) * g1 * z1 - (R - F) * g2 * z2) / s
    return val, J


def _fit_profiles(x: F64, prof: F64, iterations: int) -> tuple[F64, F64]:
    """Levenberg-Marquardt fit of :func:`_model` to every profile; returns params, RMS residual."""
    K, S = prof.shape
    n_side = max(3, S // 6)
    L0 = np.median(prof[:, :n_side], axis=1)
    R0 = np.median(prof[:, -n_side:], axis=1)
    sm = cv2.GaussianBlur(prof.astype(np.float32), (0, 0), sigmaX=1.5, sigmaY=0.01).astype(
        np.float64) if S > 4 else prof
    centre_zone = np.abs(x) <= x.max() * 0.6
    zi = np.argmin(np.where(centre_zone[None, :], sm, np.inf), axis=1)
    F0 = prof[np.arange(K), zi]
    c0 = x[zi]
    base = np.maximum(np.minimum(L0, R0), 1e-6)
    area = np.sum(np.clip(base[:, None] - prof, 0, None), axis=1) * (x[1] - x[0])
    w0 = np.clip(area / np.maximum(base - F0, 1e-6), 1.0, 14.0)
    prm = np.column_stack([L0, R0, F0, c0, w0, np.full(K, 1.0)])
    prm, cost = levenberg_marquardt(x, prof, prm, _model, _bound_two, (3, 4), iterations)
    return prm, np.sqrt(cost / S)


def _bound_two(prm: F64) -> F64:
    """Keeps the two-step model's width and blur in range (in place)."""
    prm[:, 4] = np.clip(prm[:, 4], 0.05, 40.0)
    prm[:, 5] = np.clip(prm[:, 5], 0.2, 6.0)
    return prm


def levenberg_marquardt(x: F64, prof: F64, prm: F64, model: Any, bound: Any,
                        moving: tuple[int, ...], iterations: int) -> tuple[F64, F64]:
    """Fit ``model(x, prm) -> (value, Jacobian)`` to every profile (rows of ``prof``) at once.

    ``bound(prm)`` keeps parameters in range; a profile stops once an accepted step moves the
    parameters ``moving`` (positions, px) by under 1e-4 px. Returns (params, residual cost).
    """
    K = prof.shape[0]
    n = prm.shape[1]
    lam = np.full(K, 1e-2)
    val, J = model(x, prm)
    res = prof - val
    cost = np.sum(res * res, axis=1)
    # Only profiles still moving are iterated: most have converged after a few steps, and the
    # model evaluation is most of the detector's time.
    active = np.arange(K)
    mv = list(moving)
    for _ in range(iterations):
        Ja, ra = J[active], res[active]
        A = np.transpose(Ja, (0, 2, 1)) @ Ja
        g = np.einsum("ksp,ks->kp", Ja, ra)
        dg = np.einsum("kii->ki", A)
        A2 = A + (lam[active, None] * (dg + 1e-9))[:, :, None] * np.eye(n)[None]
        try:
            step = np.linalg.solve(A2, g[:, :, None])[:, :, 0]
        except np.linalg.LinAlgError:
            break
        new = bound(prm[active] + step)
        v2, J2 = model(x, new)
        r2 = prof[active] - v2
        c2 = np.sum(r2 * r2, axis=1)
        better = c2 < cost[active]
        idx = active[better]
        prm[idx], J[idx], res[idx], cost[idx] = new[better], J2[better], r2[better], c2[better]
        lam[active] = np.where(better, lam[active] * 0.3, lam[active] * 5.0)
        done = better & np.all(np.abs(step[:, mv]) < 1e-4, axis=1)
        active = active[~done]
        if active.size == 0:
            break
    return prm, cost


def fit_at(grey: NDArray[np.uint8], lut: F64, pts: F64, nrm: F64, p: DetectParams,
           half_width: float | None = None) -> dict[str, Any]:
    """Fit the two-edge gap model to profiles across the curve at ``pts`` along normals ``nrm``.

    Per profile: ``centre`` (px), ``width`` (px), relative ``depth``, ``rms`` and ``contrast``
    (linear radiance), ``valid``, ``too_wide`` (every test passed but the widest gap,
    ``p.max_gap_px``); and what :mod:`controller.vision.seam_shadow` refits: the
    ``normal``, the model ``params`` (L, R, F, c, w, s) and the ``profiles`` (samples every
    ``p.profile_step_px`` from -half width to +half width).
    """
    hw = p.half_width_px if half_width is None else half_width
    x = np.arange(-hw, hw + 1e-9, p.profile_step_px)
    U = pts[:, 0:1] + nrm[:, 0:1] * x[None, :]
    V = pts[:, 1:2] + nrm[:, 1:2] * x[None, :]
    prof, inside = bilinear(grey, lut, U, V)
    prm, rms = _fit_profiles(x, prof, p.fit_iterations)
    L, R, F, cc, w, s = prm.T
    side = np.minimum(L, R)
    depth = (side - np.maximum(F, 0.0)) / np.maximum(side, 1e-6)
    H, W = grey.shape
    centre = pts + nrm * cc[:, None]
    in_img = ((centre[:, 0] >= -0.5) & (centre[:, 0] <= W - 0.5)
              & (centre[:, 1] >= -0.5) & (centre[:, 1] <= H - 0.5))
    fits = ((depth > p.min_profile_depth) & (np.abs(cc) < 8.0) & (w > 0.4) & (s < 4.0)
            & (rms < 0.35 * (side - F) + 0.004) & in_img & inside[:, inside.shape[1] // 2])
    valid = fits & (w < p.max_gap_px)
    return {"valid": valid, "too_wide": fits & ~valid, "centre": centre, "depth": depth,
            "width": w, "rms": rms,
            "contrast": side - F, "left": L, "right": R, "normal": nrm, "params": prm,
            "profiles": prof}


def track_on(grey: NDArray[np.uint8], lut: F64, fit: dict[str, Any], p: DetectParams,
             at_end: bool, chunk: int = 8, max_px: float = 4000.0) -> dict[str, Any]:
    """Extend ``fit`` (from :func:`fit_at`) past one end while the gap profiles keep fitting.

    From the last good centres a quadratic over the sample index predicts the next ``chunk``
    profile positions; they are fitted together and appended. It goes on while most of the last
    ``chunk`` samples are good, so a seam that reaches a sheet or image border (profiles fail
    there) stops at once.
    """
    keys = ("valid", "too_wide", "centre", "depth", "width", "rms", "contrast", "normal", "params",
            "profiles")
    if not at_end:
        fit = {k: fit[k][::-1] for k in keys}
    n_steps = 0
    while n_steps * p.step_px < max_px:
        valid = fit["valid"]
        if len(valid) < 12 or int(valid[-chunk:].sum()) < (chunk * 5 + 7) // 8:
            break
        idx = np.flatnonzero(valid[-16:]) + len(valid) - min(16, len(valid))
        t = idx.astype(np.float64) - (len(valid) - 1)
        cen = fit["centre"][idx]
        coef = np.polyfit(t, cen, 2)
        tq = np.arange(1.0, chunk + 1.0)
        pts = np.polyval(coef, tq[:, None])
        der = np.column_stack([np.polyval(np.polyder(coef[:, k]), tq) for k in range(2)])
        der /= np.linalg.norm(der, axis=1, keepdims=True) + 1e-12
        nrm = np.column_stack([-der[:, 1], der[:, 0]])
        new = fit_at(grey, lut, pts, nrm, p)
        fit = {k: np.concatenate([fit[k], new[k]]) for k in keys}
        n_steps += chunk
    if not at_end:
        fit = {k: fit[k][::-1] for k in keys}
    return fit
