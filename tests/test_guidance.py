"""The guidance pipeline: one set of defaults; `seamguide locate` measures what the cell welds."""

from __future__ import annotations

import json

import numpy as np
import pytest
import tomli_w

from controller.cell.guidance import GuidanceSettings, nominal_roi, settings_from_job
from controller.cell.job import job_from_dict
from controller.cell.typed_config import to_dict
from controller.geometry.camera_model import default_camera
from controller.geometry.poses import make_pose


def test_defaults_without_a_job_are_those_of_a_job_that_says_nothing():
    job = job_from_dict({"name": "j", "views": [], "seam": {"nominal_centre_mm": [1000, 0, 0]}})
    from_job, bare = settings_from_job(job), GuidanceSettings()
    assert from_job.quality == bare.quality
    assert (from_job.spacing_mm, from_job.count) == (bare.spacing_mm, bare.count)
    assert from_job.workspace == bare.workspace
    assert from_job.path_tolerance == bare.path_tolerance
    assert from_job.clip_unseen_ends == bare.clip_unseen_ends
    for name in ("speed_mm_s", "work_angle_deg", "travel_angle_deg", "tool_offset_mm",
                 "approach_mm", "max_joint_step_deg"):
        assert getattr(from_job.weld, name) == getattr(bare.weld, name), name
    assert np.array_equal(from_job.weld.T_flange_tcp, bare.weld.T_flange_tcp)
    assert bare.nominal_region is None
    assert from_job.nominal_region is not None and from_job.nominal_region[1] == 150.0


def test_nominal_roi_boxes_the_sphere_in_front_and_refuses_behind():
    cam = default_camera()
    T = make_pose(np.eye(3), [0.0, 0.0, 0.0])  # camera at the origin looking along +z
    roi = nominal_roi(cam, T, np.array([0.0, 0.0, 500.0]), 50.0)
    assert roi is not None
    x0, y0, x1, y1 = roi
    u, v = cam.project(np.array([[0.0, 0.0, 500.0]]), T)[0]
    assert x0 < u < x1 and y0 < v < y1
    assert nominal_roi(cam, T, np.array([0.0, 0.0, -500.0]), 50.0) is None


@pytest.mark.slow
def test_locate_on_a_cycle_record_gives_the_seam_and_path_the_cycle_welded(tmp_path, capsys):
    from controller.cell.cycle_record import read_record
    from controller.cell.dry_run import SimRig
    from controller.cli import main

    with SimRig(speedup=200.0) as rig:
        result = rig.cycle(tmp_path / "records").run()
        assert result.ok
        job_file = tmp_path / "job.toml"
        job_file.write_text(tomli_w.dumps(to_dict(rig.job)))
    rec = result.record_path
    assert read_record(rec)["status"] == "done"
    out = tmp_path / "located.json"
    assert main(["locate", "--calibration", str(rec / "calibration.yaml"),
                 "--view", str(rec / "view1.json"), "--view", str(rec / "view2.json"),
                 "--job", str(job_file), "--output", str(out)]) == 0
    replay, welded = json.loads(out.read_text()), json.loads((rec / "seam.json").read_text())
    assert np.allclose(replay["seam_points_mm"], welded["seam_points_mm"], atol=1e-3)
    assert [t["kind"] for t in replay["weld_path"]] == [t["kind"] for t in welded["weld_path"]]
    assert np.allclose([t["position_mm"] for t in replay["weld_path"]],
                       [t["position_mm"] for t in welded["weld_path"]], atol=1e-3)


def test_a_view_whose_detection_fails_is_named_first_in_the_reason():
    from controller.cell.guidance import ViewInput, detect_views
    from controller.errors import AmbiguousSeam, SeamNotFound

    cam = default_camera()
    T = make_pose(np.eye(3), [0.0, 0.0, 0.0])
    good, bad = np.zeros((4, 4), np.uint8), np.ones((4, 4), np.uint8)
    views = [ViewInput("left-top", good, cam, T), ViewInput("view2", bad, cam, T)]

    def detector(error):
        def detect(image, camera=None, roi=None):
            if image is bad:
                raise error
            return "found"
        return detect

    with pytest.raises(SeamNotFound) as info:
        detect_views(views, GuidanceSettings(), detector(SeamNotFound(
            "no weld seam found in the image (no thin dark valley long enough)", score=0.2)))
    assert str(info.value).startswith("view2: no weld seam found in the image"), info.value
    assert info.value.details == {"score": 0.2, "view": "view2"}
    with pytest.raises(AmbiguousSeam, match=r"^view2: two seam candidates"):
        detect_views(views, GuidanceSettings(), detector(AmbiguousSeam("two seam candidates")))
    views.reverse()  # the first view in order is named, whatever its name
    with pytest.raises(SeamNotFound, match=r"^view2: "):
        detect_views(views, GuidanceSettings(), detector(SeamNotFound("no weld seam")))
    assert detect_views([views[1]], GuidanceSettings(), detector(SeamNotFound("x"))) == ["found"]
