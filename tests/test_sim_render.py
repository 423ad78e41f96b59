import numpy as np
import pytest

from controller.errors import ConfigError
from controller.geometry.camera_model import default_camera
from drivers.sim.sim_render import GAMMA, render, suggest_view_poses
from drivers.sim.sim_scene import make_scene

CAM = default_camera().scaled(0.25)  # 568x426: fast


@pytest.fixture(scope="module")
def scene():
    return make_scene("arc", 2, "medium")


def test_deterministic_for_a_seed(scene):
    T = suggest_view_poses(scene, CAM)[0]
    a = render(scene, CAM, T, seed=1)
    b = render(scene, CAM, T, seed=1)
    c = render(scene, CAM, T, seed=2)
    assert a.image.dtype == np.uint8 and a.image.shape == (CAM.height, CAM.width)
    assert np.array_equal(a.image, b.image)
    assert not np.array_equal(a.image, c.image)
    assert np.abs(a.image.astype(int) - c.image.astype(int)).mean() < 6  # noise only


def test_truth_is_the_projection_of_the_visible_seam(scene):
    T = suggest_view_poses(scene, CAM)[1]
    r = render(scene, CAM, T, seed=0)
    assert len(r.seam_px) > 50
    assert np.allclose(r.seam_px, CAM.project(r.seam_points_mm, T))
    assert np.all(CAM.in_image(r.seam_px))
    assert np.array_equal(r.seam_points_mm, scene.seam_points_mm[r.seam_index])
    assert np.all(np.diff(r.seam_index) == 1)  # ordered as the scene's polyline


def test_partly_visible_seam_is_clipped_to_the_image(scene):
    T = suggest_view_poses(scene, CAM)[0].copy()
    T[:3, 3] += T[:3, 0] * 150.0  # move the camera along the seam: one end leaves the image
    r = render(scene, CAM, T, seed=0)
    assert 0 < len(r.seam_px) < len(scene.seam_points_mm)
    assert r.ends_in_image.count(True) == 1


def _gap_offsets(r, step=5, half=7):
    """Darkness centroid across the gap at truth points (px), from a clean linear image."""
    img = (r.image.astype(np.float64) / 255.0) ** GAMMA
    P = r.seam_px
    offs = []
    for i in range(10, len(P) - 10, step):
        t = P[i + 3] - P[i - 3]
        t /= np.linalg.norm(t)
        n = np.array([-t[1], t[0]])
        x = np.arange(-half, half + 0.01, 0.25)
        q = P[i] + np.outer(x, n)
        u0, v0 = np.floor(q[:, 0]).astype(int), np.floor(q[:, 1]).astype(int)
        fu, fv = q[:, 0] - u0, q[:, 1] - v0
        val = ((img[v0, u0] * (1 - fu) + img[v0, u0 + 1] * fu) * (1 - fv)
               + (img[v0 + 1, u0] * (1 - fu) + img[v0 + 1, u0 + 1] * fu) * fv)
        dark = np.clip(np.median(val[:8]) - val, 0, None)
        offs.append(np.sum(dark * x) / np.sum(dark))
    return np.array(offs)


@pytest.mark.parametrize("ss", [1, pytest.param(3, marks=pytest.mark.slow)])
def test_gap_is_drawn_where_the_truth_says(ss):
    # Equal sheets, no texture, noise, blur or clutter: the darkness centroid is unbiased here,
    # so it checks the renderer's analytic anti-aliasing (ss=1) and supersampling (ss=3).
    sc = make_scene("s_curve", 4, "easy", albedo_a=0.6, albedo_b=0.6, noise_dn=0.0, blur_px=0.0,
                    brush_contrast=0.0, clutter=False, glare=0.0, uneven_light=0.0, gap_mm=0.6)
    T = suggest_view_poses(sc, CAM, standoff_mm=150.0)[0]
    r = render(sc, CAM, T, seed=0, ss=ss)
    offs = _gap_offsets(r)
    assert abs(np.mean(offs)) < 0.03
    assert np.sqrt(np.mean(offs**2)) < 0.08


def test_suggested_views_look_at_the_seam_across_it():
    cam = default_camera()
    for kind in ("straight", "arc", "s_curve", "nonplanar"):
        sc = make_scene(kind, 5)
        poses = suggest_view_poses(sc, cam, n=2, standoff_mm=350.0, baseline_mm=200.0)
        c = sc.centre_mm
        for T in poses:
            assert np.linalg.norm(T[:3, 3] - c) == pytest.approx(350.0, abs=1e-6)
            uv = cam.project(c[None], T)[0]
            assert np.linalg.norm(uv - [cam.cx, cam.cy]) < 1.0
            assert T[:3, 2] @ sc.surface_normal < -0.9  # looking down at the part
        base = poses[1][:3, 3] - poses[0][:3, 3]
        chord = sc.seam_points_mm[-1] - sc.seam_points_mm[0]
        assert np.linalg.norm(base) == pytest.approx(200.0, abs=1e-6)
        assert abs(base @ chord) / np.linalg.norm(chord) < 1e-6 * 200  # baseline across the seam


def test_bad_arguments(scene):
    with pytest.raises(ConfigError):
        render(scene, CAM, np.eye(3), seed=0)
    with pytest.raises(ConfigError):
        render(scene, CAM, np.eye(4), seed=0, ss=0)
    with pytest.raises(ConfigError):
        suggest_view_poses(scene, CAM, n=0)
