"""Record rotation and systemd notification (no daemon needed)."""

import os
import socket

from controller.cell.cycle_record import CycleRecord, rotate_records
from controller.cell.sd_notify import notify, watchdog_interval_s


def test_rotation_by_age_and_size_keeps_running_records(tmp_path):
    recs = []
    for i in range(4):
        r = CycleRecord(tmp_path, "job", wall_clock=lambda i=i: 1000.0 + i)
        r.save_text("big.bin", "x" * 400_000)
        if i != 1:
            r.finish("done")
        recs.append(r)
    for i, r in enumerate(recs):
        os.utime(r.path / "record.json", (1000.0 + i * 86400, 1000.0 + i * 86400))
    now = 1000.0 + 3 * 86400 + 10
    deleted = rotate_records(tmp_path, max_age_days=2.5, max_total_mb=10, now=now)
    assert deleted == [recs[0].path]  # the only finished record older than 2.5 days
    assert recs[1].path.exists()  # incomplete: never deleted even though old
    deleted = rotate_records(tmp_path, max_age_days=100, max_total_mb=0.5, now=now)
    assert deleted == [recs[2].path]  # oldest finished first until under 0.5 MB
    assert recs[3].path.exists() and recs[1].path.exists()


def test_sd_notify_sends_datagrams(tmp_path, monkeypatch):
    path = str(tmp_path / "notify.sock")
    srv = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    srv.bind(path)
    srv.settimeout(5)
    monkeypatch.setenv("NOTIFY_SOCKET", path)
    assert notify("READY=1")
    assert srv.recv(100) == b"READY=1"
    srv.close()
    monkeypatch.setenv("WATCHDOG_USEC", "30000000")
    monkeypatch.setenv("WATCHDOG_PID", str(os.getpid()))
    assert watchdog_interval_s() == 15.0
    monkeypatch.delenv("NOTIFY_SOCKET")
    assert notify("READY=1") is False


def test_sd_notify_never_blocks_on_a_full_queue(tmp_path, monkeypatch):
    path = str(tmp_path / "notify.sock")
    srv = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    srv.bind(path)  # nobody reads: the queue fills up
    monkeypatch.setenv("NOTIFY_SOCKET", path)
    sent = [notify("WATCHDOG=1") for _ in range(2000)]
    assert sent[0] and not all(sent)  # the first ones went, the rest were dropped, no hang
    srv.close()


def test_watchdog_pings_through_a_bounded_wait_then_stops(tmp_path, monkeypatch):
    """A wait bounded by its own timeout (a reconnect backoff, a cycle state) keeps the pings
    going although the serve loop does not check in; past the bound they stop."""
    import threading
    import time

    from controller.cell.watchdog import Watchdog

    path = str(tmp_path / "notify.sock")
    srv = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    srv.bind(path)
    srv.settimeout(0.5)
    monkeypatch.setenv("NOTIFY_SOCKET", path)
    wd = Watchdog()  # nothing serves, nothing checks in
    stop = threading.Event()
    wd.busy(0.6)
    t = threading.Thread(target=wd.run, args=(0.05, stop), daemon=True)
    t.start()
    try:
        t0 = time.monotonic()
        times = []
        while time.monotonic() - t0 < 1.2:
            try:
                if srv.recv(100) == b"WATCHDOG=1":
                    times.append(time.monotonic() - t0)
            except TimeoutError:
                break
    finally:
        stop.set()
        t.join(5)
        srv.close()
    assert times and max(times) > 0.4  # well past 2 intervals without a check-in: still alive
    assert max(times) < 0.8  # the bound (0.6 s + one interval) passed: no more pings
