"""Coarse search for seam candidates: thin dark valleys, long enough, as ordered polylines.

On the image shrunk by ``coarse_factor`` (box average, so a thin gap stays visible as a dip), the
*relative valley depth* ``(min(I(p + r n), I(p - r n)) - I(p)) / min(...)`` in four directions is
high only where both sides are brighter than the centre: a step edge (sheet border), a dot or a
wide dark band give ~0, and dividing by the local brightness makes it independent of uneven light
and glare. Connected components of the thresholded depth become ordered polylines by tracking the
strongest pixel per bin along the component's main axis (a crossing mark is left behind); pieces
shorter than a seam (a faint gap dips under the threshold here and there) are joined when they
continue each other across a short hole, long ones kept, and those joined again across a longer
hole (glare, a dot on the seam).

A hairline gap (1-2 px at 2272 px wide) covers under half a coarse pixel; where it straddles two
of them each shows half its depth, under the threshold, and the valley falls apart. With ``fine``
the depth is also computed on a grid twice as fine and pooled (max) onto the coarse
one: the detector asks for that when the coarse grid gave no seam
(tests/test_seam_hairline.py).
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from controller.vision.seam_params import F64, Candidate, DetectParams


def coarse_candidates(grey: NDArray[np.uint8], lut: F64, p: DetectParams, fine: bool = False
                      ) -> tuple[list[Candidate], int, NDArray[np.uint8], int]:
    """Candidates in ``grey`` (strongest first) and how many long valley blobs were seen.

    Also returns the valley mask of the search image (uint8 0/1) and its shrink factor.
    """
    H, W = grey.shape
    f = p.coarse_factor or max(1, min(6, int(round(W / 560))),
                               int(np.ceil(p.valley_r_px / p.valley_r_coarse)))
    best = _valley_depth(grey, lut, (W // f, H // f), p.valley_r_coarse)
    if fine and f > 1:
        # A gap about one coarse px wide straddling two of them shows half its depth in each and
        # falls apart into pieces: its depth on a grid twice as fine, pooled (max) onto this one.
        h, w = best.shape
        finer = _valley_depth(grey, lut, (2 * w, 2 * h), p.valley_r_coarse)
        np.maximum(best, finer.reshape(h, 2, w, 2).max(axis=(1, 3)), out=best)
    mask = (best > p.min_depth).astype(np.uint8)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    cands: list[Candidate] = []
    diag = np.hypot(stats[:, cv2.CC_STAT_WIDTH], stats[:, cv2.CC_STAT_HEIGHT])
    # A faint gap dips under the threshold here and there and falls apart into pieces shorter
    # than a seam: pieces are kept, and joined when they continue each other across a short hole.
    idx = [i for i in range(1, n) if diag[i] >= p.piece_length_px / f]
    n_long = int(np.sum(diag[1:] >= p.min_length_px / f))
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
        cands.append(Candidate(poly_full, float(np.sum(wts)) * f, length))
    cands = _join_candidates(cands, p.piece_join_px, 2.0 * f)
    cands = [c for c in cands if c.length_px >= p.min_length_px]
    cands = _join_candidates(cands, p.join_px, 2.0 * f)
    cands.sort(key=lambda c: -c.coarse_score)
    return cands, n_long, mask, f


def _valley_depth(grey: NDArray[np.uint8], lut: F64, size: tuple[int, int],
                  r: int) -> NDArray[np.float32]:
    """Relative valley depth (0..1, most of four directions) of ``grey`` box-shrunk to ``size``."""
    H, W = grey.shape
    small = grey if size == (W, H) else cv2.resize(grey, size, interpolation=cv2.INTER_AREA)
    # No smoothing: a thin gap is at most a pixel wide here and blurring halves its depth.
    img = lut.astype(np.float32)[small]
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
    return best


def _join_candidates(cands: list[Candidate], join_px: float,
                     slack_px: float) -> list[Candidate]:
    """Join candidates that continue each other across a short hole (glare, a dot on the seam).

    Each end's tangent line must pass near the other end (within a 25 degree cone, or a few
    coarse px across a short hole) and the two tangents agree: one curve, not a branch.
    """
    cos_max = np.cos(np.radians(25.0))
    tan_max = np.tan(np.radians(25.0))
    ends = [_end_dirs(c.polyline) for c in cands]
    merged = True
    while merged and len(cands) > 1:
        merged = False
        pos = np.array([[e[0][0], e[1][0]] for e in ends])  # (n, 2 ends, 2)
        near = np.linalg.norm(pos[:, None, :, None] - pos[None, :, None, :], axis=-1) <= join_px
        for i, j in zip(*np.nonzero(np.triu(near.any(axis=(2, 3)), 1)), strict=True):
            for a_end, b_end in ((1, 0), (1, 1), (0, 0), (0, 1)):
                ea, ta = ends[i][a_end]
                eb, tb = ends[j][b_end]
                v = eb - ea
                d = float(np.linalg.norm(v))
                tol = slack_px + d * tan_max
                if (d > join_px or abs(ta[0] * v[1] - ta[1] * v[0]) > tol or ta @ v < -slack_px
                        or abs(tb[0] * v[1] - tb[1] * v[0]) > tol or tb @ -v < -slack_px
                        or ta @ -tb < cos_max):
                    continue
                pa = cands[i].polyline if a_end else cands[i].polyline[::-1]
                pb = cands[j].polyline[::-1] if b_end else cands[j].polyline
                cands[i] = Candidate(np.vstack([pa, pb]),
                                     cands[i].coarse_score + cands[j].coarse_score,
                                     cands[i].length_px + cands[j].length_px + d)
                ends[i] = _end_dirs(cands[i].polyline)
                del cands[j], ends[j]
                merged = True
                break
            if merged:
                break
    return cands


def _end_dirs(poly: F64) -> tuple[tuple[F64, F64], tuple[F64, F64]]:
    """(point, outward unit tangent over ~10 points) at the start and at the end of ``poly``."""
    n = min(len(poly) - 1, 10)
    t0, t1 = poly[0] - poly[n], poly[-1] - poly[-1 - n]
    return ((poly[0], t0 / (np.linalg.norm(t0) + 1e-12)),
            (poly[-1], t1 / (np.linalg.norm(t1) + 1e-12)))


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


def mean_dist(poly: F64, ref: F64) -> float:
    """Mean distance (px) from points of ``poly`` to the nearest of ``ref`` (subsampled)."""
    d = np.linalg.norm(poly[::4, None, :] - ref[None, ::max(1, len(ref) // 200), :], axis=2)
    return float(d.min(axis=1).mean())


def drop_duplicates(cands: list[Candidate]) -> list[Candidate]:
    """``cands`` (refined) without those lying on a stronger one's centreline.

    Two pieces of one seam (split by a tack weld in the coarse search) are each extended across
    the patch when refined and then cover the same line: the same seam, not a rival. A rejected
    rival lying 60 % on an accepted seam is dropped too.
    """
    kept: list[Candidate] = []
    order = sorted(cands, key=lambda c: -c.score if not c.why_rejected else 1.0)
    for c in order:
        if c.points is not None and (not c.why_rejected or c.rival) and any(
                k.points is not None and not k.why_rejected
                and share_near(c.points, k.points, 3.0) >= (0.8 if not c.why_rejected else 0.6)
                for k in kept):
            # A rejected piece mostly on the chosen seam (it ran off along a scratch at one
            # end) is that seam gone astray, not a second seam.
            continue
        kept.append(c)
    return kept


def share_near(poly: F64, ref: F64, tol: float) -> float:
    """Share of the points of ``poly`` within ``tol`` px of a point of ``ref`` (subsampled)."""
    d, slack = nearest_px(poly, ref)
    return float(np.mean(d <= tol + slack))


def nearest_px(poly: F64, ref: F64) -> tuple[F64, float]:
    """Distance (px) from every 4th point of ``poly`` to the nearest of ``ref``, and its slack.

    ``ref`` is subsampled to about 400 points; the slack is half its longest step then, what a
    distance may exceed the distance to the curve itself by.
    """
    a, b = poly[::4], ref[::max(1, len(ref) // 400)]
    d = np.min(np.linalg.norm(a[:, None, :] - b[None, :, :], axis=2), axis=1)
    return d, float(np.linalg.norm(np.diff(b, axis=0), axis=1).max(initial=0) / 2)
