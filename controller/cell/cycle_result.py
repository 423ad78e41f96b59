"""What a weld cycle did (:class:`CycleResult`) and the failure of a state that ran too long."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from controller.errors import RobotFault, SeamguideError
from controller.path.weld_path import WeldPath
from controller.stereo.locate import Seam3D


class CycleTimeout(RobotFault):
    """A state of the cycle took longer than its configured timeout."""

    exit_code = 17


@dataclass
class CycleResult:
    """What a cycle did: final status, reason, the located seam and path, the record folder."""

    status: str
    reason: str | None = None
    error: SeamguideError | None = None
    seam: Seam3D | None = None
    path: WeldPath | None = None
    record_path: Path | None = None
    state_history: list[tuple[str, float]] = field(default_factory=list)
    camera_poses: list[np.ndarray] = field(default_factory=list)
    capture_skews_s: list[float] = field(default_factory=list)
    detections: list[Any] = field(default_factory=list)
    images: list[np.ndarray] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        """True when the cycle ended ``done``."""
        return self.status == "done"
