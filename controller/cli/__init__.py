"""The ``seamguide`` command line: one module per group of subcommands; ``main`` is the entry."""

from controller.cli.main import main

__all__ = ["main"]
