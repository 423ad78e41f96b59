"""The wide look's gap across the seam (drivers/sim/sim_gap.py), each phenomenon with its truth."""

import numpy as np
import pytest
from sim_looks import NEUTRAL

from controller.geometry.camera_model import default_camera
from drivers.sim.sim_gap import edges, gap_band_mm
from drivers.sim.sim_render import GAMMA, render, suggest_view_poses
from drivers.sim.sim_scene import make_scene

CAM = default_camera().scaled(0.25)


def scene(gap_mm=1.6, **look):
    return make_scene("straight", 3, "easy", variety="wide", look={**NEUTRAL, **look},
                      noise_dn=0.0, blur_px=0.0, glare=0.0, uneven_light=0.0, gap_mm=gap_mm,
                      length_mm=150.0, albedo_a=0.6, albedo_b=0.6, brush_contrast=0.0,
                      clutter=False)


def profile(sc, T=None, half=14):
    """Linear radiance across the seam at its middle, sampled every 0.25 px (offset, value)."""
    if T is None:
        T = suggest_view_poses(sc, CAM, n=1, standoff_mm=120.0)[0]
    r = render(sc, CAM, T, seed=0)
    img = (r.image.astype(float) / 255.0) ** GAMMA
    P = r.seam_px
    i = len(P) // 2
    t = (P[i + 5] - P[i - 5]) / np.linalg.norm(P[i + 5] - P[i - 5])
    n = np.array([-t[1], t[0]])
    x = np.arange(-half, half + 0.01, 0.25)
    q = np.round(P[i] + np.outer(x, n)).astype(int)
    return x, img[q[:, 1], q[:, 0]], r


def test_ragged_edges_wander_about_the_nominal_gap():
    sc = scene(ragged_mm=0.3)
    a = np.linspace(-60, 60, 4001)
    lo, hi = edges(sc, a)
    g2 = sc.gap_mm / 2
    mid = (lo + hi) / 2
    assert np.std(hi - g2) > 0.1 and np.std(-lo - g2) > 0.1  # each edge jags
    assert abs(np.mean(mid)) < 0.05  # zero-mean: the truth is the nominal middle
    assert np.all(hi - lo > 0.15 * sc.gap_mm)  # never closed
    assert gap_band_mm(sc) > g2 + 1.0
    smooth = scene()
    assert np.allclose(edges(smooth, a)[1], g2)


def test_taper_widens_the_gap_toward_one_end():
    sc = scene(taper=0.4)
    lo, hi = edges(sc, np.array([-sc.chord_mm / 2, sc.chord_mm / 2]))
    w = hi - lo
    assert w[1] > 1.3 * w[0]


def test_cut_face_fills_the_far_side_of_the_gap():
    # A camera off to one side sees the far sheet's cut face inside the gap: the dark part of the
    # gap is pushed to the near side, the truth (middle of the top edges) is not.
    dark = scene()
    lit = scene(face_a=0.9, face_b=0.9)
    T = suggest_view_poses(dark, CAM, n=2, standoff_mm=120.0, baseline_mm=40.0)[0]
    x, v_dark, r = profile(dark, T)
    _, v_lit, _ = profile(lit, T)
    inside = np.abs(x) < 0.5 * r.gap_px - 0.5
    assert inside.sum() > 4

    def lopsided(v):  # mean of the gap's two halves, difference
        return abs(v[inside & (x < 0)].mean() - v[inside & (x > 0)].mean())

    assert lopsided(v_dark) < 0.03
    assert lopsided(v_lit) > 0.1  # the lit face on the far side, the dark floor on the near one
    assert v_lit[inside].mean() > v_dark[inside].mean() + 0.05


