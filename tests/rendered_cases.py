"""A benchmark case rendered for a test (bench/detect_cases.py, into a temporary cache), not read
from the benchmark's cache: the test does not depend on a render run having been made."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from bench import detect_cases


def rendered_view(cache: Path, case: detect_cases.Case, view: int
                  ) -> tuple[np.ndarray, dict[str, Any]]:
    """View ``view`` of ``case`` rendered into ``cache``: (image as rendered, truth with its
    ``image_size`` (W, H) set, as ``bench.detect_score.score_view`` takes it)."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(detect_cases, "CACHE", cache)
        detect_cases.render_case(case)
        imgs, z = detect_cases.load_case(case)
    return imgs[view], detect_cases.view_truth(z, view, imgs[view])
