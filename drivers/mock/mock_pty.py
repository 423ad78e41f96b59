"""The mock controller's transport: a real pseudo-terminal served by a thread.

:class:`PtyTransport` serves a line (:class:`drivers.mock.mock_line.MockLine`: bytes in, bytes
out) on ``os.openpty`` behind a stable symlink path (:meth:`PtyTransport.serve`), so the client's
pyserial code runs for real. A disconnect (:meth:`PtyTransport.disconnect`, or the line's
``disconnect`` fault) opens a new pty behind the same path; whatever is behind the line survives
it. Knows nothing of the protocol: it moves bytes and runs what the line's schedule has due.
"""

from __future__ import annotations

import contextlib
import logging
import os
import select
import tempfile
import threading
import time
import tty
from collections.abc import Callable
from pathlib import Path

from controller.errors import ConfigError
from drivers.mock.mock_line import MockLine

log = logging.getLogger("seamguide.mock")


class PtyTransport:
    """Serves ``line`` on a pseudo-terminal in a thread; stop it with :meth:`stop`.

    ``on_disconnect`` is called (under the line's lock) each time the link is dropped.
    """

    def __init__(self, line: MockLine, on_disconnect: Callable[[], None] | None = None) -> None:
        self.line = line
        self.on_disconnect = on_disconnect
        self._thread: threading.Thread | None = None
        self._ending: threading.Thread | None = None  # stopped, not ended within the timeout
        self._wake_r, self._wake_w = -1, -1
        self._stop = threading.Event()
        self._master = self._slave = -1
        self.link_path: str | None = None
        self._tmpdir: str | None = None
        self._swap_request = threading.Event()
        self._swap_done = threading.Event()
        # The serving thread closes its own descriptors when it ends (never another thread: a
        # number closed twice may by then be someone else's); this lock keeps wake() from
        # writing to a number being closed.
        self._fd_lock = threading.Lock()

    @property
    def serving(self) -> bool:
        """True between :meth:`serve` and :meth:`stop`."""
        return self._thread is not None

    def wake(self) -> None:
        """Wake the serving thread (something new is scheduled)."""
        with self._fd_lock:
            if self._wake_w >= 0:
                with contextlib.suppress(BlockingIOError, OSError):
                    os.write(self._wake_w, b"x")

    def drop_link(self) -> None:
        """Drop the link from inside the serving thread (the line's ``disconnect`` fault)."""
        self._swap_done.clear()
        self._swap_request.set()

    def disconnect(self, timeout_s: float = 2.0, wait: bool = True) -> None:
        """Drop the link: close the pty and open a new one behind the same symlink path.

        The controller state (session, remembered reply, motion) survives, as when a cable is
        pulled and plugged back; replies not yet written are lost. Only for a mock served with
        :meth:`serve`. ``wait=False`` returns at once (for use inside the mock's own thread).
        """
        if self._thread is None:
            raise ConfigError("disconnect() needs a mock served on a pty (serve_pty)")
        self._swap_done.clear()
        self._swap_request.set()
        self.wake()
        if wait and not self._swap_done.wait(timeout_s):
            raise ConfigError("mock controller did not swap its pty in time")

    # ---- serving on a pseudo-terminal ----------------------------------------------------------

    def _open_pty(self) -> str:
        master, slave = os.openpty()
        tty.setraw(slave)
        os.set_blocking(master, False)
        self._master, self._slave = master, slave
        return os.ttyname(slave)

    def _point_link(self, target: str) -> None:
        assert self.link_path is not None
        tmp = f"{self.link_path}.{os.getpid()}.tmp"
        if os.path.lexists(tmp):
            os.unlink(tmp)
        os.symlink(target, tmp)
        os.replace(tmp, self.link_path)

    def serve(self, link_path: str | None = None) -> str:
        """Serve on a new pseudo-terminal in a thread; return the stable symlink path to open.

        ``link_path`` (default: a new temporary directory's ``robot``) must not be an existing
        non-symlink file. Stop with :meth:`stop`.
        """
        if self._thread is not None:
            raise ConfigError("this mock controller is already serving")
        if self._ending is not None and self._ending.is_alive():
            raise ConfigError("this mock controller's last serving thread has not ended yet")
        if link_path is None:
            self._tmpdir = tempfile.mkdtemp(prefix="seamguide-mock-")
            link_path = str(Path(self._tmpdir) / "robot")
        lp = Path(link_path)
        if lp.exists() and not lp.is_symlink():
            raise ConfigError(f"--link {link_path!r} exists and is not a symlink; choose another "
                              "path (the mock makes a symlink to its pseudo-terminal there)")
        self.link_path = str(lp.absolute())
        self._point_link(self._open_pty())
        self._wake_r, self._wake_w = os.pipe()
        os.set_blocking(self._wake_r, False)
        os.set_blocking(self._wake_w, False)
        self._stop.clear()
        self.line.on_drop = self.drop_link
        self.line.schedule.on_change = self.wake
        self._thread = threading.Thread(target=self._serve, name="mock-controller", daemon=True)
        self._thread.start()
        return self.link_path

    def _serve(self) -> None:
        try:
            self._serve_until_stopped()
        finally:
            with self._fd_lock:
                for fd in (self._master, self._slave, self._wake_r, self._wake_w):
                    with contextlib.suppress(OSError):
                        os.close(fd)
                self._master = self._slave = self._wake_r = self._wake_w = -1

    def _serve_until_stopped(self) -> None:
        pending = b""
        while not self._stop.is_set():
            pending += self.line.run_due()
            if self._swap_request.is_set():  # after run_due: replies not yet written are lost
                self._swap_request.clear()
                with self.line.lock:
                    old = (self._master, self._slave)
                    name = self._open_pty()  # before closing: a new /dev/pts number
                    for fd in old:
                        os.close(fd)
                    pending = b""
                    self.line.clear()
                    self._point_link(name)
                    if self.on_disconnect is not None:
                        self.on_disconnect()
                self._swap_done.set()
            if pending:
                try:
                    n = os.write(self._master, pending)
                    pending = pending[n:]
                except BlockingIOError:
                    pass
                except OSError:
                    pending = b""
            due = self.line.next_due()
            now = time.monotonic()
            wait = 0.2 if due is None else max(0.0, min(0.2, due - now))
            if pending:
                wait = min(wait, 0.005)
            try:
                ready, _, _ = select.select([self._master, self._wake_r], [], [], wait)
            except (OSError, ValueError):
                continue
            if self._wake_r in ready:
                with contextlib.suppress(BlockingIOError):
                    os.read(self._wake_r, 4096)
            if self._master in ready:
                try:
                    data = os.read(self._master, 4096)
                except (BlockingIOError, OSError):
                    data = b""
                if data:
                    self.line.receive(data)

    def stop(self, timeout_s: float = 5.0) -> None:
        """Stop serving and remove the symlink (and the temporary directory it made).

        The serving thread closes the pseudo-terminal and its wake pipe as it ends; when it
        does not end within ``timeout_s`` (s), they are left to it and a warning is logged.
        """
        if self._thread is None:
            return
        self._stop.set()
        self.wake()
        self._thread.join(timeout=timeout_s)
        if self._thread.is_alive():
            log.warning("mock controller thread did not stop within %.1f s; it closes its "
                        "pseudo-terminal when it ends", timeout_s)
            self._ending = self._thread
        self._thread = None
        self.line.on_drop = None
        self.line.schedule.on_change = None
        if self.link_path and os.path.islink(self.link_path):
            os.unlink(self.link_path)
        if self._tmpdir:
            with contextlib.suppress(OSError):
                os.rmdir(self._tmpdir)
            self._tmpdir = None
