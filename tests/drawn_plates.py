"""Drawn test images: brightness levels painted on a 4x canvas, shrunk with exact area coverage,
blurred (sigma 1 px) and with sensor noise (sigma 2 grey levels). Not our renderer: the tests of
the seam detector that use these know their truth from the drawing itself."""

from __future__ import annotations

from collections.abc import Callable

import cv2
import numpy as np
from numpy.typing import NDArray

S = 4  # supersampling


def render(fill: Callable[[NDArray[np.float32]], None], seed: int,
           size: tuple[int, int] = (1600, 1200)) -> NDArray[np.uint8]:
    """Image (H, W) uint8 from ``fill(m)``, which paints levels (0-255) on a 4x canvas."""
    W, H = size
    m = np.zeros((H * S, W * S), np.float32)
    fill(m)
    img = cv2.resize(m, (W, H), interpolation=cv2.INTER_AREA)
    img = cv2.GaussianBlur(img, (0, 0), 1.0)
    img += np.random.default_rng(seed).normal(0, 2.0, img.shape)
    return np.clip(img, 0, 255).astype(np.uint8)
