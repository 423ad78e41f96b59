"""The overlay picture (controller.vision.seam_overlay): what a person looks at."""

from __future__ import annotations

import numpy as np

from controller.vision.seam_detection import SeamDetection
from controller.vision.seam_overlay import draw_overlay


def test_the_seam_is_drawn_over_the_text_not_under_it() -> None:
    # A long text covers the picture's top third; a seam running through it stays visible.
    img = np.full((600, 800), 120, np.uint8)
    P = np.column_stack([np.linspace(10.0, 790.0, 200), np.full(200, 72.0)])  # on a text line
    reason = "a reason long enough to run across the picture's top, word after word after word"
    det = SeamDetection(points_px=P, confidence=0.9, reasons=[reason] * 3,
                        endpoints_px=P[[0, -1]], width_px=np.full(200, 3.0))
    out = draw_overlay(img, det)
    assert out.shape == (600, 800, 3)
    row = out[72, 40:760].astype(int)
    green = (row[:, 1] > 180) & (row[:, 2] < 120) & (row[:, 0] < 120)
    assert green.all()  # drawn under the text, 43 % of it was
