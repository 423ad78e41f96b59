"""The job's nominal seam line (``[seam] nominal_line_mm``, ``line_tolerance_mm``) and the
detector's nominal seam (``detect_seam(hint=...)``, ``DetectParams.hint_tol_px``,
``seamguide detect --hint``): a line lying the tolerance or more from it is never returned,
and still counts as a rival (a nominal seam never turns a refusal into a seam).

Drawn images (``tests/test_seam_parallel.py``'s two sheets meeting along a gap at y = 600 that
runs out of the image at both ends, with or without a pen line parallel to it, through the
image or fading out inside the sheet)."""

import json

import cv2
import numpy as np
import pytest
from drawn_plates import S, render
from test_seam_parallel import line, sheets

from controller.cell.guidance import (
    GuidanceSettings,
    ViewInput,
    detect_views,
    nominal_hint,
    settings_from_job,
    view_params,
)
from controller.cell.job import job_from_dict
from controller.cli import main
from controller.errors import AmbiguousSeam, ConfigError, InputError, SeamNotFound
from controller.geometry.camera_model import default_camera
from controller.geometry.poses import make_pose
from controller.vision.seam_detect import detect_seam
from controller.vision.seam_params import DetectParams


def test_a_seam_the_tolerance_or_more_from_the_nominal_seam_is_refused():
    img = sheets(None)  # the joint alone
    det = detect_seam(img, hint=line(640.0))  # 40 px off, within the default 60
    assert np.abs(det.points_px[:, 1] - 600.0).max() < 1.0
    with pytest.raises(SeamNotFound, match=r"4\d px \(mean\) from the nominal seam, where the seam "
                                           "may lie at most 30 px from it"):
        detect_seam(img, hint=line(640.0), params=DetectParams(hint_tol_px=30.0))
    # Given by two vertices only (a straight drawing), the same.
    det = detect_seam(img, hint=[[0.0, 598.0], [1599.0, 603.0]],
                      params=DetectParams(hint_tol_px=20.0))
    assert np.abs(det.points_px[:, 1] - 600.0).max() < 1.0


def test_a_line_beyond_the_tolerance_is_not_returned_but_still_counts():
    # A pen line through the whole image 30 px from the joint passes every check.
    img = sheets(30)
    for hint, tol in ((line(600.0), 60.0), (line(600.0), 20.0), (line(630.0), 20.0)):
        with pytest.raises(AmbiguousSeam):
            detect_seam(img, hint=hint, params=DetectParams(hint_tol_px=tol))
    # A line that fades out inside the sheet (a pen line from x = 300 to the border, 100 px
    # below the joint) is refused for it and stays a rival as strong as the joint.
    def fill(m):
        m[:] = 170.0
        m[600 * S:, :] = 150.0
        m[598 * S:602 * S, :] = 30.0
        m[699 * S:703 * S, 300 * S:] = 30.0

    faded = render(fill, 0)
    for hint in (None, line(600.0)):
        with pytest.raises(AmbiguousSeam, match="similar strength"):
            detect_seam(faded, hint=hint, params=DetectParams(hint_tol_px=40.0))


@pytest.mark.parametrize("hint,what", [
    ([[10.0, 600.0]], "two or more"),
    ([[0.0, 600.0], [float("nan"), 600.0]], "two or more finite"),
    ([[0.0, 600.0], [4.0, 600.0]], "under 10 px long"),
    ("not points", "list of"),
])
def test_a_bad_nominal_seam_is_an_input_error_saying_what_is_wrong(hint, what):
    with pytest.raises(InputError, match=what):
        detect_seam(sheets(None), hint=hint)


