"""A dark band wider than the job's gap is refused (DetectParams.max_band_px, seam_decision).

Where a higher plate edge's shadow beside the gap is as dark as the gap floor, one view cannot
tell which part of the dark band is the gap: the two-step model returns the band's middle, half
the shadow's width off the gap (README, seam vision: the main source of wrong seams in the wide
look). A job that states its gap (``[seam] gap_mm``, ``seamguide detect --gap-mm``) bounds how
wide the band of the gap can be; a wider band is refused, naming the job key. Rendered lopsided
gaps with the renderer's exact truth (tests/test_seam_shadow.py).
"""

import numpy as np
import pytest
from test_seam_shadow import CAM, lopsided, signed_offsets

from controller.cell.guidance import GuidanceSettings, view_params
from controller.errors import AmbiguousSeam, SeamNotFound
from controller.geometry.poses import make_pose
from controller.vision.seam_detect import detect_seam
from controller.vision.seam_scale import BLUR_PX, SHADOW_SHARE, params_for_scale

STANDOFF_MM = 250.0  # lopsided()'s view
PX_PER_MM = CAM.K[0, 0] / STANDOFF_MM  # 5.68 px/mm: the 0.45 mm gap is 2.3-2.6 px wide
JOB_GAP_MM = (0.3, 0.6)


def job_params():
    return params_for_scale(PX_PER_MM, JOB_GAP_MM, limit_band=True)


def test_the_band_limit_is_set_only_on_the_jobs_word():
    s = 6.0
    band = (1 + SHADOW_SHARE) * 0.6 * s + BLUR_PX
    assert params_for_scale(s, (0.3, 0.6), limit_band=True).max_band_px == pytest.approx(band)
    assert params_for_scale(s, (0.3, 0.6)).max_band_px == 0.0  # a range alone: no limit
    # The narrowest gap, for the shadow split (a core narrower is a floor beside a cut face).
    assert params_for_scale(s, (0.3, 0.6), limit_band=True).min_gap_px == pytest.approx(1.8)
    assert params_for_scale(s, (0.3, 0.6)).min_gap_px == 0.0


@pytest.mark.parametrize("side", [-1, 1])
def test_a_shadow_as_dark_as_the_gap_is_refused_when_the_job_states_its_gap(side):
    r = lopsided(side, depth=0.95)  # the shadow (0.6 x 0.05) as dark as the gap floor
    # Without the job's gap: the band (gap + 1.5 mm shadow, ~10 px) is taken for the gap and
    # its middle is returned, ~4 px (0.7 mm) off the joint, on the shadow's side.
    det = detect_seam(r.image)
    off = float(np.median(signed_offsets(det, r.seam_px)))
    assert np.median(det.width_px) > r.gap_px + 6.0
    assert abs(off) > 3.0 and np.sign(off) == -side
    # The job says 0.3-0.6 mm: the band can be at most 6.3 px wide here; refused, saying why.
    with pytest.raises((SeamNotFound, AmbiguousSeam)) as info:
        detect_seam(r.image, params=job_params())
    msg = str(info.value)
    assert "dark band" in msg and "seam.gap_mm" in msg, msg


@pytest.mark.parametrize("side", [-1, 1])
def test_a_lighter_shadow_beside_the_gap_is_still_found_with_the_job_gap(side):
    # The shadow lighter than the gap floor: the three-edge split finds the gap inside the band,
    # whose width is the gap's: within the job's limit, returned on the joint.
    r = lopsided(side, depth=0.6)
    det = detect_seam(r.image, params=job_params())
    off = signed_offsets(det, r.seam_px)[10:-10]
    assert abs(np.median(off)) < 0.8
    assert np.median(det.width_px) < job_params().max_band_px


