"""Ends of a located seam: seen, or unseen and then refused or clipped to the nominal region."""

import dataclasses

import numpy as np
import pytest
from stereo_scenes import CENTRE, camera_poses, observe

from controller.errors import TriangulationError
from controller.stereo.locate import locate_seam


def long_seam(half_mm=250.0, n=5000):
    """A straight seam 500 mm long: both ends leave both images (they see ~280 mm)."""
    s = np.linspace(-1, 1, n)
    return CENTRE + np.column_stack([0 * s, half_mm * s, 0 * s])


def with_kinds(obs, kinds):
    return [dataclasses.replace(o, end_kinds=k) for o, k in zip(obs, kinds, strict=True)]


def test_ends_leaving_every_image_are_refused_with_the_reason():
    P = long_seam()
    obs = with_kinds(observe(P, camera_poses(P), step=2), [("image_border",) * 2] * 2)
    with pytest.raises(TriangulationError) as info:
        locate_seam(obs, nominal_region=(CENTRE, 120.0))
    msg = str(info.value)
    assert "no view sees where the seam ends at its start" in msg and "and its end" in msg
    assert "view1: the seam runs out of the image" in msg and "clip_unseen_ends" in msg


def test_ends_leaving_every_image_are_clipped_when_allowed():
    P = long_seam()
    obs = with_kinds(observe(P, camera_poses(P), step=2), [("image_border",) * 2] * 2)
    seam = locate_seam(obs, nominal_region=(CENTRE, 120.0), clip_unseen_ends=True)
    ends = seam.quality["ends"]
    assert [e["status"] for e in ends] == ["clipped", "clipped"]
    assert all(e["clipped_mm"] > 5.0 for e in ends)
    d = np.linalg.norm(seam.dense_points_mm - CENTRE, axis=1)
    assert d.max() <= 120.0 and seam.length_mm > 230.0
    err = np.abs(seam.dense_points_mm[:, [0, 2]] - CENTRE[[0, 2]]).max()
    assert err < 0.01
    # Clipping needs a region to clip to; without one the seam is refused.
    with pytest.raises(TriangulationError, match="no view sees"):
        locate_seam(obs, clip_unseen_ends=True)


def test_real_ends_are_seen_and_never_clipped():
    P = long_seam(half_mm=100.0)
    obs = with_kinds(observe(P, camera_poses(P), step=2), [("joint_end",) * 2] * 2)
    seam = locate_seam(obs, nominal_region=(CENTRE, 150.0), clip_unseen_ends=True)
    assert [e["status"] for e in seam.quality["ends"]] == ["seen", "seen"]
    assert [e["seen_by"] for e in seam.quality["ends"]] == [["view1", "view2"]] * 2
    assert abs(seam.length_mm - 200.0) < 1.0


def test_an_end_cut_by_one_view_is_not_taken_from_the_other_alone():
    P = long_seam(half_mm=100.0)
    obs = observe(P, camera_poses(P), step=2)
    # view 2 loses the seam's last 40 mm at its (pretend) border; view 1 sees the real end.
    uv = obs[1].seam_px
    keep = len(uv) - int(0.2 * len(uv))
    obs = [dataclasses.replace(obs[0], end_kinds=("joint_end", "joint_end")),
           dataclasses.replace(obs[1], seam_px=uv[:keep],
                               end_kinds=("joint_end", "image_border"))]
    with pytest.raises(TriangulationError) as info:
        locate_seam(obs, nominal_region=(CENTRE, 150.0))
    msg = str(info.value)
    assert "view2: the seam runs out of the image" in msg
    assert "view1: its joint end lies" in msg
    # view 2's end kinds differ: its start is a joint end, seen by both views; only the end is not
    start, end = info.value.details["quality"]["ends"]
    assert start["status"] == "seen" and start["seen_by"] == ["view1", "view2"]
    assert end["status"] == "unseen" and end["seen_by"] == [] and end["ray_gap_mm"] == 0.0
    # The 40 mm only view 1 sees lie outside view 2's image, not missed by it: the end's own rule
    # refuses (or clips), not the share of the reference curve matched (80 % of it here).
    assert "was matched between the views" not in msg
    q = info.value.details["quality"]
    assert q["coverage"] > 0.99 and abs(q["coverage_of_reference"] - 0.8) < 0.02
    # A job that clips: the seam is what both views see, ending where view 2's image does.
    seam = locate_seam(obs, nominal_region=(CENTRE, 150.0), clip_unseen_ends=True)
    assert [e["status"] for e in seam.quality["ends"]] == ["seen", "clipped"]
    assert 155.0 < seam.length_mm < 165.0
    assert np.abs(seam.dense_points_mm[:, [0, 2]] - CENTRE[[0, 2]]).max() < 0.01


