"""The controller's ``ER`` replies as the product's exceptions (codes: ``docs/protocol.md``)."""

from __future__ import annotations

from controller.errors import (
    JointLimitError,
    LinkError,
    ProtocolError,
    ReachabilityError,
    RobotFault,
    SafetyError,
    SeamguideError,
)
from drivers.abb import abb_codec as codec

#: ``ER`` code -> the exception the client raises (an unknown code: :class:`RobotFault`).
ERROR_CLASSES: dict[int, type[SeamguideError]] = {
    11: ProtocolError, 12: ProtocolError, 13: LinkError, 14: ProtocolError, 15: RobotFault,
    20: RobotFault, 21: ProtocolError,
    22: RobotFault, 23: SafetyError, 24: ProtocolError, 25: RobotFault, 30: ReachabilityError,
    31: JointLimitError, 40: RobotFault, 41: RobotFault, 50: SafetyError}


def raise_for(reply: codec.Reply, request: str) -> None:
    """Raise the exception of an ``ER`` ``reply`` to ``request`` (its text); none for ``OK``."""
    if reply.ok:
        return
    cls = ERROR_CLASSES.get(reply.code, RobotFault)
    raise cls(f"the controller refused {request!r}: ER {reply.code} {reply.text}",
              request=request, code=reply.code, reply=reply.text)
