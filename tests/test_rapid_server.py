"""SGSERVER.mod itself, run by the RAPID interpreter and talked to over its pseudo-terminal with raw
protocol lines: what the module does where the mock cannot show it (a string that would exceed
80 characters is refused with an error line and the program runs on; the optional reach check
loads only on a controller that has CalcJointT)."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

import pytest
import serial

from drivers.abb import abb_codec as codec
from drivers.rapid_vm.errors import RapidError, RapidLoadError
from drivers.rapid_vm.machine import ERRORS_S4, SIGNALS, Machine
from drivers.rapid_vm.program import Program
from drivers.rapid_vm.vm_controller import RAPID_DIR, RapidController

SERVER = (RAPID_DIR / "SGSERVER.mod").read_text()
# t_main waits for one byte from the PC before it replies: a line written before the test has
# opened the port would be flushed by the open (pyserial resets the input buffer).
LONG_REPLIES = f'''MODULE SGTEST
  PROC t_main()
    VAR num go;
    Open "sio1:", ch \\Bin;
    go := ReadBin(ch);
    Reply 0, "OK {"x" * 68}";
    Reply 0, "OK {"y" * 74}";
    Close ch;
    main;
  ENDPROC
ENDMODULE
'''


class Raw:
    """Raw protocol lines to and from a served controller."""

    def __init__(self, port: serial.Serial) -> None:
        self.port, self.seq = port, 0

    def line(self) -> codec.Frame:
        raw = self.port.readline()
        assert raw.endswith(b"\n"), f"no line from the controller (got {raw!r})"
        return codec.decode_frame(raw)

    def reply(self) -> codec.Frame:
        while (f := self.line()).kind == "E":
            pass
        return f

    def ask(self, body: str) -> str:
        self.seq = self.seq % 99 + 1
        self.port.write(codec.encode_frame("Q", self.seq, body))
        f = self.reply()
        assert f.seq == self.seq
        return f.body


@contextlib.contextmanager
def served(ctl: RapidController) -> Iterator[Raw]:
    path = ctl.serve_pty()
    try:
        with serial.serial_for_url(path, timeout=10.0) as port:  # bounds a failure only
            if getattr(ctl, "entry", None) == "t_main":
                port.write(b"\n")  # the test program's go-ahead (see LONG_REPLIES)
            yield Raw(port)
    finally:
        ctl.stop()


def test_a_reply_over_71_characters_is_refused_and_the_program_runs_on():
    ctl = RapidController(modules=[(SERVER, "SGSERVER.mod"), (LONG_REPLIES, "SGTEST.mod")],
                          entry="t_main")
    with served(ctl) as raw:
        assert raw.line().body == "OK " + "x" * 68  # 71 characters: an 80-character line
        assert raw.line().body == "ER 14 reply too long"
        assert raw.ask("ID") == "OK SGRS 1 IRB2400 250"
    assert ctl.stopped_with is None


def test_without_the_length_check_the_same_reply_stops_the_program():
    # the check is what keeps the program alive: take it out and the interpreter stops the
    # program where the controller would (a string over 80 characters)
    guard = 'IF StrLen(body) > MAXBODY RETURN "ER 14 reply too long";'
    assert guard in SERVER
    ctl = RapidController(modules=[(SERVER.replace(guard, ""), "SGSERVER.mod"),
                                   (LONG_REPLIES, "SGTEST.mod")], entry="t_main")
    with served(ctl) as raw:
        assert raw.line().body == "OK " + "x" * 68
        raw.port.timeout = 0.5
        raw.port.write(codec.encode_frame("Q", 1, "ID"))
        assert raw.port.readline() == b""  # nobody answers any more
    assert ctl.stopped_with is not None and "characters" in ctl.stopped_with


def test_an_unknown_request_with_a_long_word_is_answered_with_its_first_8_characters():
    with served(RapidController()) as raw:
        assert raw.ask("HI 7").startswith("OK ")
        assert raw.ask("Z" * 60) == "ER 11 unknown request ZZZZZZZZ"
        assert raw.ask("XP " + "9" * 60) == "ER 12 bad arguments to XP"
        assert raw.ask("ID") == "OK SGRS 1 IRB2400 250"


@pytest.mark.parametrize("job", ["j" * 17, "x" * 60, "bad-name"])
def test_a_job_name_outside_the_protocol_is_refused_when_the_operator_asks(job):
    ctl = RapidController()
    with served(ctl) as raw:
        assert raw.ask("HI 7").startswith("OK ")
        ctl.request_cycle(job)
        assert raw.ask("ST").split()[-1] == "-"  # nothing latched; the reply fits a line
        ctl.request_cycle("job_42")
        assert raw.ask("ST").split()[-1] == "job_42"
        assert raw.ask("CK") == "OK"
    assert ctl.tp_log == ["seamguide: sg_job must be 1-16 letters, digits or _"]
    assert ctl.stopped_with is None


def test_reach_check_only_where_the_controller_has_calcjointt():
    reach = (RAPID_DIR / "SGREACH.mod").read_text()
    m = Machine(None, lambda b: None, "s4")  # type: ignore[arg-type]
    p = Program(m.builtins(), ERRORS_S4, SIGNALS)
    p.load(SERVER, "SGSERVER.mod")
    p.load(reach, "SGREACH.mod")
    with pytest.raises(RapidLoadError, match="SGREACH.mod:.*unknown function 'calcjointt'"):
        p.link()
    far = ["XP 0 5000 0 0", "XO 0 1 0 0 0"]
    with served(RapidController(reach=1)) as raw:  # RobotWare: refused before it moves
        raw.ask("HI 7")
        assert [raw.ask(b) for b in far] == ["OK", "OK"]
        assert raw.ask("ML 1") == "ER 30 target unreachable"
    ctl = RapidController(reach=0)  # S4 BaseWare: accepted, and the motion itself fails
    with served(ctl) as raw:
        raw.ask("HI 7")
        for b in far:
            raw.ask(b)
        assert raw.ask("ML 1") == "OK 1"
        ev = raw.line()
        assert (ev.kind, ev.body) == ("E", "FL 1 40 0")
        assert raw.ask("ST").split()[1:7] == ["0", "0", "1", "F", "0", "40"]


# ---- the mock and the RAPID program answer alike -------------------------------------------

DIFFERENTIAL = [
    "ID", "ST", "RJ", "HI 0", "HI 1000", "HI x", "HI 12", "HI 12", "ID extra", "ST 1",
    "RQ", "RP", "RQ", "RJ", "TP 0 0 250", "TP 0 0", "TO 1 0 0 0", "TO 2 0 0 0",
    "SV 100 0", "SV 0 0", "SV 100 201", "SV 1e3 0", "SV +5 0", "SV 5.1234567 0", "SV 123456 0",
    "XP 0 1000 0 1000", "XP 251 0 0 0", "XP 0 1 2", "XP x 1 2 3", "XR 0", "XR 1", "XR 3",
    "XO 0 0.707107 0 0.707107 0", "XO 0 1 1 0 0", "PN 0", "PN 251", "PN 3",
    "XP 1 1000 0 1000", "XO 1 0.707107 0 0.707107 0", "XP 2 1000 10 1000", "XR 2",
    "RW 5 1", "XP 3 1000 20 1000", "XR 3", "RW 5 2", "RW 5 0", "RW 5 0", "ST",
    "MJ 6 0 0 90 0 0 0", "MJ 6 0 0 0 0 30", "MJ 6 0 10 0 0 60 0", "ST", "RJ",
    "ML 7", "XP 0 5000 0 0", "XO 0 1 0 0 0", "CK", "AB", "ST", "QQ", "A" * 20, "XP 1 2",
    "MJ 8 1 2 3 4 5 6 7 8 9 10 11 12", "ST",
    # MT: the target and the move in one line; refused, slot 0 is left empty
    "MT 9 1000 0 1000", "MT x 1000 0 1000 1 0 0 0", "MT 9 1000 0 1000 2 0 0 0", "ML 9",
    "MT 9 1000 0 1000 0.707107 0 0.707107 0", "ML 10", "MT 9 1000 5 1000 1 0 0 0", "ML 11",
    "MT 0 1000 0 1000 1 0 0 0", "ML 12", "XT 0 1000 0 1000 0.707107 0 0.707107 0", "MT 13 1",
    "ML 13", "ST",
]


def _answers(url_robot_ctl, raw: Raw) -> list[str]:
    out = []
    for body in DIFFERENTIAL:
        reply = raw.ask(body)
        if body[:2] in ("MJ", "ML", "MT", "RW") and reply.startswith("OK"):
            mid = reply.split()[1]  # wait for its end: the two do not take the same time
            while (ev := raw.line()).kind != "E" or ev.body.split()[:2] not in (
                    ["IP", mid], ["DN", mid], ["FL", mid]):
                pass
            reply += f" / event {ev.body}"
        if reply.startswith("ER "):
            reply = " ".join(reply.split()[:2])  # the code; the texts may differ in detail
        out.append(reply)
    return out


def test_the_mock_and_the_rapid_program_give_the_same_replies():
    from drivers.mock.mock_controller import MockController

    answers = []
    for ctl in (MockController(seed=1), RapidController(seed=1)):
        path = ctl.serve_pty()
        try:
            with serial.serial_for_url(path, timeout=3.0) as port:
                answers.append(_answers(ctl, Raw(port)))
        finally:
            ctl.stop()
    diffs = [(req, m, r) for req, m, r in zip(DIFFERENTIAL, *answers, strict=True) if m != r]
    assert diffs == [], "\n".join(map(str, diffs))


def test_a_bad_target_line_leaves_the_slot_as_it_was_on_both():
    # SGSERVER.mod kept XT's orientation before it checked the position: a later ML moved to
    # the old position with the refused line's orientation (the mock checked both first)
    from drivers.mock.mock_controller import MockController

    for ctl in (MockController(), RapidController()):
        with served(ctl) as raw:
            raw.ask("HI 7")
            assert raw.ask("XT 0 1000 0 1000 0.707107 0 0.707107 0") == "OK"
            assert raw.ask("XT 0 x 0 1000 1 0 0 0").startswith("ER 12")
            assert raw.ask("MT 3 1000 0 1000 1 0 0 x").startswith("ER 12")
            assert raw.ask("ML 4") == "OK 4"
            while (ev := raw.line()).kind != "E" or ev.body.split()[1] != "4":
                pass
            assert ev.body == "IP 4"
            assert raw.ask("RP") == "OK 1000.000 0.000 1000.000"
            assert raw.ask("RQ") == "OK 0.707107 0.000000 0.707107 0.000000", type(ctl)


def test_an_aborted_move_is_reported_at_point_0_by_both():
    # a move is not a path: FL mid 41 0 (protocol, section 4); the mock said 1 before
    from drivers.mock.mock_controller import MockController

    events = []
    for ctl in (MockController(time_scale=1.0), RapidController(time_scale=1.0)):
        with served(ctl) as raw:
            raw.ask("HI 7")
            raw.ask("SV 5 0")
            assert raw.ask("MJ 9 90 0 0 0 30 0") == "OK 9"  # about 1 s of motion
            assert raw.ask("ST").split()[1:5] == ["1", "0", "9", "R"]
            raw.port.write(codec.encode_frame("Q", 99, "AB"))
            lines = [raw.line(), raw.line()]
            events.append(sorted(f"{f.kind} {f.body}" for f in lines))
    assert events[0] == events[1] == ["A OK", "E FL 9 41 0"]


def test_the_client_raises_what_the_protocol_says_for_every_error_code():
    import re

    from drivers.abb.abb_errors import ERROR_CLASSES

    doc = (RAPID_DIR.parents[2] / "docs" / "protocol.md").read_text()
    rows = re.findall(r"^\| (\d\d) \| [^|]+\| `(\w+)` \|$", doc, re.M)
    assert len(rows) >= 15 and {"14", "15"} <= {c for c, _ in rows}
    assert {int(c): name for c, name in rows} == {
        c: cls.__name__ for c, cls in ERROR_CLASSES.items()}


def test_an_error_while_serving_is_answered_and_does_not_stop_a_running_motion():
    # a recoverable RAPID error inside a request (here CJointT failing for RJ only) is answered
    # ER 15 with its number; the motion running meanwhile ends normally, not as motion fault 40
    line = next(i for i, s in enumerate(SERVER.splitlines(), 1) if "jt := CJointT();" in s)
    ctl = RapidController(time_scale=1.0)
    real = ctl.machine._cjoint_t

    def failing_for_rj(where, a, o):
        if where.endswith(f":{line}"):
            raise RapidError(4711, "simulated failure")
        return real(where, a, o)

    ctl.machine._cjoint_t = failing_for_rj
    ctl.program = ctl._load()
    with served(ctl) as raw:
        raw.ask("HI 7")
        raw.ask("SV 200 0")
        assert raw.ask("MJ 3 20 0 0 0 30 0") == "OK 3"  # 0.2 s of motion
        assert raw.ask("RJ") == "ER 15 server error 4711"
        while (ev := raw.line()).kind != "E":
            pass
        assert ev.body == "IP 3"
        assert raw.ask("ST").split()[1:7] == ["0", "0", "3", "D", "0", "0"]
    assert ctl.stopped_with is None
