"""Routines, call frames and the control-flow signals of the interpreter.

RETURN, RETRY, TRYNEXT and an error leaving a routine, with the ERROR handler semantics of
the RAPID kernel:

* a recoverable error in a statement runs the routine's ERROR handler at once, with ``ERRNO``;
  ``RETRY`` executes the statement again, ``TRYNEXT`` goes on with the next one, ``RETURN`` leaves
  the routine, ``RAISE`` passes the error to the caller (where its handler takes it);
* a routine without a handler passes the error to its caller; at the top the program stops;
* an error inside a handler goes to the caller;
* a handler that runs off its end: a FUNC stops the program (a function must end in RETURN or
  RAISE), a PROC passes the error on, as RAISE (the pessimistic reading, so that a handler
  that forgets an error number is caught here rather than on the controller).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from drivers.rapid_vm.errors import RapidError, RapidStop

Stmt = Callable[["Frame"], None]
#: RETRY runs a failing statement again at most this many times; then the error goes on to the
#: caller (the controller's limit, a system parameter, is also small).
MAX_RETRIES = 4


class ReturnSig(Exception):
    """RETURN [value]."""

    def __init__(self, value: Any = None) -> None:
        super().__init__()
        self.value = value


class RetrySig(Exception):
    """RETRY in an error handler."""


class TryNextSig(Exception):
    """TRYNEXT in an error handler."""


class Propagate(Exception):
    """An error leaving a routine (RAISE, no handler, or an error inside the handler)."""

    def __init__(self, err: RapidError) -> None:
        super().__init__(str(err))
        self.err = err


class ProgramExit(Exception):
    """EXIT: the program ends."""


@dataclass
class Param:
    r"""A formal parameter: mode IN/INOUT/VAR/PERS, type, name, optional (``\name``)."""

    mode: str
    type: str
    name: str
    optional: bool
    dims: int = 0


@dataclass
class Routine:
    """A PROC, FUNC or TRAP, compiled: ``body``/``handler`` are lists of statement closures."""

    kind: str
    name: str
    rtype: str | None
    params: list[Param]
    module: str
    line: int
    decls: list[tuple[str, Callable[[Frame], Any]]] = field(default_factory=list)
    body: list[Stmt] = field(default_factory=list)
    handler: list[Stmt] | None = None

    def where(self) -> str:
        """``module:line routine`` for messages."""
        return f"{self.module}:{self.line} {self.kind} {self.name}"


class Frame:
    """One activation of a routine: its local variables and its error state."""

    __slots__ = ("v", "routine", "errno", "err", "in_handler")

    def __init__(self, routine: Routine) -> None:
        self.v: dict[str, Any] = {}
        self.routine = routine
        self.errno = 0.0
        self.err: RapidError | None = None
        self.in_handler = False

    def handle(self, err: RapidError) -> bool:
        """Run the ERROR handler for ``err``: True to retry the statement, False to go on."""
        handler = self.routine.handler
        if handler is None or self.in_handler:
            raise Propagate(err)
        self.errno, self.err, self.in_handler = float(err.errno), err, True
        try:
            for s in handler:
                s(self)
        except RetrySig:
            return True
        except TryNextSig:
            return False
        finally:
            self.in_handler = False
        if self.routine.kind == "FUNC":
            raise RapidStop(f"{self.routine.where()}: its error handler ended without RETURN "
                            f"or RAISE for error {err.errno} ({err})")
        raise Propagate(err)


def run_block(stmts: list[Stmt], fr: Frame) -> None:
    """Execute statements in order."""
    for s in stmts:
        s(fr)


def invoke(routine: Routine, fr: Frame) -> Any:
    """Run ``routine`` in frame ``fr`` (locals set); its RETURN value, or None for a PROC."""
    try:
        for name, init in routine.decls:
            fr.v[name] = init(fr)
        run_block(routine.body, fr)
    except ReturnSig as r:
        return r.value
    except Propagate as p:
        raise p.err from None
    except (RetrySig, TryNextSig) as sig:
        raise RapidStop(f"{routine.where()}: {type(sig).__name__[:-3].upper()} outside an "
                        "error handler") from None
    if routine.kind == "FUNC":
        raise RapidStop(f"{routine.where()}: ended without RETURN")
    return None
