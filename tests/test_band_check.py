"""Two views tell a shadow beside the gap from a cut face inside it (controller.stereo.band_check).

Exact synthetic geometry: the true seam (the gap's middle at the sheet top) and, per view, the
detector's two readings projected from where they lie in 3D. A shadow of a higher plate edge on
the lower sheet: the core is the gap, the whole band's middle lies half the shadow's width across
the seam. A cut face seen inside the gap: the core's middle lies half the sheet's thickness deep,
under the gap's middle, and the band's middle is the gap's.
"""

import dataclasses

import numpy as np
import pytest
from stereo_scenes import camera_poses, observe, seam_curve

from controller.errors import TriangulationError
from controller.stereo.band_check import band_or_core
from controller.stereo.locate import locate_seam
from controller.stereo.triangulate import PolylineDistance

DOWN = np.array([0.0, 0.0, -1.0])  # into the sheet: the cameras look down


def across(P):
    """Unit vectors across the seam in the sheet's plane (the sheets lie in z = const)."""
    a = np.cross(np.gradient(P, axis=0), DOWN)
    return a / np.linalg.norm(a, axis=1, keepdims=True)


def with_bands(P_core, P_band, poses):
    """Views whose seam is the core reading and whose band is the whole band's."""
    core, band = observe(P_core, poses), observe(P_band, poses)
    return [dataclasses.replace(c, gap_width_px=4.0, band_px=b.seam_px, band_width_px=8.0)
            for c, b in zip(core, band, strict=True)]


def rms_to(P, seam):
    return float(np.sqrt(np.mean(PolylineDistance(P)(seam.dense_points_mm) ** 2)))


@pytest.mark.parametrize("kind", ["straight", "s_curve"])
def test_a_cut_face_in_the_gap_takes_the_whole_band(kind):
    P = seam_curve(kind)
    poses = camera_poses(P)
    views = with_bands(P + 1.5 * DOWN, P, poses)  # a 3 mm sheet's face: core 1.5 mm deep
    seam = locate_seam(views)
    assert seam.quality["band_reading"]["reading"] == "band"
    assert seam.quality["band_reading"]["along_normal_mm"] == pytest.approx(1.5, abs=0.05)
    assert rms_to(P, seam) < 0.01
    # The cores alone (what was located before the check) put the seam 1.5 mm deep.
    cores = [dataclasses.replace(v, band_px=None) for v in views]
    assert rms_to(P, locate_seam(cores)) == pytest.approx(1.5, abs=0.05)


@pytest.mark.parametrize("kind", ["straight", "s_curve"])
def test_a_shadow_beside_the_gap_keeps_the_core(kind):
    P = seam_curve(kind)
    poses = camera_poses(P)
    views = with_bands(P, P + 0.75 * across(P), poses)  # a 1.5 mm shadow beside the gap
    seam = locate_seam(views)
    rec = seam.quality["band_reading"]
    assert rec["reading"] == "core"
    assert rec["across_mm"] == pytest.approx(0.75, abs=0.05) and abs(rec["along_normal_mm"]) < 0.05
    assert rms_to(P, seam) < 0.01


def test_views_seeing_opposite_faces_still_agree_on_the_band():
    # View 1 sees the far sheet's face, view 2 the near one's: the cores lie on opposite sides
    # of the band in the images, and both triangulate to the same point half a thickness deep.
    P = seam_curve("straight")
    poses = camera_poses(P)
    views = with_bands(P + 1.0 * DOWN, P, poses)
    seam = locate_seam(views)
    assert seam.quality["band_reading"]["reading"] == "band" and rms_to(P, seam) < 0.01


def test_a_split_in_only_one_view_is_left_to_the_stereo_checks():
    P = seam_curve("straight")
    views = with_bands(P, P + 0.75 * across(P), camera_poses(P))
    views[1] = dataclasses.replace(views[1], band_px=None, band_width_px=None)
    out, record, _ = band_or_core(views, 8.0)
    assert out is views and record is None
    assert "band_reading" not in locate_seam(views).quality


def test_the_jobs_normal_is_the_reference_when_given():
    # The same cut-face geometry judged against a normal lying in the sheet (a wrong one, on
    # purpose): the offset is then across it, and the core is kept. The job's normal is used.
    P = seam_curve("straight")
    views = with_bands(P + 1.5 * DOWN, P, camera_poses(P))
    _, right, _ = band_or_core(views, 8.0, normal=np.array([0.0, 0.0, 1.0]))
    _, wrong, _ = band_or_core(views, 8.0, normal=np.array([1.0, 0.0, 0.0]))
    assert right["reading"] == "band" and right["angle_deg"] < 5.0
    assert wrong["reading"] == "core" and wrong["angle_deg"] > 85.0


def test_readings_apart_at_45_deg_are_neither_and_refused():
    P = seam_curve("straight")
    views = with_bands(P, P + 0.5 * across(P) - 0.5 * DOWN, camera_poses(P))
    with pytest.raises(TriangulationError) as info:
        locate_seam(views)
    msg = str(info.value)
    assert "neither a shadow" in msg and "[seam] gap_mm" in msg, msg
    assert info.value.details["band_reading"]["reading"] == "undecided"
    assert 35.0 < info.value.details["band_reading"]["angle_deg"] < 55.0


def test_a_split_in_one_view_only_is_refused_saying_what_would_decide_it():
    # View 1 split (core 4 px, whole band 9 px); view 2 saw one band 9 px wide. The widths in mm
    # disagree, and the reason says which view split and that the job's gap decides it.
    P = seam_curve("straight")
    views = with_bands(P, P + 0.75 * across(P), camera_poses(P))
    views[1] = dataclasses.replace(views[1], gap_width_px=9.0, band_px=None, band_width_px=None)
    views[0] = dataclasses.replace(views[0], gap_width_px=4.0, band_width_px=9.0)
    with pytest.raises(TriangulationError) as info:
        locate_seam(views)
    msg = str(info.value)
    assert "different widths" in msg and "view1 (whole band" in msg, msg
    assert "[seam] gap_mm" in msg and "view2 (whole band" not in msg
