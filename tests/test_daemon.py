"""The cell daemon in-process (threads) and as a real process (signals, SIGKILL and restart)."""

import contextlib
import json
import logging
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from daemon_harness import make_cell

from controller.cell.cell_config import load_cell_config
from controller.cell.control_socket import exchange, send_request
from controller.cell.cycle_record import read_record
from controller.cell.daemon import Daemon
from controller.errors import ConfigError

pytestmark = pytest.mark.slow


@contextlib.contextmanager
def serving(cfg_path):
    """An in-process daemon on ``cfg_path``, ready; stopped (and checked stopped) afterwards."""
    d = Daemon(cfg_path)
    t = threading.Thread(target=d.serve, daemon=True)
    t.start()
    try:
        assert d.ready.wait(30), "daemon did not become ready"
        yield d, load_cell_config(cfg_path)
    finally:
        d.request_stop("test over")
        t.join(60)
    assert not t.is_alive()


def confirming_cell(folder):
    """The simulated cell with a demo job that asks the operator to confirm the weld path."""
    cfg_path = make_cell(folder)
    job = cfg_path.parent / "demo-job.toml"
    job.write_text(job.read_text().replace("confirm = false", "confirm = true"))
    return cfg_path


@pytest.fixture
def running(tmp_path):
    with serving(make_cell(tmp_path / "cell")) as (d, cfg):
        yield d, cfg


def test_status_start_and_counters(running):
    d, cfg = running
    st = send_request(cfg.control.socket, {"cmd": "status"})
    assert st["ok"] and st["state"] == "idle" and st["robot"] == "connected"
    assert st["counters"] == {"cycles_done": 0, "cycles_faulted": 0, "cycles_aborted": 0,
                              "requests_rejected": 0}
    r = send_request(cfg.control.socket, {"cmd": "start", "job": "demo"})
    assert r["ok"] and r["queued"] == "demo"
    assert d.wait_cycles(1, 120)
    st = send_request(cfg.control.socket, {"cmd": "status"})
    assert st["counters"]["cycles_done"] == 1, st["last_cycle"]
    assert st["last_cycle"]["status"] == "done"
    assert read_record(st["last_cycle"]["record"])["status"] == "done"
    assert oct(os.stat(cfg.control.socket).st_mode & 0o777) == "0o600"


def test_cycle_requested_by_the_controller(running):
    d, cfg = running
    d.robot.mock.request_cycle("demo")
    assert d.wait_cycles(1, 120)
    assert d.status()["last_cycle"]["status"] == "done"


def raw(path, data: bytes) -> bytes:
    return exchange(path, data)


def test_bad_control_requests_keep_the_daemon_running(running):
    d, cfg = running
    sock = cfg.control.socket
    assert "malformed" in json.loads(raw(sock, b"this is not json\n"))["error"]
    assert "JSON object" in json.loads(raw(sock, b"[1, 2]\n"))["error"]
    assert "unknown command" in send_request(sock, {"cmd": "explode"})["error"]
    assert "unknown job" in send_request(sock, {"cmd": "start", "job": "nope"})["error"]
    assert "job name" in send_request(sock, {"cmd": "start"})["error"]
    assert "longer than" in json.loads(raw(sock, b"x" * 10000 + b"\n"))["error"]
    st = send_request(sock, {"cmd": "status"})
    assert st["ok"] and st["counters"]["requests_rejected"] == 3


def test_pause_holds_requests_and_abort_drops_them(running):
    d, cfg = running
    sock = cfg.control.socket
    assert send_request(sock, {"cmd": "pause"})["paused"] is True
    send_request(sock, {"cmd": "start", "job": "demo"})
    st = send_request(sock, {"cmd": "status"})
    assert st["paused"] and st["queue_length"] == 1 and st["state"] == "idle"
    r = send_request(sock, {"cmd": "abort"})
    assert r["ok"] and r["dropped_requests"] == 1
    assert send_request(sock, {"cmd": "resume"})["paused"] is False


def test_bad_configuration_files(tmp_path):
    cfg = make_cell(tmp_path / "c")
    text = cfg.read_text()
    cases = {
        "robot.url": text.replace('[robot]\nurl = ', '[robot]\nurll = '),
        "sim": text.replace("[sim]", "[simulation]"),
        "max_line_bytes": text.replace("max_line_bytes = 4096", 'max_line_bytes = "big"'),
        "safe_joints_deg": text.replace("safe_joints_deg = [0.0, 0.0, 0.0, 0.0, 30.0, 0.0]",
                                        "safe_joints_deg = [0.0, 0.0, 99.0, 0.0, 30.0, 0.0]"),
    }
    for key, bad in cases.items():
        cfg.write_text(bad)
        with pytest.raises(ConfigError) as info:
            load_cell_config(cfg)
        assert str(cfg) in str(info.value), key


