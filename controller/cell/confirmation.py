"""The operator's yes or no to a planned weld path, asked by the cycle, answered over the socket.

The daemon's cycle blocks in :meth:`OperatorConfirmation.ask` (bounded by the job's confirm
timeout) while ``seamguide ctl status`` shows the path's summary and ``ctl confirm`` / ``ctl
reject`` answer it (:meth:`OperatorConfirmation.answer`). No answer, an abort or a shutdown is a
no.
"""

from __future__ import annotations

import logging
import threading
from typing import Any

import numpy as np

from controller.cell.sd_notify import notify
from controller.path.weld_path import WeldPath

log = logging.getLogger(__name__)


def path_summary(path: WeldPath, timeout_s: float) -> dict[str, Any]:
    """What the operator is shown: weld points, length, first and last torch tip (mm, base)."""
    tips = np.array([t.T_base_tcp[:3, 3] for t in path.weld_targets])
    return {"weld_points": len(tips),
            "length_mm": round(float(np.linalg.norm(np.diff(tips, axis=0), axis=1).sum()), 1),
            "first_mm": np.round(tips[0], 2).tolist(),
            "last_mm": np.round(tips[-1], 2).tolist(),
            "timeout_s": round(timeout_s, 1)}


class OperatorConfirmation:
    """One weld path at a time waiting for the operator. Thread-safe.

    ``stop`` is the daemon's shutdown flag: once set, a waiting question ends with a no (call
    :meth:`wake` after setting it).
    """

    def __init__(self, stop: threading.Event) -> None:
        self._stop = stop
        self._decided = threading.Condition()
        self._awaiting: dict[str, Any] | None = None
        self._decision: bool | None = None

    @property
    def awaiting(self) -> dict[str, Any] | None:
        """The summary of the path waiting for an answer, or None."""
        with self._decided:
            return self._awaiting

    def ask(self, path: WeldPath, timeout_s: float) -> bool:
        """Wait up to ``timeout_s`` for the operator; True only for a confirm before then."""
        summary = path_summary(path, timeout_s)
        log.warning("weld path waiting for the operator: %s; answer with `seamguide ctl confirm` "
                    "or `reject`", summary)
        notify("STATUS=waiting for the operator to confirm the weld path")
        with self._decided:
            self._awaiting, self._decision = summary, None
            try:
                self._decided.wait_for(lambda: self._decision is not None or self._stop.is_set(),
                                       timeout=timeout_s)
                return self._decision is True and not self._stop.is_set()
            finally:
                self._awaiting, self._decision = None, None

    def answer(self, yes: bool) -> bool:
        """Answer the waiting path; False when no path is waiting."""
        with self._decided:
            if self._awaiting is None:
                return False
            self._decision = yes
            self._decided.notify_all()
            return True

    def wake(self) -> None:
        """Re-check the stop flag now (after a shutdown request)."""
        with self._decided:
            self._decided.notify_all()
