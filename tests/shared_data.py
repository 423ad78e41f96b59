"""Where the shared real data lives (``../shared/data`` beside the checkout, or
``$SEAMGUIDE_SHARED_DATA``), and a skip marker for tests that need it."""

from __future__ import annotations

import os
from pathlib import Path

import pytest


def shared_data_dir() -> Path:
    """The shared data folder: ``$SEAMGUIDE_SHARED_DATA`` if set, else ``../shared/data``."""
    env = os.environ.get("SEAMGUIDE_SHARED_DATA")
    if env:
        return Path(env)
    return Path(__file__).resolve().parents[2] / "shared" / "data"


CHESSBOARD = shared_data_dir() / "opencv-chessboard"
ETHZ = shared_data_dir() / "ethz-handeye-robot-arm"


def needs(path: Path) -> pytest.MarkDecorator:
    """Skip the test when the shared data folder ``path`` is not present (a clone elsewhere)."""
    return pytest.mark.skipif(not path.exists(), reason=f"shared data {path} not present; set "
                              "SEAMGUIDE_SHARED_DATA to the shared data folder")