def _spawn(cfg: Path, log: Path) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "controller.cli", "run", "--config", str(cfg)],
                            stdout=subprocess.DEVNULL, stderr=open(log, "ab"),
                            cwd=Path(__file__).resolve().parent.parent)


def _wait_for(predicate, timeout_s, what):
    """Wait on the daemon's replies until ``predicate`` holds (each call is a request/reply)."""
    deadline = time.monotonic() + timeout_s
    last = None
    while time.monotonic() < deadline:
        try:
            last = predicate()
            if last:
                return last
        except Exception as err:  # noqa: BLE001 - the daemon may not be up yet
            last = err
        threading.Event().wait(0.05)  # pacing between requests, not synchronisation
    raise AssertionError(f"timed out waiting for {what}: {last}")


def _signal_mid_weld(tmp_path, sig, exit_code):
    """Start a daemon process, start a cycle, send ``sig`` once the weld runs; returns paths."""
    # a 0.2 mm/s weld lasts minutes at this time scale: the signal lands while the arc is on
    cfg_path = make_cell(tmp_path / "cell", time_scale=0.05, weld_speed_mm_s=0.2)
    sock = load_cell_config(cfg_path).control.socket
    p = _spawn(cfg_path, tmp_path / f"stderr-{sig}.log")
    try:
        _wait_for(lambda: send_request(sock, {"cmd": "status"})["ok"], 60, "daemon start")
        send_request(sock, {"cmd": "start", "job": "demo"})
        _wait_for(lambda: send_request(sock, {"cmd": "status"})["state"] == "welding", 120,
                  "the weld to start")
        p.send_signal(sig)
        code = p.wait(60)
        if exit_code is not None:
            assert code == exit_code
    finally:
        if p.poll() is None:
            p.kill()
    return cfg_path, sock, next((cfg_path.parent / "records").iterdir())


def test_sigkill_mid_cycle_then_restart(tmp_path):
    cfg_path, sock, rec = _signal_mid_weld(tmp_path, signal.SIGKILL, None)
    assert read_record(rec)["status"] == "incomplete"
    job = cfg_path.parent / "demo-job.toml"  # the next cycle welds at the demo's own speed
    job.write_text(job.read_text().replace("[weld]\nspeed_mm_s = 0.2", "[weld]\nspeed_mm_s = 8.0"))
    p2 = _spawn(cfg_path, tmp_path / "stderr2.log")
    try:
        _wait_for(lambda: send_request(sock, {"cmd": "status"})["ok"], 60, "daemon restart")
        doc = read_record(rec)
        assert doc["status"] == "interrupted" and "process stopped" in doc["reason"]
        assert doc["states"][-1]["state"] == "welding"
        lines = [json.loads(x) for x in (cfg_path.parent / "log.jsonl").read_text().splitlines()]
        second = [x["message"] for x in lines if "interrupted" in x["message"]
                  or "made safe" in x["message"] or "daemon ready" in x["message"]]
        i_safe = max(i for i, m in enumerate(second) if "made safe" in m)
        i_ready = max(i for i, m in enumerate(second) if "daemon ready" in m)
        assert i_safe < i_ready  # the robot was made safe before the daemon took requests
        send_request(sock, {"cmd": "start", "job": "demo"})
        st = _wait_for(lambda: (lambda s: s if s["counters"]["cycles_done"] == 1 else None)(
            send_request(sock, {"cmd": "status"})), 120, "the next cycle")
        assert st["last_cycle"]["status"] == "done"
        p2.send_signal(signal.SIGTERM)
        assert p2.wait(60) == 0
    finally:
        if p2.poll() is None:
            p2.kill()


def test_sigterm_mid_weld_aborts_and_exits_cleanly(tmp_path):
    cfg_path, sock, rec = _signal_mid_weld(tmp_path, signal.SIGTERM, 0)
    doc = read_record(rec)
    assert doc["status"] == "aborted" and "SIGTERM" in doc["reason"]
    assert not Path(sock).exists()


