import numpy as np
import pytest
from sim_looks import NEUTRAL as LOOK0

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


# ---------------------------------------------------------------------------------------------
# Wide looks: each phenomenon with its truth
# ---------------------------------------------------------------------------------------------
NEUTRAL = {**LOOK0, "gap_contrast": 0.9, "face_a": 0.3, "face_b": 0.3}


def _wide(seed=2, glare=0.0, **look):
    return make_scene("straight", seed, "easy", variety="wide", look={**NEUTRAL, **look},
                      noise_dn=0.0, blur_px=0.6, glare=glare, uneven_light=0.0, gap_mm=1.2,
                      length_mm=150.0)


def _at(img, P):
    P = np.round(np.asarray(P)).astype(int)
    return img[P[:, 1], P[:, 0]].astype(float)


def test_tack_welds_bridge_the_gap_and_are_reported_as_occluded_spans():
    sc = _wide(tacks=2, spatter=0)
    r = render(sc, CAM, suggest_view_poses(sc, CAM)[0], seed=0)
    assert len(r.occluded_spans_px) == 2
    s = np.concatenate([[0], np.cumsum(np.linalg.norm(np.diff(r.seam_px, axis=0), axis=1))])
    inside = np.zeros(len(s), bool)
    for s0, s1 in r.occluded_spans_px:
        assert 0 <= s0 < s1 <= s[-1]
        inside |= (s > s0 + 1) & (s < s1 - 1)
    vals = _at(r.image, r.seam_px)
    open_ = ~inside
    for s0, s1 in r.occluded_spans_px:
        open_ &= (s < s0 - 4) | (s > s1 + 4)
    for s0, s1 in r.occluded_spans_px:  # a bright bead over the gap (its crater may be dark)
        span = (s > s0 + 1) & (s < s1 - 1)
        assert np.percentile(vals[span], 75) > np.median(vals[open_]) + 40


def test_pen_lines_are_drawn_where_their_truth_says():
    sc = _wide(pens=2)
    r = render(sc, CAM, suggest_view_poses(sc, CAM)[0], seed=0)
    assert len(r.pen_lines_px) == 2
    for P in r.pen_lines_px:
        d = np.min(np.linalg.norm(P[:, None, :] - r.seam_px[None, ::10, :], axis=2), axis=1)
        assert d.min() > 3.0 * CAM.fx / 350.0 * 0.9  # at least 3 mm beside the joint
        t = np.gradient(P, axis=0)
        n = np.column_stack([-t[:, 1], t[:, 0]]) / np.linalg.norm(t, axis=1)[:, None]
        on, off = _at(r.image, P[2:-2]), _at(r.image, (P + 6 * n)[2:-2])
        assert np.median(np.abs(on - off)) > 15  # the ink differs from the sheet beside it


def test_ends_leaving_the_image_are_image_border_ends():
    from controller.cell.dry_run import VIEW2_ROLL_DEG
    from controller.geometry.poses import make_pose, rotation_about

    sc = make_scene("tack_open", 1, "medium")
    poses = suggest_view_poses(sc, CAM)
    poses[1] = poses[1] @ make_pose(rotation_about([0, 0, 1], np.radians(VIEW2_ROLL_DEG)))
    for T in poses:
        r = render(sc, CAM, T, seed=0)
        assert r.end_kinds == ("image_border", "image_border")
        assert r.occluded_spans_px  # tack welds in view
    whole = render(_wide(), CAM, suggest_view_poses(_wide(), CAM)[0], seed=0)
    assert whole.end_kinds == ("joint_end", "joint_end")


def test_rounded_corners_end_the_truth_where_the_gap_has_doubled():
    from drivers.sim.sim_gap import corner_cover

    sc = _wide(corner_mm=8.0)
    a = np.array([sc.a_end_mm, -sc.a_end_mm], np.float32)
    for d in (sc.gap_mm, -sc.gap_mm):  # each edge has receded by half a gap there
        assert np.allclose(corner_cover(sc, a, np.full(2, d, np.float32)), 0.0, atol=0.02)
    r = render(sc, CAM, suggest_view_poses(sc, CAM)[0], seed=0)
    assert r.end_kinds == ("joint_end", "joint_end") and r.end_tol_px > 0


def test_colour_cast_and_jpeg():
    grey = render(_wide(), CAM, suggest_view_poses(_wide(), CAM)[0], seed=0).image
    sc = _wide(cast_bgr=(0.6, 1.0, 0.5))
    col = render(sc, CAM, suggest_view_poses(sc, CAM)[0], seed=0).image
    assert grey.ndim == 2 and col.shape == (*grey.shape, 3)
    m = col.reshape(-1, 3).mean(0)
    assert m[1] > m[0] > m[2]  # green tint
    sj = _wide(jpeg_quality=40)
    jpg = render(sj, CAM, suggest_view_poses(sj, CAM)[0], seed=0).image
    diff = np.abs(jpg.astype(int) - grey.astype(int))
    assert 0 < diff.mean() < 3


def test_tilted_sheets_shade_differently_and_keep_the_seam():
    flat = _wide(glare=1.0)  # metal: a tilt moves the sheen more than the diffuse light
    tilted = _wide(glare=1.0, tilt_a_rad=np.radians(4.0), tilt_b_rad=np.radians(-4.0))
    assert np.allclose(flat.seam_points_mm, tilted.seam_points_mm)
    T = suggest_view_poses(flat, CAM)[0]
    a, b = render(flat, CAM, T, seed=0), render(tilted, CAM, T, seed=0)
    assert np.allclose(a.seam_px, b.seam_px)
    t = np.gradient(a.seam_px, axis=0)
    n = np.column_stack([-t[:, 1], t[:, 0]]) / np.linalg.norm(t, axis=1)[:, None]

    def sides(r):  # mean grey 15 px either side of the seam
        return _at(r.image, r.seam_px + 15 * n).mean(), _at(r.image, r.seam_px - 15 * n).mean()

    (fa, fb), (ta, tb) = sides(a), sides(b)
    assert abs((ta - tb) - (fa - fb)) > 4  # the two sides now face the light differently
