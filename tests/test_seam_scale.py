"""The detector's pixel scales from the working distance (controller/vision/seam_scale.py): the pure
function's figures, a close-up view whose gap is too wide for the defaults, the job key, the cycle
passing each view its scaled parameters, and `seamguide detect --distance-mm`."""

from dataclasses import fields, replace

import cv2
import numpy as np
import pytest

from calibration.calibration_file import Calibration, save_calibration
from controller.cell.guidance import GuidanceSettings, ViewInput, detect_views, view_params
from controller.cell.job import job_from_dict
from controller.cli import main
from controller.errors import ConfigError, InputError, SeamguideError
from controller.geometry.camera_model import default_camera
from controller.geometry.poses import make_pose, rotation_about
from controller.vision.seam_detect import detect_seam
from controller.vision.seam_params import DetectParams
from controller.vision.seam_scale import (
    DEFAULT_GAP_MM,
    check_gap_mm,
    params_for_scale,
    px_per_mm_at,
)
from drivers.sim.sim_render import render, suggest_view_poses
from drivers.sim.sim_scene import make_scene

# The defaults as tuned (2272x1704 camera at 350-450 mm). DetectParams() must stay exactly this:
# `seamguide detect` without a working distance behaves as before.
TUNED = {"gamma": 2.2, "coarse_factor": 0, "valley_r_coarse": 3, "valley_r_px": 0.0,
         "min_depth": 0.2, "min_length_px": 300.0, "step_px": 4.0, "half_width_px": 14.0,
         "profile_step_px": 1.0, "fit_iterations": 7, "max_gap_px": 16.0,
         "min_profile_depth": 0.25, "bridge_px": 200.0, "join_px": 200.0,
         "piece_length_px": 100.0, "piece_join_px": 48.0, "ambiguity_ratio": 0.6,
         "min_confidence": 0.5, "max_candidates": 4, "robust": True, "straight_px": 2.5,
         "pattern_offset_px": 200.0, "max_band_px": 0.0, "min_gap_px": 0.0, "smaller": True,
         "grain": True, "carry": True, "hint_tol_px": 60.0}
SCALED = ("max_gap_px", "half_width_px", "valley_r_px", "min_length_px", "piece_length_px")


def test_the_defaults_are_unchanged():
    d = DetectParams()
    assert {f.name: getattr(d, f.name) for f in fields(d)} == TUNED


@pytest.mark.parametrize("px_per_mm,gap,length,expect", [
    # band = 1.25 * widest gap px + 2: max gap = band, half width = band / 2 + 6, reach band / 2
    (8.0, (0.1, 2.0), None, (22.0, 17.0, 11.0, 300.0, 100.0)),
    (20.0, (0.1, 1.2), None, (32.0, 22.0, 16.0, 300.0, 100.0)),
    (30.0, (0.5, 3.0), None, (114.5, 63.25, 57.25, 300.0, 100.0)),
    # far: the gap-driven scales stay at the defaults' floors; the whole seam is 300 px long
    (2.0, (0.1, 2.0), 300.0, (16.0, 14.0, 3.5, 150.0, 100.0)),
    (1.0, (0.1, 2.0), 120.0, (16.0, 14.0, 2.25, 100.0, 100.0)),  # never under 100 px
    (8.0, (0.1, 1.2), 5000.0, (16.0, 14.0, 7.0, 300.0, 100.0)),  # never over the default
])
def test_scales_follow_px_per_mm_and_the_widest_gap(px_per_mm, gap, length, expect):
    p = params_for_scale(px_per_mm, gap, seam_length_px=length)
    assert tuple(getattr(p, k) for k in SCALED) == pytest.approx(expect)
    # A table's grid pitch: 25 mm, never closer than the defaults' 200 px.
    assert p.pattern_offset_px == pytest.approx(max(200.0, 25.0 * px_per_mm))
    # Everything else is the defaults' (the noise floors: depth, fit, confidence).
    base = DetectParams()
    assert all(getattr(p, f.name) == getattr(base, f.name) for f in fields(p)
               if f.name not in SCALED + ("pattern_offset_px",))


