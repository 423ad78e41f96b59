"""The mock controller's server logic, through its sans-I/O core (bytes in, bytes out), and its
pseudo-terminal serving."""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np
import pytest
import serial
from hypothesis import given, settings
from hypothesis import strategies as st

from controller.errors import ConfigError
from controller.geometry.kinematics import flange_pose, irb2400
from controller.geometry.poses import make_pose, pos_quat_from_pose
from drivers.abb import abb_codec as codec
from drivers.mock.mock_controller import MockController, parse_mock_options


class Wire:
    """Talk to a MockController's core directly, one request at a time."""

    def __init__(self, mock: MockController) -> None:
        self.mock = mock
        self.seq = 0

    def raw(self, data: bytes) -> list[codec.Frame]:
        lines = codec.LineSplitter().feed(self.mock.exchange(data))
        return [codec.decode_frame(ln) for ln in lines]

    def send(self, body: str, seq: int | None = None) -> tuple[codec.Reply, list[codec.WireEvent]]:
        if seq is None:
            self.seq = self.seq % 99 + 1
            seq = self.seq
        frames = self.raw(codec.encode_frame("Q", seq, body))
        replies = [codec.parse_reply(f) for f in frames if f.kind == "A"]
        events = [codec.parse_event(f) for f in frames if f.kind == "E"]
        assert len(replies) == 1, frames
        assert replies[0].seq == seq
        return replies[0], events


@pytest.fixture
def wire():
    w = Wire(MockController(seed=1))
    assert w.send("HI 5")[0].ok
    return w


def test_no_session_refused_until_hello():
    w = Wire(MockController())
    assert w.send("ID")[0].data == ("SGRS", "1", "IRB2400", "250")
    r, _ = w.send("RJ")
    assert (r.ok, r.code) == (False, 13)
    assert w.send("HI 3")[0].ok
    assert w.send("RJ")[0].ok


def test_bad_line_gets_er10_on_seq_00():
    w = Wire(MockController())
    frames = w.raw(b"Q01 RJ*0000\n")
    assert [(f.seq, f.body) for f in frames] == [(0, "ER 10 bad line")]


def test_duplicate_request_is_answered_but_not_executed(wire):
    r1, ev1 = wire.send("MJ 1 10.0000 0.0000 0.0000 0.0000 30.0000 0.0000", seq=40)
    r2, ev2 = wire.send("MJ 1 10.0000 0.0000 0.0000 0.0000 30.0000 0.0000", seq=40)
    assert r1 == r2 and r1.ok
    assert [e.kind for e in ev1] == ["IP"] and ev2 == []
    assert len(wire.mock.executed) == 1
    assert wire.mock.link_stats["duplicates_suppressed"] == 1
    # the same motion id under a new seq is refused too (second layer)
    r3, _ = wire.send("MJ 1 20.0000 0.0000 0.0000 0.0000 30.0000 0.0000", seq=41)
    assert (r3.ok, r3.code) == (False, 25)
    assert len(wire.mock.executed) == 1


def test_joint_limits_and_unreachable_targets_refused(wire):
    r, _ = wire.send("MJ 1 0.0000 0.0000 90.0000 0.0000 0.0000 0.0000")
    assert (r.ok, r.code) == (False, 31)
    wire.send("XP 0 5000.000 0.000 500.000")
    wire.send("XO 0 1.000000 0.000000 0.000000 0.000000")
    r, _ = wire.send("ML 2")
    assert (r.ok, r.code) == (False, 30)
    r, _ = wire.send("ML 3")
    assert (r.ok, r.code) == (False, 30)  # a refused move leaves the slot as it was
    assert wire.mock.executed == []
    T = flange_pose(irb2400(), [0, 10, 0, 0, 60, 0])
    p, q = pos_quat_from_pose(T)
    wire.send(f"XP 0 {codec.fmt_position(p)}")
    wire.send(f"XO 0 {codec.fmt_quat(q)}")
    assert wire.send("ML 4")[0].ok
    r, _ = wire.send("ML 5")  # a target is used once: no accidental second move
    assert (r.ok, r.code) == (False, 21)
    assert [e["mid"] for e in wire.mock.executed] == [4]


def test_path_longer_than_buffer_refused_and_incomplete_path_not_run(wire):
    assert wire.send("PN 251")[0].code == 23
    assert wire.send("PN 2")[0].data == ("2",)
    T = flange_pose(irb2400(), [0, 10, 0, 0, 60, 0])
    p, q = pos_quat_from_pose(T)
    wire.send(f"XP 1 {codec.fmt_position(p)}")
    wire.send(f"XO 1 {codec.fmt_quat(q)}")
    r, _ = wire.send("RW 5 1")
    assert (r.ok, r.code) == (False, 22)
    assert not wire.mock.arc_on and wire.mock.executed == []


