"""How a collection of views is going: the views collected, counts, orientation spread, coverage."""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from itertools import combinations

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from calibration.intrinsics import image_coverage
from calibration.targets import Detection
from controller.geometry.poses import Pose

F64 = NDArray[np.float64]


#: Good views the routine asks for before it says "enough".
TARGET_VIEWS = 15
#: Spread of orientations (largest rotation between two views, deg) it asks for.
TARGET_SPREAD_DEG = 30.0
#: Fraction of the 4x4 image cells that must hold corners.
TARGET_COVERAGE = 0.75


@dataclass
class ViewRecord:
    """One collected view: its name, robot pose (recorded), detection (None if no board)."""

    name: str
    T_base_flange: Pose
    detection: Detection | None
    joints_deg: F64 | None = None
    image_path: str | None = None
    #: Why the board is not used in this view (printed and reported); None when it was found.
    skip_reason: str | None = None


@dataclass
class Progress:
    """How a collection is going: counts, orientation spread, coverage, and what is missing."""

    good: int
    total: int
    spread_deg: float
    coverage: float
    missing_cells: list[str]
    enough: bool
    target_views: int

    def line(self, width: int = 20) -> str:
        """One status line with a progress bar, for stderr."""
        frac = min(1.0, self.good / self.target_views)
        done = int(round(frac * width))
        bar = "#" * done + "." * (width - done)
        text = (f"[{bar}] {self.good}/{self.target_views} good views ({self.total} taken) | "
                f"orientation spread {self.spread_deg:.0f}/{TARGET_SPREAD_DEG:.0f} deg | "
                f"coverage {100 * self.coverage:.0f}%")
        if self.enough:
            return text + " | ENOUGH good views: confirm 'done' to solve, or add more"
        todo = []
        if self.spread_deg < TARGET_SPREAD_DEG:
            todo.append("tilt the camera more (20-40 deg) about different axes")
        if self.coverage < TARGET_COVERAGE and self.missing_cells:
            words = list(dict.fromkeys(c.split(" (")[0] for c in self.missing_cells))
            todo.append("put the board in the " + ", ".join(words[:4]) + " of the image")
        return text + (" | next: " + "; ".join(todo) if todo else "")


def orientation_spread_deg(poses: Sequence[Pose]) -> float:
    """Largest rotation angle between any two poses (deg); 0 for fewer than two."""
    best = 0.0
    Rs = [np.asarray(T)[:3, :3] for T in poses]
    for a, b in combinations(Rs, 2):
        best = max(best, float(np.degrees(Rotation.from_matrix(a.T @ b).magnitude())))
    return best


def collection_progress(views: Sequence[ViewRecord], image_size: tuple[int, int],
                        target_views: int = TARGET_VIEWS) -> Progress:
    """Progress of a collection of views against the targets of this module."""
    good = [v for v in views if v.detection is not None]
    spread = orientation_spread_deg([v.T_base_flange for v in good])
    cov = image_coverage([v.detection.image_points for v in good if v.detection is not None],
                         image_size)
    enough = (len(good) >= target_views and spread >= TARGET_SPREAD_DEG
              and cov.fraction >= TARGET_COVERAGE)
    return Progress(len(good), len(views), spread, cov.fraction, cov.missing, enough,
                    target_views)

