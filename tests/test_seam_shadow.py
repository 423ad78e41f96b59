"""A shadow band beside the gap (controller/vision/seam_shadow.py): the centre is the gap's middle.

Rendered lopsided gaps (drivers/sim/sim_gap.py: a plate edge standing higher casts a shadow on one
side of the gap) with the exact truth of the renderer, and the profile model on its own.
"""

import dataclasses

import numpy as np
import pytest
from sim_looks import NEUTRAL

from controller.geometry.camera_model import default_camera
from controller.vision.seam_detect import DetectParams, detect_seam
from controller.vision.seam_profiles import _fit_profiles
from controller.vision.seam_shadow import fit_three, split_shadow
from drivers.sim.sim_render import render, suggest_view_poses
from drivers.sim.sim_scene import make_scene

CAM = default_camera().scaled(0.5)


def lopsided(side, shadow_mm=1.5, depth=0.6, gap_mm=0.45, seed=3):
    sc = make_scene("straight", seed, "easy", variety="wide",
                    look={**NEUTRAL, "step_shadow_mm": shadow_mm, "step_side": side,
                          "step_depth": depth},
                    noise_dn=1.5, blur_px=0.6, glare=0.0, uneven_light=0.0, gap_mm=gap_mm,
                    length_mm=150.0, albedo_a=0.6, albedo_b=0.6, brush_contrast=0.05,
                    clutter=False)
    T = suggest_view_poses(sc, CAM, standoff_mm=250.0)[0]
    return render(sc, CAM, T, seed=seed)


def signed_offsets(det, P):
    """Signed distance (px) of the detected points to the straight truth, along its normal."""
    t = (P[-1] - P[0]) / np.linalg.norm(P[-1] - P[0])
    n = np.array([-t[1], t[0]])
    return (det.points_px - P[0]) @ n


@pytest.mark.parametrize("side", [-1, 1])
def test_the_centre_is_the_gap_not_the_gap_and_its_shadow(side):
    r = lopsided(side)
    det = detect_seam(r.image)
    off = signed_offsets(det, r.seam_px)[10:-10]
    # The shadow (1.5 mm, ~9 px) beside the gap (0.45 mm, ~3 px): the middle of the whole dark
    # band is ~4.5 px off the gap's. The width returned is the gap's, not the band's.
    assert abs(np.median(off)) < 0.8, np.median(off)
    assert np.percentile(np.abs(off), 95) < 1.5
    assert np.median(det.width_px) < 0.6 * (r.gap_px + 9.0)
    # The whole band's reading comes along for the stereo stage (controller.stereo.band_check):
    # its middle lies on the shadow's side, about half the shadow's width off the gap's.
    band = signed_offsets(dataclasses.replace(det, points_px=det.band_px), r.seam_px)[10:-10]
    assert 3.0 < -side * np.median(band) < 6.0  # step_side +1 puts the shadow at -n here
    assert det.band_width_px > np.median(det.width_px) + 4.0


def test_a_symmetric_wide_gap_is_not_split():
    # A wide gap without shadow has no core: the model stays the two-step one.
    sc = make_scene("straight", 5, "easy", variety="wide", look=NEUTRAL, noise_dn=1.5,
                    blur_px=0.6, glare=0.0, uneven_light=0.0, gap_mm=1.2, length_mm=150.0,
                    albedo_a=0.6, albedo_b=0.6, brush_contrast=0.05, clutter=False)
    r = render(sc, CAM, suggest_view_poses(sc, CAM, standoff_mm=250.0)[0], seed=5)
    det = detect_seam(r.image)
    off = signed_offsets(det, r.seam_px)[10:-10]
    assert abs(np.median(off)) < 0.3
    assert abs(np.median(det.width_px) - r.gap_px) < 0.25 * r.gap_px
    assert det.band_px is None and det.band_width_px is None
    assert det.to_dict()["band_px"] is None


