"""The interpreter's errors.

A module that does not load, a recoverable RAPID run-time error
(with its error number, for ERROR handlers), and a run-time error that stops the program.
"""

from __future__ import annotations

from controller.errors import ConfigError


class RapidLoadError(ConfigError):
    """A module does not load: a syntax error, or a reference to a name the controller lacks."""


class RapidError(Exception):
    """A recoverable run-time error: ``errno`` (an ``ERR_...`` number) goes to ERROR handlers."""

    def __init__(self, errno: int, message: str) -> None:
        super().__init__(f"RAPID error {errno}: {message}")
        self.errno = errno


class RapidStop(Exception):
    """A run-time error that stops the program (as the controller does: no handler runs).

    Examples: a string longer than 80 characters, an array index out of bounds, a function
    that ends without RETURN, an error that no handler took.
    """
