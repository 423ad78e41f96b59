import cv2
import numpy as np
import pytest

from controller.errors import ConfigError
from drivers.sim.sim_look import FX_NOMINAL, TABLES_HELDOUT, TABLES_TUNING, seeds_in, split_of
from drivers.sim.sim_scene import make_scene


def test_split_is_a_fixed_half_of_the_seeds():
    parts = [split_of(s) for s in range(2000)]
    assert parts == [split_of(s) for s in range(2000)]
    assert 0.45 < parts.count("heldout") / 2000 < 0.55
    held = seeds_in("heldout", 30, start=100)
    assert len(held) == 30 and min(held) >= 100
    assert all(split_of(s) == "heldout" for s in held)
    assert not set(held) & set(seeds_in("tuning", 60, start=100))


def test_the_two_parts_draw_from_disjoint_ranges():
    for split in ("tuning", "heldout"):
        tables = set()
        for seed in seeds_in(split, 40):
            sc = make_scene("straight", seed, "medium", variety="wide")
            assert sc.look.split == split
            tables.add(sc.look.table)
            for tilt in (sc.look.tilt_a_rad, sc.look.tilt_b_rad):
                k = int(np.degrees(abs(tilt)) / (4.0 / 6))  # 6 bins over 0-4 deg
                assert k % 2 == (0 if split == "tuning" else 1)
        allowed = TABLES_TUNING if split == "tuning" else TABLES_HELDOUT
        assert tables <= set(allowed)
    assert "slotted" not in TABLES_HELDOUT and "grid_lines" not in TABLES_TUNING


@pytest.mark.parametrize("difficulty", ["easy", "medium", "hard"])
def test_wide_gaps_span_hairline_to_wide(difficulty):
    px = []
    for seed in range(40):
        sc = make_scene(["straight", "arc", "s_curve", "nonplanar"][seed % 4], seed, difficulty,
                        variety="wide")
        px.append(sc.gap_mm * FX_NOMINAL / sc.look.standoff_mm)
        assert 2.0 <= sc.thickness_mm <= 6.0
        assert abs(sc.look.tilt_a_rad) <= np.radians(4.0) + 1e-9
        assert 0.0 <= sc.look.bow_mm <= 1.5
    assert min(px) >= 1.0 and max(px) <= 30.0
    assert min(px) < 3.5 and max(px) > 10.0


def test_wide_scene_truth_and_variety():
    sc = make_scene("straight", 3, "hard", variety="wide", look={"bow_mm": 1.5, "corner_mm": 10.0})
    P = sc.seam_points_mm
    steps = np.linalg.norm(np.diff(P, axis=0), axis=1)
    assert steps.max() < 0.25 and steps.min() > 0.1
    # rounded corners: the truth ends where the gap has doubled, short of the sheet border
    assert sc.a_end_mm is not None and sc.a_end_mm < sc.chord_mm / 2 - 1.0
    assert sc.end_tol_mm > 0
    flat = make_scene("straight", 3, "hard", variety="wide", look={"bow_mm": 0.0})
    a = np.linspace(-10, 10, 5)
    assert np.allclose(sc.seam_b(np.zeros(1)) - flat.seam_b(np.zeros(1)), 1.5)
    assert np.allclose(sc.seam_b(np.array([-sc.chord_mm / 2, sc.chord_mm / 2])), 0.0)
    assert np.all(sc.seam_b(a) != flat.seam_b(a))
    with pytest.raises(ConfigError, match="look"):
        make_scene("arc", 3, "hard", variety="wide", look={"sparkle": 1})
    with pytest.raises(ConfigError, match="variety"):
        make_scene("arc", 3, variety="funky")
    with pytest.raises(ConfigError):
        make_scene("arc", 3, look={"tacks": 1})  # classic has no look


def test_tack_open_preset():
    sc = make_scene("tack_open", 1, "medium")
    assert sc.variety == "tack_open" and sc.kind == "straight"
    assert 460.0 <= sc.length_mm <= 520.0
    assert len(sc.occluded_spans_mm) >= 4
    for s0, s1 in sc.occluded_spans_mm:
        assert 0 <= s0 < s1 <= sc.length_mm
    assert any(d.layer == "over" and d.kind == "tack" for d in sc.decals)


def test_close_ups_are_dark_noisy_defocused_and_tinted():
    ups = [make_scene("straight", s, "hard", variety="wide") for s in range(60)]
    ups = [sc for sc in ups if sc.look.family == "closeup"]
    assert len(ups) >= 5
    for sc in ups:
        assert 150.0 <= sc.look.standoff_mm <= 220.0
        assert 14.0 <= sc.gap_mm * FX_NOMINAL / sc.look.standoff_mm <= 28.0  # a wide gap band
        assert sc.noise_dn >= 4.0 and sc.blur_px >= 2.0 and sc.exposure <= 0.45
        b, g, r = sc.look.cast_bgr
        assert g > b and g > r and sc.look.spot > 0  # a green-tinted spot light
    shop = [sc for sc in (make_scene("arc", s, "medium", variety="wide") for s in range(40))
            if sc.look.family == "shop"]
    assert shop and all(sc.look.rust > 0 and sc.look.ground_mm[0] > 0 and sc.look.ridge_mm > 0
                        for sc in shop)
    # most ground strips end in a grinder's dark line (photographs 1_x1, 1_x2), some softly
    lined = [sc.look.ground_edge_mm > 0 for sc in shop]
    assert 0 < sum(lined) < len(lined)
    assert all(0.3 <= sc.look.ground_edge_depth <= 0.85 for sc in shop if sc.look.ground_edge_mm)