def test_scales_keep_a_given_base_and_refuse_bad_input():
    p = params_for_scale(20.0, base=DetectParams(gamma=1.0, robust=False))
    assert (p.gamma, p.robust) == (1.0, False) and p.max_gap_px == pytest.approx(32.0)
    for bad in (0.0, -3.0, float("nan"), float("inf")):
        with pytest.raises(InputError, match="px_per_mm"):
            params_for_scale(bad)
    with pytest.raises(InputError, match="seam_length_px"):
        params_for_scale(8.0, seam_length_px=0.0)
    for bad_gap in ((2.0, 1.0), (0.0, 0.0), (-0.1, 1.0), (0.1, 80.0), (0.1,), "wide"):
        with pytest.raises(InputError, match="gap_mm"):
            params_for_scale(8.0, bad_gap)
    assert check_gap_mm([0, 1]) == (0.0, 1.0)


def test_px_per_mm_is_fx_over_the_depth_along_the_optical_axis():
    T = make_pose(rotation_about((1.0, 0.0, 0.0), np.pi), [100.0, 0.0, 600.0])  # looking down
    assert px_per_mm_at(2840.0, T, [100.0, 0.0, 200.0]) == pytest.approx(2840.0 / 400.0)
    # Off the axis the depth, not the range, counts.
    assert px_per_mm_at(2840.0, T, [160.0, 30.0, 200.0]) == pytest.approx(2840.0 / 400.0)
    assert px_per_mm_at(2840.0, T, [100.0, 0.0, 700.0]) is None  # behind the camera


# Half-size images (1136x852, fx 1420 px) from 70 mm: 20.3 px per mm, so a 1.2 mm gap is 24 px
# wide, past the defaults' widest gap (16 px).
CAM = default_camera().scaled(0.5)
Z_MM = 70.0


@pytest.fixture(scope="module")
def close_up():
    sc = make_scene("arc", 1, "medium", gap_mm=1.2)
    T = suggest_view_poses(sc, CAM, standoff_mm=Z_MM, baseline_mm=200.0 * Z_MM / 350.0)[1]
    return render(sc, CAM, T, seed=1)


def _err(points, truth):
    from test_seam_detect import dist_to_polyline

    return dist_to_polyline(points, truth)


def test_a_close_up_gap_too_wide_for_the_defaults_is_found_with_the_scaled_params(close_up):
    r = close_up
    assert 22.0 < r.gap_px < 26.0
    # Defaults: the gap is no thin valley for them; what they return (a mark on a sheet) or
    # refuse is not the joint.
    try:
        det = detect_seam(r.image)
        assert np.percentile(_err(det.points_px, r.seam_px), 95) > 20.0
    except SeamguideError:
        pass
    p = params_for_scale(CAM.K[0, 0] / Z_MM, (0.1, 2.0))
    det = detect_seam(r.image, params=p)
    err = _err(det.points_px, r.seam_px)
    assert np.percentile(err, 95) < 0.5 and err.max() < 2.0
    assert det.stats["way"] == "profiles"
    assert np.median(det.width_px) == pytest.approx(r.gap_px, abs=1.5)
    assert det.end_kinds == ("image_border", "image_border")


def test_the_job_key_gap_mm(tmp_path):
    base = {"name": "j", "views": [], "seam": {"nominal_centre_mm": [1000, 0, 0]}}
    job = job_from_dict(base)
    # Not stated: None (the scales of the default range, no limit on the dark band).
    assert job.seam.gap_mm is None and DEFAULT_GAP_MM == (0.1, 1.2)
    job = job_from_dict({**base, "seam": {**base["seam"], "gap_mm": [0.2, 1.5]}})
    from controller.cell.guidance import settings_from_job

    assert settings_from_job(job).gap_mm == (0.2, 1.5)
    for bad, what in (([1.5, 0.2], "0 <= min <= max"), ([0.1], "2 values"),
                      ([0.1, 500], "not a butt joint"), ([-1, 1], "0 <= min"),
                      ("1mm", "list of numbers")):
        with pytest.raises(ConfigError) as info:
            job_from_dict({**base, "seam": {**base["seam"], "gap_mm": bad}})
        assert "seam.gap_mm" in str(info.value) and what in str(info.value), info.value


