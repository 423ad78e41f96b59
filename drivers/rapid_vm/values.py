"""RAPID data in Python.

``num`` (single precision), ``bool``, ``string`` (at most 80 characters),
the records the server uses, arrays, and the predefined data (``fine``, ``tool0``, ``wobj0``...).

A ``num`` is a Python float that always holds a single-precision value: every literal, result
and assignment goes through :func:`f32` (``numpy.float32``), as on the controller, so the
interpreter loses the digits the controller loses. A record is a :class:`Rec` (type name and
ordered components); an array is a Python list (RAPID indexes it from 1). Values are copied on
assignment and when passed by value, as RAPID does.
"""

from __future__ import annotations

import struct
from typing import Any

import numpy as np

from drivers.rapid_vm.errors import RapidLoadError, RapidStop

MAX_STRING = 80

#: Record types (lower-case names) and their components (name, type), from the RAPID reference
#: (Data Types) of the types the server uses.
RECORDS: dict[str, list[tuple[str, str]]] = {
    "pos": [("x", "num"), ("y", "num"), ("z", "num")],
    "orient": [("q1", "num"), ("q2", "num"), ("q3", "num"), ("q4", "num")],
    "pose": [("trans", "pos"), ("rot", "orient")],
    "confdata": [("cf1", "num"), ("cf4", "num"), ("cf6", "num"), ("cfx", "num")],
    "extjoint": [(f"eax_{c}", "num") for c in "abcdef"],
    "robjoint": [(f"rax_{i}", "num") for i in range(1, 7)],
    "robtarget": [("trans", "pos"), ("rot", "orient"), ("robconf", "confdata"),
                  ("extax", "extjoint")],
    "jointtarget": [("robax", "robjoint"), ("extax", "extjoint")],
    "loaddata": [("mass", "num"), ("cog", "pos"), ("aom", "orient"), ("ix", "num"),
                 ("iy", "num"), ("iz", "num")],
    "tooldata": [("robhold", "bool"), ("tframe", "pose"), ("tload", "loaddata")],
    "wobjdata": [("robhold", "bool"), ("ufprog", "bool"), ("ufmec", "string"),
                 ("uframe", "pose"), ("oframe", "pose")],
    "speeddata": [("v_tcp", "num"), ("v_ori", "num"), ("v_leax", "num"), ("v_reax", "num")],
    "zonedata": [("finep", "bool"), ("pzone_tcp", "num"), ("pzone_ori", "num"),
                 ("pzone_eax", "num"), ("zone_ori", "num"), ("zone_leax", "num"),
                 ("zone_reax", "num")],
}
#: Atomic types with no components: opaque handles of the controller.
OPAQUE = {"iodev": None, "intnum": 0.0, "signaldo": None, "signaldi": None, "errnum": 0.0}
SCALARS = {"num": 0.0, "bool": False, "string": ""}
_ALIASES = {"errnum": "num", "intnum": "num"}


_F32 = struct.Struct("f")


def f32(x: float) -> float:
    """``x`` rounded to single precision (RAPID ``num``, as ``numpy.float32`` rounds it)."""
    try:
        return _F32.unpack(_F32.pack(x))[0]  # type: ignore[no-any-return]
    except OverflowError:
        return float(np.float32(x))  # +-inf, as numpy.float32 gives beyond its range


class Rec:
    """A record value: ``type`` (lower-case name) and ``f`` (component name -> value)."""

    __slots__ = ("type", "f")

    def __init__(self, type_: str, f: dict[str, Any]) -> None:
        self.type = type_
        self.f = f

    def __repr__(self) -> str:
        return f"{self.type}{list(self.f.values())!r}"


def known_type(t: str) -> bool:
    """True for a data type this interpreter has."""
    return t in RECORDS or t in SCALARS or t in OPAQUE


def default(t: str) -> Any:
    """The initial value of a variable of type ``t`` (zero, FALSE, "" and records of them)."""
    if t in SCALARS:
        return SCALARS[t]
    if t in RECORDS:
        return Rec(t, {n: default(ct) for n, ct in RECORDS[t]})
    return OPAQUE[t]


def copy(v: Any) -> Any:
    """A deep copy of a RAPID value (records and arrays; scalars are immutable)."""
    if isinstance(v, Rec):
        return Rec(v.type, {k: copy(x) for k, x in v.f.items()})
    if isinstance(v, list):
        return [copy(x) for x in v]
    return v


def check_string(s: str) -> str:
    """``s`` if it fits a RAPID string; :class:`RapidStop` (the program stops) otherwise."""
    if len(s) > MAX_STRING:
        raise RapidStop(f"string of {len(s)} characters (RAPID strings hold at most "
                        f"{MAX_STRING}): {s[:40]!r}...")
    return s


def convert(v: Any, t: str) -> Any:
    """``v`` as a value of type ``t`` (an aggregate ``[...]`` becomes a record), copied.

    Raises :class:`RapidStop` for a value of another type (a type error).
    """
    if t == "num" and type(v) is float:
        return f32(v)
    t = _ALIASES.get(t, t)
    if t == "num":
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise RapidStop(f"type error: {v!r} is not a num")
        return f32(v)
    if t == "bool":
        if not isinstance(v, bool):
            raise RapidStop(f"type error: {v!r} is not a bool")
        return v
    if t == "string":
        if not isinstance(v, str):
            raise RapidStop(f"type error: {v!r} is not a string")
        return check_string(v)
    if t in RECORDS:
        comps = RECORDS[t]
        if isinstance(v, Rec):
            if v.type != t:
                raise RapidStop(f"type error: {v.type} is not a {t}")
            return copy(v)
        if isinstance(v, list) and len(v) == len(comps):
            return Rec(t, {n: convert(x, ct) for (n, ct), x in zip(comps, v, strict=True)})
        raise RapidStop(f"type error: {v!r} is not a {t} ({len(comps)} components)")
    return v


def component_type(t: str, name: str, where: str) -> str:
    """The type of component ``name`` of record type ``t``; :class:`RapidLoadError` if none."""
    for n, ct in RECORDS.get(t, []):
        if n == name:
            return ct
    raise RapidLoadError(f"{where}: {t} has no component {name}")


def _rec(t: str, *vals: Any) -> Rec:
    return convert(list(vals), t)  # type: ignore[no-any-return]


_IDQ = [[0, 0, 0], [1, 0, 0, 0]]

#: Predefined data of the system (name -> (type, value)), as in the RAPID reference.
PREDEFINED: dict[str, tuple[str, Any]] = {
    "fine": ("zonedata", _rec("zonedata", True, 0, 0, 0, 0, 0, 0)),
    "z10": ("zonedata", _rec("zonedata", False, 10, 15, 15, 1.5, 15, 1.5)),
    "v100": ("speeddata", _rec("speeddata", 100, 500, 5000, 1000)),
    "tool0": ("tooldata", _rec("tooldata", True, _IDQ, [0.001, [0, 0, 0.001], [1, 0, 0, 0],
                                                       0, 0, 0])),
    "wobj0": ("wobjdata", _rec("wobjdata", False, True, "", _IDQ, _IDQ)),
}
