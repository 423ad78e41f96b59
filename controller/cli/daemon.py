"""``seamguide run``, ``seamguide ctl`` and ``seamguide check-config``: the cell daemon."""

from __future__ import annotations

import argparse
import logging
import sys
from typing import Any

from controller.jsonio import emit_json


def register(sub: Any) -> None:
    """Add the ``run``, ``ctl`` and ``check-config`` subcommands."""
    r = sub.add_parser("run", help="the cell daemon", description="Runs the cell: opens the robot "
                       "link and the camera, waits for cycle requests from the controller and "
                       "from the control socket, runs cycles. SIGTERM stops safely (a running "
                       "weld is aborted with the arc off first); SIGHUP reloads the configuration.")
    r.add_argument("--config", required=True, help="cell configuration (TOML)")
    r.set_defaults(func=_run)

    c = sub.add_parser("ctl", help="control a running daemon",
                       description="Sends one request to the daemon of the given configuration "
                       "over its local control socket and prints the JSON reply.")
    c.add_argument("--config", required=True, help="cell configuration (names the socket)")
    c.add_argument("request", choices=["start", "status", "abort", "pause", "resume", "confirm",
                                       "reject"])
    c.add_argument("job", nargs="?", help="job name (for start)")
    c.add_argument("--timeout", type=float, default=10.0, help="seconds to wait for the reply")
    c.set_defaults(func=_ctl)

    k = sub.add_parser("check-config", help="validate a cell configuration, its jobs and "
                       "calibration")
    k.add_argument("--config", required=True, help="cell configuration (TOML)")
    k.set_defaults(func=_check)


def _run(args: argparse.Namespace) -> int:
    from controller.cell.daemon import Daemon

    daemon = Daemon(args.config)
    if daemon.cfg.log_file:
        from pathlib import Path

        from controller.cli.log_format import JsonLineFormatter

        Path(daemon.cfg.log_file).parent.mkdir(parents=True, exist_ok=True)
        fh = logging.FileHandler(daemon.cfg.log_file)
        fh.setFormatter(JsonLineFormatter())
        logging.getLogger().addHandler(fh)
    if logging.getLogger().level > logging.INFO:
        logging.getLogger().setLevel(logging.INFO)
    daemon.install_signal_handlers()
    station = None
    if daemon.cfg.http is not None:
        from controller.station.bootstrap import start_station

        station = start_station(daemon, daemon.cfg)
    try:
        return daemon.serve()
    finally:
        if station is not None:
            station.stop()


def _ctl(args: argparse.Namespace) -> int:
    from controller.cell.cell_config import load_cell_config
    from controller.cell.control_socket import send_request
    from controller.errors import ConfigError

    cfg = load_cell_config(args.config)
    req: dict[str, Any] = {"cmd": args.request}
    if args.request == "start":
        if not args.job:
            raise ConfigError("ctl start needs a job name: seamguide ctl --config CELL start JOB")
        req["job"] = args.job
    reply = send_request(cfg.control.socket, req, args.timeout)
    emit_json(reply, None)
    return 0 if reply.get("ok") else 2


def _check(args: argparse.Namespace) -> int:
    from controller.cell.cell_config import check_config

    for line in check_config(args.config):
        print(line, file=sys.stderr)
    from controller.cell.cell_config import load_cell_config

    cfg = load_cell_config(args.config)
    if cfg.http is not None:
        from controller.station.bootstrap import check_http

        tokens = check_http(cfg.http)
        print(f"operator station: http://{cfg.http.bind}:{cfg.http.port}/ "
              f"({'tokens' if tokens else 'no token: loopback only'})", file=sys.stderr)
    return 0
