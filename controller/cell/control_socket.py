"""The daemon's local control socket: one JSON object per line, one reply line per request.

Requests: ``{"cmd": "start", "job": "demo"}``, ``{"cmd": "status"}``, ``{"cmd": "abort"}``,
``{"cmd": "pause"}``, ``{"cmd": "resume"}``, and ``{"cmd": "confirm"}`` / ``{"cmd": "reject"}``
for a weld path waiting for the operator. Replies: ``{"ok": true, ...}`` or
``{"ok": false, "error": "..."}``. A Unix domain socket created with owner-only permissions (0600)
in a folder the daemon owns; there is no network listener. A malformed, unknown or oversize request
gets an error reply and never disturbs the daemon. Documented in docs/daemon.md.
"""

from __future__ import annotations

import json
import logging
import os
import socket
import socketserver
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

from controller.errors import ConfigError, LinkError

log = logging.getLogger(__name__)

Handler = Callable[[dict[str, Any]], dict[str, Any]]


class _Server(socketserver.ThreadingMixIn, socketserver.UnixStreamServer):
    daemon_threads = True
    allow_reuse_address = True
    handler: Handler
    max_line: int


class _RequestHandler(socketserver.StreamRequestHandler):
    timeout = 10.0

    def handle(self) -> None:
        server: _Server = self.server  # type: ignore[assignment]
        while True:
            try:
                line = self.rfile.readline(server.max_line + 1)
            except (OSError, TimeoutError):
                return
            if not line:
                return
            if len(line) > server.max_line or not line.endswith(b"\n") and \
                    len(line) == server.max_line + 1:
                self._reply({"ok": False, "error": f"request longer than {server.max_line} "
                                                   f"bytes; closing the connection"})
                return
            try:
                req = json.loads(line.decode("utf-8"))
                if not isinstance(req, dict):
                    raise ValueError("a request must be a JSON object")
            except (ValueError, UnicodeDecodeError) as err:
                self._reply({"ok": False, "error": f"malformed request ({err}); send one "
                                                   f"JSON object per line, e.g. "
                                                   f"{{\"cmd\": \"status\"}}"})
                continue
            try:
                reply = server.handler(req)
            except Exception as err:  # noqa: BLE001 - a bad request must never kill the daemon
                log.exception("control request %r failed", req)
                reply = {"ok": False, "error": str(err)}
            self._reply(reply)

    def _reply(self, obj: dict[str, Any]) -> None:
        try:
            self.wfile.write((json.dumps(obj, default=str) + "\n").encode("utf-8"))
            self.wfile.flush()
        except OSError:
            pass


class ControlServer:
    """Serves the control socket in a background thread; ``handler(request) -> reply``."""

    def __init__(self, path: str | os.PathLike[str], handler: Handler,
                 max_line_bytes: int = 4096) -> None:
        self.path = Path(path)
        self._handler = handler
        self._max_line = max_line_bytes
        self._server: _Server | None = None
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        """Create the socket (0600; a stale socket file from a dead daemon is replaced)."""
        self.path.parent.mkdir(parents=True, exist_ok=True)
        if self.path.exists():
            if _alive(self.path):
                raise ConfigError(f"control socket {self.path} is in use: another seamguide "
                                  f"daemon runs with this configuration")
            self.path.unlink()
        old = os.umask(0o177)
        try:
            server = _Server(str(self.path), _RequestHandler)
        finally:
            os.umask(old)
        os.chmod(self.path, 0o600)
        server.handler = self._handler
        server.max_line = self._max_line
        self._server = server
        self._thread = threading.Thread(target=server.serve_forever, name="control-socket",
                                        kwargs={"poll_interval": 0.2}, daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Stop serving and remove the socket file."""
        if self._server is not None:
            self._server.shutdown()
            self._server.server_close()
            self._server = None
        self.path.unlink(missing_ok=True)


def _alive(path: Path) -> bool:
    s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    s.settimeout(1.0)
    try:
        s.connect(str(path))
        return True
    except OSError:
        return False
    finally:
        s.close()


def exchange(path: str | os.PathLike[str], data: bytes, timeout_s: float = 10.0) -> bytes:
    """Send raw bytes to a daemon's control socket and return its reply line (bytes).

    Raises :class:`LinkError` when no daemon listens there or it does not answer in time.
    """
    s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    s.settimeout(timeout_s)
    try:
        s.connect(str(path))
        s.sendall(data)
        buf = b""
        while not buf.endswith(b"\n"):
            chunk = s.recv(65536)
            if not chunk:
                break
            buf += chunk
    except FileNotFoundError as err:
        raise LinkError(f"no daemon control socket at {path}: is `seamguide run` running with "
                        f"this configuration?") from err
    except (ConnectionRefusedError, TimeoutError, OSError) as err:
        raise LinkError(f"the daemon at {path} did not answer: {err}") from err
    finally:
        s.close()
    return buf


def send_request(path: str | os.PathLike[str], request: dict[str, Any],
                 timeout_s: float = 10.0) -> dict[str, Any]:
    """Send one request (a JSON object) to a daemon's control socket and return its reply.

    Raises :class:`LinkError` when no daemon listens there, it does not answer in time, or its
    reply is not JSON.
    """
    buf = exchange(path, (json.dumps(request) + "\n").encode("utf-8"), timeout_s)
    try:
        reply: dict[str, Any] = json.loads(buf.decode("utf-8"))
    except ValueError as err:
        raise LinkError(f"the daemon at {path} sent an unreadable reply: {buf[:200]!r}") from err
    return reply
