"""A short daemon soak: one cycle per kind of injected fault; the daemon must survive them all."""

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "bench"))
from soak_daemon import FAULTS, run_soak  # noqa: E402

pytestmark = pytest.mark.slow


def test_daemon_survives_every_kind_of_fault(tmp_path):
    faults = list(FAULTS)
    res = run_soak(tmp_path / "soak", len(faults), seed=3, log=lambda m: None, faults=faults)
    assert res["daemon_alive"]
    assert res["problems"] == []
    assert res["counters_add_up"] and res["records"] == len(faults)
    assert res["records_unreadable"] == 0
    assert res["metrics_match_records"], (res["metrics_cycles_by_outcome"],
                                          res["records_by_status"])
    assert res["by_fault"]["none"] == {"done": 1}
    for f in ("controller_error_mid_weld", "camera_failure", "no_seam"):
        assert res["by_fault"][f] == {"fault": 1}, f