def _profiles(core_left, n=40, noise=0.004, seed=0):
    """Synthetic profiles: sheet 0.3 | shadow 0.12 (9 px) | gap 0.03 (3 px) | sheet 0.3 (or
    mirrored), blurred by 0.8 px, sampled every px over +-14 px; the gap's middle at +2.5 (-2.5)."""
    from controller.vision.scipy_equivalents import erf
    x = np.arange(-14.0, 14.01, 1.0)
    rng = np.random.default_rng(seed)
    edges = np.array([-8.0, 1.0, 4.0]) if not core_left else np.array([-4.0, -1.0, 8.0])
    levels = [0.3, 0.12, 0.03, 0.3] if not core_left else [0.3, 0.03, 0.12, 0.3]
    v = np.full_like(x, levels[0])
    for e, a, b in zip(edges, levels[:-1], levels[1:], strict=True):
        v = v + (b - a) * 0.5 * (1 + erf((x - e) / 0.8 / np.sqrt(2)))
    prof = v[None, :] + noise * rng.standard_normal((n, len(x)))
    return x, prof, (edges[1] + edges[2]) / 2 if not core_left else (edges[0] + edges[1]) / 2


@pytest.mark.parametrize("core_left", [True, False])
def test_three_edge_fit_finds_the_core(core_left):
    x, prof, truth = _profiles(core_left)
    # Started from what the two-step model returns: the middle of the whole band.
    two, _ = _fit_profiles(x, prof, 7)
    assert np.median(np.abs(two[:, 3] - 2.0 * (1 if core_left else -1))) < 0.5
    prm, _ = fit_three(x, prof, two, 7)
    A, B, C, D, e1, e2, e3, _s = prm.T
    lo, hi = (e1, e2) if core_left else (e2, e3)
    assert np.all((B < C) == core_left)
    assert np.median(np.abs((lo + hi) / 2 - truth)) < 0.2
    assert np.median(np.abs(hi - lo - 3.0)) < 0.4


def test_split_needs_a_consistent_core_along_the_seam():
    x, left, _ = _profiles(True, n=20)
    _, right, _ = _profiles(False, n=20, seed=1)
    p = DetectParams()

    def fit_of(prof):
        two, rms = _fit_profiles(x, prof, p.fit_iterations)
        centre = np.column_stack([two[:, 3], np.zeros(len(prof))])  # the points at x = 0
        return {"valid": np.ones(len(prof), bool), "params": two, "profiles": prof,
                "rms": rms, "centre": centre, "width": two[:, 4].copy(),
                "normal": np.tile([1.0, 0.0], (len(prof), 1))}

    one_side, st = split_shadow(fit_of(np.vstack([left, left])), p)
    assert st["shadow_split"] == 1.0
    assert np.median(np.abs(one_side["centre"][:, 0] + 2.5)) < 0.2
    assert np.median(np.abs(one_side["width"] - 3.0)) < 0.4
    before = fit_of(np.vstack([left, right]))
    mixed, st = split_shadow(before, p)  # cores on both sides: not a shadow along the seam
    assert st["shadow_split"] == 0.0 and np.all(mixed["centre"] == before["centre"])


def test_a_core_narrower_than_the_jobs_narrowest_gap_is_not_split_off():
    # A 3 px core beside a 9 px lighter band: a gap beside a shadow, or the floor beside a cut
    # face seen inside a 12 px gap; one view cannot tell. The job's narrowest gap decides: 4 px
    # (wider than the core) keeps the band whole; 2 px lets the core be the gap.
    from dataclasses import replace

    x, left, _ = _profiles(True, n=40)
    p = DetectParams()
    two, rms = _fit_profiles(x, left, p.fit_iterations)
    fit = {"valid": np.ones(len(left), bool), "params": two, "profiles": left, "rms": rms,
           "centre": np.column_stack([two[:, 3], np.zeros(len(left))]),
           "width": two[:, 4].copy(), "normal": np.tile([1.0, 0.0], (len(left), 1))}
    kept, st = split_shadow(fit, replace(p, min_gap_px=4.0))
    assert st["shadow_split"] == 0.0 and st["shadow_core_under_job_gap"] == 1.0
    assert np.all(kept["centre"] == fit["centre"]) and np.all(kept["width"] == fit["width"])
    split, st = split_shadow(fit, replace(p, min_gap_px=2.0))
    assert st["shadow_split"] == 1.0
    assert np.median(np.abs(split["centre"][:, 0] + 2.5)) < 0.2