def _upload(w: Wire, targets: list[np.ndarray]) -> None:
    assert w.send(f"PN {len(targets)}")[0].ok
    for i, T in enumerate(targets, start=1):
        p, q = pos_quat_from_pose(T)
        assert w.send(f"XP {i} {codec.fmt_position(p)}")[0].ok
        assert w.send(f"XO {i} {codec.fmt_quat(q)}")[0].ok


def _line(n: int) -> list[np.ndarray]:
    T = flange_pose(irb2400(), [0, 10, 0, 0, 60, 0])
    return [T @ make_pose(t_mm=[0.0, 2.0 * i, 0.0]) for i in range(n)]


def test_xr_repeats_the_previous_orientation(wire):
    T = _line(2)
    p1, q1 = pos_quat_from_pose(T[0])
    p2, _ = pos_quat_from_pose(T[1])
    wire.send("PN 2")
    assert wire.send("XR 1")[0].code == 21  # nothing before slot 1
    wire.send(f"XP 1 {codec.fmt_position(p1)}")
    assert wire.send("XR 2")[0].code == 21  # slot 1 has no orientation yet
    wire.send(f"XO 1 {codec.fmt_quat(q1)}")
    wire.send(f"XP 2 {codec.fmt_position(p2)}")
    assert wire.send("XR 2")[0].ok
    assert wire.send("RW 3 0")[0].ok
    assert np.allclose(wire.mock.flange_pose(), T[1], atol=1e-3)


def test_weld_reports_progress_and_switches_the_arc(wire):
    _upload(wire, _line(5))
    r, ev = wire.send("RW 7 1")
    assert r.ok
    assert [(e.kind, e.index) for e in ev] == [("PG", i) for i in range(1, 6)] + [("DN", 0)]
    assert wire.mock.action_log[-2:] == ["arc_on", "arc_off"]
    assert wire.mock.executed[-1]["result"] == "done"
    st_, _ = wire.send("ST")
    assert st_.data == ("0", "0", "7", "D", "5", "0", "-")


def test_fault_at_point_n_stops_with_arc_off():
    w = Wire(MockController(fail_at_point=3))
    w.send("HI 1")
    _upload(w, _line(5))
    r, ev = w.send("RW 9 1")
    assert r.ok
    assert [(e.kind, e.index) for e in ev] == [("PG", 1), ("PG", 2), ("FL", 3)]
    assert ev[-1].code == 40
    assert not w.mock.arc_on
    assert w.mock.action_log[-3:] == ["arc_on", "arc_off", "stop"]
    assert w.mock.executed[-1]["result"] == "fault"
    assert w.send("ST")[0].data[3:6] == ("F", "2", "40")


def test_abort_turns_the_arc_off_first():
    w = Wire(MockController(time_scale=1.0))  # a slow weld, still running when AB comes
    w.send("HI 1")
    w.send("SV 1.0 0.0")
    _upload(w, _line(5))
    assert w.send("RW 3 1")[0].ok
    assert w.mock.arc_on
    r, ev = w.send("AB")
    assert r.ok and [(e.kind, e.code) for e in ev] == [("FL", 41)]
    assert w.mock.action_log == ["start weld", "arc_on", "abort", "arc_off", "stop"]
    assert not w.mock.arc_on and w.mock.executed[-1]["result"] == "aborted"


def test_tool_data_applies_to_targets(wire):
    tool = make_pose(t_mm=[0.0, 0.0, 250.0])
    p, q = pos_quat_from_pose(tool)
    wire.send(f"TP {codec.fmt_position(p)}")
    wire.send(f"TO {codec.fmt_quat(q)}")
    T_flange = flange_pose(irb2400(), [5, 15, 5, 0, 50, 0])
    pt, qt = pos_quat_from_pose(T_flange @ tool)
    wire.send(f"XP 0 {codec.fmt_position(pt)}")
    wire.send(f"XO 0 {codec.fmt_quat(qt)}")
    assert wire.send("ML 4")[0].ok
    assert np.allclose(wire.mock.flange_pose(), T_flange, atol=1e-3)


def test_cycle_request_latched_until_ck(wire):
    wire.mock.request_cycle("bracket_7")
    assert wire.send("ST")[0].data[-1] == "bracket_7"
    assert wire.send("CK")[0].ok
    assert wire.send("ST")[0].data[-1] == "-"


def test_options_are_validated():
    assert parse_mock_options("seed=7&drop=0.01&baud=9600") == {"seed": 7, "drop": 0.01,
                                                                "baud": 9600}
    with pytest.raises(ConfigError, match="known options: baud, capacity, corrupt"):
        parse_mock_options("speed=3")
    with pytest.raises(ConfigError):
        MockController(drop=2.0)


@settings(max_examples=300, deadline=None)
@given(st.lists(st.binary(max_size=90), max_size=6))
def test_fuzz_server_never_crashes_or_moves(chunks):
    mock = MockController()
    mock.exchange(codec.encode_frame("Q", 1, "HI 1"))
    for c in chunks:
        out = mock.exchange(c + b"\n")
        for ln in codec.LineSplitter().feed(out):
            codec.decode_frame(ln)  # everything the mock says is well formed
    assert mock.executed == []
    assert not mock.arc_on


