"""The RAPID string and number functions the server uses.

As the RAPID reference describes them (Functions: StrLen, StrPart, StrFind, StrMatch,
StrMemb, StrToVal, NumToStr, Abs, Sqrt, Distance). Positions are 1-based; a search that finds
nothing returns the length plus one. A position or length outside the string stops the program
(as a run-time error would).
"""

from __future__ import annotations

import decimal
import math
import re
from typing import Any

from drivers.rapid_vm.compiler import Ref
from drivers.rapid_vm.errors import RapidStop
from drivers.rapid_vm.program import Builtin
from drivers.rapid_vm.values import Rec, check_string, f32

_NUM = re.compile(r"^[+-]?(\d+(\.\d*)?|\.\d+)([eE][+-]?\d+)?$")


def _str(where: str, v: Any, name: str) -> str:
    if not isinstance(v, str):
        raise RapidStop(f"{where}: {name} must be a string, got {v!r}")
    return v


def _pos(where: str, s: str, p: Any, fn: str, allow_end: bool = True) -> int:
    hi = len(s) + 1 if allow_end else len(s)
    if not (isinstance(p, float) and p == int(p) and 1 <= p <= max(hi, 1)):
        raise RapidStop(f"{where}: {fn} position {p} outside 1..{hi} of {s!r}")
    return int(p)


def str_len(where: str, a: list[Any], o: dict[str, Any]) -> float:
    """StrLen(Str): the number of characters."""
    return float(len(_str(where, a[0], "Str")))


def str_part(where: str, a: list[Any], o: dict[str, Any]) -> str:
    """StrPart(Str, ChPos, Len): ``Len`` characters from ``ChPos``."""
    s = _str(where, a[0], "Str")
    p, n = a[1], a[2]
    if not (n == int(n) and n >= 0 and p == int(p) and p >= 1 and p + n - 1 <= len(s)):
        raise RapidStop(f"{where}: StrPart({s!r}, {p}, {n}) outside the string")
    return s[int(p) - 1:int(p) - 1 + int(n)]


def str_find(where: str, a: list[Any], o: dict[str, Any]) -> float:
    r"""StrFind(Str, ChPos, Set [\NotInSet]): first character (not) in ``Set`` from ``ChPos``."""
    s, sset = _str(where, a[0], "Str"), _str(where, a[2], "Set")
    p = _pos(where, s, a[1], "StrFind")
    notin = bool(o.get("notinset"))
    for i in range(p - 1, len(s)):
        if (s[i] in sset) != notin:
            return float(i + 1)
    return float(len(s) + 1)


def str_match(where: str, a: list[Any], o: dict[str, Any]) -> float:
    """StrMatch(Str, ChPos, Pattern): where ``Pattern`` starts, from ``ChPos``."""
    s, pat = _str(where, a[0], "Str"), _str(where, a[2], "Pattern")
    p = _pos(where, s, a[1], "StrMatch")
    k = s.find(pat, p - 1)
    return float(k + 1 if k >= 0 else len(s) + 1)


def str_memb(where: str, a: list[Any], o: dict[str, Any]) -> bool:
    """StrMemb(Str, ChPos, Set): is the character at ``ChPos`` in ``Set``."""
    s, sset = _str(where, a[0], "Str"), _str(where, a[2], "Set")
    p = _pos(where, s, a[1], "StrMemb", allow_end=False)
    return s[p - 1] in sset


def str_to_val(where: str, a: list[Any], o: dict[str, Any]) -> bool:
    """StrToVal(Str, Val): a num written as a RAPID literal into ``Val``; TRUE when it was one."""
    s, ref = _str(where, a[0], "Str"), a[1]
    assert isinstance(ref, Ref)
    if not _NUM.match(s):
        return False
    v = float(s)
    if not math.isfinite(f32(v)):
        return False
    ref.set(f32(v))
    return True


def num_to_str(where: str, a: list[Any], o: dict[str, Any]) -> str:
    """NumToStr(Val, Dec): ``Val`` rounded to ``Dec`` decimals (half away from zero), no ``-0``."""
    v, dec = float(a[0]), int(a[1])
    q = decimal.Decimal(v).quantize(decimal.Decimal(1).scaleb(-dec), decimal.ROUND_HALF_UP)
    s = f"{q:f}"
    if q == 0:
        s = s.lstrip("-")
    return check_string(s)


def _abs(where: str, a: list[Any], o: dict[str, Any]) -> float:
    return f32(abs(float(a[0])))


def _sqrt(where: str, a: list[Any], o: dict[str, Any]) -> float:
    if a[0] < 0:
        raise RapidStop(f"{where}: Sqrt of {a[0]}")
    return f32(math.sqrt(a[0]))


def _distance(where: str, a: list[Any], o: dict[str, Any]) -> float:
    p, q = a
    if not (isinstance(p, Rec) and isinstance(q, Rec) and p.type == q.type == "pos"):
        raise RapidStop(f"{where}: Distance takes two pos")
    return f32(math.dist([p.f["x"], p.f["y"], p.f["z"]], [q.f["x"], q.f["y"], q.f["z"]]))


CORE_FUNCTIONS: dict[str, Builtin] = {
    "strlen": (str_len, frozenset(), True),
    "strpart": (str_part, frozenset(), True),
    "strfind": (str_find, frozenset(), True),
    "strmatch": (str_match, frozenset(), True),
    "strmemb": (str_memb, frozenset(), True),
    "strtoval": (str_to_val, frozenset({1}), True),
    "numtostr": (num_to_str, frozenset(), True),
    "abs": (_abs, frozenset(), True),
    "sqrt": (_sqrt, frozenset(), True),
    "distance": (_distance, frozenset(), True),
}