def test_detect_cli_takes_the_nominal_seam_and_its_tolerance(tmp_path, capsys):
    p = tmp_path / "one_joint.png"
    cv2.imwrite(str(p), sheets(None))
    assert main(["detect", str(p), "--hint", "0,640", "1599,641"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert np.abs(np.asarray(doc["seam_px"])[:, 1] - 600.0).max() < 1.0
    ov = tmp_path / "o.png"
    assert main(["detect", str(p), "--hint", "0,640", "1599,641", "--hint-tolerance", "30",
                 "--overlay", str(ov)]) == 9
    assert "from the nominal seam" in capsys.readouterr().err
    assert cv2.imread(str(ov)) is not None
    assert main(["detect", str(p), "--hint", "0,600"]) == 3
    assert "two or more points" in capsys.readouterr().err
    assert main(["detect", str(p), "--hint", "0;600", "9,9"]) == 3
    assert "give each point as U,V" in capsys.readouterr().err
    assert main(["detect", str(p), "--hint", "0,600", "1599,600", "--hint-tolerance", "0"]) == 3
    assert "--hint-tolerance" in capsys.readouterr().err


def _job(**seam):
    return job_from_dict({"name": "j", "views": [],
                          "seam": {"nominal_centre_mm": [1000.0, 0.0, 0.0], **seam}})


def test_the_job_states_the_nominal_line_inside_its_region():
    job = _job(nominal_line_mm=[[950.0, 0.0, 0.0], [1050.0, 0.0, 0.0]], line_tolerance_mm=5.0)
    s = settings_from_job(job)
    assert s.nominal_line_mm == ((950.0, 0.0, 0.0), (1050.0, 0.0, 0.0))
    assert s.line_tolerance_mm == 5.0
    assert settings_from_job(_job()).nominal_line_mm is None  # not stated: the whole region


@pytest.mark.parametrize("seam,what", [
    ({"nominal_line_mm": [[950.0, 0.0, 0.0]]}, "two or more points"),
    ({"nominal_line_mm": [[950.0, 0.0, 0.0], [1200.0, 0.0, 0.0]]},
     "point 1 lies 200.0 mm from seam.nominal_centre_mm"),
    ({"nominal_line_mm": [[950.0, 0.0, 0.0], [950.0, 0.0, 0.5]]}, "under 1 mm long"),
    ({"nominal_line_mm": [[950.0, 0.0], [1050.0, 0.0]]}, "seam.nominal_line_mm"),
    ({"line_tolerance_mm": 0.0}, "seam.line_tolerance_mm must be positive"),
    ({"line_tolerance_mm": 200.0}, "at most seam.nominal_radius_mm"),
])
def test_a_bad_nominal_line_is_refused_at_load_naming_the_key(seam, what):
    with pytest.raises(ConfigError, match=what):
        _job(**seam)


def test_the_nominal_line_is_seen_from_each_view_at_its_scale():
    cam = default_camera()
    T = make_pose(np.eye(3), [0.0, 0.0, 0.0])  # at the origin, looking along +z
    line_mm = [[-50.0, 0.0, 400.0], [50.0, 0.0, 400.0]]
    hint = nominal_hint(cam, T, line_mm)
    assert hint is not None and len(hint) == 101  # a point every mm
    assert np.allclose(hint[[0, -1]], cam.project(np.asarray(line_mm), T))
    assert nominal_hint(cam, T, [[-50.0, 0.0, -400.0], [50.0, 0.0, -400.0]]) is None  # behind
    s = GuidanceSettings(nominal_centre_mm=(0.0, 0.0, 400.0), nominal_radius_mm=100.0,
                         nominal_line_mm=tuple(tuple(p) for p in line_mm), line_tolerance_mm=5.0)
    p = view_params(cam, T, s)
    assert p is not None and p.hint_tol_px == pytest.approx(5.0 * cam.fx / 400.0)


def test_the_cycle_gives_each_view_its_nominal_seam():
    cam = default_camera()
    T = make_pose(np.eye(3), [0.0, 0.0, 0.0])
    img = np.zeros((cam.height, cam.width), np.uint8)
    seen = []

    def detector(image, camera=None, roi=None, params=None, hint=None):
        seen.append((hint, params))
        return "found"

    line_mm = ((-50.0, 0.0, 400.0), (50.0, 0.0, 400.0))
    s = GuidanceSettings(nominal_centre_mm=(0.0, 0.0, 400.0), nominal_radius_mm=100.0,
                         nominal_line_mm=line_mm)
    assert detect_views([ViewInput("view1", img, cam, T)], s, detector) == ["found"]
    hint, params = seen[0]
    assert np.allclose(hint, nominal_hint(cam, T, line_mm))
    assert params.hint_tol_px == pytest.approx(10.0 * cam.fx / 400.0)
    # Without a nominal line no hint is passed (a replacement detector need not take one).
    seen.clear()
    detect_views([ViewInput("view1", img, cam, T)],
                 GuidanceSettings(nominal_centre_mm=(0.0, 0.0, 400.0), nominal_radius_mm=100.0),
                 lambda image, camera=None, roi=None, params=None: seen.append(params) or "ok")
    assert len(seen) == 1


def test_the_shrunk_look_keeps_the_tolerance_in_image_px():
    from controller.vision.seam_smaller import _found_at

    got = []

    def look(small, hint, ps, straighten):
        got.append((hint, ps))
        raise AmbiguousSeam("stop here")

    grey = np.zeros((400, 600), np.uint8)
    hint = np.array([[0.0, 200.0], [599.0, 200.0]])
    assert _found_at(grey, 2.0, hint, DetectParams(hint_tol_px=40.0), look, None) is None
    small_hint, ps = got[0]
    assert ps.hint_tol_px == pytest.approx(20.0)
    assert np.allclose(small_hint, [[-0.25, 99.75], [299.25, 99.75]])


def test_the_example_jobs_commented_nominal_line_loads_when_uncommented(tmp_path):
    from pathlib import Path

    from controller.cell.job import load_job

    text = (Path(__file__).parent.parent / "examples" / "demo-job.toml").read_text()
    assert "# nominal_line_mm = " in text and "# line_tolerance_mm = " in text
    p = tmp_path / "job.toml"
    p.write_text(text.replace("# nominal_line_mm = ", "nominal_line_mm = ")
                 .replace("# line_tolerance_mm = ", "line_tolerance_mm = "))
    seam = load_job(p).seam
    assert seam.nominal_line_mm is not None and len(seam.nominal_line_mm) == 2
    assert seam.line_tolerance_mm == 10.0


@pytest.mark.slow
def test_a_dry_run_with_the_jobs_nominal_line_searches_each_view_around_it(tmp_path):
    from controller.cell.dry_run import SimRig
    from controller.geometry.camera_model import CameraModel
    from controller.stereo.triangulate import PolylineDistance

    calls = []

    def detector(image, camera: CameraModel, roi=None, params=None, hint=None):
        calls.append((hint, params))
        return detect_seam(image, camera=camera, roi=roi, params=params, hint=hint)

    with SimRig(scene_kind="s_curve", seed=1, speedup=200.0, nominal_line=True) as rig:
        line = np.asarray(rig.job.seam.nominal_line_mm)
        # As a drawing places it: within 2 mm per axis of the seam, inside the region.
        assert len(line) >= 10
        assert PolylineDistance(rig.scene.seam_points_mm)(line).max() <= 2.0 * np.sqrt(3) + 0.1
        rep = rig.report(rig.cycle(tmp_path, detector=detector).run())
    assert rep.result.status == "done", rep.result.reason
    assert rep.seam_rms_mm <= 0.1
    assert len(calls) == 2 and all(h is not None and len(h) > 100 for h, _ in calls)
    assert all(p.hint_tol_px > 40.0 for _, p in calls)  # 10 mm at the views' 6-8 px/mm


def _drawn_pair(kinds: tuple[str, str]):
    """A straight seam seen by two views (``tests/stereo_scenes.py``), a detector that answers
    each view with its curve and end ``kinds``, and the seam as drawn (mm)."""
    from types import SimpleNamespace

    from stereo_scenes import camera_poses, observe, seam_curve

    P = seam_curve("straight")
    cam = default_camera()
    poses = camera_poses(P)
    curves = [o.seam_px for o in observe(P, poses)]
    imgs = [np.full((cam.height, cam.width), i, np.uint8) for i in range(2)]  # view i: level i
    views = [ViewInput(f"view{i + 1}", imgs[i], cam, T) for i, T in enumerate(poses)]

    def detector(image, camera=None, roi=None, params=None, hint=None):
        # (The views are detected in two threads: told apart by their images, not by order.)
        return SimpleNamespace(points_px=curves[int(image[0, 0])], end_kinds=kinds)

    drawn = tuple(tuple(float(v) for v in q) for q in np.vstack([P[::300], P[-1:]]))
    return P, views, detector, drawn


def test_the_located_seam_must_lie_within_the_tolerance_of_the_nominal_line():
    """The cycle hands the job's line to locating: a seam found in both views but further from
    the line than the tolerance is refused in 3D, whatever the views' detectors said."""
    from controller.cell.guidance import locate_views
    from controller.errors import TriangulationError

    P, views, detector, drawn = _drawn_pair(("joint_end", "joint_end"))
    centre = tuple(float(v) for v in P.mean(axis=0))
    beside = tuple((x + 8.0, y, z) for x, y, z in drawn)  # the part 8 mm off the drawing
    for drawing, ok in ((drawn, True), (beside, False)):
        s = GuidanceSettings(nominal_centre_mm=centre, nominal_radius_mm=150.0,
                             nominal_line_mm=drawing, line_tolerance_mm=5.0)
        if ok:
            seam = locate_views(views, s, detector=detector).seam
            assert seam.quality["distance_from_nominal_line_mm_max"] < 0.1
        else:
            with pytest.raises(TriangulationError, match="8.0 mm from the job's nominal line"):
                locate_views(views, s, detector=detector)


def test_a_clipped_seam_without_a_drawn_line_is_said_to_be_unchecked(caplog):
    from controller.cell.guidance import locate_views

    P, views, detector, drawn = _drawn_pair(("image_border", "image_border"))
    centre = tuple(float(v) for v in P.mean(axis=0))
    for drawing in (None, drawn):
        caplog.clear()
        s = GuidanceSettings(nominal_centre_mm=centre, nominal_radius_mm=60.0,
                             clip_unseen_ends=True, nominal_line_mm=drawing)
        ends = locate_views(views, s, detector=detector).seam.quality["ends"]
        assert [e["status"] for e in ends] == ["clipped", "clipped"]
        said = "draws no nominal seam line" in caplog.text
        assert said == (drawing is None)