def test_the_cycle_limits_the_band_only_when_the_job_states_the_gap():
    T = make_pose(np.eye(3), [0.0, 0.0, 0.0])  # camera at the origin looking along +z
    centre = (0.0, 0.0, 400.0)
    unsaid = GuidanceSettings(nominal_centre_mm=centre, nominal_radius_mm=100.0)
    said = GuidanceSettings(nominal_centre_mm=centre, nominal_radius_mm=100.0, gap_mm=(0.2, 0.5))
    assert view_params(CAM, T, unsaid).max_band_px == 0.0
    s = CAM.fx / 400.0
    assert view_params(CAM, T, said).max_band_px == pytest.approx(
        (1 + SHADOW_SHARE) * 0.5 * s + BLUR_PX)


def test_cli_detect_gap_mm_refuses_the_band_and_without_it_returns_it(tmp_path, capsys):
    import cv2

    from calibration.calibration_file import Calibration, save_calibration
    from controller.cli import main

    r = lopsided(1, depth=0.95)
    png, calib, out = tmp_path / "shadow.png", tmp_path / "cam.yaml", tmp_path / "seam.json"
    cv2.imwrite(str(png), r.image)
    save_calibration(calib, Calibration(camera=CAM))
    scale = ["detect", str(png), "--calibration", str(calib), "--distance-mm", str(STANDOFF_MM)]
    assert main([*scale, "--output", str(out)]) == 0  # the default range: no limit
    capsys.readouterr()
    out.unlink()
    code = main([*scale, "--gap-mm", *map(str, JOB_GAP_MM), "--output", str(out)])
    assert code == SeamNotFound.exit_code and not out.exists()
    assert "dark band" in capsys.readouterr().err


def test_one_image_with_a_split_and_no_gap_stated_is_two_readings_not_a_guess():
    from controller.vision.seam_decision import one_reading
    from controller.vision.seam_params import DetectParams

    core = np.column_stack([np.arange(400.0), np.full(400, 100.0)])
    band = core + [0.0, 3.5]
    one_reading(core, None, DetectParams())  # nothing split off: one reading
    with pytest.raises(AmbiguousSeam) as info:
        one_reading(core, band, DetectParams())
    assert "3.5 px away" in str(info.value) and "--gap-mm" in str(info.value)
    assert info.value.details["offset_px"] == 3.5
    # The job's gap decides it (a core narrower than the narrowest gap was kept whole).
    one_reading(core, band, job_params())


def test_cli_detect_refuses_a_split_without_the_gap_and_returns_it_with_the_gap(tmp_path,
                                                                                 capsys):
    import json

    import cv2

    from calibration.calibration_file import Calibration, save_calibration
    from controller.cli import main

    r = lopsided(1, depth=0.6)  # a lighter shadow: split off, the core is the gap
    png, calib = tmp_path / "shadow.png", tmp_path / "cam.yaml"
    out, overlay = tmp_path / "seam.json", tmp_path / "overlay.png"
    cv2.imwrite(str(png), r.image)
    save_calibration(calib, Calibration(camera=CAM))
    code = main(["detect", str(png), "--output", str(out), "--overlay", str(overlay)])
    assert code == AmbiguousSeam.exit_code and not out.exists()
    err = capsys.readouterr().err
    assert "cut face" in err and "shadow" in err and "--gap-mm" in err
    # The overlay draws both readings: green (the core) and yellow (the band) on the image.
    b, g, r_ = (cv2.imread(str(overlay)).astype(int)[:, :, k] for k in range(3))
    yellow = (b < 60) & (g > 150) & (r_ > 180)
    green = (g - np.maximum(b, r_) > 100) & (r_ < 80)
    assert yellow.sum() > 200 and green.sum() > 200
    code = main(["detect", str(png), "--calibration", str(calib), "--distance-mm",
                 str(STANDOFF_MM), "--gap-mm", *map(str, JOB_GAP_MM), "--output", str(out)])
    assert code == 0
    doc = json.loads(out.read_text())
    assert doc["band_px"] is not None and doc["band_width_px"] > doc["gap_width_px"] + 4.0
    off = signed_offsets(type("D", (), {"points_px": np.asarray(doc["seam_px"])}), r.seam_px)
    assert abs(np.median(off[10:-10])) < 0.8