def test_a_view_stopping_short_of_a_seen_end_still_counts_against_the_coverage():
    # Both views say "joint end" at both ends, but view 2's curve stops 40 mm short of view 1's:
    # a detection that stopped short, not the seam leaving an image. No end is unseen, so the
    # unmatched stretch counts, and the seam is refused for it, clipping allowed or not.
    P = long_seam(half_mm=100.0)
    obs = observe(P, camera_poses(P), step=2)
    uv = obs[1].seam_px
    obs = [dataclasses.replace(obs[0], end_kinds=("joint_end", "joint_end")),
           dataclasses.replace(obs[1], seam_px=uv[:len(uv) - int(0.2 * len(uv))],
                               end_kinds=("joint_end", "joint_end"))]
    with pytest.raises(TriangulationError, match="was matched between the views") as info:
        locate_seam(obs, nominal_region=(CENTRE, 150.0), clip_unseen_ends=True)
    q = info.value.details["quality"]
    assert q["coverage"] == q["coverage_of_reference"] < 0.85


def test_without_end_kinds_each_end_is_judged_by_its_own_last_pixel():
    # No detector end kinds: an end is cut when its last pixel lies in the border margin. The
    # seam starts inside both images (a joint end) and runs out of both at its far end.
    s = np.linspace(0.0, 1.0, 5000)
    P = CENTRE + np.column_stack([0 * s, -100.0 + 400.0 * s, 0 * s])
    obs = observe(P, camera_poses(long_seam(half_mm=100.0)), step=2)  # looking at CENTRE
    assert all(o.end_kinds is None for o in obs)
    with pytest.raises(TriangulationError) as info:
        locate_seam(obs, nominal_region=(CENTRE, 500.0))
    start, end = info.value.details["quality"]["ends"]
    assert start["status"] == "seen" and start["seen_by"] == ["view1", "view2"]
    assert start["not_seen"] == [] and start["ray_gap_mm"] < 0.5
    assert end["status"] == "unseen" and end["not_seen"] == [
        "view1: the seam runs out of the image", "view2: the seam runs out of the image"]


def _bent_at_the_end(obs, px=4.0, samples=12):
    """view 1's curve leaving the gap over its last ``samples`` points, ``px`` across at the end
    (what a curve's last pixels cut by the image border can do)."""
    uv = obs[0].seam_px.copy()
    t = uv[-1] - uv[-2]
    n = np.array([-t[1], t[0]]) / np.linalg.norm(t)
    uv[-samples:] += np.outer(np.linspace(0.0, 1.0, samples) ** 2 * px, n)
    return [dataclasses.replace(obs[0], seam_px=uv), obs[1]]


def test_a_clipped_end_turning_off_course_at_the_border_is_cut_back_not_refused():
    P = long_seam()
    obs = with_kinds(observe(P, camera_poses(P), step=2), [("image_border",) * 2] * 2)
    bent = _bent_at_the_end(obs, px=6.0, samples=6)  # view 1's last 12 px leave the gap
    # A seen end that turns off its course is refused, as before.
    with pytest.raises(TriangulationError, match="turns off its own course"):
        locate_seam(with_kinds(bent, [("joint_end",) * 2] * 2), nominal_region=(CENTRE, 300.0))
    # A clipped end is cut back off the image border first, and the turn goes with it.
    seam = locate_seam(bent, nominal_region=(CENTRE, 300.0), clip_unseen_ends=True)
    assert seam.quality["ends"][1]["border_trimmed_mm"] > 0.0
    assert seam.quality["end_bend_mm"][1] <= 0.15  # (limit 0.5)
    off = np.abs(seam.dense_points_mm[:, [0, 2]] - CENTRE[[0, 2]]).max()
    assert off < 0.15


def test_clipped_ends_keep_off_the_image_borders():
    # Where the seam runs out of the images, a curve's last pixels are its least sure: a clipped
    # end is cut back to where every view sees it border_margin_px (12) inside its image.
    P = long_seam()
    obs = with_kinds(observe(P, camera_poses(P), step=2), [("image_border",) * 2] * 2)
    seam = locate_seam(obs, nominal_region=(CENTRE, 300.0), clip_unseen_ends=True)
    for e in seam.quality["ends"]:
        assert e["status"] == "clipped" and 0.5 < e["border_trimmed_mm"] < 5.0
        assert e["clipped_mm"] == e["border_trimmed_mm"]  # the region (300 mm) cuts nothing
    for v in obs:
        uv = v.camera.project(seam.dense_points_mm, v.T_base_cam)
        assert v.camera.in_image(uv, 11.9).all()
        assert not v.camera.in_image(uv, 14.0).all()  # cut back no further than needed
