"""The operator station on a running daemon, over real HTTP: refusals leave the daemon serving;
metrics agree with the records."""

import json
import urllib.error
import urllib.request

import pytest
from station_harness import serving_station, station_cell

from controller.cell.cycle_record import read_record
from controller.station.records_view import list_records

pytestmark = pytest.mark.slow

VIEWER = "viewer-token-0123456789"
OPERATOR = "operator-token-0123456789"


def call(url, method="GET", token=None, headers=None, data=None):
    h = dict(headers or {})
    if token:
        h["Authorization"] = f"Bearer {token}"
    req = urllib.request.Request(url, data=data, method=method, headers=h)
    try:
        with urllib.request.urlopen(req, timeout=30) as r:
            return r.status, r.read()
    except urllib.error.HTTPError as err:
        return err.code, err.read()


def csrf(url, token):
    _, page = call(url + "/", token=token)
    return page.decode().split('name="csrf-token" content="')[1].split('"')[0]


def test_refused_requests_leave_the_daemon_serving_and_metrics_match_records(tmp_path):
    cfg = station_cell(tmp_path / "cell", tokens=(VIEWER, OPERATOR))
    with serving_station(cfg) as (d, url, _):
        # Refusals: no token, viewer acting, a path outside the records, an oversize body.
        assert call(url + "/action/start", "POST", data=b"job=demo")[0] == 401
        vt = csrf(url, VIEWER)
        assert call(url + "/action/start", "POST", VIEWER, {"X-CSRF-Token": vt},
                    b"job=demo")[0] == 403
        assert call(url + "/records/..%2f..%2fcell.toml/files/x", token=VIEWER)[0] == 404
        big = b"job=" + b"x" * 100_000
        assert call(url + "/action/start", "POST", OPERATOR,
                    {"X-CSRF-Token": csrf(url, OPERATOR)}, big)[0] == 413
        assert d.status()["counters"]["cycles_done"] == 0 and d.status()["queue_length"] == 0
        # The daemon still serves: two cycles started from the page, one of them a fault.
        op = csrf(url, OPERATOR)
        code, body = call(url + "/action/start", "POST", OPERATOR,
                          {"X-CSRF-Token": op,
                           "Content-Type": "application/x-www-form-urlencoded"}, b"job=demo")
        assert code == 200 and json.loads(body)["ok"], body
        assert d.wait_cycles(1, 180)
        d.robot.mock.arm.fail_at_point = 5  # the controller reports an error mid-weld
        code, _ = call(url + "/action/start", "POST", OPERATOR,
                       {"X-CSRF-Token": op, "Content-Type": "application/x-www-form-urlencoded"},
                       b"job=demo")
        assert code == 200
        assert d.wait_cycles(2, 180)
        code, text = call(url + "/metrics", token=VIEWER)
        assert code == 200
        text = text.decode()
        records = list_records(d.cfg.records.dir)
        by_outcome = {}
        for r in records:
            by_outcome[r.status] = by_outcome.get(r.status, 0) + 1
        counted = {}
        for line in text.splitlines():
            if line.startswith("seamguide_cycles_total{"):
                outcome = line.split('outcome="')[1].split('"')[0]
                counted[outcome] = counted.get(outcome, 0) + int(float(line.rsplit(" ", 1)[1]))
        assert counted == by_outcome == {"done": 1, "fault": 1}, (counted, by_outcome)
        fault_lines = [ln for ln in text.splitlines()
                       if ln.startswith("seamguide_cycles_total{") and 'outcome="fault"' in ln]
        assert fault_lines == [
            'seamguide_cycles_total{fault_kind="RobotFault",outcome="fault"} 1.0']
        assert all(read_record(d.cfg.records.dir + "/" + r.name)["status"] == r.status
                   for r in records)
        assert "seamguide_link_retransmissions_total" in text
        assert "seamguide_calibration_age_seconds" in text
        assert 'seamguide_state_duration_seconds_count{state="welding"}' in text
