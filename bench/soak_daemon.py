"""Daemon soak: many cycles against the mock controller and simulated camera with random faults.

    .venv/bin/python bench/soak_daemon.py [--cycles 200] [--seed 1]

Faults are drawn per cycle (fixed seed): none, a controller error mid-weld (``fail_at_point``), a
burst of link corruption and dropped lines, a link disconnect mid-cycle, a camera that delivers no
frame, an image without a seam. Checked after every cycle: the daemon is alive and answers, the
cycle ended ``done`` or in a recorded fault with the arc off, its record is readable and final.
At the end: no record lost, and the counters add up; the operator station's ``/metrics`` is
scraped every 10 cycles and at the end, and its cycles by outcome must equal the records'
statuses. Writes bench/out/soak_daemon.json.
"""

from __future__ import annotations

import argparse
import json
import sys
import threading
import time
from collections import Counter
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

import controller.cell.daemon as daemon_mod  # noqa: E402
from controller.cell.control_socket import send_request  # noqa: E402
from controller.cell.cycle_record import read_record  # noqa: E402
from controller.errors import CameraError  # noqa: E402

FAULTS = ("none", "controller_error_mid_weld", "link_corruption", "link_disconnect",
          "camera_failure", "no_seam")
WEIGHTS = (0.4, 0.15, 0.15, 0.1, 0.1, 0.1)


class FaultyCamera:
    """Wraps the daemon's camera; ``mode`` is set per cycle by the soak."""

    mode = "none"

    def __init__(self, inner):
        self.inner = inner
        self.n = 0

    def grab(self):
        self.n += 1
        if FaultyCamera.mode == "camera_failure" and self.n % 2 == 0:
            raise CameraError("soak: camera delivered no frame")
        image = self.inner.grab()
        if FaultyCamera.mode == "no_seam":
            import cv2

            return cv2.GaussianBlur(image, (0, 0), 25)  # the part out of focus: no joint visible
        return image

    def close(self):
        self.inner.close()


def _disconnect(mock) -> None:
    """Drop the link of ``mock``; a mock already replaced (stopped after a reconnect) is left."""
    import contextlib

    from controller.errors import ConfigError

    # The daemon may have closed this mock's link meanwhile: nothing left to disconnect then.
    with contextlib.suppress(ConfigError):
        mock.disconnect(wait=False)


