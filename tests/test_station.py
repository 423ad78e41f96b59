"""The operator station: pages, roles, CSRF, confined paths, request bounds, metrics.

Unit level with Flask's test client and a fake daemon; the station on a real daemon (a real
listener, real HTTP) in tests/test_station_daemon.py; in a real browser in test_station_browser.py.
"""

import json
import logging
import os

import cv2
import numpy as np
import pytest

from controller.errors import ConfigError
from controller.station.access import Access, Tokens, check_bind, load_tokens
from controller.station.metrics import CellMetrics
from controller.station.web_app import StationSettings, create_app

VIEWER = "viewer-token-0123456789"
OPERATOR = "operator-token-0123456789"


class FakeDaemon:
    """The daemon's control surface: records every request, answers like the daemon."""

    def __init__(self):
        self.requests = []
        self.state = "idle"

    def status(self):
        return {"ok": True, "cell": "t", "state": self.state, "job": None, "paused": False,
                "robot": "connected", "camera": "open", "queue_length": 0,
                "counters": {"cycles_done": 1, "cycles_faulted": 0, "cycles_aborted": 0,
                             "requests_rejected": 0},
                "awaiting_confirmation": None, "record": None, "views": [], "last_cycle": None}

    def handle_request(self, req):
        self.requests.append(req)
        return {"ok": True, **req}


def make_record(root, name="20261201-100000-demo-1", status="fault", reason="seam not found",
                job="demo"):
    folder = root / name
    folder.mkdir(parents=True)
    (folder / "record.json").write_text(json.dumps({
        "status": status, "job": job, "started": "2026-12-01T10:00:00+0000",
        "states": [{"state": "capturing", "t_s": 0.0, "duration_s": 1.0},
                   {"state": status, "t_s": 1.0, "duration_s": 0.0}],
        "files": ["view1.png"], "reason": reason, "duration_s": 1.0,
        "detections": [{"view": "view1", "confidence": 0.93}]}))
    cv2.imwrite(str(folder / "view1.png"), np.full((20, 30), 128, np.uint8))
    return folder


@pytest.fixture
def station(tmp_path):
    records = tmp_path / "records"
    make_record(records)
    make_record(records, "20261201-100100-other-1", "done", None, job="other")
    (tmp_path / "secret.txt").write_text("not for the web")
    calib = tmp_path / "cal.yaml"
    calib.write_text("metadata: {source: test, hand_eye_std_mm: 0.05}\n")
    daemon = FakeDaemon()
    settings = StationSettings(cell="t", records_dir=str(records), calibration_path=str(calib),
                               jobs=("demo", "other"), max_request_bytes=4096)
    metrics = CellMetrics("t")
    app = create_app(daemon, settings, Access(Tokens(VIEWER, OPERATOR)), metrics.exposition)
    return app.test_client(), daemon, metrics


def auth(token):
    return {"Authorization": f"Bearer {token}"}


def csrf_of(client, token):
    page = client.get("/", headers=auth(token)).get_data(as_text=True)
    return page.split('name="csrf-token" content="')[1].split('"')[0]


def test_pages_need_a_token_and_refusals_are_logged(station, caplog):
    client, _, _ = station
    caplog.set_level(logging.WARNING, "seamguide.station")
    r = client.get("/")
    assert r.status_code == 302 and r.headers["Location"].endswith("/login")
    assert client.get("/api/status").status_code == 401
    assert client.get("/metrics").status_code == 401
    assert client.get("/api/status", headers=auth("wrong-token-0123456789")).status_code == 401
    assert sum("refused" in m for m in caplog.messages) >= 4
    assert client.get("/api/status", headers=auth(VIEWER)).json["role"] == "viewer"
    assert client.get("/api/status", headers=auth(OPERATOR)).json["role"] == "operator"


def test_login_sets_an_http_only_strict_cookie(station):
    client, _, _ = station
    assert client.post("/login", data={"token": "nope"}).status_code == 401
    r = client.post("/login", data={"token": VIEWER})
    assert r.status_code == 302
    cookie = r.headers["Set-Cookie"]
    assert "HttpOnly" in cookie and "SameSite=Strict" in cookie
    assert client.get("/").status_code == 200  # the cookie now identifies the viewer


def test_a_viewer_cannot_act_and_an_operator_needs_the_csrf_token(station):
    client, daemon, _ = station
    tok = csrf_of(client, VIEWER)
    r = client.post("/action/abort", headers={**auth(VIEWER), "X-CSRF-Token": tok})
    assert r.status_code == 403 and "operator" in r.json["error"]
    r = client.post("/action/abort", headers=auth(OPERATOR))
    assert r.status_code == 403 and "CSRF" in r.json["error"]
    r = client.post("/action/abort", headers={**auth(OPERATOR), "X-CSRF-Token": tok})
    assert r.status_code == 403  # the viewer's CSRF token is not the operator's
    assert daemon.requests == []
    op = csrf_of(client, OPERATOR)
    r = client.post("/action/abort", headers={**auth(OPERATOR), "X-CSRF-Token": op,
                                              "Origin": "http://evil.example"})
    assert r.status_code == 403 and "cross-site" in r.json["error"]
    r = client.post("/action/start", data={"job": "demo"},
                    headers={**auth(OPERATOR), "X-CSRF-Token": op})
    assert r.status_code == 200 and daemon.requests == [{"cmd": "start", "job": "demo"}]
    r = client.post("/action/confirm", headers={**auth(OPERATOR), "X-CSRF-Token": op})
    assert daemon.requests[-1] == {"cmd": "confirm"}
    assert client.post("/action/format-disk", headers={**auth(OPERATOR),
                                                       "X-CSRF-Token": op}).status_code == 404
    assert client.get("/action/abort", headers=auth(OPERATOR)).status_code == 405


