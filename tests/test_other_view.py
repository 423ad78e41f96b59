"""A refused view resolved by the other view's seam (controller/cell/other_view.py): the line whose
ends meet it is taken, a line ending elsewhere never, two that fit are no choice."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from controller.cell.guidance import GuidanceSettings, ViewInput, locate_views
from controller.cell.other_view import seam_from_other_view
from controller.errors import SeamNotFound
from controller.geometry.camera_model import default_camera
from controller.stereo.locate import locate_seam
from controller.stereo.triangulate import PolylineDistance
from controller.vision.seam_lines import MeasuredLine
from controller.vision.seam_overlay import refused_lines
from tests.stereo_scenes import CENTRE, camera_poses, observe, seam_curve


def _locate(views):
    return locate_seam(views, nominal_region=(CENTRE, 150.0), clip_unseen_ends=True)


@pytest.fixture(scope="module")
def scene():
    """A straight seam 180 mm long seen whole by two views; view 1 found it, both ends sure."""
    P = seam_curve("straight")
    poses = camera_poses(P)
    obs = observe(P, poses)
    found = replace(obs[0], end_kinds=("joint_end", "joint_end"))
    return P, poses, found, obs[1]


def _line(P, poses, readings, shift_mm=(0.0, 0.0, 0.0)):
    uv = default_camera().project(P + np.asarray(shift_mm), poses[1])
    return MeasuredLine(uv[::3], 4.0, readings, "dark line fades out inside the sheet at one end")


def test_the_line_whose_ends_meet_the_seam_is_taken_not_a_pen_line_beside_it(scene):
    P, poses, found, like = scene
    joint = _line(P, poses, ("sheet border", "open"))
    # A pen line 10 mm beside the joint on the same sheet, ending 18 mm inside it at both ends.
    pen = _line(P[300:2700], poses, ("open", "sheet border"), (10.0, 0.0, 0.0))
    got = seam_from_other_view([pen, joint], like, found, False, _locate)
    assert got is not None and got.line is joint and got.tried == 2
    dense = got.seam.dense_points_mm
    assert np.linalg.norm(dense[[0, -1]] - P[[0, -1]], axis=1).max() < 0.5 or \
        np.linalg.norm(dense[[-1, 0]] - P[[0, -1]], axis=1).max() < 0.5
    # The refused view's end read as fading out is one it does not see: the found view's is used.
    assert got.observation.end_kinds == ("joint_end", "image_border")
    assert all(e["status"] == "seen" and "view1" in e["seen_by"] for e in got.seam.quality["ends"])
    note = got.note([found, SeamNotFound("view2: no weld seam found")])
    assert note["view"] == "view2" and note["refused"] == "SeamNotFound"
    assert note["line_end_readings"] == ["sheet border", "open"]


def test_no_line_ending_elsewhere_and_no_choice_between_two(scene):
    P, poses, found, like = scene
    pen = _line(P[300:2700], poses, ("open", "sheet border"), (10.0, 0.0, 0.0))
    short = _line(P[:2700], poses, ("sheet border", "open"))  # stops 18 mm before the joint's end
    assert seam_from_other_view([pen], like, found, False, _locate) is None
    assert seam_from_other_view([short], like, found, False, _locate) is None
    joint = _line(P, poses, ("sheet border", "open"))
    twin = _line(P, poses, ("sheet border", "sheet border"), (0.0, 0.0, 0.05))
    assert seam_from_other_view([joint, twin], like, found, False, _locate) is None
    # A found seam with no end of the joint in view says nowhere where the line must end.
    blind = replace(found, end_kinds=("image_border", "image_border"))
    assert seam_from_other_view([joint], like, blind, False, _locate) is None


def test_a_rendered_pair_with_one_view_refused_is_located(tmp_path):
    """Wide easy tuning 10014: view 1's joint is refused alone (an end read as unsure), view 2
    finds it; the cycle takes view 1's line that meets view 2's seam and locates the pair (the
    job lets an end no view sees be clipped to its region). Before, the cycle was refused."""
    from bench import detect_cases
    from tests.rendered_cases import rendered_view

    case = ("wide", "easy", "tuning", 10014)
    rendered_view(tmp_path, case, 0)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(detect_cases, "CACHE", tmp_path)
        imgs, z = detect_cases.load_case(case)
    cam = default_camera()
    views = [ViewInput(f"view{i + 1}", imgs[i], cam, z[f"T{i}"]) for i in range(2)]
    settings = GuidanceSettings(nominal_centre_mm=tuple(float(v) for v in z["centre_mm"]),
                                nominal_radius_mm=float(z["radius_mm"]) + 20.0,
                                clip_unseen_ends=True)
    notes: dict = {}
    seen: list = []
    located = locate_views(views, settings, note=lambda **k: notes.update(k),
                           on_detections=seen.extend)
    assert notes["other_view"]["view"] == "view1"
    assert notes["other_view"]["refused"] == "SeamNotFound"
    assert isinstance(seen[0], SeamNotFound) and not isinstance(seen[1], Exception)
    # View 1's picture shows its refusal and draws the line taken.
    drawn, legend = refused_lines(seen[0])
    assert len(drawn) == 1 and "view2" in legend[0]
    assert np.array_equal(drawn[0], located.observations[0].seam_px)
    both = np.intersect1d(z["seam_index0"], z["seam_index1"])
    err = PolylineDistance(z["seam_points_mm"][both])(located.seam.dense_points_mm)
    assert err.max() < 0.5
    assert located.observations[0].end_kinds is not None


def test_a_seam_is_not_cut_where_the_refused_views_line_fades_out(scene):
    """The found view's second end leaves its image (no view sees the joint end there): the 3D
    seam is clipped where the stereo overlap ends. Where that is the refused view's line fading
    out 18 mm before the joint goes on, the seam would be welded short: not taken; where the line
    leaves its image there, the end is unseen like any other and the seam is taken."""
    P, poses, found, like = scene
    half_blind = replace(found, end_kinds=("joint_end", "image_border"))
    fades = _line(P[:2700], poses, ("sheet border", "open"))
    assert seam_from_other_view([fades], like, half_blind, False, _locate) is None
    leaves = _line(P[:2700], poses, ("sheet border", "image border"))
    got = seam_from_other_view([leaves], like, half_blind, False, _locate)
    assert got is not None
    assert [e["status"] for e in got.seam.quality["ends"]] == ["seen", "clipped"]