@settings(max_examples=200, deadline=None)
@given(st.sampled_from(["MJ 1 10.0000 0.0000 0.0000 0.0000 30.0000 0.0000", "ML 1", "RW 1 1",
                        "PN 3", "XP 0 1000.000 0.000 900.000", "XO 1 1.000000 0 0 0"]),
       st.integers(0, 60), st.integers(0, 255))
def test_fuzz_mutated_motion_requests_never_move(body, pos, byte):
    mock = MockController()
    mock.exchange(codec.encode_frame("Q", 1, "HI 1"))
    line = bytearray(codec.encode_frame("Q", 2, body))
    i = pos % (len(line) - 1)
    if line[i] == byte:
        return
    line[i] = byte
    mock.exchange(bytes(line))
    assert mock.executed == []


def test_served_on_a_pty_with_a_stable_symlink(tmp_path):
    mock = MockController()
    link = str(tmp_path / "robot")
    assert mock.serve_pty(link) == link
    try:
        assert os.path.islink(link)
        with serial.serial_for_url(link, timeout=2.0) as port:
            port.write(codec.encode_frame("Q", 1, "ID"))
            line = port.readline()
        assert codec.decode_frame(line).body == "OK SGRS 1 IRB2400 250"
        first = os.readlink(link)
        mock.disconnect()
        assert os.readlink(link) != first
        with serial.serial_for_url(link, timeout=2.0) as port:
            port.write(codec.encode_frame("Q", 2, "ID"))
            assert codec.decode_frame(port.readline()).seq == 2
    finally:
        mock.stop()
    assert not os.path.lexists(link)
    (tmp_path / "plain").write_text("x")
    with pytest.raises(ConfigError, match="not a symlink"):
        MockController().serve_pty(str(tmp_path / "plain"))


# ---- the RAPID module and the mock agree ---------------------------------------------------

RAPID = (Path(__file__).resolve().parents[1] / "drivers" / "abb" / "rapid"
         / "SGSERVER.mod").read_text()


def _rapid_string(name: str) -> str:
    m = re.search(rf'CONST string {name} := "((?:[^"]|"")*)";', RAPID)
    assert m, name
    return m.group(1).replace('""', '"').replace("\\\\", "\\")


def test_rapid_character_tables_cover_printable_ascii():
    p1, p2 = _rapid_string("PRINT1"), _rapid_string("PRINT2")
    assert len(p1) <= 80 and len(p2) <= 80
    assert p1 + p2 == "".join(chr(c) for c in range(32, 127))


def test_rapid_checksum_transliterated_matches_the_codec():
    p1, p2 = _rapid_string("PRINT1"), _rapid_string("PRINT2")

    def char_code(c: str) -> int:  # as CharCode in the module: StrMatch in the two tables
        return 31 + p1.index(c) + 1 if c in p1 else 79 + p2.index(c) + 1

    def rapid_checksum(s: str) -> str:
        s1 = s2 = 0
        for c in s:
            s1 = (s1 + char_code(c)) % 255
            s2 = (s2 + s1) % 255
        hexd = _rapid_string("HEX")
        return "".join(hexd[n // 16] + hexd[n % 16] for n in (s2, s1))

    for kind, seq, body in [("Q", 1, "ID"), ("A", 99, 'OK "quote" \\ back`slash ~')]:
        head = f"{kind}{seq:02d} {body}"
        assert rapid_checksum(head) == codec.checksum(head)


def test_rapid_and_mock_serve_the_same_requests_and_errors():
    rapid_cmds = set(re.findall(r'c = "([A-Z]{2})"', RAPID))
    mock_cmds = set(MockController().server.handlers)
    assert rapid_cmds == mock_cmds
    # the mock controller is split into drivers/mock/mock_*.py modules: read them all
    src = "".join(f.read_text() for f in sorted(
        (Path(__file__).resolve().parents[1] / "drivers" / "mock").glob("mock_*.py")))
    rapid_codes = {int(c) for c in re.findall(r'"ER (\d\d) ', RAPID)}
    mock_codes = {int(c) for c in re.findall(r"error_body\((\d\d),", src)}
    # 14 (a reply that would not fit a line) and 15 (a RAPID error while serving) are the
    # RAPID program's safety nets; the mock's replies always fit and it has no RAPID errors
    assert rapid_codes - {14, 15} == mock_codes
    doc = (Path(__file__).resolve().parents[1] / "docs" / "protocol.md").read_text()
    doc_codes = {int(c) for c in re.findall(r"^\| (\d\d) \|", doc, re.M)}
    assert rapid_codes | mock_codes <= doc_codes
    assert '"ER 10 bad line"' in RAPID and "CAPACITY := 250" in RAPID
