"""The record of one weld cycle: a folder with everything needed to replay and audit it.

Layout (docs/cycle-record.md)::

    <records>/<YYYYmmdd-HHMMSS>-<job>-<n>/
        record.json        status (incomplete | done | fault | aborted | interrupted), job, times,
                           state history with durations, outcome, reason, error details
        view1.png ...      the images as taken
        view1.json ...     their view files (DESIGN.md contract: image + joints_deg)
        calibration.yaml   the calibration used
        view1_overlay.png  detection overlays
        seam.json          `seamguide locate` output contract: seam_points_mm, weld_path, quality
        weld_path.mod      the weld path as a RAPID module
        seam_plot.png      3D plot of seam and path

Every file is written to a temporary name and renamed, and record.json is rewritten after every
state change, so a crash or power loss leaves a readable record whose status says ``incomplete``.
``seamguide locate --calibration calibration.yaml --view view1.json --view view2.json`` replays
the vision of a recorded cycle.
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from controller.errors import SeamguideError
from controller.jsonio import atomic_write_bytes, atomic_write_text, dumps

FINAL_STATUSES = ("done", "fault", "aborted", "interrupted")


class CycleRecord:
    """Writes one cycle's folder. Create it at the start of the cycle, :meth:`finish` at the end."""

    def __init__(self, root: str | os.PathLike[str], job: str, *, wall_clock: Any = time.time,
                 clock: Any = time.monotonic) -> None:
        self._wall = wall_clock
        self._clock = clock
        stamp = time.strftime("%Y%m%d-%H%M%S", time.localtime(wall_clock()))
        root_path = Path(root)
        root_path.mkdir(parents=True, exist_ok=True)
        n = 1
        while (root_path / f"{stamp}-{job}-{n}").exists():
            n += 1
        self.path = root_path / f"{stamp}-{job}-{n}"
        self.path.mkdir()
        self._t0 = clock()
        self.doc: dict[str, Any] = {
            "status": "incomplete", "job": job,
            "started": time.strftime("%Y-%m-%dT%H:%M:%S%z", time.localtime(wall_clock())),
            "states": [], "files": [], "outcome": None, "reason": None}
        self._flush()

    def _flush(self) -> None:
        atomic_write_text(self.path / "record.json", dumps(self.doc))

    def state(self, name: str) -> None:
        """Note entering state ``name``; closes the previous state's duration."""
        now = self._clock() - self._t0
        if self.doc["states"]:
            last = self.doc["states"][-1]
            last["duration_s"] = round(now - last["t_s"], 4)
        self.doc["states"].append({"state": name, "t_s": round(now, 4)})
        self._flush()

    def note(self, **items: Any) -> None:
        """Add facts to record.json (e.g. the located seam's length, the truth errors)."""
        self.doc.update(items)
        self._flush()

    def _added(self, name: str) -> Path:
        if name not in self.doc["files"]:
            self.doc["files"].append(name)
        return self.path / name

    def save_image(self, name: str, image: np.ndarray) -> Path:
        """Save an image as PNG (lossless)."""
        ok, buf = cv2.imencode(".png", image)
        if not ok:
            raise SeamguideError(f"could not encode {name} as PNG")
        p = self._added(name)
        atomic_write_bytes(p, buf.tobytes())
        self._flush()
        return p

    def save_json(self, name: str, obj: Any) -> Path:
        """Save JSON in the project's style."""
        p = self._added(name)
        atomic_write_text(p, dumps(obj))
        self._flush()
        return p

    def save_text(self, name: str, text: str) -> Path:
        """Save a text file (RAPID module, YAML)."""
        p = self._added(name)
        atomic_write_text(p, text)
        self._flush()
        return p

    def save_bytes(self, name: str, data: bytes) -> Path:
        """Save raw bytes (a PNG made elsewhere)."""
        p = self._added(name)
        atomic_write_bytes(p, data)
        self._flush()
        return p

    def finish(self, status: str, reason: str | None = None, **details: Any) -> None:
        """Close the record with a final status and the reason (for fault/aborted)."""
        if status not in FINAL_STATUSES:
            raise ValueError(f"unknown final status {status!r}")
        now = self._clock() - self._t0
        if self.doc["states"] and "duration_s" not in self.doc["states"][-1]:
            last = self.doc["states"][-1]
            last["duration_s"] = round(now - last["t_s"], 4)
        self.doc.update(status=status, reason=reason, duration_s=round(now, 4),
                        finished=time.strftime("%Y-%m-%dT%H:%M:%S%z",
                                               time.localtime(self._wall())))
        if details:
            self.doc["details"] = json.loads(json.dumps(details, default=str))
        self._flush()


def read_record(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Read a cycle folder's record.json (raises SeamguideError naming the folder if unreadable)."""
    p = Path(path) / "record.json"
    try:
        doc: dict[str, Any] = json.loads(p.read_text(encoding="utf-8"))
        return doc
    except (OSError, ValueError) as err:
        raise SeamguideError(f"cycle record {p} cannot be read: {err}") from err


def read_record_if_any(path: str | os.PathLike[str] | None) -> dict[str, Any] | None:
    """:func:`read_record`, or None when there is no folder or it cannot be read."""
    if path is None:
        return None
    try:
        return read_record(path)
    except SeamguideError:
        return None


def mark_interrupted(root: str | os.PathLike[str]) -> list[Path]:
    """Mark every record under ``root`` still ``incomplete`` as ``interrupted``; return them.

    Called by the daemon at start-up: a record left incomplete means the process died mid-cycle.
    """
    marked: list[Path] = []
    rootp = Path(root)
    if not rootp.is_dir():
        return marked
    for d in sorted(rootp.iterdir()):
        if not (d / "record.json").is_file():
            continue
        doc = read_record(d)
        if doc.get("status") == "incomplete":
            doc["status"] = "interrupted"
            doc["reason"] = "the process stopped during this cycle (crash, kill or power loss)"
            atomic_write_text(d / "record.json", dumps(doc))
            marked.append(d)
    return marked


def rotate_records(root: str | os.PathLike[str], max_age_days: float, max_total_mb: float,
                   now: float | None = None) -> list[Path]:
    """Delete old finished records: older than ``max_age_days``, then the oldest over the size.

    The oldest are deleted until the folder is under ``max_total_mb``; incomplete records (a
    cycle running) are never deleted.

    Returns the deleted folders.
    """
    import shutil

    rootp = Path(root)
    if not rootp.is_dir():
        return []
    now = time.time() if now is None else now
    entries = []
    for d in sorted(rootp.iterdir()):
        rec = d / "record.json"
        if not rec.is_file():
            continue
        try:
            status = read_record(d).get("status")
        except SeamguideError:
            status = "unreadable"
        if status == "incomplete":
            continue
        size = sum(f.stat().st_size for f in d.iterdir() if f.is_file())
        entries.append((rec.stat().st_mtime, d, size))
    entries.sort()
    deleted = []
    total = sum(e[2] for e in entries)
    for mtime, d, size in entries:
        too_old = now - mtime > max_age_days * 86400.0
        too_big = total > max_total_mb * 1e6
        if not (too_old or too_big):
            continue
        shutil.rmtree(d, ignore_errors=True)
        total -= size
        deleted.append(d)
    return deleted
