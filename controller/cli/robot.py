"""``seamguide mock-robot`` and ``seamguide robot``: the robot link by hand.

``mock-robot`` serves the mock controller on a pseudo-terminal behind a stable symlink until
interrupted; ``robot --port URL ping|joints|pose`` talks to any controller (the mock's link path,
``/dev/ttyS0``, ``socket://host:port``, ``mock://``) and prints JSON on stdout.
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
import time
from typing import Any

from controller.jsonio import emit_json


def register(sub: Any) -> None:
    """Add the ``mock-robot`` and ``robot`` subcommands to ``sub`` (argparse subparsers)."""
    mr = sub.add_parser(
        "mock-robot", help="run the mock controller on a pseudo-terminal",
        description="Serve the mock ABB controller (SGRS/1 protocol, simulated IRB 2400) on a "
        "pseudo-terminal. Prints {\"link\": PATH} on stdout once it is ready, then runs until "
        "Ctrl-C or SIGTERM. Connect with `seamguide robot --port PATH ping`.")
    mr.add_argument("--link", help="symlink to create for the pty (default: a temporary path)")
    mr.add_argument("--options", default="",
                    help="fault injection and simulation options as a URL query, e.g. "
                    "'seed=7&drop=0.01&corrupt=0.02&baud=9600&time_scale=1'")
    mr.set_defaults(func=_mock_robot)

    rb = sub.add_parser(
        "robot", help="talk to a robot controller by hand",
        description="Open the robot link at URL and print JSON: ping -> the controller's "
        "identity and the round trip; joints -> {\"joints_deg\": [...]}; pose -> the flange "
        "pose (tool0, wobj0) {\"position_mm\": [...], \"quaternion_wxyz\": [...]}.")
    rb.add_argument("action", choices=["ping", "joints", "pose"])
    rb.add_argument("--port", required=True,
                    help="robot URL: /dev/ttyS0, socket://host:port, a mock-robot link path, "
                    "or mock://?options")
    rb.add_argument("--baud", type=int, default=9600, help="serial baud rate (default 9600)")
    rb.add_argument("--timeout", type=float, default=5.0, help="per-request timeout (s)")
    rb.add_argument("--output", help="write the JSON here instead of stdout")
    rb.set_defaults(func=_robot)


def _mock_robot(args: argparse.Namespace) -> int:
    from drivers.mock.mock_controller import MockController, parse_mock_options

    mock = MockController(**parse_mock_options(args.options))
    stop = threading.Event()
    previous = signal.signal(signal.SIGTERM, lambda *_: stop.set())
    path = mock.serve_pty(args.link)
    try:
        emit_json({"link": path, "options": args.options}, None)
        print(f"mock controller serving on {path}; Ctrl-C to stop", file=sys.stderr)
        try:
            while not stop.wait(1.0):
                pass
        except KeyboardInterrupt:
            pass
    finally:
        mock.stop()
        signal.signal(signal.SIGTERM, previous)
    return 0


def _robot(args: argparse.Namespace) -> int:
    from controller.geometry.poses import pose_to_dict
    from drivers.robot import open_robot

    options: dict[str, Any] = {}
    if not args.port.startswith(("mock://", "rapid://")):
        options["baudrate"] = args.baud
    with open_robot(args.port, timeout_s=args.timeout, **options) as robot:
        if args.action == "ping":
            t0 = time.perf_counter()
            info = robot.identify()
            info["round_trip_ms"] = round((time.perf_counter() - t0) * 1000.0, 2)
            emit_json(info, args.output)
        elif args.action == "joints":
            emit_json({"joints_deg": [round(float(v), 4) for v in robot.read_joints()]},
                      args.output)
        else:
            emit_json(pose_to_dict(robot.read_pose()), args.output)
    return 0
