"""A simulated cell served by an in-process daemon with the operator station on a free port."""

import contextlib
import threading

from daemon_harness import make_cell

from controller.cell.cell_config import load_cell_config
from controller.cell.daemon import Daemon
from controller.station.bootstrap import start_station


def station_cell(folder, *, confirm=False, tokens=None, extra_http=""):
    """A sim cell with ``[http]`` on 127.0.0.1 port 0; ``tokens`` = (viewer, operator) or None."""
    http = '\n[http]\nbind = "127.0.0.1"\nport = 0\n' + extra_http
    if tokens is not None:
        tf = folder / "tokens.toml"
        folder.mkdir(parents=True, exist_ok=True)
        tf.write_text(f'viewer = "{tokens[0]}"\noperator = "{tokens[1]}"\n')
        tf.chmod(0o600)
        http += 'token_file = "tokens.toml"\n'
    cfg = make_cell(folder, extra=http)
    if confirm:
        job = cfg.parent / "demo-job.toml"
        job.write_text(job.read_text().replace("confirm = false", "confirm = true"))
    return cfg


@contextlib.contextmanager
def serving_station(cfg_path):
    """(daemon, station url, state log) with the daemon serving; stopped afterwards.

    The state log holds ``(time.time(), state)`` for every state the daemon entered.
    """
    import time

    d = Daemon(cfg_path)
    states = []
    d.observers.append(lambda ev, data: states.append((time.time(), data.get("state")))
                       if ev == "state" else None)
    server = start_station(d, load_cell_config(cfg_path))
    assert server is not None
    t = threading.Thread(target=d.serve, daemon=True)
    t.start()
    try:
        assert d.ready.wait(30), "daemon did not become ready"
        yield d, server.url, states
    finally:
        d.request_stop("test over")
        t.join(60)
        server.stop()
    assert not t.is_alive()
