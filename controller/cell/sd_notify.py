"""systemd's notify protocol (``Type=notify``, ``WatchdogSec=``) without a dependency.

See sd_notify(3): a datagram to the socket named by ``$NOTIFY_SOCKET``. Outside systemd (no
variable) every call does nothing.
"""

from __future__ import annotations

import os
import socket


def notify(state: str) -> bool:
    """Send ``state`` (e.g. ``READY=1``, ``WATCHDOG=1``, ``STATUS=...``); True if sent."""
    addr = os.environ.get("NOTIFY_SOCKET")
    if not addr:
        return False
    if addr.startswith("@"):
        addr = "\0" + addr[1:]
    try:
        with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as s:
            s.connect(addr)
            # Never block the daemon on a slow or stuck receiver: a full queue drops the message.
            s.send(state.encode("utf-8"), socket.MSG_DONTWAIT)
        return True
    except OSError:  # BlockingIOError (queue full) included
        return False


def watchdog_interval_s() -> float | None:
    """Half the watchdog period systemd asks for (``$WATCHDOG_USEC``), or None without one."""
    usec = os.environ.get("WATCHDOG_USEC")
    pid = os.environ.get("WATCHDOG_PID")
    if not usec or (pid and pid != str(os.getpid())):
        return None
    try:
        return int(usec) / 2e6
    except ValueError:
        return None
