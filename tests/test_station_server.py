"""The station's HTTP server stops without killing its loop (waitress issue 468).

Closing the listener from the stopping thread while the server's loop waits on it in select()
raised EBADF in the loop's thread now and then (a PytestUnhandledThreadExceptionWarning in the
browser tests). The channels are now closed by the loop's own thread.
"""

from __future__ import annotations

import threading
import urllib.request
from typing import Any

import pytest
from waitress import wasyncore

from controller.station.server import StationServer


def _app(environ: dict[str, Any], start_response: Any) -> list[bytes]:
    start_response("200 OK", [("Content-Type", "text/plain")])
    return [b"ok"]


@pytest.fixture
def closed_by(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """The names of the threads that call ``wasyncore.close_all``, in order."""
    names: list[str] = []
    real = wasyncore.close_all

    def spy(map: Any = None, ignore_all: bool = False) -> None:
        names.append(threading.current_thread().name)
        real(map, ignore_all)

    monkeypatch.setattr(wasyncore, "close_all", spy)
    return names


def test_the_loop_closes_its_own_channels_and_ends(closed_by: list[str]) -> None:
    server = StationServer(_app, "127.0.0.1", 0, 65536)
    server.start()
    with urllib.request.urlopen(server.url + "/", timeout=10) as r:
        assert r.read() == b"ok"
    server.stop()
    assert closed_by == ["station"]  # the loop's thread, once
    assert server._thread is not None and not server._thread.is_alive()


def test_a_stop_that_times_out_leaves_the_closing_to_the_loop(closed_by: list[str]) -> None:
    server = StationServer(_app, "127.0.0.1", 0, 65536)
    server.start()
    trigger = server._server.trigger
    entered, release = threading.Event(), threading.Event()
    wake_up = trigger.handle_read

    def held() -> None:  # the loop's thread held inside a handler, as by a slow one
        entered.set()
        release.wait(10.0)
        wake_up()

    trigger.handle_read = held
    trigger.pull_trigger()
    try:
        assert entered.wait(5.0)
        server.stop(timeout_s=0.2)
        assert closed_by == []  # nothing closed from this thread while the loop runs
    finally:
        release.set()
    assert server._thread is not None
    server._thread.join(5.0)
    assert not server._thread.is_alive() and closed_by == ["station"]


def test_a_server_never_started_is_closed_by_stop() -> None:
    server = StationServer(_app, "127.0.0.1", 0, 65536)
    server.stop()
    assert not server._server._map  # the listener closed, nothing left to leak


def test_many_stops_leave_no_thread_exception() -> None:
    errors: list[BaseException] = []
    old = threading.excepthook
    threading.excepthook = lambda args: errors.append(args.exc_value)  # type: ignore[assignment]
    try:
        for _ in range(20):
            server = StationServer(_app, "127.0.0.1", 0, 65536)
            server.start()
            server.stop()
    finally:
        threading.excepthook = old
    assert errors == []
