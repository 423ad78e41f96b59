"""Textures of the wide look (drivers/sim/sim_texture.py): rust, and tacks over the gap."""

import numpy as np
from sim_looks import NEUTRAL

from controller.geometry.camera_model import default_camera
from drivers.sim.sim_render import RUST_BGR, render, suggest_view_poses
from drivers.sim.sim_scene import make_scene
from drivers.sim.sim_texture import textures

CAM = default_camera().scaled(0.25)


def _scene(**look):
    return make_scene("straight", 6, "easy", variety="wide", look={**NEUTRAL, **look},
                      noise_dn=0.0, length_mm=150.0, clutter=False)


def test_rust_covers_about_the_share_asked_and_tints_the_sheets():
    for amount in (0.3, 0.7):
        tex = textures(_scene(rust=amount, cast_bgr=(1.0, 1.0, 1.0)))
        assert tex.rust is not None and tex.over is None
        share = float(np.mean(tex.rust > 0.5))
        assert abs(share - amount) < 0.15
    clean, rusty = _scene(cast_bgr=(1.0, 1.0, 1.0)), _scene(rust=0.7, cast_bgr=(1.0, 1.0, 1.0))
    T = suggest_view_poses(clean, CAM, n=1)[0]
    a = render(clean, CAM, T, seed=0).image.reshape(-1, 3).astype(float)
    b = render(rusty, CAM, T, seed=0).image.reshape(-1, 3).astype(float)
    assert np.allclose(a[:, 0], a[:, 2], atol=2)  # a neutral cast: grey
    red_over_blue = (b[:, 2] + 1) / (b[:, 0] + 1)
    assert np.percentile(red_over_blue, 90) > 1.2 and RUST_BGR[2] > RUST_BGR[0]
    assert b.mean() < a.mean()  # rust is darker than bare steel


def test_tack_welds_are_drawn_on_their_own_layer_over_the_gap():
    sc = make_scene("straight", 6, "easy", variety="wide", look={**NEUTRAL, "tacks": 2})
    tex = textures(sc)
    assert tex.over is not None and tex.over[:, :, 1].max() == 255
    assert tex.over[:, :, 1].mean() < 5  # small beads on a large sheet
