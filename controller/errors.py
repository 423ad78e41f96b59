"""The product's exception tree.

One root, :class:`SeamguideError`, and one subclass per kind of failure a user can act on. Every
message says what was wrong, with which input, and what to do. Each leaf has its own CLI exit code
(:attr:`SeamguideError.exit_code`), listed in the README.

Only the link module catches ``serial.SerialException`` / ``OSError`` and re-raises them as
:class:`LinkError` ``from`` the original.
"""

from __future__ import annotations

from typing import Any


class SeamguideError(Exception):
    """Root of every error seamguide raises on purpose.

    ``details`` carries the data behind the failure (the input, the score, the residual in mm) so
    that cycle records and the daemon's status can report it without parsing the message.
    """

    exit_code = 1

    def __init__(self, message: str, **details: Any) -> None:
        super().__init__(message)
        self.details: dict[str, Any] = details


class ConfigError(SeamguideError):
    """A configuration, job or command-line value is missing, malformed or out of range."""

    exit_code = 2


class InputError(SeamguideError):
    """A user-supplied file or value (image, view file, pose, joint list) is unusable."""

    exit_code = 3


class CalibrationError(SeamguideError):
    """A calibration file is invalid, or a calibration could not be solved or failed validation."""

    exit_code = 4


class LinkError(SeamguideError):
    """The serial link failed: port cannot be opened, no reply within the timeout, disconnected."""

    exit_code = 5


class ProtocolError(LinkError):
    """Bytes arrived but do not form a valid message (bad framing, checksum, field, sequence)."""

    exit_code = 6


class RobotFault(SeamguideError):
    """The controller answered with an error, or reported a fault during a motion or weld."""

    exit_code = 7


class CameraError(SeamguideError):
    """The camera could not be opened or did not deliver a usable frame."""

    exit_code = 8


class SeamNotFound(SeamguideError):
    """No weld joint was found in an image (or in the region of interest)."""

    exit_code = 9


class AmbiguousSeam(SeamguideError):
    """Two or more seam candidates of similar strength: refusing to choose."""

    exit_code = 10


class TriangulationError(SeamguideError):
    """The 3D seam failed a quality limit (ray gap, reprojection error, angle, coverage)."""

    exit_code = 11


class ReachabilityError(SeamguideError):
    """A target cannot be reached: outside joint limits, no IK solution, outside the workspace."""

    exit_code = 12


class JointLimitError(ReachabilityError):
    """Joint values lie outside the robot's joint limits."""

    exit_code = 13


class SafetyError(SeamguideError):
    """A command was refused by a safety check (workspace box, speed, state) before sending."""

    exit_code = 14


class PoseMismatchError(SeamguideError):
    """FK of the reported joints disagrees with the controller's Cartesian pose.

    Usually a wrong robot model, a wrong tool on the controller, or a wrong axis 2/3 coupling.
    """

    exit_code = 15


class CycleAborted(SeamguideError):
    """The weld cycle was aborted by the operator or by a shutdown request."""

    exit_code = 16


def named_error(err: SeamguideError, name: str) -> SeamguideError:
    """``err`` as the same error type, its message starting with ``NAME: `` (details + view)."""
    msg = str(err)
    if msg.startswith(f"{name}:"):
        return err
    try:
        return type(err)(f"{name}: {msg}", **{**err.details, "view": name})
    except TypeError:  # an error type with its own constructor: keep it as it is
        return err