def test_sigterm_while_the_arc_is_on_stops_the_weld_with_the_arc_off(tmp_path):
    # In-process, so that the mock controller can be looked at: the daemon's own signal handlers,
    # a real SIGTERM to this process once the mock has switched the arc on.
    # a 0.2 mm/s weld lasts minutes at this time scale: the signal lands while the arc is on
    cfg_path = make_cell(tmp_path / "cell", time_scale=0.05, weld_speed_mm_s=0.2)
    sock = load_cell_config(cfg_path).control.socket
    old = {s: signal.getsignal(s) for s in (signal.SIGTERM, signal.SIGINT, signal.SIGHUP)}
    d = Daemon(cfg_path)
    t = threading.Thread(target=d.serve, daemon=True)
    try:
        d.install_signal_handlers()
        t.start()
        assert d.ready.wait(30), "daemon did not become ready"
        mock = d.robot.mock
        assert send_request(sock, {"cmd": "start", "job": "demo"})["ok"]
        _wait_for(lambda: mock.arc_on, 120, "the arc to go on")
        os.kill(os.getpid(), signal.SIGTERM)
        t.join(60)
        assert not t.is_alive()
    finally:
        for s, h in old.items():
            signal.signal(s, h)
        if t.is_alive():
            d.request_stop("test over")
            t.join(60)
    w = [e for e in mock.executed if e["kind"] == "weld"]
    assert len(w) == 1 and w[0]["result"] == "aborted", w  # stopped mid-weld, not finished
    log = mock.action_log
    after = log[log.index("arc_on"):]
    assert after[:4] == ["arc_on", "abort", "arc_off", "stop"], log
    assert mock.arc_on is False
    assert not any(a.startswith("start") for a in after)  # no motion after the abort
    doc = read_record(next((cfg_path.parent / "records").iterdir()))
    assert doc["status"] == "aborted" and "SIGTERM" in doc["reason"]


def test_sighup_reload_between_cycles(running):
    d, cfg = running
    sock = cfg.control.socket
    assert "unknown job" in send_request(sock, {"cmd": "start", "job": "demo2"})["error"]
    path = Path(d.cfg.path)
    path.write_text(path.read_text().replace('demo = "demo-job.toml"',
                                             'demo = "demo-job.toml"\ndemo2 = "demo-job.toml"'))
    d._reload.set()  # what the SIGHUP handler does
    _wait_for(lambda: send_request(sock, {"cmd": "status"})["config_reloads"] == 1, 30,
              "the reload")
    assert send_request(sock, {"cmd": "start", "job": "demo2"})["ok"]
    assert d.wait_cycles(1, 120)
    path.write_text("this is = not [valid toml")
    refused = threading.Event()

    class OnRefusal(logging.Handler):
        def emit(self, record):
            if "not reloaded, keeping the old one" in record.getMessage():
                refused.set()

    handler = OnRefusal()
    logger = logging.getLogger("controller.cell.daemon")
    logger.addHandler(handler)
    try:
        d._reload.set()
        assert refused.wait(30), "the bad reload was not refused"
    finally:
        logger.removeHandler(handler)
    st = send_request(sock, {"cmd": "status"})  # a bad new file keeps the old configuration
    assert st["ok"] and st["config_reloads"] == 1
    assert d.cfg.job("demo2") is not None
    assert send_request(sock, {"cmd": "start", "job": "demo2"})["ok"]
    assert d.wait_cycles(2, 120)
    assert send_request(sock, {"cmd": "status"})["last_cycle"]["job"] == "demo2"


def test_reload_reconnects_only_when_the_devices_change(running):
    d, cfg = running
    sock = cfg.control.socket
    path = Path(d.cfg.path)

    def reload(old, new, n):
        text = path.read_text()
        assert text.count(old) == 1, old
        path.write_text(text.replace(old, new))
        d._reload.set()
        _wait_for(lambda: send_request(sock, {"cmd": "status"})["config_reloads"] == n, 60,
                  f"reload {n}")

    robot = d.robot
    reload('demo = "demo-job.toml"', 'demo = "demo-job.toml"\ndemo2 = "demo-job.toml"', 1)
    assert d.robot is robot  # jobs only: the link stays
    reload("mock://?seed=1", "mock://?seed=2", 2)  # another robot: reconnected
    robot = _wait_for(lambda: d.robot if d.robot not in (None, robot) else None, 60,
                      "the new robot")
    reload('scene = "s_curve"\nseed = 1', 'scene = "s_curve"\nseed = 2', 3)  # another part
    _wait_for(lambda: d.robot not in (None, robot), 60, "the robot of the new simulated cell")


def test_operator_confirms_or_rejects_the_weld_path(tmp_path):
    with serving(confirming_cell(tmp_path / "cell")) as (d, cfg):
        sock = cfg.control.socket
        r = send_request(sock, {"cmd": "confirm"})
        assert not r["ok"] and "no weld path is waiting" in r["error"]

        def waiting():
            return send_request(sock, {"cmd": "status"})["awaiting_confirmation"]

        send_request(sock, {"cmd": "start", "job": "demo"})
        summary = _wait_for(waiting, 120, "the path to wait for confirmation")
        assert summary["weld_points"] > 10 and summary["length_mm"] > 50
        assert send_request(sock, {"cmd": "status"})["state"] == "confirming"
        assert send_request(sock, {"cmd": "reject"}) == {"ok": True, "confirmed": False}
        assert d.wait_cycles(1, 60)
        last = d.status()["last_cycle"]
        assert last["status"] == "aborted" and "did not confirm" in last["reason"]
        assert "arc_on" not in d.robot.mock.action_log and not d.robot.mock.arc_on

        send_request(sock, {"cmd": "start", "job": "demo"})
        _wait_for(waiting, 120, "the second path to wait for confirmation")
        assert send_request(sock, {"cmd": "confirm"})["confirmed"]
        assert d.wait_cycles(2, 120)
        assert d.status()["last_cycle"]["status"] == "done"
        assert d.status()["awaiting_confirmation"] is None


