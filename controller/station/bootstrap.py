"""Start the operator station beside a daemon: access, metrics, the application, the listener."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

from controller.cell.cell_config import CellConfig, HttpSection
from controller.station.access import Access, Tokens, check_bind, load_tokens
from controller.station.metrics import CellMetrics
from controller.station.server import StationServer
from controller.station.web_app import StationSettings, create_app


def check_http(http: HttpSection) -> Tokens | None:
    """Validate the ``[http]`` section: token file readable and owner-only, bind policy.

    Returns the tokens (None without a token file); raises :class:`ConfigError` naming the key.
    """
    tokens = load_tokens(http.token_file) if http.token_file else None
    check_bind(http.bind, tokens)
    return tokens


def _link_stats(daemon: Any) -> tuple[int, dict[str, int]] | None:
    link = getattr(daemon.robot, "link", None)
    stats = getattr(link, "stats", None)
    return (id(link), dict(stats)) if isinstance(stats, dict) else None


def _calibration_age_s(cfg: CellConfig) -> float | None:
    """Age of the oldest camera calibration file (s); None when one cannot be read."""
    try:
        return time.time() - min(Path(e.calibration).stat().st_mtime
                                 for e in cfg.camera_entries().values())
    except OSError:
        return None


def start_station(daemon: Any, cfg: CellConfig) -> StationServer | None:
    """Serve the station for ``daemon`` if ``cfg.http`` is set; returns the running server."""
    if cfg.http is None:
        return None
    tokens = check_http(cfg.http)
    metrics = CellMetrics(cfg.name, link_stats=lambda: _link_stats(daemon),
                          calibration_age_s=lambda: _calibration_age_s(cfg))

    def observe(event: str, data: dict[str, Any]) -> None:
        if event == "state":
            metrics.state_changed(str(data.get("state")))
        elif event == "cycle_end":
            doc = data.get("record_doc") or {}
            metrics.cycle_ended(str(data.get("status")),
                                data.get("error_kind") if data.get("status") == "fault" else None,
                                doc, doc.get("duration_s"))
            metrics.state_changed("idle")

    daemon.observers.append(observe)
    # The first camera's calibration is shown (a one-camera cell's only one).
    first_calibration = next(iter(cfg.camera_entries().values())).calibration
    settings = StationSettings(cell=cfg.name, records_dir=cfg.records.dir,
                               calibration_path=first_calibration, jobs=tuple(sorted(cfg.jobs)),
                               max_request_bytes=cfg.http.max_request_bytes)
    app = create_app(daemon, settings, Access(tokens), metrics.exposition)
    server = StationServer(app, cfg.http.bind, cfg.http.port, cfg.http.max_request_bytes)
    server.start()
    return server
