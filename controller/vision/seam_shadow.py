"""The gap told from a shadow band beside it: a three-edge profile model, decided per seam.

A plate edge standing higher than the other casts a shadow on the lower sheet right beside the
gap; the two-step model of :mod:`controller.vision.seam_profiles` then takes gap + shadow as one
dark band and returns its middle, off the gap's by half the shadow's width. Across such a seam
the profile has four levels and three edges::

    sheet A | B | C | sheet D        (B or C the gap floor, the other the lighter shadow)

:func:`split_shadow` fits this model (all profiles at once, started from the two-step fit) to the
profiles whose dark band is wide enough to hide a shadow, and keeps it for the seam only when the
data ask for it along the seam: most profiles show a darker core at the *same* side of the band,
clearly darker than the rest of the band, and the extra edge lowers the residual well beyond what
two extra parameters fit from noise. The gap is then the darker inner band and its middle is the
centre; the lighter band beside it is not part of the gap.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from controller.vision.scipy_equivalents import erf
from controller.vision.seam_params import F64, DetectParams
from controller.vision.seam_profiles import levenberg_marquardt

#: Narrowest dark band (px) checked for a shadow: below it, half a shadow moves the centre by
#: well under the detector's precision.
MIN_BAND_PX = 3.0
#: Share of the wide profiles that must show the core on the same side of the band.
MIN_SAME_SIDE = 0.7
#: The core's step below the rest of the band, relative to the sheet-to-core contrast (median).
MIN_CORE_STEP = 0.08
#: Residual drop per extra parameter over the residual variance (median F statistic).
MIN_F = 6.0
#: Widest core (median share of the band) taken for a gap beside a shadow.
MAX_CORE_SHARE = 0.4


def _model3(x: F64, prm: F64) -> tuple[F64, F64]:
    """Three blurred steps: value (K, S) and Jacobian (K, S, 8) for (A, B, C, D, e1, e2, e3, s)."""
    A, B, C, D, e1, e2, e3, s = (prm[:, i:i + 1] for i in range(8))
    s = np.maximum(s, 0.15)
    jumps = (B - A, C - B, D - C)
    J = np.empty(np.broadcast_shapes(x.shape, A.shape) + (8,))
    Phi = []
    val = A + 0.0 * x
    dss = 0.0 * val
    for k, (e, h) in enumerate(zip((e1, e2, e3), jumps, strict=True)):
        z = (x - e) / s
        P = 0.5 * (1 + erf(z / np.sqrt(2)))
        g = np.exp(-0.5 * z * z) / np.sqrt(2 * np.pi)
        Phi.append(P)
        val = val + h * P
        J[..., 4 + k] = -h * g / s
        dss = dss - h * g * z / s
    J[..., 0] = 1 - Phi[0]
    J[..., 1] = Phi[0] - Phi[1]
    J[..., 2] = Phi[1] - Phi[2]
    J[..., 3] = Phi[2]
    J[..., 7] = dss
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
    those of the darker core; a profile whose own three-edge fit fails is moved by the seam's
    median core offset relative to its band width. Otherwise ``fit`` is returned unchanged.
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
    prof = fit["profiles"][idx]
    S = prof.shape[1]
    hw = (S - 1) * p.profile_step_px / 2
    x = np.linspace(-hw, hw, S)
    two_w = two[idx]
    three, cost3 = fit_three(x, prof, two_w.copy(), p.fit_iterations)
    cost2 = fit["rms"][idx] ** 2 * S
    A, B, C, D, e1, e2, e3, _ = three.T
    core_left = B < C
    dark, light = np.minimum(B, C), np.maximum(B, C)
    sheet = np.where(core_left, A, D)  # the core's own sheet: the other one is beyond the shadow
    step = (light - dark) / np.maximum(sheet - dark, 1e-6)
    F_stat = (cost2 - cost3) / 2 / np.maximum(cost3 / max(S - 8, 1), 1e-12)
    side = 1 if np.mean(core_left) >= 0.5 else -1
    same = core_left if side == 1 else ~core_left
    core_lo = np.where(core_left, e1, e2)
    core_hi = np.where(core_left, e2, e3)
    core_c, core_w = (core_lo + core_hi) / 2, core_hi - core_lo
    band_c, band_w = two_w[:, 3], two_w[:, 4]
    ok = same & (step > 0.5 * MIN_CORE_STEP) & (core_w > 0.4) & (np.abs(core_c - band_c)
                                                                   < band_w / 2)
    stats["shadow_same_side"] = float(same.mean())
    stats["shadow_core_step"] = float(np.median(step[same])) if same.any() else 0.0
    stats["shadow_f"] = float(np.median(F_stat[same])) if same.any() else 0.0
    stats["shadow_core_share"] = float(np.median(core_w[ok] / band_w[ok])) if ok.any() else 1.0
    if (same.mean() < MIN_SAME_SIDE or stats["shadow_core_step"] < MIN_CORE_STEP
            or stats["shadow_f"] < MIN_F or stats["shadow_core_share"] > MAX_CORE_SHARE
            or ok.sum() < 4):
        return fit, stats
    rel_off = float(np.median((core_c[ok] - band_c[ok]) / band_w[ok]))
    rel_w = stats["shadow_core_share"]
    new_c = np.where(ok, core_c, band_c + rel_off * band_w)
    new_w = np.where(ok, core_w, rel_w * band_w)
    out = dict(fit)
    out["centre"] = fit["centre"].copy()
    out["width"] = fit["width"].copy()
    out["centre"][idx] = fit["centre"][idx] + fit["normal"][idx] * (new_c - band_c)[:, None]
    out["width"][idx] = new_w
    stats["shadow_split"] = 1.0
    return out, stats
