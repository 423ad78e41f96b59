"""The records folder as the operator station shows it: a searchable list and safe file access.

A record is named by its folder (``YYYYmmdd-HHMMSS-JOB-N``) and a file by its name inside it;
:func:`record_file` refuses anything that would leave the records folder (``..``, absolute
paths, symbolic links pointing out, other characters), so a URL cannot read another file.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from controller.cell.cycle_record import FINAL_STATUSES
from controller.errors import InputError

_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]{0,200}$")
OUTCOMES = ("incomplete",) + FINAL_STATUSES


@dataclass(frozen=True)
class RecordSummary:
    """One line of the history: folder name, job, status, start time, duration (s), reason."""

    name: str
    job: str
    status: str
    started: str
    duration_s: float | None
    reason: str | None


def _inside(root: Path, candidate: Path) -> Path:
    real_root = root.resolve()
    real = candidate.resolve()
    if real != real_root and real_root not in real.parents:
        raise InputError(f"{candidate.name!r} is outside the records folder")
    return real


def record_dir(root: str | Path, name: str) -> Path:
    """The folder of record ``name`` in ``root``; :class:`InputError` if invalid or absent."""
    if not _NAME.match(name) or name in (".", ".."):
        raise InputError(f"{name!r} is not a record name")
    path = _inside(Path(root), Path(root) / name)
    if not (path / "record.json").is_file():
        raise InputError(f"no record {name!r}")
    return path


def record_file(root: str | Path, name: str, file: str) -> Path:
    """A file of a record, confined to that record's folder; :class:`InputError` otherwise."""
    folder = record_dir(root, name)
    if not _NAME.match(file):
        raise InputError(f"{file!r} is not a file name of a record")
    path = _inside(folder, folder / file)
    if not path.is_file():
        raise InputError(f"record {name} has no file {file!r}")
    return path


def read_record_doc(root: str | Path, name: str) -> dict[str, Any]:
    """``record.json`` of a record (a dict); an unreadable one says so in ``status``."""
    folder = record_dir(root, name)
    try:
        doc = json.loads((folder / "record.json").read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError) as err:
        return {"status": "unreadable", "reason": str(err), "files": [], "states": []}
    return doc if isinstance(doc, dict) else {"status": "unreadable", "files": [], "states": []}


def list_records(root: str | Path, *, outcome: str | None = None, job: str | None = None,
                 text: str | None = None, limit: int = 200) -> list[RecordSummary]:
    """Records newest first, filtered by outcome (status), job name and free text in the reason."""
    base = Path(root)
    if not base.is_dir():
        return []
    out: list[RecordSummary] = []
    for folder in sorted((p for p in base.iterdir() if p.is_dir() and _NAME.match(p.name)),
                         key=lambda p: p.name, reverse=True):
        try:
            doc = read_record_doc(base, folder.name)
        except InputError:
            continue
        s = RecordSummary(folder.name, str(doc.get("job", "")), str(doc.get("status", "")),
                          str(doc.get("started", "")), doc.get("duration_s"), doc.get("reason"))
        if outcome and s.status != outcome:
            continue
        if job and s.job != job:
            continue
        if text and text.lower() not in f"{s.name} {s.reason or ''}".lower():
            continue
        out.append(s)
        if len(out) >= limit:
            break
    return out
