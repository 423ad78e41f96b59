"""The cycle with cut ends: a long seam whose ends leave both images (the dry run's open_ends).

The job decides: clip to the nominal region (DONE, the record says which ends were clipped) or
refuse (FAULT with the reason, nothing welded).
"""

import pytest

from controller.cell.cycle_record import read_record
from controller.cell.dry_run import run_dry_run

pytestmark = pytest.mark.slow


@pytest.mark.parametrize("clip", [True, False])
def test_open_ends_clipped_or_refused(tmp_path, clip):
    rep = run_dry_run(tmp_path, scene_kind="open_ends", seed=2, speedup=200.0,
                      clip_unseen_ends=clip)
    r = rep.result
    doc = read_record(r.record_path)
    if clip:
        assert r.status == "done", r.reason
        assert [e["status"] for e in doc["seam_ends"]] == ["clipped", "clipped"]
        assert all("runs out of the image" in " ".join(e["not_seen"]) for e in doc["seam_ends"])
        assert rep.seam_rms_mm <= 0.1
    else:
        assert r.status == "fault"
        assert "no view sees where the seam ends" in r.reason and "clip_unseen_ends" in r.reason
        assert doc["details"]["error"] == "TriangulationError"
        assert rep.arc_on_after is False
