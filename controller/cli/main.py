"""The ``seamguide`` command line: one program, one subcommand per job.

Each group of subcommands lives in a module of this package that exposes ``register(subparsers)``;
the module adds its parsers and sets ``func`` (``args -> int`` exit code). The modules import
nothing heavy at the top (numpy, OpenCV, Pinocchio, scipy come in when a command runs), and only
the module of the command given is imported at all: ``seamguide fk`` does not pay for the vision
stack, ``seamguide --help`` for none of it (``bench/bench_cli_startup.py``). Output JSON goes to
``--output`` or stdout; logs and progress go to stderr. Errors derived from
:class:`SeamguideError` end the program with their own exit code (see the README) and a one-line
message saying what to do.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys
from collections.abc import Sequence

from controller.errors import SeamguideError

# The explicit registry: every subcommand and the module that registers it (imported lazily).
# tests/test_cli_geometry.py checks it against what the modules register.
COMMANDS: dict[str, str] = {
    "fk": "controller.cli.geometry",
    "ik": "controller.cli.geometry",
    "mock-robot": "controller.cli.robot",
    "robot": "controller.cli.robot",
    "dry-run": "controller.cli.cycle",
    "teach-view": "controller.cli.cycle",
    "locate": "controller.cli.cycle",
    "run": "controller.cli.daemon",
    "ctl": "controller.cli.daemon",
    "check-config": "controller.cli.daemon",
    "calibrate": "controller.cli.calibrate",
    "detect": "controller.cli.detect",
}
#: The subcommand modules, in the order their commands are listed by ``--help``.
COMMAND_MODULES: tuple[str, ...] = tuple(dict.fromkeys(COMMANDS.values()))


def _command_of(argv: Sequence[str]) -> str | None:
    """The subcommand named in ``argv`` (the first word that is not an option), if known."""
    for word in argv:
        if not word.startswith("-"):
            return word if word in COMMANDS else None
    return None


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The argument parser: every subcommand, or only ``command``'s module when it is known."""
    parser = argparse.ArgumentParser(
        prog="seamguide",
        description="Vision guidance for a welding robot: find the seam, triangulate it, weld it.")
    parser.add_argument("-v", "--verbose", action="count", default=0,
                        help="more log output on stderr (-vv for debug)")
    parser.add_argument("--log-json", action="store_true",
                        help="log JSON lines on stderr instead of readable text")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    modules = (COMMANDS[command],) if command in COMMANDS else COMMAND_MODULES
    for name in modules:
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
    words = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser(_command_of(words))
    args = parser.parse_args(words)
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
