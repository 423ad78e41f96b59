"""Find the weld joint in one image: an ordered sub-pixel centreline with a confidence and reasons.

The joint is a thin dark valley with a sheet on each side, running from one sheet border to the
other. Sheet borders, table holes, marker dots, clutter and glare give edges as strong as the
joint's, so this looks for the *shape*, not for edges:

1. **Coarse search** on the image shrunk by ``coarse_factor`` (box average, so a thin gap stays
   visible as a dip): linearise the grey levels (camera response ``gamma``) and compute, in four
   directions, the *relative valley depth* ``(min(I(p + r n), I(p - r n)) - I(p)) / min(...)``.
   It is high only where both sides are brighter than the centre: a step edge (sheet border), a
   dot or a wide dark band give ~0, and dividing by the local brightness makes it independent of
   uneven light and glare (adaptive rather than a fixed threshold).
2. **Candidates**: connected components of the thresholded depth, long ones kept; each becomes an
   ordered polyline by binning its pixels along its principal axis (any orientation in the image;
   the curve must be monotonic along some direction: straight seams, arcs up to a half circle,
   S-curves).
3. **Sub-pixel refinement at full resolution**, only along the candidate: a profile across the
   curve every ``step_px`` pixels, sampled by exact bilinear interpolation of the *linearised*
   image (not ``cv2.remap``, which quantises coordinates to 1/32 px), is fitted by a model of two
   blurred steps (left sheet level, gap floor, right sheet level, centre, width, blur). The centre
   is the midpoint of the two gap edges, which is unbiased when the sheets differ in brightness,
   unlike the darkness centroid (biased toward the darker sheet by up to 0.3 px).
4. **Curve and ends**: the longest run of good profiles (short interruptions by a crossing
   scratch are bridged) gives honest end points; outliers are dropped and the centreline is
   smoothed by a local quadratic (Savitzky-Golay) fit over arc length, which follows any shape
   without the curling of a global polynomial and without shrinking curves.
5. **Decision**: no candidate that passes -> :class:`SeamNotFound`; two of similar strength ->
   :class:`AmbiguousSeam`; both carry what was seen in ``details``.

Pixels are (u, v) = (column, row), origin at the centre of the top-left pixel, in the *distorted*
image (undistort with ``CameraModel.pixels_to_normalized``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.interpolate import CubicSpline
from scipy.signal import savgol_filter
from scipy.special import erf

from controller.camera_model import CameraModel
from controller.errors import AmbiguousSeam, InputError, SeamNotFound

F64 = NDArray[np.float64]
F32 = NDArray[np.float32]
_MIN_STEP = 0.25  # relative brightness step that marks a sheet border


@dataclass(frozen=True)
class DetectParams:
    """Tuning of :func:`detect_seam` (pixel values at full resolution unless named ``coarse``).

    ``gamma``: camera response used to linearise grey levels (1.0 for a linear camera).
    ``coarse_factor``: shrink factor of the search image (0: automatic, ~560 px wide).
    ``valley_r_coarse``: distance (coarse px) from the valley centre to where both sides are read.
    ``min_depth``: relative valley depth that marks a candidate pixel (0..1).
    ``min_length_px``: shortest candidate kept (px along the curve).
    ``step_px``: spacing of the refinement profiles along the seam; ``half_width_px``: half
    length of each profile. ``max_gap_px``: widest gap accepted. ``ambiguity_ratio``: a second
    candidate at least this strong relative to the best makes the result ambiguous.
    ``min_confidence``: below this the detection is refused (:class:`SeamNotFound`); an open end
    caps the confidence at 0.45, so a seam not seen to a border is refused by default.
    """

    gamma: float = 2.2
    coarse_factor: int = 0
    valley_r_coarse: int = 3
    min_depth: float = 0.2
    min_length_px: float = 300.0
    step_px: float = 4.0
    half_width_px: float = 14.0
    profile_step_px: float = 1.0
    fit_iterations: int = 7
    max_gap_px: float = 16.0
    min_profile_depth: float = 0.25
    bridge_px: float = 200.0
    join_px: float = 200.0
    ambiguity_ratio: float = 0.6
    min_confidence: float = 0.5
    max_candidates: int = 4


@dataclass(frozen=True)
class SeamDetection:
    """A seam found in one image.

    ``points_px`` (K, 2) float64 sub-pixel centreline (u, v), ordered from one end to the other
    (the end nearer the image's left border first, or the top one for a vertical seam);
    ``endpoints_px`` (2, 2) its first and last point; ``width_px`` (K,) the fitted gap width;
    ``confidence`` 0..1; ``reasons`` human-readable lines saying why; ``stats`` numbers behind it.
    """

    points_px: F64
    confidence: float
    reasons: list[str]
    endpoints_px: F64
    width_px: F64
    stats: dict[str, Any] = field(default_factory=dict)

    def to_dict(self, decimals: int = 3) -> dict[str, Any]:
        """JSON-ready dictionary: ``seam_px``, ``endpoints_px``, ``confidence``, ``reasons``..."""
        return {
            "seam_px": np.round(self.points_px, decimals).tolist(),
            "endpoints_px": np.round(self.endpoints_px, decimals).tolist(),
            "confidence": round(float(self.confidence), 4),
            "reasons": list(self.reasons),
            "gap_width_px": round(float(np.median(self.width_px)), 3),
            "stats": {k: (round(v, 4) if isinstance(v, float) else v)
                      for k, v in self.stats.items()},
        }


@dataclass
class _Candidate:
    polyline: F64  # ordered coarse centreline, full-res px
    coarse_score: float
    length_px: float
    points: F64 | None = None
    width: F64 | None = None
    depth: float = 0.0
    valid_frac: float = 0.0
    resid: float = 0.0
    score: float = 0.0
    end_kinds: tuple[str, str] = ("open", "open")
    why_rejected: str = ""


# ---------------------------------------------------------------------------------------------
# Public entry
# ---------------------------------------------------------------------------------------------
def detect_seam(image: NDArray[Any], *, camera: CameraModel | None = None,
                roi: tuple[int, int, int, int] | None = None, hint: ArrayLike | None = None,
                params: DetectParams | None = None) -> SeamDetection:
    """Find the seam in ``image`` (uint8, greyscale HxW or BGR HxWx3) and return its centreline.

    ``camera``: when given, the image size must match it (a wrong-size image is an
    :class:`InputError`). ``roi``: (x0, y0, x1, y1) pixel box to search in (end exclusive).
    ``hint``: a nominal seam polyline (N, 2) px from the job; candidates further than 60 px (mean)
    from it are ignored. Raises :class:`SeamNotFound` (no candidate passes), :class:`AmbiguousSeam`
    (two candidates of similar strength), :class:`InputError` (not a uint8 image, wrong size, bad
    ROI).
    """
    p = params or DetectParams()
    grey = _as_grey(image)
    H, W = grey.shape
    if camera is not None and (camera.width, camera.height) != (W, H):
        raise InputError(f"image is {W}x{H} px but the calibration is for "
                         f"{camera.width}x{camera.height}; use the calibration of this camera "
                         "(or resize the image back to the calibrated size)",
                         image_size=[W, H], calibration_size=[camera.width, camera.height])
    x0, y0, x1, y1 = _check_roi(roi, W, H)
    sub = grey[y0:y1, x0:x1]
    lut = _linear_lut(p.gamma)
    hint_arr = None if hint is None else np.asarray(hint, dtype=np.float64).reshape(-1, 2)
    if hint_arr is not None:
        hint_arr = hint_arr - [x0, y0]
    cands, seen = _coarse_candidates(sub, lut, p)
    if hint_arr is not None:
        cands = [c for c in cands if _mean_dist(c.polyline, hint_arr) < 60.0]
    for c in cands[: p.max_candidates]:
        _refine(sub, lut, c, p)
    good = sorted([c for c in cands[: p.max_candidates] if not c.why_rejected],
                  key=lambda c: -c.score)
    rejected = [c.why_rejected for c in cands[: p.max_candidates] if c.why_rejected]
    details: dict[str, Any] = {"candidates_seen": seen, "roi": [x0, y0, x1, y1],
                               "rejected": rejected}
    if not good:
        raise SeamNotFound(
            f"no weld seam found in the image ({len(cands)} candidate(s) looked at: "
            + ("; ".join(rejected) or "no thin dark valley long enough")
            + "); check that the joint is in view, in focus and lit, or give a --roi", **details)
    best = good[0]
    second = good[1] if len(good) > 1 else None
    ratio = (second.score / best.score) if second is not None else 0.0
    if second is not None and ratio >= p.ambiguity_ratio:
        raise AmbiguousSeam(
            f"two seam candidates of similar strength (score {best.score:.0f} vs "
            f"{second.score:.0f}, ratio {ratio:.2f}); refusing to choose: give a --roi or a "
            "nominal seam hint", best_px=_summary(best, x0, y0),
            second_px=_summary(second, x0, y0), **details)
    assert best.points is not None and best.width is not None
    conf, reasons = _confidence(best, ratio)
    if conf < p.min_confidence:
        raise SeamNotFound(f"best seam candidate too weak (confidence {conf:.2f}): "
                           + "; ".join(reasons), confidence=conf, reasons=reasons, **details)
    pts = best.points + [x0, y0]
    pts = _orient(pts)
    width = best.width if np.allclose(pts[0], best.points[0] + [x0, y0]) else best.width[::-1]
    stats = {"length_px": float(np.sum(np.linalg.norm(np.diff(pts, axis=0), axis=1))),
             "valid_fraction": float(best.valid_frac), "relative_depth": float(best.depth),
             "fit_residual": float(best.resid), "second_best_ratio": float(ratio),
             "candidates": len(cands)}
    return SeamDetection(points_px=pts, confidence=conf, reasons=reasons,
                         endpoints_px=np.array([pts[0], pts[-1]]), width_px=width, stats=stats)


# ---------------------------------------------------------------------------------------------
# Input checks
# ---------------------------------------------------------------------------------------------
def _as_grey(image: NDArray[Any]) -> NDArray[np.uint8]:
    img = np.asarray(image)
    if img.dtype != np.uint8:
        raise InputError(f"detect_seam needs a uint8 image, got dtype {img.dtype}; load 8-bit "
                         "images (controller.image_io.load_image)")
    if img.ndim == 3 and img.shape[2] == 3:
        return np.asarray(cv2.cvtColor(img, cv2.COLOR_BGR2GRAY), dtype=np.uint8)
    if img.ndim == 3 and img.shape[2] == 1:
        return img[:, :, 0]
    if img.ndim != 2:
        raise InputError(f"detect_seam needs a greyscale (H, W) or BGR (H, W, 3) image, got "
                         f"shape {img.shape}")
    if min(img.shape) < 32:
        raise InputError(f"image {img.shape[1]}x{img.shape[0]} px is too small to hold a seam "
                         "(at least 32 px each way)")
    return img


def _check_roi(roi: Any, W: int, H: int) -> tuple[int, int, int, int]:
    if roi is None:
        return 0, 0, W, H
    try:
        x0, y0, x1, y1 = (int(v) for v in roi)
    except (TypeError, ValueError) as err:
        raise InputError(f"roi must be four integers x0,y0,x1,y1, got {roi!r}") from err
    x0, y0 = max(x0, 0), max(y0, 0)
    x1, y1 = min(x1, W), min(y1, H)
    if x1 - x0 < 32 or y1 - y0 < 32:
        raise InputError(f"roi {list(roi)} leaves {max(x1 - x0, 0)}x{max(y1 - y0, 0)} px of the "
                         f"{W}x{H} image; give a box of at least 32x32 px inside the image")
    return x0, y0, x1, y1


def _linear_lut(gamma: float) -> F64:
    """Grey level (0..255) -> linear radiance (0..1) for a camera response of ``gamma``."""
    return np.asarray((np.arange(256, dtype=np.float64) / 255.0) ** gamma, dtype=np.float64)


# ---------------------------------------------------------------------------------------------
# Coarse search
# ---------------------------------------------------------------------------------------------
def _coarse_candidates(grey: NDArray[np.uint8], lut: F64,
                       p: DetectParams) -> tuple[list[_Candidate], int]:
    H, W = grey.shape
    f = p.coarse_factor or max(1, min(6, int(round(W / 560))))
    small = grey if f == 1 else cv2.resize(grey, (W // f, H // f), interpolation=cv2.INTER_AREA)
    # No smoothing: a thin gap is at most a pixel wide here and blurring halves its depth.
    img = lut.astype(np.float32)[small]
    r = p.valley_r_coarse
    rd = max(1, int(round(r / np.sqrt(2))))
    best = np.zeros_like(img)
    pad = cv2.copyMakeBorder(img, r, r, r, r, cv2.BORDER_REPLICATE)
    h, w = img.shape
    for dy, dx in ((0, r), (r, 0), (rd, rd), (rd, -rd)):
        a = pad[r + dy:r + dy + h, r + dx:r + dx + w]
        b = pad[r - dy:r - dy + h, r - dx:r - dx + w]
        side = np.minimum(a, b)
        depth = (side - img) / (side + 0.01)
        np.maximum(best, depth, out=best)
    mask = (best > p.min_depth).astype(np.uint8)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    cands: list[_Candidate] = []
    min_len_c = p.min_length_px / f
    idx = [i for i in range(1, n)
           if np.hypot(stats[i, cv2.CC_STAT_WIDTH], stats[i, cv2.CC_STAT_HEIGHT]) >= min_len_c]
    for i in idx:
        x, y, ww, hh = stats[i, :4]
        sl = labels[y:y + hh, x:x + ww] == i
        ys, xs = np.nonzero(sl)
        wts = best[y:y + hh, x:x + ww][sl]
        poly = _order_pixels(xs + x, ys + y, wts)
        if poly is None:
            continue
        poly_full = (poly + 0.5) * f - 0.5
        length = float(np.sum(np.linalg.norm(np.diff(poly_full, axis=0), axis=1)))
        if length < p.min_length_px:
            continue
        cands.append(_Candidate(poly_full, float(np.sum(wts)) * f, length))
    cands = _join_candidates(cands, p.join_px)
    cands.sort(key=lambda c: -c.coarse_score)
    return cands, len(idx)


def _join_candidates(cands: list[_Candidate], join_px: float) -> list[_Candidate]:
    """Join candidates that continue each other across a short hole (glare, a dot on the seam)."""
    cos_max = np.cos(np.radians(25.0))

    def end_dir(poly: F64, at_end: bool) -> tuple[F64, F64]:
        n = min(len(poly) - 1, 10)
        e, q = (poly[-1], poly[-1 - n]) if at_end else (poly[0], poly[n])
        t = e - q
        return e, t / (np.linalg.norm(t) + 1e-12)

    merged = True
    while merged and len(cands) > 1:
        merged = False
        for i in range(len(cands)):
            for j in range(i + 1, len(cands)):
                a, b = cands[i].polyline, cands[j].polyline
                for a_end in (True, False):
                    for b_end in (False, True):
                        ea, ta = end_dir(a, a_end)
                        eb, tb = end_dir(b, b_end)
                        v = eb - ea
                        d = float(np.linalg.norm(v))
                        if d > join_px:
                            continue
                        v = v / (d + 1e-12)
                        if d > 3 and (ta @ v < cos_max or tb @ -v < cos_max):
                            continue
                        pa = a if a_end else a[::-1]
                        pb = b[::-1] if b_end else b
                        cands[i] = _Candidate(np.vstack([pa, pb]),
                                              cands[i].coarse_score + cands[j].coarse_score,
                                              cands[i].length_px + cands[j].length_px + d)
                        del cands[j]
                        merged = True
                        break
                    if merged:
                        break
                if merged:
                    break
            if merged:
                break
    return cands


def _order_pixels(xs: NDArray[Any], ys: NDArray[Any], w: NDArray[Any]) -> F64 | None:
    """Ordered polyline through a thin blob: the strongest pixel per bin along its main axis."""
    P = np.column_stack([xs, ys]).astype(np.float64)
    c = np.average(P, axis=0, weights=w)
    cov = np.cov((P - c).T, aweights=w)
    evals, evecs = np.linalg.eigh(cov)
    axis, perp = evecs[:, 1], evecs[:, 0]
    s = (P - c) @ axis
    o = (P - c) @ perp
    bins = np.floor((s - s.min()) / 1.5).astype(np.int64)
    nb = int(bins.max()) + 1
    if nb < 8:
        return None
    # Per bin, split the pixels into clusters of offsets (a crossing pen line or scratch adds a
    # second cluster), then track the curve bin by bin from its strongest single-cluster bin,
    # choosing the cluster that continues it (a branch is left behind).
    order = np.lexsort((o, bins))
    bo, oo, wo = bins[order], o[order], w[order]
    new_cluster = np.ones(len(order), bool)
    new_cluster[1:] = (bo[1:] != bo[:-1]) | (np.diff(oo) > 1.5)
    cid = np.cumsum(new_cluster) - 1
    cw = np.asarray(np.bincount(cid, weights=wo), dtype=np.float64)
    co = np.bincount(cid, weights=wo * oo) / cw
    cb = bo[new_cluster]
    starts_idx = np.flatnonzero(new_cluster)
    cmin = np.minimum.reduceat(oo, starts_idx)
    cmax = np.maximum.reduceat(oo, starts_idx)
    per_bin: dict[int, list[int]] = {}
    for k, b in enumerate(cb.tolist()):
        per_bin.setdefault(b, []).append(k)
    keys = sorted(per_bin)
    single = [b for b in keys if len(per_bin[b]) == 1] or keys
    best_track: dict[int, float] = {}
    best_w = -1.0
    # Several starts (a start on a junction with a branch can lose the curve); keep the strongest.
    for q in (0.5, 0.2, 0.8):
        start_bin = single[int(q * (len(single) - 1))]
        track = _track_bins(keys, per_bin, co, cw, cmin, cmax, start_bin)
        tw = float(len(track))
        if tw > best_w:
            best_track, best_w = track, tw
        if best_w >= 0.9 * len(keys):
            break  # the whole blob is one curve: no need to start elsewhere
    chosen = best_track
    kb = sorted(chosen)
    if len(kb) < 8:
        return None
    sb = (np.asarray(kb, np.float64) + 0.5) * 1.5 + s.min()
    ob = np.asarray([chosen[b] for b in kb])
    return np.asarray(c + np.outer(sb, axis) + np.outer(ob, perp))


def _track_bins(keys: list[int], per_bin: dict[int, list[int]], co: F64, cw: F64, cmin: F64,
                cmax: F64, start_bin: int) -> dict[int, float]:
    """Follow one curve through the bins from ``start_bin``: bin -> offset on the curve.

    The next offset is predicted by a line through the last few accepted ones; in each bin the
    cluster nearest the prediction is taken. Where a crossing line has merged with the curve
    into one wide cluster, the prediction clipped to the cluster is used instead of its mean.
    """
    si = keys.index(start_bin)
    k0 = max(per_bin[start_bin], key=lambda k: cw[k])
    chosen = {start_bin: float(co[k0])}
    for direction in (1, -1):
        hb, ho = [float(start_bin)], [float(co[k0])]
        i = si + direction
        while 0 <= i < len(keys):
            b = keys[i]
            if abs(b - hb[-1]) > 12:
                break  # a long hole: the curve ends here
            if len(hb) >= 3:
                # Least-squares line through the last 8 accepted points (plain floats: fast).
                xs, ys = hb[-8:], ho[-8:]
                mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
                sxx = sum((x - mx) ** 2 for x in xs)
                sxy = sum((x - mx) * (y - my) for x, y in zip(xs, ys, strict=True))
                pred = my + (sxy / sxx if sxx > 0 else 0.0) * (b - mx)
            else:
                pred = ho[-1]
            k = min(per_bin[b], key=lambda k: max(cmin[k] - pred, pred - cmax[k], 0.0))
            off = float(co[k]) if cmax[k] - cmin[k] < 2.5 else float(np.clip(pred, cmin[k],
                                                                              cmax[k]))
            if abs(off - pred) <= 2.0 + 0.3 * abs(b - hb[-1]):
                chosen[b] = off
                hb.append(float(b))
                ho.append(off)
            i += direction
    return chosen


def _running_median(x: F64, k: int) -> F64:
    h = k // 2
    xp = np.pad(x, h, mode="edge")
    win = np.lib.stride_tricks.sliding_window_view(xp, k)
    return np.asarray(np.median(win, axis=1))


def _mean_dist(poly: F64, ref: F64) -> float:
    d = np.linalg.norm(poly[::4, None, :] - ref[None, ::max(1, len(ref) // 200), :], axis=2)
    return float(d.min(axis=1).mean())


# ---------------------------------------------------------------------------------------------
# Sub-pixel refinement
# ---------------------------------------------------------------------------------------------
def _resample(poly: F64, step: float, extend: float) -> tuple[F64, F64]:
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


def _bilinear(grey: NDArray[np.uint8], lut: F64, u: F64, v: F64) -> tuple[F64, NDArray[np.bool_]]:
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
    P1 = 0.5 * (1 + erf(z1 / np.sqrt(2)))
    P2 = 0.5 * (1 + erf(z2 / np.sqrt(2)))
    g1 = np.exp(-0.5 * z1 * z1) / np.sqrt(2 * np.pi)
    g2 = np.exp(-0.5 * z2 * z2) / np.sqrt(2 * np.pi)
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
    lam = np.full(K, 1e-2)
    val, J = _model(x, prm)
    res = prof - val
    cost = np.sum(res * res, axis=1)
    for _ in range(iterations):
        JT = np.transpose(J, (0, 2, 1))
        A = JT @ J
        g = np.einsum("ksp,ks->kp", J, res)
        dg = np.einsum("kii->ki", A)
        A2 = A + (lam[:, None] * (dg + 1e-9))[:, :, None] * np.eye(6)[None]
        try:
            step = np.linalg.solve(A2, g[:, :, None])[:, :, 0]
        except np.linalg.LinAlgError:
            break
        new = prm + step
        new[:, 4] = np.clip(new[:, 4], 0.05, 40.0)
        new[:, 5] = np.clip(new[:, 5], 0.2, 6.0)
        v2, J2 = _model(x, new)
        r2 = prof - v2
        c2 = np.sum(r2 * r2, axis=1)
        better = c2 < cost
        prm[better], J[better], res[better], cost[better] = new[better], J2[better], r2[better], \
            c2[better]
        lam = np.where(better, lam * 0.3, lam * 5.0)
    return prm, np.sqrt(cost / S)


def _fit_at(grey: NDArray[np.uint8], lut: F64, pts: F64, nrm: F64, p: DetectParams,
            half_width: float | None = None) -> dict[str, Any]:
    """Fit the two-edge gap model to profiles across the curve at ``pts`` along normals ``nrm``."""
    hw = p.half_width_px if half_width is None else half_width
    x = np.arange(-hw, hw + 1e-9, p.profile_step_px)
    U = pts[:, 0:1] + nrm[:, 0:1] * x[None, :]
    V = pts[:, 1:2] + nrm[:, 1:2] * x[None, :]
    prof, inside = _bilinear(grey, lut, U, V)
    prm, rms = _fit_profiles(x, prof, p.fit_iterations)
    L, R, F, cc, w, s = prm.T
    side = np.minimum(L, R)
    depth = (side - np.maximum(F, 0.0)) / np.maximum(side, 1e-6)
    H, W = grey.shape
    centre = pts + nrm * cc[:, None]
    in_img = ((centre[:, 0] >= -0.5) & (centre[:, 0] <= W - 0.5)
              & (centre[:, 1] >= -0.5) & (centre[:, 1] <= H - 0.5))
    valid = ((depth > p.min_profile_depth) & (np.abs(cc) < 8.0) & (w > 0.4)
             & (w < p.max_gap_px) & (s < 4.0) & (rms < 0.35 * (side - F) + 0.004) & in_img
             & inside[:, inside.shape[1] // 2])
    return {"valid": valid, "centre": centre, "depth": depth, "width": w, "rms": rms,
            "contrast": side - F}


def _refine(grey: NDArray[np.uint8], lut: F64, c: _Candidate, p: DetectParams) -> None:
    pts, nrm = _resample(c.polyline, p.step_px, extend=24.0)
    fit = _fit_at(grey, lut, pts, nrm, p)
    # The coarse search loses a faint stretch of the gap (thin, blurred, low contrast); the
    # profiles still see it, so follow it on at full resolution until they stop fitting.
    fit = _track_on(grey, lut, fit, p, at_end=True)
    fit = _track_on(grey, lut, fit, p, at_end=False)
    valid = fit["valid"]
    if valid.sum() >= 8:
        # Where a mark crosses the seam at a shallow angle the two valleys merge into one wide
        # one whose centre is pulled toward the mark: not a measurement of the gap.
        w_typ = float(np.median(fit["width"][valid]))
        valid = valid & (fit["width"] < 1.6 * w_typ + 1.0)
    # Longest run of valid profiles, bridging short interruptions; short islands at its ends are
    # dropped (a lone fit on the sheet border beyond the seam's end is not the seam).
    bridge = int(round(p.bridge_px / p.step_px))
    run = _longest_bridged_run(valid, bridge, min_island=max(3, int(round(12 / p.step_px))))
    if run is None or (run[1] - run[0]) * p.step_px < p.min_length_px * 0.5:
        c.why_rejected = (f"candidate of {c.length_px:.0f} px has no long run of gap profiles "
                          f"({int(valid.sum())} of {len(valid)} good)")
        return
    i0, i1 = run
    sel = np.arange(i0, i1 + 1)
    ok = valid[sel]
    pts_run = fit["centre"][sel].copy()
    t = np.arange(len(sel), dtype=np.float64)
    if (~ok).any():
        # Bridged samples (a hole in the gap) follow a cubic through the measured ones.
        pts_run[~ok] = CubicSpline(t[ok], pts_run[ok], axis=0)(t[~ok])
    win = int(min((len(sel) - 1) // 2 * 2 + 1, 2 * int(round(14 / p.step_px)) + 1))
    if win >= 5:
        sm = savgol_filter(pts_run, win, 2, axis=0, mode="interp")
        dev = np.linalg.norm(pts_run - sm, axis=1)
        mad = np.median(dev[ok]) + 1e-6
        good = ok & (dev < max(4 * mad, 0.6))
        if (~good).any():
            pts_run[~good] = CubicSpline(t[good], pts_run[good], axis=0)(t[~good])
        pts_run = savgol_filter(pts_run, win, 2, axis=0, mode="interp")
    depth_med = float(np.median(fit["depth"][sel][ok]))
    # Honest ends: where the sheets end (or the image does), found from the two sides separately.
    # Profiles within a profile length of an end may be crossed by the sheet border, so the
    # last stretch of the curve is extrapolated from the samples before it, only to guide short
    # profiles that measure it again (:func:`_measure_tail`): a quadratic extrapolated over tens
    # of pixels drifts by 1-2 px on a curve.
    w_med = float(np.median(fit["width"][sel][ok]))
    w_run = fit["width"][sel]
    m = int(np.ceil(p.half_width_px / p.step_px)) + 1
    n_fit = 12
    use_extrap = len(pts_run) >= 2 * (m + n_fit)
    parts: list[F64] = []
    end_kinds: list[str] = []
    lo, hi = 0, len(pts_run)
    for first in (True, False):
        seq = pts_run if not first else pts_run[::-1]  # seq runs toward this end
        L = len(seq)
        if use_extrap:
            tt = np.arange(L - m - n_fit, L - m, dtype=np.float64)
            coef = np.polyfit(tt - (L - 1), seq[L - m - n_fit:L - m], 2)
            e_pt = np.array([np.polyval(coef[:, k], 0.0) for k in range(2)])
            d_pt = np.array([np.polyval(np.polyder(coef[:, k]), 0.0) for k in range(2)])
            tang = d_pt / (np.linalg.norm(d_pt) + 1e-12)
        else:
            e_pt = seq[-1]
            tang = seq[-1] - seq[max(0, L - 4)]
            tang /= np.linalg.norm(tang) + 1e-12
        k_end, end_kind = _end_offset(grey, lut, e_pt, tang, w_med)
        end_kinds.append(end_kind)
        if use_extrap:
            # Extrapolated points from the last trusted sample to the end, one per step.
            t_end = k_end / max(float(np.linalg.norm(d_pt)), 1e-9)
            tq = np.arange(-m + 1.0, t_end, 1.0)
            tq = np.append(tq, t_end)
            ext = np.column_stack([np.polyval(coef[:, k], tq) for k in range(2)])
            der = np.column_stack([np.polyval(np.polyder(coef[:, k]), tq) for k in range(2)])
            ext = _measure_tail(grey, lut, ext, der, w_med, p)
            keep_n = L - m
        else:
            ext = (e_pt + k_end * tang)[None, :]
            along = (seq - e_pt) @ tang
            keep_n = int(np.sum(along < k_end - 0.5 * p.step_px))
        if first:
            lo = L - keep_n
            parts.insert(0, ext[::-1])
        else:
            hi = keep_n
            parts.append(ext)
    c.end_kinds = (end_kinds[0], end_kinds[1])
    if hi - lo < 2:
        c.why_rejected = "seam candidate collapsed when its ends were measured"
        return
    body = pts_run[lo:hi]
    pts_run = np.vstack([parts[0], body, parts[1]])
    c.points = pts_run
    wb = w_run[lo:hi]
    c.width = np.concatenate([np.full(len(parts[0]), wb[0]), wb, np.full(len(parts[1]), wb[-1])])
    c.depth = depth_med
    c.valid_frac = float(ok.mean())
    c.resid = float(np.median(fit["rms"][sel][ok] / np.maximum(fit["contrast"][sel][ok], 1e-6)))
    length = float(np.sum(np.linalg.norm(np.diff(pts_run, axis=0), axis=1)))
    if length < p.min_length_px:
        c.why_rejected = f"gap run only {length:.0f} px long (< {p.min_length_px:.0f})"
        return
    c.length_px = length
    if c.end_kinds == ("open", "open"):
        c.why_rejected = (f"dark line of {length:.0f} px fades out inside the sheet at both ends "
                          "(a pen mark or scratch, not a joint running border to border)")
        return
    c.score = length * c.depth * c.valid_frac


def _measure_tail(grey: NDArray[np.uint8], lut: F64, guide: F64, der: F64, w_med: float,
                  p: DetectParams) -> F64:
    """Measure the last stretch of the seam (``guide``, extrapolated toward its end) again.

    Profiles of full length there may be crossed by the sheet border, so the stretch was
    extrapolated; an extrapolation over tens of pixels drifts on a curve. Short profiles (just
    wider than the gap) are not reached by the border until the end itself: where they fit the
    gap near the guide they replace it; within a profile length of the end (where even a short
    profile may reach past the border) the guide is shifted by the offset measured last.
    """
    tang = der / (np.linalg.norm(der, axis=1, keepdims=True) + 1e-12)
    nrm = np.column_stack([-tang[:, 1], tang[:, 0]])
    hw = max(6.0, w_med / 2 + 5.0)
    fit = _fit_at(grey, lut, guide, nrm, p, half_width=hw)
    off = np.einsum("kd,kd->k", fit["centre"] - guide, nrm)
    seg = np.linalg.norm(np.diff(guide, axis=0), axis=1)
    to_end = np.concatenate([np.cumsum(seg[::-1])[::-1], [0.0]])
    # A profile within its own length of the end may reach past the border: not used.
    ok = (fit["valid"] & (np.abs(off) < 2.0) & (fit["width"] < 1.6 * w_med + 1.0)
          & (to_end >= hw + 3.0))
    if not ok.any():
        return guide
    idx = np.arange(len(guide), dtype=np.float64)
    # Offsets from the guide along the stretch: measured where the profiles fit, linear between,
    # the last measured one held to the end; then smoothed (one profile is noisy).
    o = np.interp(idx, idx[ok], off[ok])
    if len(o) >= 5:
        o = savgol_filter(o, min(len(o) // 2 * 2 - 1, 7), 1, mode="interp")
    return np.asarray(guide + nrm * o[:, None])


def _track_on(grey: NDArray[np.uint8], lut: F64, fit: dict[str, Any], p: DetectParams,
              at_end: bool, chunk: int = 8, max_px: float = 4000.0) -> dict[str, Any]:
    """Extend ``fit`` (from :func:`_fit_at`) past one end while the gap profiles keep fitting.

    From the last good centres a quadratic over the sample index predicts the next ``chunk``
    profile positions; they are fitted together and appended. It goes on while most of the last
    ``chunk`` samples are good, so a seam that reaches a sheet or image border (profiles fail
    there) stops at once.
    """
    keys = ("valid", "centre", "depth", "width", "rms", "contrast")
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
        pts = np.column_stack([np.polyval(coef[:, k], tq) for k in range(2)])
        der = np.column_stack([np.polyval(np.polyder(coef[:, k]), tq) for k in range(2)])
        der /= np.linalg.norm(der, axis=1, keepdims=True) + 1e-12
        nrm = np.column_stack([-der[:, 1], der[:, 0]])
        new = _fit_at(grey, lut, pts, nrm, p)
        fit = {k: np.concatenate([fit[k], new[k]]) for k in keys}
        n_steps += chunk
    if not at_end:
        fit = {k: fit[k][::-1] for k in keys}
    return fit


def _end_offset(grey: NDArray[np.uint8], lut: F64, e_pt: F64, tang: F64,
                w_med: float) -> tuple[float, str]:
    """Distance (px, along ``tang``) from ``e_pt`` to the seam's end, and what ends it there.

    The kind is ``"sheet border"``, ``"image border"`` or ``"open"`` (the gap fades out inside a
    sheet: a pen mark or scratch does that, a joint does not).

    The end is where the sheets end. Each side of the gap is read on two lines parallel to the
    centreline just outside the gap, and the gap itself on the centreline; where a sheet border
    crosses a line the brightness steps (where the gap ends, its dark floor gives way to the
    table). The border is straight across the seam, so its crossings of the lines lie on one line
    in (offset across, distance along): :func:`_border_line` finds the steps that agree and
    follows that line in to the centreline (a step that agrees with no other, such as the edge
    of a table hole beyond the border, is not the end). When no line steps, the seam runs out of
    the image (the end is the image border) or ends where the profiles stopped fitting.
    """
    H, W = grey.shape
    nrm = np.array([-tang[1], tang[0]])
    ks = np.arange(-28.0, 20.01, 0.5)
    q = e_pt + np.outer(ks, tang)
    delta = w_med / 2 + 2.5
    offs = (-2 * delta, -delta, 0.0, delta, 2 * delta)
    steps = [_side_crossings(grey, lut, q + o * nrm, ks) for o in offs]
    k_line, unsure = _border_line(offs, steps)
    k_border = _border_crossing(e_pt, tang, W, H, float(ks[-1]))
    kind = "unsure sheet border" if unsure else "sheet border"
    if k_line is not None:
        k = k_line
    elif k_border < 40.0:
        # Profiles fail within a profile length of the image border: the seam runs out there.
        k, kind = k_border, "image border"
    else:
        k, kind = 0.0, "open"
    if k_border <= k:
        k, kind = k_border, "image border"
    return float(k), kind


def _border_line(offs: tuple[float, ...],
                 steps: list[list[float]]) -> tuple[float | None, bool]:
    """Distance along the seam at which a straight border through the steps meets the centreline.

    ``steps[i]`` are the step positions found on the line at offset ``offs[i]`` across the seam,
    inner first; the first one on each line is where that line leaves its sheet, unless the
    sheet and the table look alike there (then it is something beyond, such as a table hole).
    Every pair of first steps defines a border line (crossing the seam at 15 degrees or more);
    the one most lines agree with (within 1.5 px) wins, the inner one on a tie, and is fitted
    to them. A lone step, seen on one line only, is taken only from the centreline (offset 0).
    Also says whether the end is unsure: the winner is seen on two lines only and another line
    seen on as many crosses the seam more than 3 px away (a mark meeting the seam at the border
    can do that; the inner one is then no better a guess than the other).
    """
    firsts = [(o, s[0]) for o, s in zip(offs, steps, strict=True) if s]
    best: tuple[int, float] | None = None  # (-agreeing lines, k at the centreline)
    fits: list[tuple[int, float]] = []
    for i in range(len(firsts)):
        for j in range(i + 1, len(firsts)):
            (oa, ka), (ob, kb) = firsts[i], firsts[j]
            s = (kb - ka) / (ob - oa)
            if abs(s) > 3.7:
                continue
            sel = [(o, k) for o, k in firsts if abs(k - ka - s * (o - oa)) <= 1.5]
            o_arr, k_arr = np.array(sel).T
            k0 = float(np.polyfit(o_arr, k_arr, 1)[1])
            fits.append((-len(sel), k0))
            if best is None or (-len(sel), k0) < best:
                best = (-len(sel), k0)
    if best is not None:
        rivals = [k for n, k in fits if n == best[0] and abs(k - best[1]) > 3.0]
        return best[1], best[0] == -2 and bool(rivals)
    # A lone step counts only where the gap's own dark floor ends (a lone step beside the gap
    # may be a texture stripe or a dot).
    near = [k for o, k in firsts if o == 0]
    return (near[0] if near else None), False


def _side_crossings(grey: NDArray[np.uint8], lut: F64, ps: F64, ks: F64) -> list[float]:
    """Where the brightness along the line ``ps`` (at offsets ``ks``) steps sharply and lastingly.

    From well inside the sheet (``ks > -14``) outward: a step is where the median brightness
    over the next 6 px differs from the median over the last 6 px by at least 25 %. A dark
    scratch or a texture stripe is a dip too narrow to move a median, and a gradual change of
    light moves it too slowly. Each step is placed where the brightness passes half-way between
    the two levels, and must be sharp (a few pixels of blur). All steps are returned, inner
    first: which one is the sheet border is decided across lines (:func:`_border_line`).
    """
    val, inside = _bilinear(grey, lut, ps[:, 0], ps[:, 1])
    val = np.convolve(np.pad(val, 1, mode="edge"), np.ones(3) / 3, mode="valid")
    # Only samples inside the image count (outside, the border pixels are repeated).
    lim = int(np.argmin(inside)) if not inside.all() else len(ks)
    n_in = int(np.sum(ks <= -14))
    hold = 12  # samples (6 px) on each side of a step
    if n_in < hold or lim - n_in < hold + 2:
        return []
    win = np.lib.stride_tricks.sliding_window_view(val[:lim], hold)
    med = np.median(win, axis=1)  # med[i]: median of val[i:i + hold]
    js = np.arange(n_in, lim - hold + 1)
    behind, ahead = med[js - hold], med[js]
    step = np.abs(ahead - behind)
    big = np.concatenate([[0], (step > _MIN_STEP * np.maximum(np.maximum(behind, ahead), 1e-6))
                          .astype(np.int8), [0]])
    out: list[float] = []
    for g0, g1 in zip(np.flatnonzero(np.diff(big) == 1), np.flatnonzero(np.diff(big) == -1),
                      strict=True):
        jj = int(g0) + int(np.argmax(step[g0:g1]))
        j = int(js[jj])
        lvl_in, lvl_out = float(behind[jj]), float(ahead[jj])
        half = 0.5 * (lvl_in + lvl_out)
        sgn = np.sign(lvl_in - half)
        on_in = sgn * (val - half) > 0
        # The half-level crossing nearest j: back to the last sample on the inner side, or on
        # to the first one past it.
        k = j
        if on_in[k]:
            while k + 1 < lim and on_in[k + 1]:
                k += 1
        else:
            while k > 0 and not on_in[k]:
                k -= 1
            if not on_in[k]:
                continue
        if k + 1 >= lim:
            continue
        amp = abs(lvl_in - half)
        lo_i, hi_i = max(k - 7, 0), min(k + 8, lim - 1)
        if sgn * (val[lo_i] - half) < 0.25 * amp or sgn * (val[hi_i] - half) > -0.25 * amp:
            continue
        # Off the sheet for good: the brightness never comes back past half-way (a dot or a
        # glare band on the sheet is left again; the table beyond a border is not).
        if np.any(sgn * (val[k + 2:lim] - half) > 0.2 * amp):
            continue
        v0, v1 = val[k], val[k + 1]
        frac = (v0 - half) / (v0 - v1) if v0 != v1 else 0.5
        out.append(float(ks[k] + frac * (ks[k + 1] - ks[k])))
    return out


def _border_crossing(e_pt: F64, tang: F64, W: int, H: int, default: float) -> float:
    """Distance along ``tang`` from ``e_pt`` (inside the image) to the image border (px)."""
    ts = []
    for lo, hi, x, d in ((-0.5, W - 0.5, e_pt[0], tang[0]), (-0.5, H - 0.5, e_pt[1], tang[1])):
        if d > 1e-9:
            ts.append((hi - x) / d)
        elif d < -1e-9:
            ts.append((lo - x) / d)
    return float(min(ts)) if ts else default


def _longest_bridged_run(valid: NDArray[np.bool_], bridge: int, min_island: int,
                         bridge_short: int | None = None) -> tuple[int, int] | None:
    """Longest run of valid samples after joining islands across holes.

    Islands shorter than ``min_island`` are dropped; a hole of up to ``bridge_short`` samples is
    always bridged, one of up to ``bridge`` only between two islands of at least 4 x min_island
    (a long hole is bridged only when the seam is clearly seen on both sides of it).
    """
    short = max(1, bridge // 6) if bridge_short is None else bridge_short
    m = np.concatenate([[0], valid.astype(np.int8), [0]])
    st, en = np.flatnonzero(np.diff(m) == 1), np.flatnonzero(np.diff(m) == -1)
    islands = [(int(a), int(b)) for a, b in zip(st, en, strict=True) if b - a >= min_island]
    if not islands:
        return None
    runs = [list(islands[0])]
    last_len = islands[0][1] - islands[0][0]
    for a, b in islands[1:]:
        hole = a - runs[-1][1]
        long_both = last_len >= 4 * min_island and b - a >= 4 * min_island
        if hole <= short or (hole <= bridge and long_both):
            runs[-1][1] = b
        else:
            runs.append([a, b])
        last_len = b - a
    a, b = max(runs, key=lambda r: r[1] - r[0])
    return a, b - 1


# ---------------------------------------------------------------------------------------------
# Decision
# ---------------------------------------------------------------------------------------------
def _confidence(c: _Candidate, ratio: float) -> tuple[float, list[str]]:
    reasons = [f"thin dark valley {c.length_px:.0f} px long with a sheet on each side",
               f"{100 * c.valid_frac:.0f} % of cross-profiles fit two gap edges",
               f"relative gap depth {c.depth:.2f}, fit residual {100 * c.resid:.1f} % of depth"]
    conf = (min(1.0, c.valid_frac / 0.9) * min(1.0, c.depth / 0.4)
            * max(0.0, 1.0 - max(0.0, c.resid - 0.05) * 4) * (1.0 - 0.5 * ratio))
    n_open = sum(k == "open" for k in c.end_kinds)
    reasons.append(f"ends at: {c.end_kinds[0]}, {c.end_kinds[1]}")
    if n_open:
        # A joint runs from border to border: an open end means part of it is not seen, or the
        # line is a mark, not a joint. Never report that with high confidence.
        conf = min(conf * 0.6, 0.45)
        reasons.append("one end fades out inside a sheet: the seam may continue unseen")
    if any(k.startswith("unsure") for k in c.end_kinds):
        # Where the seam meets the border is not clear: an end point off by more than a few px
        # would put the weld's start or stop in the wrong place.
        conf = min(conf * 0.6, 0.45)
        reasons.append("two sheet borders seen equally well at one end: the end point is unsure")
    if ratio > 0:
        reasons.append(f"next candidate {100 * ratio:.0f} % as strong")
    else:
        reasons.append("no other candidate")
    return float(np.clip(conf, 0.0, 1.0)), reasons


def _summary(c: _Candidate, x0: int, y0: int) -> list[list[float]]:
    pts = c.points if c.points is not None else c.polyline
    return np.round(pts[[0, len(pts) // 2, -1]] + [x0, y0], 1).tolist()


def _orient(pts: F64) -> F64:
    d = pts[-1] - pts[0]
    if abs(d[0]) >= abs(d[1]):
        return pts if d[0] >= 0 else pts[::-1].copy()
    return pts if d[1] >= 0 else pts[::-1].copy()
