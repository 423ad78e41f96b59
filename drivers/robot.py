"""``open_robot(url)``: the one registry of robot links, and the robot interface's public names.

The interface itself is in :mod:`drivers.robot_interface` (``Robot``, ``MotionHandle``,
``Event``, ``MotionTimeout``) and the validated commands with their :class:`SafetyLimits` in
:mod:`drivers.robot_commands`; the interface and ``SafetyLimits`` are re-exported here, the
module to open robots from. The link (:mod:`drivers.abb`) imports those two and never this one,
so imports run one way.

The controller only sees :class:`Robot`; it cannot tell the mock from the real controller. Robots
are chosen by URL through one explicit registry (:func:`open_robot`):

* ``mock://?seed=7&drop=0.01&...``: an in-process
:class:`~drivers.mock.mock_controller.MockController`
  served on a real pseudo-terminal and driven by the same client as the real robot; the mock
  object is reachable as ``robot.mock`` (for tests and the simulated camera).
* anything else (``/dev/ttyS0``, ``/dev/pts/N``, a pty symlink, ``socket://host:port``,
  ``loop://``, ``spy://...``) goes to pyserial's ``serial_for_url`` untouched.

Every motion command is a frozen value object validated against :class:`SafetyLimits` (workspace
box, speed) and the robot model (joint limits, reachability) *before* a byte is encoded.
"""

from __future__ import annotations

import importlib
import pkgutil
from typing import Any

from controller.errors import ConfigError
from drivers.abb.abb_robot import AbbRobot
from drivers.robot_commands import SafetyLimits
from drivers.robot_interface import DEFAULT_TIMEOUT_S, Event, MotionHandle, MotionTimeout, Robot

# The public names of the robot interface, importable from here (the module users open robots with).
__all__ = ["DEFAULT_TIMEOUT_S", "ROBOT_SCHEMES", "Event", "MotionHandle", "MotionTimeout", "Robot",
           "SafetyLimits", "open_robot", "serial_schemes"]


# ---- the registry ---------------------------------------------------------------------------

#: Robot URL schemes handled by seamguide itself (module:function, imported lazily).
ROBOT_SCHEMES: dict[str, str] = {"mock": "drivers.mock.mock_controller:open_mock_robot",
                                 "rapid": "drivers.rapid_vm.vm_controller:open_rapid_robot"}


def serial_schemes() -> list[str]:
    """URL schemes pyserial's ``serial_for_url`` knows (its ``protocol_*`` handler modules)."""
    import serial.urlhandler

    mods = pkgutil.iter_modules(serial.urlhandler.__path__)
    return sorted(m.name[len("protocol_"):] for m in mods if m.name.startswith("protocol_"))


def open_robot(url: str, *, limits: SafetyLimits | None = None,
               timeout_s: float = DEFAULT_TIMEOUT_S, **link_options: Any) -> Robot:
    """A :class:`Robot` for ``url`` (not opened yet: use it as a context manager or call open()).

    ``mock://?opts`` builds an in-process mock controller on a pseudo-terminal; any other URL
    (device path or a pyserial URL) is handed to ``serial_for_url`` untouched. ``limits`` default
    to :class:`SafetyLimits` ``()``; ``timeout_s`` bounds each request. ``link_options`` go to
    :class:`~drivers.abb.abb_robot.AbbRobot` (``ack_timeout_s``, ``retries``, ``baudrate``, ...).
    Raises :class:`ConfigError` for an unknown scheme (listing the known ones) or mock option.
    """
    if not isinstance(url, str) or not url:
        raise ConfigError(f"robot URL must be a non-empty string, got {url!r}")
    lim = limits if limits is not None else SafetyLimits()
    if "://" in url:
        scheme = url.split("://", 1)[0].lower()
        if scheme in ROBOT_SCHEMES:
            mod, fn = ROBOT_SCHEMES[scheme].split(":")
            factory = getattr(importlib.import_module(mod), fn)
            robot: Robot = factory(url, limits=lim, timeout_s=timeout_s, **link_options)
            return robot
        known = sorted(ROBOT_SCHEMES) + serial_schemes()
        if scheme not in known:
            raise ConfigError(f"robot URL {url!r}: unknown scheme {scheme!r}; known schemes: "
                              f"{', '.join(s + '://' for s in known)} or a device path")
    return AbbRobot(url, limits=lim, timeout_s=timeout_s, **link_options)