def test_watchdog_keeps_pinging_through_a_long_state_of_a_cycle(tmp_path, monkeypatch):
    """A cycle waiting for the operator (or welding for minutes) blocks the serve loop; the
    watchdog thread still pings because the state is within its timeout."""
    notify_path = str(tmp_path / "notify.sock")
    srv = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    srv.bind(notify_path)
    monkeypatch.setenv("NOTIFY_SOCKET", notify_path)
    monkeypatch.setenv("WATCHDOG_USEC", "200000")  # ping every 0.1 s
    monkeypatch.setenv("WATCHDOG_PID", str(os.getpid()))
    with contextlib.closing(srv), serving(confirming_cell(tmp_path / "cell")) as (d, cfg):
        sock = cfg.control.socket
        send_request(sock, {"cmd": "start", "job": "demo"})
        _wait_for(lambda: send_request(sock, {"cmd": "status"})["awaiting_confirmation"], 120,
                  "the path to wait for confirmation")
        srv.setblocking(False)
        with contextlib.suppress(BlockingIOError):
            while True:
                srv.recv(200)  # drop what was sent before the wait
        srv.settimeout(0.5)
        pings = 0
        deadline = time.monotonic() + 1.0
        while time.monotonic() < deadline:
            if srv.recv(200) == b"WATCHDOG=1":
                pings += 1
        assert pings >= 5, pings
        assert send_request(sock, {"cmd": "status"})["awaiting_confirmation"] is not None
        send_request(sock, {"cmd": "reject"})
        assert d.wait_cycles(1, 60)


def test_each_cycle_moves_within_its_own_jobs_box(tmp_path):
    """The daemon's robot checks every motion of a cycle against that cycle's job limits: a
    view outside the job's box is refused before a motion byte is sent (the robot's own default
    box, +-1800 mm, would let it through), and the next job's cycle gets its own limits."""
    cfg_path = make_cell(tmp_path / "cell")
    folder = cfg_path.parent
    demo = (folder / "demo-job.toml").read_text()
    tight_box = "workspace_max_mm = [1600.0, 900.0, 500.0]"  # the views look from z 540-890 mm
    (folder / "tight-job.toml").write_text(
        demo.replace('name = "demo"', 'name = "tight"')
        .replace("workspace_max_mm = [1600.0, 900.0, 1500.0]", tight_box))
    cfg_path.write_text(cfg_path.read_text().replace(
        'demo = "demo-job.toml"', 'demo = "demo-job.toml"\ntight = "tight-job.toml"'))
    motion_codes = {"SV", "MJ", "MT", "ML", "XT", "XP", "XO", "PN", "RW"}
    with serving(cfg_path) as (d, cfg):
        sent: list[str] = []
        request = d.robot.link.request
        d.robot.link.request = lambda body, *a, **k: (sent.append(body.split()[0]),
                                                     request(body, *a, **k))[1]
        mock = d.robot.mock
        assert send_request(cfg.control.socket, {"cmd": "start", "job": "tight"})["ok"]
        assert d.wait_cycles(1, 120)
        last = d.status()["last_cycle"]
        assert last["status"] == "fault", last
        assert last["reason"].startswith("move_joints target (TCP) at"), last
        assert "outside the safety workspace box [300.0, -900.0, -100.0] .. " \
               "[1600.0, 900.0, 500.0] mm" in last["reason"], last
        assert read_record(last["record"])["details"]["error"] == "SafetyError"
        assert not motion_codes & set(sent), sent  # not one motion request left the controller
        assert mock.executed == [] and not any(a.startswith("start") for a in mock.action_log)
        # the next cycle, of the demo job, moves in the demo job's box (z up to 1500 mm)
        assert send_request(cfg.control.socket, {"cmd": "start", "job": "demo"})["ok"]
        assert d.wait_cycles(2, 120)
        assert d.status()["last_cycle"]["status"] == "done", d.status()["last_cycle"]
        assert d.robot.limits.workspace_max_mm == (1600.0, 900.0, 1500.0)
