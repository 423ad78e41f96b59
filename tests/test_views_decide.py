"""One view ambiguous, the others decide: the stronger candidate is taken only if 3D confirms it.

A view is refused as ambiguous when a rival line is as strong as its best candidate. Where that
rival is no seam the detector would return (rejected for how it ends, kept as a rival because it
may be a joint whose end was misread), the best candidate travels with the error
(``AmbiguousSeam.detection``) and the cycle triangulates it with the other views' seams
(``controller.cell.guidance.locate_views``): taken if every 3D check passes, else the view's
ambiguity is raised with why the others did not confirm it.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from stereo_scenes import camera_poses, observe, seam_curve

from controller.cell.guidance import GuidanceSettings, ViewInput, locate_views
from controller.errors import AmbiguousSeam
from controller.geometry.camera_model import default_camera
from controller.vision.seam_decision import choose
from controller.vision.seam_params import Candidate, DetectParams


def _cand(score: float, kinds: tuple[str, str], why: str = "", y: float = 300.0) -> Candidate:
    pts = np.column_stack([np.linspace(100.0, 1100.0, 251), np.full(251, y)])
    return Candidate(pts, 1.0, 1000.0, points=pts, width=np.full(251, 3.0), depth=0.8,
                     valid_frac=0.95, resid=0.02, score=score, end_kinds=kinds,
                     why_rejected=why, rival=bool(why))


FADES = "dark line of 1000 px fades out inside the sheet at one end"
BORDERS = ("sheet border", "image border")


def _ambiguity(cands: list[Candidate]) -> AmbiguousSeam:
    with pytest.raises(AmbiguousSeam) as info:
        choose(cands, DetectParams(), {}, (0, 0))
    return info.value


def test_the_stronger_candidate_goes_with_the_error_only_where_its_rival_is_no_seam():
    best = _cand(1000.0, BORDERS)
    err = _ambiguity([best, _cand(800.0, ("open", "image border"), FADES, y=500.0)])
    assert err.undecided is not None and err.undecided[0] is best
    assert err.details["other_views_decide"] is True
    assert any("the other views decide" in r for r in err.undecided[3])
    # The rival is a seam the detector would return: a true ambiguity, nothing to decide on.
    err = _ambiguity([best, _cand(800.0, BORDERS, y=500.0)])
    assert err.undecided is None and err.details["other_views_decide"] is False
    # A rejected line stronger than the best: the best may be the wrong one.
    err = _ambiguity([_cand(700.0, BORDERS), _cand(1000.0, ("open", "image border"), FADES,
                                                   y=500.0)])
    assert err.undecided is None
    # The best would not be returned without the rival either (an end read as unsure).
    err = _ambiguity([_cand(1000.0, ("unsure sheet border", "image border")),
                      _cand(800.0, ("open", "image border"), FADES, y=500.0)])
    assert err.undecided is None


def _det(uv: np.ndarray) -> SimpleNamespace:
    return SimpleNamespace(points_px=uv, end_kinds=None, gap_width_px=None, band_px=None,
                           band_width_px=None)


def _setup(view2_line: np.ndarray | None, view1_undecided: bool = False):
    """Two views of a straight seam; view 2 is refused as ambiguous with ``view2_line`` (3D, mm)
    as its stronger candidate (None: the true seam)."""
    P = seam_curve("straight")
    poses = camera_poses(P)
    cam = default_camera()
    obs = observe(P, poses)
    other = obs[1].seam_px if view2_line is None else observe(view2_line, poses)[1].seam_px
    imgs = [np.zeros((4, 4), np.uint8), np.ones((4, 4), np.uint8)]

    def detector(image, camera=None, roi=None, **_):
        if image is imgs[1] or view1_undecided:
            err = AmbiguousSeam("two seam candidates of similar strength")
            err.detection = _det(other if image is imgs[1] else obs[0].seam_px)
            raise err
        return _det(obs[0].seam_px)

    views = [ViewInput(f"view{i + 1}", imgs[i], cam, poses[i]) for i in range(2)]
    settings = GuidanceSettings(nominal_centre_mm=tuple(P.mean(axis=0)), nominal_radius_mm=100.0)
    return views, settings, detector, P


def test_the_other_view_confirms_the_stronger_candidate_and_the_record_says_so():
    views, settings, detector, P = _setup(None)
    notes: dict = {}
    located = locate_views(views, settings, detector=detector,
                           note=lambda **kw: notes.update(kw))
    err = np.linalg.norm(located.seam.points_mm[:, None] - P[None], axis=2).min(axis=1)
    assert err.max() < 0.05
    assert notes["decided_by_views"]["view"] == "view2"
    assert "similar strength" in notes["decided_by_views"]["ambiguity"]


def test_a_wrong_stronger_candidate_is_not_confirmed_and_the_view_stays_ambiguous():
    Q = seam_curve("straight")
    Q[:, 0] += 60.0  # a line 60 mm from the seam: consistent in 2D, outside the nominal region
    views, settings, detector, _ = _setup(Q)
    with pytest.raises(AmbiguousSeam, match=r"^view2: two seam.*do not confirm.*nominal") as info:
        locate_views(views, settings, detector=detector)
    assert "not_confirmed" in info.value.details and info.value.details["view"] == "view2"


def test_two_ambiguous_views_are_not_decided():
    views, settings, detector, _ = _setup(None, view1_undecided=True)
    with pytest.raises(AmbiguousSeam, match=r"^view1: two seam"):
        locate_views(views, settings, detector=detector)
