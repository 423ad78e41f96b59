"""Prometheus metrics of the cell (``/metrics``), with the ``prometheus_client`` library.

Counted from the daemon's cycle-end events (:meth:`CellMetrics.cycle_ended`): cycles by outcome
and fault kind, cycle and state durations (histograms), detection confidence; read at scrape
time: link retransmissions and reconnects (summed over the links the daemon has had: a link that
is dropped and reopened starts its own counts at zero) and the calibration's age.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from typing import Any

from prometheus_client import CollectorRegistry, Counter, Gauge, Histogram, generate_latest
from prometheus_client.core import CounterMetricFamily, GaugeMetricFamily
from prometheus_client.registry import Collector

#: Buckets (s) for whole cycles and for single states.
CYCLE_BUCKETS = (1, 2, 5, 10, 20, 30, 60, 120, 300, 600)
STATE_BUCKETS = (0.05, 0.1, 0.25, 0.5, 1, 2, 5, 10, 30, 60, 120)
CONFIDENCE_BUCKETS = (0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 0.95, 0.99, 1.0)


class _LiveCollector(Collector):
    """Values read from the daemon when scraped."""

    def __init__(self, link_stats: Callable[[], tuple[int, dict[str, int]] | None],
                 calibration_age_s: Callable[[], float | None]) -> None:
        self._link_stats = link_stats
        self._calibration_age_s = calibration_age_s
        self._lock = threading.Lock()
        self._base = {"retransmissions": 0, "reconnects": 0}
        self._last: tuple[int, dict[str, int]] | None = None

    def _link_totals(self) -> dict[str, int]:
        now = self._link_stats()
        with self._lock:
            if self._last is not None and (now is None or now[0] != self._last[0]):
                for k in self._base:  # the daemon has a new link: keep the old one's counts
                    self._base[k] += int(self._last[1].get(k, 0))
            self._last = now
            cur = now[1] if now is not None else {}
            return {k: self._base[k] + int(cur.get(k, 0)) for k in self._base}

    def collect(self) -> Iterator[Any]:
        """Yield the live metric families."""
        totals = self._link_totals()
        c = CounterMetricFamily("seamguide_link_retransmissions",
                                "Requests re-sent on the robot link (no or bad reply)")
        c.add_metric([], totals["retransmissions"])
        yield c
        c = CounterMetricFamily("seamguide_link_reconnects", "Robot link reconnects")
        c.add_metric([], totals["reconnects"])
        yield c
        age = self._calibration_age_s()
        if age is not None:
            g = GaugeMetricFamily("seamguide_calibration_age_seconds",
                                  "Age of the calibration file in use")
            g.add_metric([], age)
            yield g


class CellMetrics:
    """The cell's metrics in their own registry (no process-global state)."""

    def __init__(self, cell: str,
                 link_stats: Callable[[], tuple[int, dict[str, int]] | None] = lambda: None,
                 calibration_age_s: Callable[[], float | None] = lambda: None) -> None:
        self.registry = CollectorRegistry()
        self.cell = cell
        self.cycles = Counter("seamguide_cycles", "Weld cycles ended, by outcome and fault kind",
                              ["outcome", "fault_kind"], registry=self.registry)
        self.cycle_seconds = Histogram("seamguide_cycle_duration_seconds",
                                       "Duration of whole weld cycles", ["outcome"],
                                       buckets=CYCLE_BUCKETS, registry=self.registry)
        self.state_seconds = Histogram("seamguide_state_duration_seconds",
                                       "Time spent in each cycle state", ["state"],
                                       buckets=STATE_BUCKETS, registry=self.registry)
        self.confidence = Histogram("seamguide_detection_confidence",
                                    "Confidence of each seam detection in a cycle",
                                    buckets=CONFIDENCE_BUCKETS, registry=self.registry)
        self.state = Gauge("seamguide_cycle_state", "1 for the state the cell is in now",
                           ["state"], registry=self.registry)
        self.registry.register(_LiveCollector(link_stats, calibration_age_s))
        self._state_now: str | None = None

    def cycle_ended(self, outcome: str, fault_kind: str | None, record: dict[str, Any] | None,
                    duration_s: float | None) -> None:
        """Count one ended cycle (``outcome`` done / fault / aborted; the record's states)."""
        self.cycles.labels(outcome, fault_kind or "").inc()
        if duration_s is not None:
            self.cycle_seconds.labels(outcome).observe(duration_s)
        for st in (record or {}).get("states", []):
            if isinstance(st, dict) and st.get("duration_s") is not None:
                self.state_seconds.labels(str(st.get("state"))).observe(float(st["duration_s"]))
        for det in (record or {}).get("detections", []):
            if isinstance(det, dict) and isinstance(det.get("confidence"), (int, float)):
                self.confidence.observe(float(det["confidence"]))

    def state_changed(self, state: str) -> None:
        """Set the state gauge (the previous state goes to 0)."""
        if self._state_now is not None:
            self.state.labels(self._state_now).set(0)
        self.state.labels(state).set(1)
        self._state_now = state

    def exposition(self) -> bytes:
        """The text exposition format of every metric."""
        return generate_latest(self.registry)
