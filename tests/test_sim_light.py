"""The wide look's light (drivers/sim/sim_light.py): key-light shadow, ring glare, spot light."""

import numpy as np
from sim_looks import NEUTRAL

from controller.geometry.camera_model import default_camera
from drivers.sim.sim_render import render, suggest_view_poses
from drivers.sim.sim_scene import make_scene

CAM = default_camera().scaled(0.25)


def _scene(glare=0.0, **look):
    return make_scene("straight", 5, "easy", variety="wide", look={**NEUTRAL, **look},
                      noise_dn=0.0, blur_px=0.5, glare=glare, uneven_light=0.0, gap_mm=1.0,
                      length_mm=250.0, albedo_a=0.5, albedo_b=0.5, brush_contrast=0.0,
                      clutter=False, vignetting=0.0)


def _pair(**look):
    base = _scene()
    T = suggest_view_poses(base, CAM, n=1)[0]
    return (render(base, CAM, T, seed=0).image.astype(float),
            render(_scene(**look), CAM, T, seed=0).image.astype(float))


def test_key_light_shadow_is_a_soft_half_plane():
    # Shadow edge across the chord at a = 0 (normal along +a): the +a half darkens, softly.
    plain, shaded = _pair(key_shadow=(0.0, 0.0, 0.0, 20.0, 0.6))
    ratio = shaded / np.maximum(plain, 1)
    part = plain > 40
    cols = [np.median(ratio[:, c][part[:, c]]) for c in range(ratio.shape[1]) if part[:, c].sum()]
    cols = np.array(cols)
    lo, hi = min(cols[0], cols[-1]), max(cols[0], cols[-1])
    assert hi > 0.97 and lo < 0.85  # one side lit, the other in shadow
    steps = np.abs(np.diff(cols))
    assert steps.max() < 0.05  # a penumbra, not a hard edge


def test_ring_light_glare_is_a_bright_ring_round_the_mirror_point():
    plain, ring = _pair(ring_glare=1.5)
    extra = ring - plain
    assert extra.max() > 40
    H, W = extra.shape
    v, u = np.mgrid[0:H, 0:W]
    r = np.hypot(u - W / 2, v - H / 2)
    peak_r = r[extra > 0.8 * extra.max()]
    assert np.median(peak_r) > 5  # a ring, not a spot at the centre
    assert extra[r < 2].mean() < 0.5 * extra.max()


def test_spot_light_falls_off_toward_the_corners():
    plain, spot = _pair(spot=1.5)
    H, W = plain.shape
    centre = (spot / np.maximum(plain, 1))[H // 2 - 20:H // 2 + 20, W // 2 - 20:W // 2 + 20]
    corner = (spot / np.maximum(plain, 1))[:40, :40]
    assert np.median(centre) > 0.9 and np.median(corner) < 0.8 * np.median(centre)
