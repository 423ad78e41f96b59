"""A seam found in one image: what :func:`controller.vision.seam_detect.detect_seam` returns.

Pixels are (u, v) = (column, row), origin at the centre of the top-left pixel, in the *distorted*
image (undistort with ``CameraModel.pixels_to_normalized``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from controller.vision.seam_decision import JOINT_END, arc_length
from controller.vision.seam_params import F64


@dataclass(frozen=True)
class SeamDetection:
    """A seam found in one image.

    ``points_px`` (K, 2) float64 sub-pixel centreline (u, v), ordered from one end to the other
    (the end nearer the image's left border first, or the top one for a vertical seam);
    ``endpoints_px`` (2, 2) its first and last point; ``width_px`` (K,) the fitted gap width;
    ``confidence`` 0..1; ``reasons`` human-readable lines saying why; ``stats`` numbers behind it.

    ``end_kinds`` says what each end is, in the order of ``points_px`` (first point first):
    ``"joint_end"`` (the two sheets stop facing each other inside the image: a sheet border, a
    plate corner, a T-corner; the end point is a real feature of the part) or ``"image_border"``
    (the seam leaves the image there; the end point is only where the view stops, not an end of
    the joint). A point inside a sheet is never returned as an end: a line that fades out inside
    a sheet is refused. :attr:`ends` gives the same as ``[{"px": [u, v], "kind": ...}, ...]``.

    ``occluded_spans_px``: ``[(s0, s1), ...]`` arc-length ranges (px along ``points_px`` from
    its first point) where the gap was not seen and the centreline is bridged through (a tack
    weld, spatter, slag, glare); :attr:`occluded` gives the same per point (K,) bool. The
    centreline there is interpolated from the gap on both sides: not an end, and not measured.

    ``band_px`` / ``band_width_px``: where a shadow was split off (:mod:`seam_shadow`), the whole
    dark band's centreline (K, 2) and median width (px): the seam if that was a cut face inside
    the gap (:mod:`controller.stereo.band_check` decides with two views). Else None.
    """

    points_px: F64
    confidence: float
    reasons: list[str]
    endpoints_px: F64
    width_px: F64
    stats: dict[str, Any] = field(default_factory=dict)
    end_kinds: tuple[str, str] = (JOINT_END, JOINT_END)
    occluded_spans_px: list[tuple[float, float]] = field(default_factory=list)
    band_px: F64 | None = None
    band_width_px: float | None = None

    @property
    def ends(self) -> list[dict[str, Any]]:
        """The two ends in seam order: ``[{"px": [u, v], "kind": "joint_end"|"image_border"}]``."""
        return [{"px": [float(e[0]), float(e[1])], "kind": k}
                for e, k in zip(self.endpoints_px, self.end_kinds, strict=True)]

    @property
    def gap_width_px(self) -> float:
        """The gap's median width along the seam (px)."""
        return float(np.median(self.width_px))

    @property
    def occluded(self) -> NDArray[np.bool_]:
        """(K,) bool per point of ``points_px``: inside an occluded (bridged) span."""
        s = arc_length(self.points_px)
        out = np.zeros(len(s), bool)
        for a, b in self.occluded_spans_px:
            out |= (s >= a) & (s <= b)
        return out

    def to_dict(self, decimals: int = 3) -> dict[str, Any]:
        """JSON-ready dictionary: ``seam_px``, ``endpoints_px``, ``confidence``, ``reasons``..."""
        return {
            "seam_px": np.round(self.points_px, decimals).tolist(),
            "endpoints_px": np.round(self.endpoints_px, decimals).tolist(),
            "ends": [{"px": [round(e["px"][0], decimals), round(e["px"][1], decimals)],
                      "kind": e["kind"]} for e in self.ends],
            "occluded_spans_px": [[round(a, 1), round(b, 1)] for a, b in self.occluded_spans_px],
            "confidence": round(float(self.confidence), 4),
            "reasons": list(self.reasons),
            "gap_width_px": round(self.gap_width_px, 3),
            "band_px": (None if self.band_px is None
                        else np.round(self.band_px, decimals).tolist()),
            "band_width_px": (None if self.band_width_px is None
                              else round(self.band_width_px, 3)),
            "stats": {k: (round(v, 4) if isinstance(v, float) else v)
                      for k, v in self.stats.items()},
        }