def test_record_paths_cannot_leave_the_records_folder(station, tmp_path):
    client, _, _ = station
    h = auth(VIEWER)
    assert client.get("/records/20261201-100000-demo-1/files/view1.png",
                      headers=h).status_code == 200
    for bad in ("/records/../secret.txt", "/records/%2e%2e/files/secret.txt",
                "/records/20261201-100000-demo-1/files/..%2f..%2fsecret.txt",
                "/records/20261201-100000-demo-1/files/%2e%2e",
                "/records/20261201-100000-demo-1/files/record.json%00.png"):
        r = client.get(bad, headers=h)
        assert r.status_code == 404, bad
        assert b"not for the web" not in r.data
    # A symbolic link inside a record that points outside is refused too.
    os.symlink(tmp_path / "secret.txt", tmp_path / "records" / "20261201-100000-demo-1" / "s.txt")
    r = client.get("/records/20261201-100000-demo-1/files/s.txt", headers=h)
    assert r.status_code == 404 and b"not for the web" not in r.data


def test_oversize_requests_are_refused(station):
    client, daemon, _ = station
    op = csrf_of(client, OPERATOR)
    r = client.post("/action/start", data={"job": "x" * 10000},
                    headers={**auth(OPERATOR), "X-CSRF-Token": op})
    assert r.status_code == 413 and daemon.requests == []


def test_history_is_searchable_and_a_record_opens_as_a_page(station):
    client, _, _ = station
    h = auth(VIEWER)
    page = client.get("/records?outcome=fault", headers=h).get_data(as_text=True)
    assert "20261201-100000-demo-1" in page and "20261201-100100-other-1" not in page
    page = client.get("/records?job=other", headers=h).get_data(as_text=True)
    assert "20261201-100100-other-1" in page and "20261201-100000-demo-1" not in page
    page = client.get("/records?q=seam+not", headers=h).get_data(as_text=True)
    assert "20261201-100000-demo-1" in page and "20261201-100100-other-1" not in page
    page = client.get("/records/20261201-100000-demo-1", headers=h).get_data(as_text=True)
    assert "seam not found" in page and "0.93" in page and "view1.png" in page
    assert client.get("/records/nope-1", headers=h).status_code == 404


def test_metrics_count_cycles_by_outcome(station):
    client, _, metrics = station
    metrics.cycle_ended("done", None, {"states": [{"state": "welding", "duration_s": 2.0}],
                                       "detections": [{"view": "v1", "confidence": 0.9}]}, 7.0)
    metrics.cycle_ended("fault", "SeamNotFound", None, 1.0)
    text = client.get("/metrics", headers=auth(VIEWER)).get_data(as_text=True)
    assert 'seamguide_cycles_total{fault_kind="",outcome="done"} 1.0' in text
    assert 'seamguide_cycles_total{fault_kind="SeamNotFound",outcome="fault"} 1.0' in text
    assert 'seamguide_state_duration_seconds_count{state="welding"} 1.0' in text
    assert "seamguide_detection_confidence_count 1.0" in text


def test_token_file_and_bind_policy(tmp_path):
    f = tmp_path / "tokens.toml"
    f.write_text(f'viewer = "{VIEWER}"\noperator = "{OPERATOR}"\n')
    f.chmod(0o644)
    with pytest.raises(ConfigError, match="readable by other users"):
        load_tokens(f)
    f.chmod(0o600)
    assert load_tokens(f) == Tokens(VIEWER, OPERATOR)
    f.write_text('operator = "short"\n')
    with pytest.raises(ConfigError, match="at least 16"):
        load_tokens(f)
    with pytest.raises(ConfigError, match="does not exist"):
        load_tokens(tmp_path / "none.toml")
    check_bind("127.0.0.1", None)
    check_bind("::1", None)
    with pytest.raises(ConfigError, match="token_file"):
        check_bind("0.0.0.0", None)
    with pytest.raises(ConfigError, match="token_file"):
        check_bind("192.0.2.4", Tokens(None, OPERATOR))
    check_bind("0.0.0.0", Tokens(VIEWER, OPERATOR))


def test_open_station_on_loopback_makes_everyone_operator(tmp_path):
    access = Access(None)
    assert access.role(None) == "operator"
    assert access.csrf_ok(None, access.csrf_token(None))
    assert not access.csrf_ok(None, "0" * 64)


def test_the_grafana_example_uses_only_metrics_we_export():
    import re
    from pathlib import Path

    dash = json.loads((Path(__file__).parent.parent / "examples" / "grafana-dashboard.json")
                      .read_text())
    m = CellMetrics("t", link_stats=lambda: (1, {"retransmissions": 0, "reconnects": 0}),
                    calibration_age_s=lambda: 5.0)
    m.cycle_ended("done", None, {"detections": [{"confidence": 0.9}],
                                 "states": [{"state": "welding", "duration_s": 1.0}]}, 1.0)
    m.state_changed("idle")
    exported = {ln.split("{")[0].split(" ")[0] for ln in m.exposition().decode().splitlines()
                if ln and not ln.startswith("#")}
    used = {name for p in dash["panels"] for t in p["targets"]
            for name in re.findall(r"seamguide_[a-z_]+", t["expr"])}
    assert used and used <= exported, used - exported
