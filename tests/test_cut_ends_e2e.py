"""The cycle with cut ends: a long seam whose ends leave both images (the dry run's open_ends),
and the same seam with tack welds and spatter on it (tack_open: issue 13's dry run).

The job decides: clip to the nominal region (DONE, the record says which ends were clipped) or
refuse (FAULT with the reason, nothing welded). State timeouts are relaxed: this seam is twice
the usual length and the test must not depend on the machine's load.
"""

import dataclasses

import pytest

from controller.cell.cycle_record import read_record
from controller.cell.dry_run import SimRig
from controller.cell.job import TimeoutsSpec

pytestmark = pytest.mark.slow


def run(tmp_path, clip, scene="open_ends", seed=2, gap_stated=True):
    with SimRig(scene_kind=scene, seed=seed, speedup=200.0, clip_unseen_ends=clip) as rig:
        # The dry-run job states the scene's gap; ``gap_stated=False``: a job that does not.
        seam = rig.job.seam if gap_stated else dataclasses.replace(rig.job.seam, gap_mm=None)
        rig.job = dataclasses.replace(rig.job, seam=seam, timeouts=TimeoutsSpec(
            capture_s=600.0, locate_s=600.0, plan_s=600.0))
        cycle = rig.cycle(tmp_path)
        rep = rig.report(cycle.run(), cycle)
        welds = [e for e in rig.mock.executed if e["kind"] == "weld"]
    return rep, welds


@pytest.mark.parametrize("scene", ["open_ends", "tack_open"])
@pytest.mark.parametrize("clip", [True, False])
def test_open_ends_clipped_or_refused(tmp_path, clip, scene):
    rep, welds = run(tmp_path, clip, scene)
    r = rep.result
    doc = read_record(r.record_path)
    if clip:
        assert r.status == "done", r.reason
        assert [e["status"] for e in doc["seam_ends"]] == ["clipped", "clipped"]
        assert all("runs out of the image" in " ".join(e["not_seen"]) for e in doc["seam_ends"])
        # The record says how much of each clipped end was cut at the image borders (kept 12 px in).
        assert all(0.5 < e["border_trimmed_mm"] <= e["clipped_mm"] < 10.0 for e in doc["seam_ends"])
        assert rep.seam_rms_mm <= 0.1 and len(welds) == 1
    else:
        assert r.status == "fault"
        assert "no view sees where the seam ends" in r.reason and "clip_unseen_ends" in r.reason
        assert doc["details"]["error"] == "TriangulationError"
        assert rep.arc_on_after is False and welds == []


def test_open_ends_seed_3_with_the_jobs_gap_lands_within_a_fraction_of_a_millimetre(tmp_path):
    # The far sheet's cut face shows inside the gap: a lighter band beside the darker floor,
    # which the shadow split took for a shadow beside the gap (1.16 mm RMS off). The job's
    # narrowest gap (the dry run states the scene's gap +-50 %) is wider than that floor: the
    # band is kept whole (seam_shadow, DetectParams.min_gap_px).
    rep, welds = run(tmp_path, True, seed=3)
    assert rep.result.status == "done", rep.result.reason
    assert rep.seam_rms_mm <= 0.2 and len(welds) == 1


def test_open_ends_seed_3_without_the_jobs_gap_lands_within_a_fraction_of_a_millimetre(tmp_path):
    # Without the job's gap both views split the cut face off as a shadow (welded 1.16 mm RMS
    # off from 5f0beca to 2026-12-04); the two readings triangulate 1.06 mm apart along the
    # sheet normal, which a shadow cannot do: the whole band is the gap (stereo.band_check).
    rep, welds = run(tmp_path, True, seed=3, gap_stated=False)
    assert rep.result.status == "done", rep.result.reason
    assert rep.seam_rms_mm <= 0.2 and len(welds) == 1
    reading = read_record(rep.result.record_path)["band_reading"]
    assert reading["reading"] == "band" and reading["along_normal_mm"] > 0.5


@pytest.mark.xfail(strict=True, reason="refused in view 1 (README *Twenty-eighth session*)")
@pytest.mark.parametrize("seed", [1, 4])
def test_tack_open_seeds_1_and_4_clipped_and_welded(tmp_path, seed):
    # What the next change to the end rules should make DONE, and what it must not break (the
    # twenty-eighth session's tries each added wrong single views on the benchmark). Seed 1: the
    # gap stops at a spatter ball 39 px from view 1's right edge; the ball's outline steps on one
    # side of the gap and faintly on the other, as a true sheet border with the table about as
    # bright as the sheet does, and a brushing streak 50 px beside it, stepping 12 px before the
    # edge, reads as a sheet ending there: an unsure end. Seed 4: the seam runs out of view 1
    # under a tack weld at its left edge, whose bead's outline crosses one side of the gap only:
    # read as a line fading out inside a sheet.
    rep, welds = run(tmp_path, True, "tack_open", seed=seed)
    assert rep.result.status == "done", rep.result.reason
    assert rep.seam_rms_mm <= 0.1 and len(welds) == 1
