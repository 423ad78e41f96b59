"""The gap told from a shadow band beside it: a three-edge profile model, decided per seam.

A plate edge standing higher than the other casts a shadow on the lower sheet right beside the
gap; the two-step model of :mod:`controller.vision.seam_profiles` then takes gap + shadow as one
dark band and returns its middle, off the gap's by half the shadow's width. Across such a seam
the profile has four levels and three edges::

    sheet A | B | C | sheet D        (B or C the gap floor, the other the lighter shadow)

:func:`split_shadow` fits this model (started from the two-step fit) to up to 64 profiles spread
along the seam among those whose dark band is wide enough to hide a shadow, after a cheap screen
(the two-step residual darker on the same half of the band along the seam), and keeps it for the
seam only when the data ask for it: most profiles show a darker core at the *same* side of the
band, clearly darker than the rest of the band, and the extra edge lowers the residual well beyond
what two extra parameters fit from noise. The gap is then the darker inner band and its middle is
the centre (the core's offset from the band's middle, smoothed and interpolated along the seam);
the lighter band beside it is not part of the gap.

What it cannot tell: a lit cut face inside a wide gap (the far sheet's edge seen through it) looks
the same in one view, a lighter band beside a darker floor; the rule that the core is at most
:data:`MAX_CORE_SHARE` of the band keeps most of those whole, not all (README, seam vision).
Where the job states its gap (``DetectParams.min_gap_px``), a core narrower than the narrowest
gap is such a floor, and the band is kept whole.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from controller.vision.scipy_equivalents import norm_cdf_pdf
from controller.vision.seam_params import F64, DetectParams
from controller.vision.seam_profiles import _model as two_step_model
from controller.vision.seam_profiles import levenberg_marquardt

#: Narrowest dark band (px) checked for a shadow: below it, half a shadow moves the centre by
#: well under the detector's precision.
MIN_BAND_PX = 3.0
#: Share of the wide profiles that must show the core on the same side of the band.
MIN_SAME_SIDE = 0.7
#: The core's step below the rest of the band, relative to the sheet-to-core contrast (median).
MIN_CORE_STEP = 0.08
#: Residual drop per extra parameter over the residual variance (median F statistic).
MIN_F = 4.0
#: Most profiles of one seam fitted by the three-edge model.
MAX_FITTED = 64
#: Widest core (median share of the band) taken for a gap beside a shadow.
MAX_CORE_SHARE = 0.4


def _model3(x: F64, prm: F64) -> tuple[F64, F64]:
    """Three blurred steps: value (K, S) and Jacobian (K, S, 8) for (A, B, C, D, e1, e2, e3, s)."""
    A, B, C, D = (prm[:, i:i + 1] for i in range(4))
    e = prm[:, 4:7].T[:, :, None]  # (3, K, 1)
    s = np.maximum(prm[:, 7:8], 0.15)
    h = np.stack([B - A, C - B, D - C])  # the three steps, (3, K, 1)
    z = (x[None, None, :] - e) / s  # (3, K, S); one erf call for the three edges
    P, g = norm_cdf_pdf(z)
    val = A + np.sum(h * P, axis=0)
    J = np.empty(val.shape + (8,))
    J[..., 0] = 1 - P[0]
    J[..., 1] = P[0] - P[1]
    J[..., 2] = P[1] - P[2]
    J[..., 3] = P[2]
    hg = h * g / s
    J[..., 4:7] = -np.moveaxis(hg, 0, -1)
    J[..., 7] = -np.sum(hg * z, axis=0)
    return val, J


def _bound_three(prm: F64) -> F64:
    """Keeps the edges in order and the blur in range (in place)."""
    prm[:, 7] = np.clip(prm[:, 7], 0.2, 6.0)
    prm[:, 6] = np.maximum(prm[:, 6], prm[:, 4] + 0.5)
    prm[:, 5] = np.clip(prm[:, 5], prm[:, 4] + 0.25, prm[:, 6] - 0.25)
    return prm


def fit_three(x: F64, prof: F64, two: F64, iterations: int) -> tuple[F64, F64]:
    """Fit :func:`_model3` to ``prof`` (K, S) started from the two-step params ``two`` (K, 6).

    The middle edge starts where the darkest point of the band puts it: a narrow gap at one side
    of a wide band has its darkest point there, and the gap is as wide as twice its distance to
    that side's edge. Returns (params (K, 8), residual cost (K,)).
    """
    L, R, F, c, w, s = two.T
    e1, e3 = c - w / 2, c + w / 2
    inside = (x[None, :] > e1[:, None]) & (x[None, :] < e3[:, None])
    xm = x[np.argmin(np.where(inside, prof, np.inf), axis=1)]
    left = xm < c
    e2 = np.where(left, 2 * xm - e1, 2 * xm - e3)
    e2 = np.clip(e2, e1 + 0.5, e3 - 0.5)
    lo_band = (x[None, :] > e1[:, None]) & (x[None, :] < e2[:, None])
    hi_band = (x[None, :] > e2[:, None]) & (x[None, :] < e3[:, None])

    def band_mean(m: Any) -> F64:
        return np.asarray(np.sum(prof * m, axis=1) / np.maximum(m.sum(axis=1), 1), np.float64)

    B = np.where(lo_band.any(axis=1), band_mean(lo_band), F)
    C = np.where(hi_band.any(axis=1), band_mean(hi_band), F)
    prm = np.column_stack([L, B, C, R, e1, e2, e3, s])
    return levenberg_marquardt(x, prof, prm, _model3, _bound_three, (4, 5, 6), iterations)


def split_shadow(fit: dict[str, Any], p: DetectParams) -> tuple[dict[str, Any], dict[str, float]]:
    """``fit`` (from :func:`~controller.vision.seam_profiles.fit_at`), the gap told from a shadow.

    When the seam is lopsided (module doc) the centres and widths of its wide profiles become
    those of the darker core (measured on up to :data:`MAX_FITTED` of them, smoothed and
    interpolated along the seam). Otherwise ``fit`` is returned unchanged.
    Also returns what was measured (for the record): the share of wide profiles, the share with
    the core on the majority side, the median core step and F statistic, and whether it split.
    """
    stats = {"shadow_split": 0.0}
    valid, two = fit["valid"], fit["params"]
    wide = valid & (two[:, 4] >= MIN_BAND_PX)
    n_wide = int(wide.sum())
    stats["shadow_wide"] = n_wide / max(int(valid.sum()), 1)
    if n_wide < 8 or n_wide < 0.3 * valid.sum():
        return fit, stats
    idx = np.flatnonzero(wide)
    # Both tests on at most MAX_FITTED profiles spread along the seam: a shadow changes slowly
    # along it, and the three-edge fit costs as much as the two-step one.
    sub = np.unique(np.linspace(0, len(idx) - 1, min(len(idx), MAX_FITTED)).round().astype(int))
    prof = fit["profiles"][idx[sub]]
    S = prof.shape[1]
    hw = (S - 1) * p.profile_step_px / 2
    x = np.linspace(-hw, hw, S)
    two_w = two[idx]
    two_s = two_w[sub]
    # Cheap screen first: a core at one side leaves the two-step fit too bright on that half of
    # the band and too dark on the other, on the same side along the seam.
    res = prof - two_step_model(x, two_s)[0]
    c2, w2 = two_s[:, 3:4], two_s[:, 4:5]
    half_l = (x[None, :] > c2 - w2 / 2) & (x[None, :] < c2)
    half_r = (x[None, :] > c2) & (x[None, :] < c2 + w2 / 2)
    darker_l = (np.sum(res * half_l, axis=1) / np.maximum(half_l.sum(axis=1), 1)
                < np.sum(res * half_r, axis=1) / np.maximum(half_r.sum(axis=1), 1))
    stats["shadow_screen"] = float(max(darker_l.mean(), 1 - darker_l.mean()))
    if stats["shadow_screen"] < MIN_SAME_SIDE:
        return fit, stats
    three, cost3 = fit_three(x, prof, two_s.copy(), p.fit_iterations)
    core_left, core_c, core_w, step = _cores(three)
    cost2 = fit["rms"][idx[sub]] ** 2 * S
    F_stat = (cost2 - cost3) / 2 / np.maximum(cost3 / max(S - 8, 1), 1e-12)
    side_left = bool(np.mean(core_left) >= 0.5)
    same = core_left == side_left
    band_c, band_w = two_s[:, 3], two_s[:, 4]
    ok = same & _plausible(core_c, core_w, step, band_c, band_w)
    stats["shadow_same_side"] = float(same.mean())
    stats["shadow_core_step"] = float(np.median(step[same])) if same.any() else 0.0
    stats["shadow_f"] = float(np.median(F_stat[same])) if same.any() else 0.0
    stats["shadow_core_share"] = float(np.median(core_w[ok] / band_w[ok])) if ok.any() else 1.0
    if p.min_gap_px > 0 and ok.any() and float(np.median(core_w[ok])) < p.min_gap_px:
        # Narrower than the job's narrowest gap: the core is not the gap but the floor beside a
        # cut face seen inside it (which one view cannot tell from a shadow); the band is the gap.
        stats["shadow_core_under_job_gap"] = 1.0
        return fit, stats
    if (same.mean() < MIN_SAME_SIDE or stats["shadow_core_step"] < MIN_CORE_STEP
            or stats["shadow_f"] < MIN_F or stats["shadow_core_share"] > MAX_CORE_SHARE
            or ok.sum() < 4):
        return fit, stats
    # The seam is lopsided: every wide profile gets its own core; where that fit fails, the
    # core's offset from the band's middle and its width are interpolated along the seam (a
    # running median over the fitted profiles: one fit may catch a texture streak).
    k = sub[ok]
    at = np.arange(len(idx))
    shift = np.interp(at, k, _running_median(core_c[ok] - band_c[ok], 5))
    new_w = np.interp(at, k, _running_median(core_w[ok], 5))
    shift[k], new_w[k] = core_c[ok] - band_c[ok], core_w[ok]
    rest = np.setdiff1d(at, sub)
    if rest.size:
        two_r = two_w[rest]
        cl, cc, cw, st = _cores(fit_three(x, fit["profiles"][idx[rest]], two_r.copy(),
                                          p.fit_iterations)[0])
        good = (cl == side_left) & _plausible(cc, cw, st, two_r[:, 3], two_r[:, 4])
        shift[rest[good]] = cc[good] - two_r[good, 3]
        new_w[rest[good]] = cw[good]
    out = dict(fit)
    out["centre"] = fit["centre"].copy()
    out["width"] = fit["width"].copy()
    out["centre"][idx] = fit["centre"][idx] + fit["normal"][idx] * shift[:, None]
    out["width"][idx] = new_w
    stats["shadow_split"] = 1.0
    return out, stats


def _cores(three: F64) -> tuple[NDArray[np.bool_], F64, F64, F64]:
    """Per three-edge fit: the core (darker inner band) on the left?, its centre, width (px), step.

    The step is the core's depth below the other inner band relative to the core's own sheet.
    """
    A, B, C, D, e1, e2, e3, _ = three.T
    left = B < C
    dark = np.minimum(B, C)
    sheet = np.where(left, A, D)  # the core's own sheet: the other one is beyond the shadow
    step = (np.maximum(B, C) - dark) / np.maximum(sheet - dark, 1e-6)
    lo, hi = np.where(left, e1, e2), np.where(left, e2, e3)
    return left, (lo + hi) / 2, hi - lo, step


def _plausible(core_c: F64, core_w: F64, step: F64, band_c: F64, band_w: F64) -> NDArray[np.bool_]:
    """Cores that are a gap: clearly darker, not vanishing, inside the two-step band."""
    return np.asarray((step > 0.5 * MIN_CORE_STEP) & (core_w > 0.4)
                      & (np.abs(core_c - band_c) < band_w / 2))


def _running_median(v: F64, n: int) -> F64:
    """Median of each sample and its neighbours over ``n`` (odd) samples, the ends repeated."""
    h = n // 2
    padded = np.pad(v, h, mode="edge")
    return np.asarray(np.median(np.lib.stride_tricks.sliding_window_view(padded, n), axis=1))