def test_ridge_and_ground_strip_brighten_beside_the_gap():
    plain_x, plain, r = profile(scene())
    _, ground = profile(scene(ground_mm=(8.0, 8.0), ground_gain=1.6))[:2]
    _, ridge = profile(scene(ridge_mm=0.4, ridge_gain=1.0))[:2]
    far = np.abs(plain_x) > 0.5 * r.gap_px + 3
    assert np.median(ground[far] / plain[far]) > 1.4
    near = (np.abs(plain_x) > 0.5 * r.gap_px) & (np.abs(plain_x) < 0.5 * r.gap_px + 2.5)
    assert ridge[near].max() > 1.5 * plain[near].max()


def test_plate_edge_shadow_darkens_one_side_only():
    x, plain, r = profile(scene())
    _, shadow = profile(scene(step_shadow_mm=1.5, step_side=1, step_depth=0.6))[:2]
    band = (np.abs(x) > 0.5 * r.gap_px + 1) & (np.abs(x) < 0.5 * r.gap_px + 4)
    ratio = shadow[band] / plain[band]
    side = np.sign(x[band])
    # the seam's "b" side is on one side of the image profile; exactly one side is darker
    dark_side = [np.median(ratio[side == s]) < 0.6 for s in (-1, 1)]
    assert sorted(dark_side) == [False, True]


def test_ground_strip_edge_is_a_thin_dark_line_between_strip_and_sheet():
    # The grinder leaves a crisp dark line where the ground strip ends (real photographs 1_x1,
    # 1_x2: a line parallel to the joint, bright strip on one side, rusty sheet on the other).
    strip = dict(ground_mm=(2.0, 2.0), ground_gain=1.6)
    x, plain, r = profile(scene(**strip), half=24)
    lined = profile(scene(**strip, ground_edge_mm=0.4, ground_edge_depth=0.7), half=24)[1]
    px_mm = r.gap_px / 1.6
    for s in (-1, 1):
        side = (s * x > 0.5 * r.gap_px + 2)
        i = np.flatnonzero(side)[np.argmin(lined[side])]
        # the darkest point beside the gap is the strip's edge (wavy by up to 1.5 mm)
        assert abs(abs(x[i]) - 2.0 * px_mm) < 1.6 * px_mm
        inside = side & (np.abs(x) < abs(x[i]) - 2) & (np.abs(x) > 0.5 * r.gap_px + 1)
        outside = side & (np.abs(x) > abs(x[i]) + 2)
        assert lined[i] < 0.6 * np.median(lined[inside])
        assert lined[i] < 0.75 * np.median(lined[outside])
        assert plain[i] > 0.9 * np.median(plain[outside])  # no line without it


def test_beyond_the_strips_the_sheet_is_unground_and_the_edge_is_straight():
    # The strip variety's sheet beyond the ground strips (mill scale, rust) is `unground` times
    # as bright as the metal, so the strip's edge is a step with a dark line along it (the
    # photographs 1_x2 and 1_x5); the default look (unground 1) leaves the sheet as it was.
    strip = dict(ground_mm=(2.0, 2.0), ground_gain=1.0, ground_wave_mm=0.0)
    x, plain, r = profile(scene(**strip), half=24)
    dark = profile(scene(**strip, unground=0.4), half=24)[1]
    px_mm = r.gap_px / 1.6
    beyond = np.abs(x) > 2.0 * px_mm + 3
    within = (np.abs(x) < 2.0 * px_mm - 3) & (np.abs(x) > 0.5 * r.gap_px + 2)
    assert np.allclose(np.median(dark[within]), np.median(plain[within]), rtol=0.05)
    assert np.median(dark[beyond]) == pytest.approx(0.4 * np.median(plain[beyond]), rel=0.1)
    # Straight: the step lies where the strip ends, within a px of 2 mm, on both sides.
    for s in (-1, 1):
        side = s * x > 0.5 * r.gap_px + 2
        half_way = 0.7 * np.median(plain[within])
        cross = np.abs(x[side][np.argmin(np.abs(dark[side] - half_way))])
        assert abs(cross - 2.0 * px_mm) < 0.5 * px_mm + 1.0
