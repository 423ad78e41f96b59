"""A mock ABB S4 controller running the seamguide RAPID server, for tests, dry runs and benches.

It speaks SGRS/1 (``docs/protocol.md``) byte for byte as ``drivers/abb/rapid/SGSERVER.mod`` does,
with the same sans-I/O codec, and simulates an IRB 2400 with :mod:`controller.geometry.kinematics`:
motions take
time at the commanded speed (times ``time_scale``; 0 makes them instantaneous, but completion is
still reported by an event after the reply), joint limits and unreachable targets are refused with
an error reply, the tool frame is applied, the arc output is switched, a path is executed point by
point with progress events. Fault injection, seeded: corrupted bytes, dropped and duplicated lines
(both directions), slow replies (``delay_ms``), a simulated baud rate (every byte takes 10/baud s
of real time; bytes are counted so :meth:`MockController.link_time_s` computes the wire time),
a controller error at path point N (``fail_at_point``), disconnects (:meth:`disconnect`) and
controller restarts (:meth:`restart`); the operator's cycle request is :meth:`request_cycle`.

It is served on a real pseudo-terminal (``os.openpty``) with a stable symlink path by
:meth:`MockController.serve_pty`, in a thread, so the client's pyserial code runs for real.

What it does not model: dynamics and acceleration (speed is constant, motion is linear in joints
for ``MJ`` and in Cartesian space for ``ML``/welds), zones (every point is reached exactly), the
axis 2/3 interaction limit, singularities along a linear move, the RAPID task's own timing, and
the serial line's electrical faults other than the byte errors above.

It is built in layers, one module each, the class here being the whole: the ``mock://`` options
and the seeded fault-injected line (:mod:`drivers.mock.mock_link`), the simulated arm and its
motions
(:mod:`drivers.mock.mock_robot`), the SGRS/1 request handlers (:mod:`drivers.mock.mock_server`) and
the pseudo-terminal transport (:mod:`drivers.mock.mock_pty`). Import from here.
"""

from __future__ import annotations

import urllib.parse
from typing import Any

from controller.errors import ConfigError
from drivers.abb import abb_codec as codec
from drivers.mock.mock_link import DEFAULT_CAPACITY, MOCK_OPTIONS, parse_mock_options
from drivers.mock.mock_pty import MockPty
from drivers.mock.mock_robot import HOME_DEG

__all__ = ["DEFAULT_CAPACITY", "HOME_DEG", "MOCK_OPTIONS", "MockController", "open_mock_robot",
           "parse_mock_options"]


class MockController(MockPty):
    """The simulated controller, all layers. Thread-safe; inspect it with its properties.

    Construct with the options of :class:`~drivers.mock.mock_link.MockLink` (the ``mock://``
    options of
    :data:`MOCK_OPTIONS`, by keyword); serve it with :meth:`serve_pty`.
    """


def open_mock_robot(url: str, *, limits: Any = None, timeout_s: float = 5.0,
                    **link_options: Any) -> Any:
    """``mock://?opts``: a MockController on a pty and an AbbRobot on it (``robot.mock``).

    The client's ack timeout and status poll are set from the mock's simulated speeds unless given.
    The mock is stopped when the robot is closed. Raises :class:`ConfigError` for bad options.
    """
    from drivers.abb.abb_link import line_time_s
    from drivers.abb.abb_robot import AbbRobot

    parsed = urllib.parse.urlsplit(url)
    if parsed.netloc or parsed.path not in ("", "/"):
        raise ConfigError(f"mock URL {url!r} takes options only: mock://?seed=7&drop=0.01")
    mock = MockController(**parse_mock_options(parsed.query))
    wire = line_time_s(2 * (codec.MAX_LINE + 1), mock.baud)
    link_options.setdefault("ack_timeout_s", 0.15 + mock.delay_s + wire)
    link_options.setdefault("status_poll_s", max(0.3, 4 * link_options["ack_timeout_s"]))
    link_options.setdefault("session", 1 + mock.seed % 999)
    robot = AbbRobot("mock://", limits=limits, timeout_s=timeout_s, **link_options)
    robot.mock = mock
    robot.prepare = mock.serve_pty
    robot._owned.append(mock)
    return robot