def run_soak(folder: Path, cycles: int, seed: int, log=print, faults: list[str] | None = None
             ) -> dict:
    """Run the soak; ``faults`` fixes the fault of each cycle instead of drawing it."""
    from daemon_harness import make_cell

    cfg_path = make_cell(folder, time_scale=0.002,
                         extra='\n[http]\nbind = "127.0.0.1"\nport = 0\n')
    real_open = daemon_mod.open_cell_camera
    daemon_mod.open_cell_camera = lambda cfg, robot: FaultyCamera(real_open(cfg, robot))
    d = daemon_mod.Daemon(cfg_path)
    from controller.station.bootstrap import start_station

    station = start_station(d, d.cfg)
    assert station is not None
    scrapes: list[dict[str, int]] = []
    t = threading.Thread(target=d.serve, daemon=True)
    t.start()
    if not d.ready.wait(60):
        raise RuntimeError("daemon did not start")
    sock = d.cfg.control.socket
    rng = np.random.default_rng(seed)
    outcomes: Counter[str] = Counter()
    by_fault: dict[str, Counter[str]] = {f: Counter() for f in FAULTS}
    problems: list[str] = []
    t0 = time.monotonic()
    try:
        for i in range(cycles):
            fault = faults[i] if faults else str(rng.choice(FAULTS, p=WEIGHTS))
            mock = d.robot.mock if d.robot is not None else None
            FaultyCamera.mode = fault
            timer = None
            if mock is not None:
                # the weld goes as segments: a straight seam is 3 path points (the line from the
                # approach, one segment, the depart), so the fault comes at point 2 or 3
                mock.arm.fail_at_point = int(rng.integers(2, 4)) if fault == \
                    "controller_error_mid_weld" else None
                mock.line.corrupt, mock.line.drop = (0.03, 0.02) if fault == "link_corruption" \
                    else (0, 0)
                if fault == "link_disconnect":
                    timer = threading.Timer(float(rng.uniform(0.2, 2.0)), _disconnect, (mock,))
                    timer.start()
            r = send_request(sock, {"cmd": "start", "job": "demo"})
            if not r.get("ok"):
                problems.append(f"cycle {i}: start refused: {r}")
                continue
            if not d.wait_cycles(i + 1, 300):
                problems.append(f"cycle {i}: did not end within 300 s")
                break
            if timer is not None:
                timer.cancel()
            st = send_request(sock, {"cmd": "status"})
            last = st["last_cycle"]
            outcomes[last["status"]] += 1
            by_fault[fault][last["status"]] += 1
            if d.robot is not None and d.robot.mock.arc_on:
                problems.append(f"cycle {i} ({fault}): arc still on after the cycle")
            if last["record"] is None:
                if "camera unavailable" not in (last["reason"] or ""):
                    problems.append(f"cycle {i} ({fault}): no record")
            else:
                doc = read_record(last["record"])
                if doc["status"] not in ("done", "fault", "aborted"):
                    problems.append(f"cycle {i}: record status {doc['status']}")
                if doc["status"] != "done" and not doc.get("reason"):
                    problems.append(f"cycle {i}: fault without a reason")
            if (i + 1) % 10 == 0:
                scrapes.append(scrape_cycles(station.url))
                log(f"{i + 1}/{cycles} cycles, {dict(outcomes)}, {time.monotonic() - t0:.0f} s, "
                    f"/metrics {scrapes[-1]}")
        alive = t.is_alive() and send_request(sock, {"cmd": "status"})["ok"]
        st = send_request(sock, {"cmd": "status"})
        scrapes.append(scrape_cycles(station.url))
    finally:
        d.request_stop("soak over")
        t.join(120)
        station.stop()
        daemon_mod.open_cell_camera = real_open
    c = st["counters"]
    records = [p for p in (folder / "records").iterdir() if (p / "record.json").is_file()]
    unreadable = 0
    for p in records:
        try:
            read_record(p)
        except Exception:  # noqa: BLE001 - counted, reported
            unreadable += 1
    total = c["cycles_done"] + c["cycles_faulted"] + c["cycles_aborted"]
    by_status = Counter(read_record(p)["status"] for p in records)
    camera_unavailable = sum(outcomes.values()) - len(records)  # no record: camera never opened
    # /metrics counts every ended cycle; one whose camera never opened is a fault with no record.
    expected = Counter(by_status)
    expected["fault"] += camera_unavailable
    expected = Counter({k: v for k, v in expected.items() if v})
    return {"cycles": cycles, "seconds": round(time.monotonic() - t0, 1),
            "daemon_alive": bool(alive), "outcomes": dict(outcomes),
            "by_fault": {k: dict(v) for k, v in by_fault.items()}, "counters": c,
            "counters_add_up": total == sum(outcomes.values()), "records": len(records),
            "records_unreadable": unreadable, "problems": problems,
            "metrics_cycles_by_outcome": scrapes[-1] if scrapes else None,
            "records_by_status": dict(by_status), "cycles_without_record": camera_unavailable,
            "metrics_match_records": bool(scrapes) and scrapes[-1] == dict(expected),
            "metrics_scrapes": len(scrapes)}


def scrape_cycles(url: str) -> dict[str, int]:
    """``seamguide_cycles_total`` from the station's /metrics, summed by outcome."""
    import urllib.request

    with urllib.request.urlopen(url + "/metrics", timeout=30) as r:
        text = r.read().decode()
    out: dict[str, int] = {}
    for line in text.splitlines():
        if line.startswith("seamguide_cycles_total{"):
            outcome = line.split('outcome="')[1].split('"')[0]
            out[outcome] = out.get(outcome, 0) + int(float(line.rsplit(" ", 1)[1]))
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cycles", type=int, default=200)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--folder", default=str(ROOT / "bench" / "out" / "soak_daemon"))
    args = ap.parse_args()
    import shutil

    folder = Path(args.folder)
    shutil.rmtree(folder, ignore_errors=True)
    res = run_soak(folder, args.cycles, args.seed, log=lambda m: print(m, file=sys.stderr))
    out = ROOT / "bench" / "out" / "soak_daemon.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(res, indent=1))
    print(json.dumps(res, indent=1))
    ok = res["daemon_alive"] and not res["problems"] and res["counters_add_up"]
    return 0 if ok and res["metrics_match_records"] else 1


if __name__ == "__main__":
    raise SystemExit(main())
