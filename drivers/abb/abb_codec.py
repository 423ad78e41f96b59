"""Sans-I/O codec of the seamguide robot link protocol (SGRS/1, see ``docs/protocol.md``).

Pure functions: characters in, frames out, and back. No port, no clock, no state except the
:class:`LineSplitter` buffer. The client (:mod:`drivers.abb.abb_link`) and the mock controller
(:mod:`drivers.mock.mock_controller`) both use it; the golden frames in the tests come from the
protocol document, so a bug that would be symmetric between client and mock is still caught.

Every function that reads bytes raises :class:`ProtocolError` (and nothing else) on bad input.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from controller.errors import ProtocolError

#: Maximum characters of a line, the LF terminator not counted (a RAPID string holds 80).
MAX_LINE = 80
#: Longest error text in an ``ER`` reply.
MAX_ERROR_TEXT = 40
KINDS = ("Q", "A", "E")
PROTOCOL_NAME = "SGRS"
PROTOCOL_VERSION = 1

_NUMBER = re.compile(r"^-?\d{1,5}(\.\d{1,6})?$")
_INT = re.compile(r"^\d{1,4}$")
_JOB = re.compile(r"^[A-Za-z0-9_]{1,16}$")


@dataclass(frozen=True)
class Frame:
    """One line of the protocol: kind ``Q``/``A``/``E``, sequence number 0..99, body text."""

    kind: str
    seq: int
    body: str

    @property
    def fields(self) -> list[str]:
        """The body split on single spaces."""
        return self.body.split(" ")


def checksum(text: str) -> str:
    """Fletcher-16 (modulus 255) of ``text`` as 4 upper-case hex digits (s2 then s1).

    Only ``+``, ``DIV`` and ``MOD`` are needed, so the RAPID server computes it the same way.
    """
    s1 = s2 = 0
    for ch in text:
        s1 = (s1 + ord(ch)) % 255
        s2 = (s2 + s1) % 255
    return f"{s2:02X}{s1:02X}"


def _check_body(body: str) -> None:
    if not body:
        raise ProtocolError("empty message body")
    for ch in body:
        if not (32 <= ord(ch) <= 126) or ch == "*":
            raise ProtocolError(f"message body {body!r} has a character {ch!r} outside the "
                                "protocol's printable ASCII (0x20..0x7E, no '*')")
    if body.startswith(" ") or body.endswith(" ") or "  " in body:
        raise ProtocolError(f"message body {body!r} must have fields separated by single spaces")


def encode_frame(kind: str, seq: int, body: str) -> bytes:
    """The wire bytes of one line: ``kind seq SP body * chk LF``.

    Raises :class:`ProtocolError` for an unknown kind, a seq outside 0..99, a bad character, or a
    line longer than :data:`MAX_LINE` characters (a message that would not fit a RAPID string).
    """
    if kind not in KINDS:
        raise ProtocolError(f"unknown frame kind {kind!r}; use one of {KINDS}")
    if not 0 <= seq <= 99:
        raise ProtocolError(f"sequence number {seq} outside 0..99")
    _check_body(body)
    text = f"{kind}{seq:02d} {body}"
    line = f"{text}*{checksum(text)}"
    if len(line) > MAX_LINE:
        raise ProtocolError(f"line of {len(line)} characters exceeds {MAX_LINE}: {line!r}")
    return (line + "\n").encode("ascii")


def decode_frame(line: bytes) -> Frame:
    """Parse one line (with or without its LF/CR LF) into a :class:`Frame`.

    Raises :class:`ProtocolError` naming the line when it is too long, not printable ASCII, badly
    framed, or its checksum does not match.
    """
    raw = line
    if raw.endswith(b"\n"):
        raw = raw[:-1]
    if raw.endswith(b"\r"):
        raw = raw[:-1]
    if len(raw) > MAX_LINE:
        raise ProtocolError(f"line of {len(raw)} characters exceeds {MAX_LINE}: {raw[:90]!r}")
    try:
        text = raw.decode("ascii")
    except UnicodeDecodeError as err:
        raise ProtocolError(f"line is not ASCII: {raw!r}") from err
    star = text.rfind("*")
    if star < 0 or len(text) - star != 5:
        raise ProtocolError(f"line {text!r} has no '*' followed by a 4-digit checksum")
    head, chk = text[:star], text[star + 1:]
    if len(head) < 5 or head[0] not in KINDS or not head[1:3].isdigit() or head[3] != " " \
            or not head[1:3].isascii():
        raise ProtocolError(f"line {text!r} does not start with Q/A/E, two digits and a space")
    if chk != checksum(head):
        raise ProtocolError(f"line {text!r}: checksum {chk} does not match {checksum(head)}")
    body = head[4:]
    _check_body(body)
    return Frame(kind=head[0], seq=int(head[1:3]), body=body)


class LineSplitter:
    """Cuts a byte stream into lines at LF; sans-I/O (``feed`` bytes, get complete lines).

    A run of more than :data:`MAX_LINE` + 1 bytes without LF is cut short and returned as an
    over-long line (which :func:`decode_frame` refuses), so garbage never grows the buffer.
    """

    def __init__(self) -> None:
        self._buf = bytearray()
        self._overflow = False

    def feed(self, data: bytes) -> list[bytes]:
        """Add received bytes; return the complete lines (each ending in LF, or over-long)."""
        out: list[bytes] = []
        for b in data:
            if b == 0x0A:
                if self._overflow:
                    self._overflow = False
                else:
                    out.append(bytes(self._buf) + b"\n")
                self._buf.clear()
                continue
            if self._overflow:
                continue
            self._buf.append(b)
            if len(self._buf) > MAX_LINE + 1:
                out.append(bytes(self._buf))
                self._buf.clear()
                self._overflow = True
        return out

    def clear(self) -> None:
        """Forget any partial line."""
        self._buf.clear()
        self._overflow = False


# ---- numbers --------------------------------------------------------------------------------


def fmt(value: float, decimals: int, trim: bool = False) -> str:
    """A number as the protocol writes it: ``decimals`` decimals, never ``-0``, no exponent.

    ``trim``: trailing zeros (and then the point) dropped, the same number in fewer bytes
    (``300.000`` -> ``300``, ``0.500`` -> ``0.5``): how the client writes its requests. Replies
    keep the fixed form, as RAPID's ``NumToStr`` writes them.
    """
    s = f"{float(value):.{decimals}f}"
    if float(s) == 0.0:
        s = f"{0.0:.{decimals}f}"
    if trim and "." in s:
        s = s.rstrip("0").rstrip(".")
    return s


def fmt_joints(joints_deg: ArrayLike, trim: bool = False) -> str:
    """Six controller joint values (deg) with 4 decimals, space separated."""
    return " ".join(fmt(v, 4, trim) for v in np.asarray(joints_deg, dtype=np.float64).reshape(6))


def fmt_position(p_mm: ArrayLike, trim: bool = False) -> str:
    """Three coordinates (mm) with 3 decimals."""
    return " ".join(fmt(v, 3, trim) for v in np.asarray(p_mm, dtype=np.float64).reshape(3))


def fmt_quat(q_wxyz: ArrayLike, trim: bool = False) -> str:
    """Quaternion w x y z with 6 decimals."""
    return " ".join(fmt(v, 6, trim) for v in np.asarray(q_wxyz, dtype=np.float64).reshape(4))


def parse_number(text: str, name: str) -> float:
    """A protocol number (``-?d+(.d+)?``, at most 5 + 6 digits); else :class:`ProtocolError`."""
    if not _NUMBER.match(text):
        raise ProtocolError(f"{name}: {text!r} is not a protocol number")
    return float(text)


def parse_int(text: str, name: str, lo: int = 0, hi: int = 9999) -> int:
    """A non-negative integer of at most 4 digits within [lo, hi]; :class:`ProtocolError` else."""
    if not _INT.match(text):
        raise ProtocolError(f"{name}: {text!r} is not an integer")
    v = int(text)
    if not lo <= v <= hi:
        raise ProtocolError(f"{name}: {v} outside {lo}..{hi}")
    return v


def parse_numbers(fields: list[str], count: int, name: str) -> NDArray[np.float64]:
    """Exactly ``count`` protocol numbers; :class:`ProtocolError` naming ``name`` otherwise."""
    if len(fields) != count:
        raise ProtocolError(f"{name}: expected {count} numbers, got {len(fields)}: {fields!r}")
    return np.array([parse_number(f, f"{name}[{i}]") for i, f in enumerate(fields)])


def check_job_name(job: str) -> str:
    """A job name for a cycle request: 1..16 of ``[A-Za-z0-9_]``; :class:`ProtocolError` else."""
    if not _JOB.match(job):
        raise ProtocolError(f"job name {job!r} must be 1..16 characters of [A-Za-z0-9_]")
    return job


# ---- target slots (protocol sections 5 and 5.1) ----------------------------------------------


def target_bodies(slot: int, p_mm: ArrayLike, q_wxyz: ArrayLike, previous_quat: str = ""
                  ) -> list[str]:
    """Request bodies that set target ``slot`` to position ``p_mm`` and orientation ``q_wxyz``.

    ``XP`` + ``XR`` when the quaternion as written equals ``previous_quat`` (the previous path
    point's, as written; slots 2 and up), else ``XT`` when its line fits in :data:`MAX_LINE`
    characters, else ``XP`` + ``XO``.
    """
    pos, quat = fmt_position(p_mm, trim=True), fmt_quat(q_wxyz, trim=True)
    if previous_quat and quat == previous_quat and slot >= 2:
        return [f"XP {slot} {pos}", f"XR {slot}"]
    one = f"XT {slot} {pos} {quat}"
    if len(f"Q00 {one}*0000") <= MAX_LINE:
        return [one]
    return [f"XP {slot} {pos}", f"XO {slot} {quat}"]


def linear_move_bodies(mid: int, p_mm: ArrayLike, q_wxyz: ArrayLike) -> list[str]:
    """Request bodies of a linear move ``mid`` to position ``p_mm``, orientation ``q_wxyz``.

    ``MT`` (target and move in one line) when its line fits in :data:`MAX_LINE` characters,
    else the target slot 0 (:func:`target_bodies`) and ``ML``. The move request is the last.
    """
    one = f"MT {mid} {fmt_position(p_mm, trim=True)} {fmt_quat(q_wxyz, trim=True)}"
    if len(f"Q00 {one}*0000") <= MAX_LINE:
        return [one]
    return [*target_bodies(0, p_mm, q_wxyz), f"ML {mid}"]


def circle_body(slot: int, p_mm: ArrayLike) -> str:
    """``XC slot x y z``: path point ``slot`` is reached by a MoveC through this point (mm)."""
    return f"XC {slot} {fmt_position(p_mm, trim=True)}"


# ---- replies and events ------------------------------------------------------------------------


@dataclass(frozen=True)
class Reply:
    """A decoded reply: ``ok`` with its data fields, or an error ``code`` and ``text``."""

    seq: int
    ok: bool
    data: tuple[str, ...] = ()
    code: int = 0
    text: str = ""


def parse_reply(frame: Frame) -> Reply:
    """Interpret an ``A`` frame as ``OK ...`` or ``ER code text``; :class:`ProtocolError` else."""
    if frame.kind != "A":
        raise ProtocolError(f"expected a reply, got {frame!r}")
    f = frame.fields
    if f[0] == "OK":
        return Reply(seq=frame.seq, ok=True, data=tuple(f[1:]))
    if f[0] == "ER" and len(f) >= 2:
        return Reply(seq=frame.seq, ok=False, code=parse_int(f[1], "error code", 1, 99),
                     text=" ".join(f[2:]))
    raise ProtocolError(f"reply body {frame.body!r} is neither 'OK ...' nor 'ER code text'")


def ok_body(*data: str) -> str:
    """Body of a positive reply."""
    return " ".join(("OK", *data))


def error_body(code: int, text: str) -> str:
    """Body of an error reply, text cut to :data:`MAX_ERROR_TEXT` characters."""
    return f"ER {code} {text[:MAX_ERROR_TEXT].strip()}".strip()


EVENT_KINDS = ("IP", "PG", "DN", "FL", "CY")


@dataclass(frozen=True)
class WireEvent:
    """A decoded event line: ``kind`` (``IP``/``PG``/``DN``/``FL``/``CY``) and its values."""

    seq: int
    kind: str
    mid: int = 0
    index: int = 0
    code: int = 0
    job: str = ""


def parse_event(frame: Frame) -> WireEvent:
    """Interpret an ``E`` frame; :class:`ProtocolError` for an unknown event or bad fields."""
    if frame.kind != "E":
        raise ProtocolError(f"expected an event, got {frame!r}")
    f = frame.fields
    k, args = f[0], f[1:]
    want = {"IP": 1, "PG": 2, "DN": 1, "FL": 3, "CY": 1}
    if k not in want:
        raise ProtocolError(f"unknown event {k!r} in {frame.body!r}")
    if len(args) != want[k]:
        raise ProtocolError(f"event {frame.body!r}: {k} takes {want[k]} fields")
    if k == "CY":
        return WireEvent(seq=frame.seq, kind=k, job=check_job_name(args[0]))
    mid = parse_int(args[0], "motion id", 1, 9999)
    if k == "PG":
        return WireEvent(seq=frame.seq, kind=k, mid=mid, index=parse_int(args[1], "index"))
    if k == "FL":
        return WireEvent(seq=frame.seq, kind=k, mid=mid, code=parse_int(args[1], "code", 1, 99),
                         index=parse_int(args[2], "index"))
    return WireEvent(seq=frame.seq, kind=k, mid=mid)


def event_body(ev: WireEvent) -> str:
    """Body of an event line (inverse of :func:`parse_event`)."""
    if ev.kind == "CY":
        return f"CY {ev.job}"
    if ev.kind == "PG":
        return f"PG {ev.mid} {ev.index}"
    if ev.kind == "FL":
        return f"FL {ev.mid} {ev.code} {ev.index}"
    return f"{ev.kind} {ev.mid}"


def golden_lines() -> list[str]:
    """The golden frames of ``docs/protocol.md`` (without LF), as this codec writes them."""
    return [encode_frame(k, s, b).decode().rstrip("\n") for k, s, b in (
        ("Q", 1, "ID"), ("A", 1, "OK SGRS 1 IRB2400 250"), ("Q", 2, "RJ"),
        ("A", 0, "ER 10 bad line"),
        ("Q", 3, target_bodies(2, [1000.5, -50.25, 300.0], [0.0, 0.92388, -0.382683,
                                                              0.0])[0]),
        ("Q", 4, circle_body(3, [1010.0, -45.125, 300.0])),
        ("Q", 5, "RW 7 1"),
        ("Q", 6, linear_move_bodies(12, [944.297, 67.225, 302.964],
                                    [0.051095, 0.803004, -0.589689, 0.069578])[0]))]


if __name__ == "__main__":  # pragma: no cover - regenerates the doc's golden table
    import sys

    if "--golden" in sys.argv:
        for line in golden_lines():
            print(line)
