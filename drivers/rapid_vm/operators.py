"""RAPID's operators on interpreter values.

Arithmetic rounds every ``num`` result to single precision; ``DIV`` and ``MOD`` take integer
operands and truncate toward zero; ``+`` joins strings (over 80 characters stops the program);
AND, OR and XOR take two bools, both already evaluated (RAPID does not short-circuit); a division
by zero is a recoverable error.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from drivers.rapid_vm.errors import RapidError, RapidStop
from drivers.rapid_vm.values import check_string, f32

ERR_DIVZERO = 1036.0


def as_num(x: Any) -> float:
    """``x`` as a num; the program stops (a type error) for anything else."""
    if type(x) is float:
        return x  # type: ignore[no-any-return]
    if isinstance(x, bool) or not isinstance(x, float | int):
        raise RapidStop(f"type error: {x!r} is not a num")
    return float(x)


def _int(x: Any, op: str) -> int:
    v = as_num(x)
    if v != math.floor(v):
        raise RapidStop(f"type error: {op} needs integer operands, got {v}")
    return int(v)


def _add(a: Any, b: Any) -> Any:
    if isinstance(a, str) and isinstance(b, str):
        return check_string(a + b)
    return f32(as_num(a) + as_num(b))


def _div(a: Any, b: Any) -> float:
    if as_num(b) == 0:
        raise RapidError(int(ERR_DIVZERO), "division by zero")
    return f32(as_num(a) / as_num(b))


def _idiv(a: Any, b: Any) -> float:
    x, y = _int(a, "DIV"), _int(b, "DIV")
    if y == 0:
        raise RapidError(int(ERR_DIVZERO), "division by zero")
    return float(int(x / y))


def _imod(a: Any, b: Any) -> float:
    x, y = _int(a, "MOD"), _int(b, "MOD")
    if y == 0:
        raise RapidError(int(ERR_DIVZERO), "division by zero")
    return float(x - y * int(x / y))


def as_bool(x: Any) -> bool:
    """``x`` as a bool; the program stops (a type error) for anything else."""
    if not isinstance(x, bool):
        raise RapidStop(f"type error: {x!r} is not a bool")
    return x


def _order(a: Any, b: Any) -> tuple[float, float]:
    return as_num(a), as_num(b)


#: The binary operators by their RAPID spelling.
BINOPS: dict[str, Callable[[Any, Any], Any]] = {
    "+": _add, "-": lambda a, b: f32(as_num(a) - as_num(b)),
    "*": lambda a, b: f32(as_num(a) * as_num(b)),
    "/": _div, "DIV": _idiv, "MOD": _imod,
    "=": lambda a, b: a == b, "<>": lambda a, b: a != b,
    "<": lambda a, b: _order(a, b)[0] < _order(a, b)[1],
    "<=": lambda a, b: _order(a, b)[0] <= _order(a, b)[1],
    ">": lambda a, b: _order(a, b)[0] > _order(a, b)[1],
    ">=": lambda a, b: _order(a, b)[0] >= _order(a, b)[1],
    "AND": lambda a, b: as_bool(a) & as_bool(b), "OR": lambda a, b: as_bool(a) | as_bool(b),
    "XOR": lambda a, b: as_bool(a) ^ as_bool(b),
}