def test_the_rough_look_is_the_wide_look_with_mottled_sheets():
    for split in ("tuning", "heldout"):
        for seed in seeds_in(split, 12, start=70000):
            rough = make_scene("straight", seed, "medium", variety="rough")
            m = rough.look.mottle
            assert 0.5 <= m <= 1.1 and 0.3 <= rough.look.mottle_mm <= 2.0
            k = int((m - 0.5) / (0.6 / 6))  # 6 bins over 0.5-1.1: the parts' own
            assert k % 2 == (0 if split == "tuning" else 1)
            # The gap's floor stays under the mottle's dark patches (a person sees it).
            assert rough.look.gap_contrast >= 1.0 - np.exp(-2.0 * m) - 1e-12
            # Scratches and pits in it, as many per area as the part's bins of 2-26 give.
            k = int((rough.look.marks - 2.0) / (24.0 / 6))
            assert 2.0 <= rough.look.marks <= 26.0 and k % 2 == (0 if split == "tuning" else 1)
    # The other varieties draw no mottle (their scenes as before the rough set).
    assert all(make_scene("arc", s, "hard", variety=v).look.mottle == 0.0
               and make_scene("arc", s, "hard", variety=v).look.marks == 0.0
               for s in range(6) for v in ("wide", "pen", "tee"))


def test_the_marks_are_thin_dark_lines_and_pits_as_many_as_asked():
    from drivers.sim.sim_texture import MOTTLE_MM, _marks_map

    w = h = 400  # 100 x 100 mm at 0.25 mm texels
    few = _marks_map(np.random.default_rng(1), w, h, 2.0)
    many = _marks_map(np.random.default_rng(1), w, h, 20.0)
    assert few.shape == (h, w, 2) and few.max() <= 0.0 and few.min() >= -1.5 - 1e-6
    # Dark texels grow with the count; thin: a 3 x 3 opening (0.75 mm) takes most of them.
    dark = [(m[:, :, 0] < -0.2).astype(np.uint8) for m in (few, many)]
    assert 4 * dark[0].sum() < dark[1].sum()
    opened = cv2.morphologyEx(dark[0], cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))
    assert opened.sum() < 0.2 * dark[0].sum()
    # The two sheets get marks of their own.
    assert not np.array_equal(many[:, :, 0], many[:, :, 1])
    assert MOTTLE_MM == 0.25


def test_the_rough_look_changes_along_the_joint_as_the_photographs_do():
    # bench/detect_realism.py's `along` on the true centreline: the wide set's 95th percentile
    # is about 0.18 (README, *The renderer against the photographs*), the photographs 0.31-0.93.
    from bench.detect_realism import joint_stats
    from controller.geometry.camera_model import default_camera
    from drivers.sim.sim_render import render, suggest_view_poses

    cam = default_camera()
    along, alike = {}, {}
    for variety, look in (("wide", {"mottle": 0.0}), ("rough", {})):
        sc = make_scene("straight", 70001, "easy", variety=variety,
                        look={"gap_contrast": 0.9, "pens": 0, "tacks": 0, **look})
        r = render(sc, cam, suggest_view_poses(sc, cam)[0], seed=1)
        st = joint_stats(r.image if r.image.ndim == 2 else r.image.mean(axis=2).astype(np.uint8),
                         np.asarray(r.seam_px), r.gap_px, r.occluded_spans_px)
        assert st is not None
        along[variety], alike[variety] = st["along"], st["look_alike"]
    assert along["wide"] < 0.18 < along["rough"]
    # Its scratches and pits look like a gap to the detector's profile test far more often than
    # a wide view's sheets (README: the rough set's 5-95 % takes in the photographs' 0.11-0.21).
    assert alike["wide"] < 0.02 and alike["rough"] > 0.05


def test_the_strip_look_is_the_shop_look_with_the_photographs_strip_edges():
    from drivers.sim.sim_scene import make_scene

    for seed in (80000, 80001, 80002, 80003):
        look = make_scene("straight", seed, "medium", variety="strip").look
        assert look.variety == "strip" and look.family == "shop"
        assert min(look.ground_mm) >= 5.0 and look.ground_edge_mm >= 0.3
        assert look.ground_edge_depth >= 0.6 and 0.3 <= look.unground <= 0.65
        assert look.ground_wave_mm <= 0.4 and look.corner_mm == 0.0
    # A joint longer than the view: both ends leave the images.
    assert make_scene("straight", 80001, "medium", variety="strip").chord_mm > 500.0
    # The wide look of the same seeds is as it was (the strip's values come from a stream of
    # their own, its family is forced to the shop look).
    wide = make_scene("straight", 80000, "medium", variety="wide").look
    assert wide.unground == 1.0 and wide.ground_wave_mm == 1.5


def test_the_strip_set_draws_its_own_seeds_in_both_parts_mixing_difficulties():
    from bench.detect_cases import case_list, plan
    from drivers.sim.sim_look import split_of

    cases = case_list("strip", "", "heldout", 6)
    assert [c[1] for c in cases] == ["easy", "medium", "hard"] * 2
    assert all(c[0] == "strip" and c[3] >= 80000 and split_of(c[3]) == "heldout" for c in cases)
    groups = plan({"strip": 4}, ["easy"], ["tuning", "heldout"], ["strip"])
    assert sorted(groups) == ["strip/mixed/heldout", "strip/mixed/tuning"]