def test_the_cycle_gives_each_view_the_scales_of_its_working_distance():
    cam = default_camera()
    down = rotation_about((1.0, 0.0, 0.0), np.pi)
    centre = (1000.0, 0.0, 0.0)
    near = make_pose(down, [1000.0, 0.0, 100.0])  # 100 mm above the nominal centre
    far = make_pose(down, [1000.0, 0.0, 400.0])
    settings = GuidanceSettings(nominal_centre_mm=centre, nominal_radius_mm=60.0,
                                gap_mm=(0.1, 1.5))
    img = np.zeros((8, 8), np.uint8)
    seen = []

    def spy(image, camera=None, roi=None, **kw):
        seen.append((roi, kw.get("params")))
        return "found"

    views = [ViewInput("near", img, cam, near), ViewInput("far", img, cam, far)]
    assert detect_views(views, settings, spy) == ["found", "found"]
    (roi_n, p_near), (roi_f, p_far) = sorted(seen, key=lambda s: -s[1].max_gap_px)
    assert p_near == params_for_scale(28.4, (0.1, 1.5),
                                      seam_length_px=np.hypot(roi_n[2] - roi_n[0],
                                                              roi_n[3] - roi_n[1]),
                                      limit_band=True)
    assert p_near.max_gap_px == pytest.approx(1.25 * 1.5 * 28.4 + 2.0)
    # 400 mm: 7.1 px/mm, the seam at most 120 mm = 852 px long: the defaults' scales.
    assert p_far == params_for_scale(7.1, (0.1, 1.5), seam_length_px=120.0 * 7.1,
                                     limit_band=True)
    # The job states its gap: the widest dark band taken for it follows (seam_decision).
    assert p_far.max_band_px == pytest.approx(1.25 * 1.5 * 7.1 + 2.0)
    assert (p_far.max_gap_px, p_far.min_length_px) == (16.0, 300.0)
    assert view_params(cam, far, settings, roi_f) == p_far
    # No nominal region (locate without a job): the detector's own defaults, no params passed.
    seen.clear()
    detect_views(views, GuidanceSettings(), spy)
    assert [s[1] for s in seen] == [None, None]
    # A nominal centre behind the camera: no scale to set.
    behind = make_pose(down, [1000.0, 0.0, -100.0])
    assert view_params(cam, behind, settings) is None


def test_cli_detect_distance_and_gap(tmp_path, close_up, capsys):
    import json

    png, calib, out = tmp_path / "close.png", tmp_path / "cam.yaml", tmp_path / "seam.json"
    cv2.imwrite(str(png), close_up.image)
    save_calibration(calib, Calibration(camera=CAM))
    assert main(["detect", str(png), "--calibration", str(calib), "--distance-mm", "70",
                 "--gap-mm", "0.1", "2", "--output", str(out)]) == 0
    seam = np.array(json.loads(out.read_text())["seam_px"])
    assert np.percentile(_err(seam, close_up.seam_px), 95) < 0.5
    capsys.readouterr()
    assert main(["detect", str(png), "--distance-mm", "70"]) == InputError.exit_code
    assert "give --calibration too" in capsys.readouterr().err
    assert main(["detect", str(png), "--calibration", str(calib),
                 "--gap-mm", "0.1", "2"]) == InputError.exit_code
    assert "--gap-mm sets the scales with --distance-mm" in capsys.readouterr().err
    for bad in (["--distance-mm", "0"], ["--distance-mm", "70", "--gap-mm", "2", "1"]):
        assert main(["detect", str(png), "--calibration", str(calib), *bad]) \
            == InputError.exit_code
    err = capsys.readouterr().err
    assert "--distance-mm 0.0" in err and "--gap-mm = [2, 1]" in err


def test_at_the_defaults_own_scale_only_the_coarse_reach_is_set():
    # About 7 px/mm with gaps up to 1.5 mm: the defaults, and a reach of 7.7 px that the 2272 px
    # image's automatic coarse factor (4 x 3 px) already has.
    assert params_for_scale(2840.0 / 400.0, (0.1, 1.5)) == replace(DetectParams(),
                                                                    valley_r_px=7.65625)
