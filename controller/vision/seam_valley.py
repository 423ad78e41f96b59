"""Multi-scale valley response on a working image, and the main directions of the valleys in it.

The gap between two sheets is a dark *valley*: brighter on both sides than in the middle, at
whatever width the camera gives it (a hairline to ~30 px at full resolution, blurred or not). The
relative valley depth of :mod:`controller.vision.seam_coarse` is measured here at several
distances ``r`` (on the working image smoothed in proportion), in four directions, and the
largest is kept with the scale that gave it. A step edge (a sheet border, a shadow edge) has one
side as dark as the centre and gives ~0 at every scale; a bright tack weld gives 0.

Working image: the input shrunk by box averaging so that its longer side is about
``WORK_SIDE_PX`` (a thin gap stays a dip; a wide one becomes a few px).
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

F32 = NDArray[np.float32]

WORK_SIDE_PX = 640
SCALES = (1, 2, 4, 8)  # distances (working px) from the valley centre to where its sides are read


def work_factor(shape: tuple[int, ...]) -> int:
    """Integer shrink factor from the image (H, W) to the working image."""
    return max(1, int(round(max(shape[:2]) / WORK_SIDE_PX)))


def shrink(grey: NDArray[np.uint8], f: int) -> F32:
    """``grey`` box-averaged by ``f`` (float32, 0..255)."""
    H, W = grey.shape
    if f == 1:
        return grey.astype(np.float32)
    return np.asarray(cv2.resize(grey, (W // f, H // f), interpolation=cv2.INTER_AREA),
                      dtype=np.float32)


def valley_response(img: F32, lut: NDArray[np.float64] | None = None) -> tuple[F32, F32]:
    """(relative valley depth 0..1, scale r that gave it) per pixel of the working image ``img``.

    ``lut`` (256,) linearises grey levels first (camera response); the depth is relative to the
    brighter-of-the-two-sides' dimmer side, so it does not depend on the light level.
    """
    lin = img if lut is None else np.interp(img, np.arange(256), lut).astype(np.float32)
    best = np.zeros_like(lin)
    scale = np.zeros_like(lin)
    eps = max(float(np.percentile(lin, 50)) * 0.05, 1e-3)
    for r in SCALES:
        src = lin if r == 1 else cv2.GaussianBlur(lin, (0, 0), 0.35 * r)
        d = _depth_at(np.asarray(src, np.float32), r, eps)
        up = d > best
        best[up] = d[up]
        scale[up] = r
    return best, scale


def _depth_at(img: F32, r: int, eps: float) -> F32:
    """Relative valley depth with sides read at distance ``r`` in four directions (max)."""
    rd = max(1, int(round(r / np.sqrt(2))))
    pad = cv2.copyMakeBorder(img, r, r, r, r, cv2.BORDER_REPLICATE)
    h, w = img.shape
    best = np.zeros_like(img)
    for dy, dx in ((0, r), (r, 0), (rd, rd), (rd, -rd)):
        a = pad[r + dy:r + dy + h, r + dx:r + dx + w]
        b = pad[r - dy:r - dy + h, r - dx:r - dx + w]
        side = np.minimum(a, b)
        np.maximum(best, (side - img) / (side + eps), out=best)
    return best


def main_directions(resp: F32, thr: float, n: int = 3, min_share: float = 0.15) -> list[float]:
    """Up to ``n`` directions (rad, 0..pi, along the valleys) shared by many strong valley pixels.

    The direction of each pixel is the eigenvector of the response's structure: the valley runs
    along the smaller curvature of ``resp`` smoothed a little. Peaks of the histogram weighted by
    the response above ``thr`` within ``min_share`` of the highest are returned, strongest first.
    """
    sm = cv2.GaussianBlur(resp, (0, 0), 1.5)
    dxx = cv2.Sobel(sm, cv2.CV_32F, 2, 0, ksize=3)
    dyy = cv2.Sobel(sm, cv2.CV_32F, 0, 2, ksize=3)
    dxy = cv2.Sobel(sm, cv2.CV_32F, 1, 1, ksize=3)
    # Direction of the eigenvector of the algebraically larger curvature: along a ridge of resp
    # (across it the curvature is strongly negative), i.e. the direction the valley runs.
    along = 0.5 * np.arctan2(2 * dxy, dxx - dyy)
    m = (resp > thr) & (dxx + dyy < 0)
    if m.sum() < 20:
        return []
    ang = np.mod(along[m], np.pi)
    nb = 36
    hist = np.bincount(np.minimum((ang / np.pi * nb).astype(np.int64), nb - 1),
                       weights=resp[m], minlength=nb).astype(np.float64)
    hist = np.convolve(np.concatenate([hist[-1:], hist, hist[:1]]), [0.25, 0.5, 0.25], "valid")
    order = np.argsort(-hist)
    out: list[float] = []
    for k in order:
        if hist[k] < min_share * hist[order[0]] or len(out) >= n:
            break
        if hist[k] < hist[(k - 1) % nb] or hist[k] < hist[(k + 1) % nb]:
            continue
        out.append(float((k + 0.5) * np.pi / nb))
    return out


def rotate_to_rows(a: F32, theta: float, fill: float) -> tuple[F32, NDArray[Any]]:
    """``a`` rotated so that direction ``theta`` (rad, in image (u, v)) runs down the rows.

    Returns the rotated array (outside the image: ``fill``) and the 2x3 affine matrix from the
    rotated canvas back to ``a``'s pixel coordinates.
    """
    h, w = a.shape
    # Rotate by (theta - pi/2) so the direction (cos theta, sin theta) maps to (0, 1).
    ang = theta - np.pi / 2
    c, s = np.cos(ang), np.sin(ang)
    R = np.array([[c, s], [-s, c]])  # image -> canvas (rotation by -ang)
    corners = np.array([[0, 0], [w - 1, 0], [0, h - 1], [w - 1, h - 1]], np.float64)
    rc = corners @ R.T
    lo = rc.min(axis=0)
    size = np.ceil(rc.max(axis=0) - lo).astype(int) + 1
    M = np.hstack([R, -lo[:, None]])  # image -> canvas
    rot = cv2.warpAffine(a, M, (int(size[0]), int(size[1])), flags=cv2.INTER_LINEAR,
                         borderMode=cv2.BORDER_CONSTANT, borderValue=fill)
    Minv = cv2.invertAffineTransform(M)
    return np.asarray(rot, np.float32), Minv
