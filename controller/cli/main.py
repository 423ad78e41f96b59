"""The ``seamguide`` command line: one program, one subcommand per job.

Each subcommand lives in a ``cli_*.py`` module that exposes ``register(subparsers)``; the module
adds its parser and sets ``func`` (``args -> int`` exit code). Output JSON goes to ``--output`` or
stdout; logs and progress go to stderr. Errors derived from :class:`SeamguideError` end the program
with their own exit code (see the README) and a one-line message saying what to do.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys
from collections.abc import Sequence

from controller.errors import SeamguideError

# The explicit registry of subcommand modules (imported lazily, so `seamguide fk` does not pay for
# OpenCV and the vision stack).
COMMAND_MODULES: tuple[str, ...] = (
    "controller.cli.geometry",
    "controller.cli.robot",
    "controller.cli.cycle",
    "controller.cli.daemon",
    "controller.cli.calibrate",
    "controller.cli.detect",
)


def build_parser() -> argparse.ArgumentParser:
    """The full argument parser with every registered subcommand."""
    parser = argparse.ArgumentParser(
        prog="seamguide",
        description="Vision guidance for a welding robot: find the seam, triangulate it, weld it.")
    parser.add_argument("-v", "--verbose", action="count", default=0,
                        help="more log output on stderr (-vv for debug)")
    parser.add_argument("--log-json", action="store_true",
                        help="log JSON lines on stderr instead of readable text")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name in COMMAND_MODULES:
        importlib.import_module(name).register(sub)
    return parser


def setup_logging(verbosity: int, json_lines: bool = False) -> None:
    """Configure the root logger on stderr: the only place the product configures logging."""
    level = logging.WARNING - 10 * min(verbosity, 2)
    handler = logging.StreamHandler(sys.stderr)
    if json_lines:
        from controller.cli.log_format import JsonLineFormatter

        handler.setFormatter(JsonLineFormatter())
    else:
        handler.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(name)s: %(message)s",
                                               "%H:%M:%S"))
    root = logging.getLogger()
    root.handlers[:] = [handler]
    root.setLevel(level)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``seamguide`` console script; returns the process exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    setup_logging(args.verbose, args.log_json)
    try:
        return int(args.func(args))
    except SeamguideError as err:
        print(f"seamguide {args.command}: error: {err}", file=sys.stderr)
        return err.exit_code
    except KeyboardInterrupt:
        print(f"seamguide {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
