"""Serve the station with waitress (a pure-Python production WSGI server) in a daemon thread.

waitress bounds request headers and bodies itself (``max_request_header_size``,
``max_request_body_size``), and runs the application in a small thread pool, so a slow browser
never blocks the cell's serve thread.
"""

from __future__ import annotations

import logging
import threading
from typing import Any

log = logging.getLogger("seamguide.station")


class StationServer:
    """The HTTP listener; :meth:`start` binds (port 0 picks a free one), :meth:`stop` closes."""

    def __init__(self, app: Any, bind: str, port: int, max_request_bytes: int) -> None:
        from waitress.server import create_server

        self._server = create_server(app, host=bind, port=port, threads=4,
                                     max_request_body_size=max_request_bytes,
                                     max_request_header_size=max(8192, max_request_bytes),
                                     ident="seamguide", clear_untrusted_proxy_headers=True)
        self._thread: threading.Thread | None = None

    @property
    def url(self) -> str:
        """``http://HOST:PORT`` the server listens on."""
        host = str(self._server.effective_host)
        host = f"[{host}]" if ":" in host else host
        return f"http://{host}:{self._server.effective_port}"

    def start(self) -> None:
        """Serve in a background thread."""
        self._thread = threading.Thread(target=self._server.run, name="station", daemon=True)
        self._thread.start()
        log.info("operator station at %s", self.url)

    def stop(self, timeout_s: float = 5.0) -> None:
        """Finish the requests being served, close every connection, wait for the thread.

        When the loop's thread does not end within ``timeout_s`` (s), its connections are left
        for it to close when it does, and a warning is logged.
        """
        from waitress import wasyncore

        # In this order: running tasks still wake the loop through its trigger when they end;
        # closing every channel (the listener and the trigger included) then ends run().
        self._server.task_dispatcher.shutdown(cancel_pending=True, timeout=5)
        server_map = self._server._map
        if self._thread is not None and self._thread.is_alive():
            # Closed by the loop's own thread, between two select() calls: a socket closed
            # from here while the loop waits on it in select() ends the loop with EBADF
            # (waitress issue 468, fixed upstream after 3.0.2, the release this machine has).
            self._server.trigger.pull_trigger(lambda: wasyncore.close_all(server_map))
            self._thread.join(timeout=timeout_s)
            if self._thread.is_alive():
                # Not closed from here as well: two threads closing the same channels can close
                # a descriptor number twice, the second time someone else's by then.
                log.warning("operator station did not stop within %.1f s; its loop closes its "
                            "connections when it ends", timeout_s)
                return
        if server_map:  # never started, or the loop ended without running the close
            wasyncore.close_all(server_map)
