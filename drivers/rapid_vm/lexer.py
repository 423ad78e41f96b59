r"""Tokens of a RAPID module: keywords (any case), names, numbers, strings, operators.

The ``%%% ... %%%`` header of a module file is skipped with its line numbers kept; ``!`` starts
a comment to the end of the line. A string literal is ``"..."`` with ``""`` for a quote, ``\\``
for a backslash and ``\hh`` (two hex digits) for any character, at most 80 characters long
(RAPID kernel reference, *Lexical elements*).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from drivers.rapid_vm.errors import RapidLoadError

KEYWORDS = frozenset("""
ALIAS AND BACKWARD CASE CONNECT CONST DEFAULT DIV DO ELSE ELSEIF ENDFOR ENDFUNC ENDIF ENDMODULE
ENDPROC ENDRECORD ENDTEST ENDTRAP ENDWHILE ERROR EXIT FALSE FOR FROM FUNC GOTO IF INOUT LOCAL
MOD MODULE NOT OR PERS PROC RAISE RECORD RETRY RETURN STEP TASK TEST THEN TO TRAP TRUE TRYNEXT
UNDO VAR WHILE WITH XOR""".split())  # noqa: SIM905

MAX_STRING = 80

_TOKEN = re.compile(r"""
    (?P<ws>[ \t\r]+) | (?P<nl>\n) | (?P<comment>![^\n]*)
  | (?P<num>(\d+\.\d*|\.\d+|\d+)([eE][+-]?\d+)?)
  | (?P<str>"(?:[^"\n]|"")*")
  | (?P<name>[A-Za-z][A-Za-z0-9_]*)
  | (?P<op>:=|<>|<=|>=|[-+*/<>=()\[\]{},;:.\\?%|])
""", re.VERBOSE)


@dataclass(frozen=True)
class Token:
    """One token: ``kind`` is kw, name, num, str, op or end; ``value`` upper-case for kw/op."""

    kind: str
    value: object
    line: int
    text: str


def _string_value(lit: str, where: str) -> str:
    body = lit[1:-1].replace('""', '"')
    out: list[str] = []
    i = 0
    while i < len(body):
        c = body[i]
        if c == "\\":
            nxt = body[i + 1:i + 2]
            if nxt == "\\":
                out.append("\\")
                i += 2
                continue
            hexd = body[i + 1:i + 3]
            if len(hexd) == 2 and all(h in "0123456789abcdefABCDEF" for h in hexd):
                out.append(chr(int(hexd, 16)))
                i += 3
                continue
            raise RapidLoadError(f"{where}: backslash in a string must be \\\\ or \\hh: {lit}")
        out.append(c)
        i += 1
    s = "".join(out)
    if len(s) > MAX_STRING:
        raise RapidLoadError(f"{where}: string literal of {len(s)} characters (RAPID: at most "
                             f"{MAX_STRING})")
    return s


def tokenize(text: str, filename: str = "<rapid>") -> list[Token]:
    """The tokens of ``text``; :class:`RapidLoadError` naming file and line for a bad one."""
    lines = text.split("\n")
    if lines and lines[0].strip() == "%%%":  # module file header: skip, keep line numbers
        end = next((i for i in range(1, len(lines)) if lines[i].strip() == "%%%"), None)
        if end is None:
            raise RapidLoadError(f"{filename}: %%% header not closed")
        text = "\n" * (end + 1) + "\n".join(lines[end + 1:])
    out: list[Token] = []
    pos, line = 0, 1
    while pos < len(text):
        m = _TOKEN.match(text, pos)
        if m is None:
            raise RapidLoadError(f"{filename}:{line}: unexpected character {text[pos]!r}")
        kind, raw = m.lastgroup, m.group()
        pos = m.end()
        if kind == "nl":
            line += 1
        elif kind in ("ws", "comment"):
            pass
        elif kind == "num":
            out.append(Token("num", float(raw), line, raw))
        elif kind == "str":
            out.append(Token("str", _string_value(raw, f"{filename}:{line}"), line, raw))
        elif kind == "name":
            up = raw.upper()
            out.append(Token("kw", up, line, raw) if up in KEYWORDS else
                       Token("name", raw.lower(), line, raw))
        else:
            out.append(Token("op", raw, line, raw))
    out.append(Token("end", None, line, "<end of file>"))
    return out
