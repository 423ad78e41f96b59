"""The labelled real photographs (``../shared/data/real-seams``): where they are, how to read them.

One reader for the benchmarks that set the photographs against the simulator
(``bench.bench_gap_depth``, ``bench.detect_realism``). A label is the JSON that
``score.py`` reads (its README): ``image`` (path under the folder), ``polyline_px`` (the gap's
centreline, image px), ``gap_width_px``, ``occluded_spans`` and ``seam_present``.
"""

from __future__ import annotations

import json
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import cv2
import numpy as np

PHOTOS = Path(__file__).resolve().parents[2] / "shared" / "data" / "real-seams"


def labelled_photos(root: Path = PHOTOS, need: tuple[str, ...] = ("image", "polyline_px")
                    ) -> Iterator[tuple[str, dict[str, Any], np.ndarray]]:
    """(name, label, greyscale image) of each label in ``root/labels``, in name order.

    Raises ValueError naming a label that lacks one of the keys ``need`` (and ``image``), and
    FileNotFoundError for an image that cannot be read.
    """
    for lab_path in sorted((root / "labels").glob("*.json")):
        lab = json.loads(lab_path.read_text())
        missing = [k for k in dict.fromkeys(("image", *need)) if k not in lab]
        if missing:
            raise ValueError(f"label {lab_path} has no {', '.join(missing)} (score.py's label "
                             "format: ../shared/data/real-seams/README.md)")
        img = cv2.imread(str(root / lab["image"]), cv2.IMREAD_GRAYSCALE)
        if img is None:
            raise FileNotFoundError(f"cannot read {root / lab['image']} (label {lab_path})")
        yield lab_path.stem, lab, img


def have_photos(root: Path, tool: str) -> bool:
    """Whether ``root`` holds score.py's labels; if not, says so on stderr for ``tool``."""
    if (root / "labels").is_dir():
        return True
    print(f"{tool}: no labelled photographs in {root} (../shared/data/real-seams beside the "
          "checkout: see its README)", file=sys.stderr)
    return False
