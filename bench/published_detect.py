"""The published seam detector, ported to Python for comparison (bench only).

The published MATLAB prototype: greyscale, Canny edges, connected components, delete the small
blobs, the vertical ones and those in a corridor at the top of the image, then fit one degree-7
polynomial y(x) through every remaining edge pixel and report it over the x range of those pixels.
Thresholds are fixed (as published); nothing pairs the two edges of the gap, nothing checks that the
result is a seam. Raises SeamNotFound only when no edge pixel survives the filtering.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from controller.errors import SeamNotFound


@dataclass(frozen=True)
class PublishedParams:
    canny_low: float = 50.0
    canny_high: float = 150.0
    min_area_px: int = 150
    top_corridor_frac: float = 0.1
    degree: int = 7


def published_detect(image: NDArray[np.uint8],
                     params: PublishedParams | None = None) -> NDArray[np.float64]:
    """Seam points (K, 2) px (u, v) by the published method; SeamNotFound when nothing is left."""
    p = params or PublishedParams()
    grey = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    H, W = grey.shape
    edges = cv2.Canny(grey, p.canny_low, p.canny_high)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(edges, connectivity=8)
    keep = np.zeros(n, bool)
    for i in range(1, n):
        x, y, w, h, area = stats[i]
        if area < p.min_area_px:
            continue  # small blob
        if h > w:
            continue  # vertical blob
        if y + h < p.top_corridor_frac * H:
            continue  # in the top corridor
        keep[i] = True
    mask = keep[labels]
    ys, xs = np.nonzero(mask)
    if xs.size < p.degree + 1:
        raise SeamNotFound("published method: no edge pixels left after filtering")
    # Fit on normalised x for conditioning (np.polyfit warns otherwise); same polynomial.
    x0, sx = xs.mean(), max(xs.std(), 1.0)
    coef = np.polyfit((xs - x0) / sx, ys.astype(np.float64), p.degree)
    u = np.arange(xs.min(), xs.max() + 1, dtype=np.float64)
    v = np.polyval(coef, (u - x0) / sx)
    return np.column_stack([u, v])
