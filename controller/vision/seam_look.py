"""What a seam candidate looks like across and along itself: the numbers the learned check reads.

A joint separates two sheets: the brightness, the texture and the direction of the brushing may
change across it, and it runs until the sheets stop facing each other. A line drawn on one sheet,
a scratch or a line of a table has the same surface on both sides. :func:`look_features` measures
that from a strip of the image straightened along the candidate's centreline (the strip is
sampled every :data:`STEP_PX` along the line, :data:`HALF_PX` to either side), plus what the
refinement already knows (depth, share of fitting profiles, residual, how it ends). The features
are dimensionless (ratios, contrasts, correlations) so that they do not depend on exposure.
"""

from __future__ import annotations

import warnings

import cv2
import numpy as np

from controller.vision.seam_params import F64, Candidate

STEP_PX = 4.0  # along the line
HALF_PX = 40  # across, each side
MAX_SAMPLES = 400  # along: a long line is sampled at a larger step

FEATURE_NAMES = (
    "score", "relative_depth", "valid_fraction", "fit_residual", "log_length", "straightness",
    "n_image_border", "n_sheet_border", "n_open", "n_other_end", "valley_path", "bridged",
    "width_px", "width_spread",
    "side_step_near", "side_step_far", "side_step_sign_steady",
    "texture_ratio_near", "texture_ratio_far", "grain_along_left", "grain_along_right",
    "grain_change", "corr_across_near", "corr_across_far", "centre_contrast",
    "centre_steady", "side_steady",
)


def strip_along(grey: np.ndarray, pts: F64) -> tuple[F64, float]:
    """The image straightened along ``pts`` (K, 2) px: (2*HALF_PX+1, N) linear grey 0..1.

    Row ``HALF_PX`` is the centreline, row ``HALF_PX + d`` is ``d`` px along the left-hand normal;
    columns are ``step`` px apart along the line (returned with it). Outside the image: NaN.
    """
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    step = max(STEP_PX, float(s[-1]) / MAX_SAMPLES)
    q = np.arange(0.0, s[-1] + 1e-9, step)
    c = np.column_stack([np.interp(q, s, pts[:, 0]), np.interp(q, s, pts[:, 1])])
    k = max(1, int(round(12.0 / step)))
    idx = np.arange(len(c))
    t = c[np.clip(idx + k, 0, len(c) - 1)] - c[np.clip(idx - k, 0, len(c) - 1)]
    t /= np.linalg.norm(t, axis=1, keepdims=True) + 1e-12
    n = np.column_stack([-t[:, 1], t[:, 0]])
    d = np.arange(-HALF_PX, HALF_PX + 1, dtype=np.float64)[:, None]
    mx = (c[None, :, 0] + d * n[None, :, 0]).astype(np.float32)
    my = (c[None, :, 1] + d * n[None, :, 1]).astype(np.float32)
    img = grey.astype(np.float32) / 255.0
    out = cv2.remap(img, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                    borderValue=float("nan"))
    return np.asarray(out, dtype=np.float64), step


def _corr(a: F64, b: F64) -> float:
    a, b = a - np.nanmean(a), b - np.nanmean(b)
    den = float(np.sqrt(np.nansum(a * a) * np.nansum(b * b)))
    return float(np.nansum(a * b) / den) if den > 1e-12 else 0.0


def _grain(band: F64) -> float:
    """Share of the gradient energy of ``band`` (rows across, columns along) that is along."""
    ga = np.diff(band, axis=1)[:-1, :]
    gx = np.diff(band, axis=0)[:, :-1]
    ea, ex = float(np.nansum(ga * ga)), float(np.nansum(gx * gx))
    return ea / (ea + ex) if ea + ex > 1e-12 else 0.5


def look_features(grey: np.ndarray, c: Candidate) -> F64:
    """The :data:`FEATURE_NAMES` of a refined candidate ``c`` in ``grey`` (uint8 H x W).

    Distances in full-resolution px of ``grey``; ``c.points`` in the same frame.
    """
    pts = c.points if c.points is not None else c.polyline
    S, _ = strip_along(grey, pts)
    w = float(np.median(c.width)) if c.width is not None and len(c.width) else 3.0
    h = int(min(HALF_PX - 12, max(3, round(w / 2 + 3))))
    near = (slice(HALF_PX + h, HALF_PX + h + 6), slice(HALF_PX - h - 5, HALF_PX - h + 1))
    far = (slice(HALF_PX + h + 14, HALF_PX + h + 26), slice(HALF_PX - h - 25, HALF_PX - h - 13))
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN columns: outside the image
        ln = np.nanmean(S[near[1]], axis=0)  # per column, left side near (negative d)
        rn = np.nanmean(S[near[0]], axis=0)
        lf = np.nanmean(S[far[1]], axis=0)
        rf = np.nanmean(S[far[0]], axis=0)
        centre = np.nanmin(S[HALF_PX - max(1, h - 2): HALF_PX + max(1, h - 2) + 1], axis=0)
        level = float(np.nanmean(np.concatenate([ln, rn]))) + 1e-3
        step_n = (rn - ln) / level
        step_f = (rf - lf) / level
        tex = [float(np.nanstd(np.diff(S[r], axis=1))) + 1e-4 for r in (near[1], near[0],
                                                                           far[1], far[0])]
        grain_l = _grain(S[far[1]])
        grain_r = _grain(S[far[0]])
        sides = 0.5 * (ln + rn)
        cc = (sides - centre) / (sides + 1e-3)
        seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
        length = float(seg.sum())
        chord = pts[-1] - pts[0]
        cn = np.array([-chord[1], chord[0]]) / (np.linalg.norm(chord) + 1e-9)
        straight = float(np.sqrt(np.mean(((pts - pts[0]) @ cn) ** 2))) / (length + 1.0)
        kinds = list(c.end_kinds)
        bridged = float(np.mean(c.bridged)) if c.bridged is not None and len(c.bridged) else 0.0
        wsp = (float(np.subtract(*np.percentile(c.width, [90, 10]))) / (w + 1.0)
               if c.width is not None and len(c.width) else 0.0)
        f = [
            c.score, c.depth, c.valid_frac, c.resid, np.log(length + 1.0), straight,
            kinds.count("image border"), sum(k.endswith("sheet border") for k in kinds),
            kinds.count("open"),
            sum(k != "image border" and not k.endswith("sheet border") and k != "open"
                for k in kinds),
            float(c.way != "profiles"), bridged, w, wsp,
            float(np.nanmedian(np.abs(step_n))), float(np.nanmedian(np.abs(step_f))),
            abs(float(np.nanmean(np.sign(step_n)))),
            abs(np.log(tex[0] / tex[1])), abs(np.log(tex[2] / tex[3])), grain_l, grain_r,
            abs(grain_l - grain_r), _corr(ln, rn), _corr(lf, rf),
            float(np.nanmedian(cc)), float(np.nanstd(cc) / (abs(np.nanmedian(cc)) + 1e-3)),
            float(np.nanstd(sides) / level),
        ]
    out = np.asarray(f, dtype=np.float64)
    return np.where(np.isfinite(out), out, 0.0)
