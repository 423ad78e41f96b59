import numpy as np
import pytest

from controller.errors import ConfigError
from drivers.sim.sim_scene import DEFAULT_CENTRE_MM, DIFFICULTIES, KINDS, make_scene


def arc_length(P):
    return float(np.sum(np.linalg.norm(np.diff(P, axis=0), axis=1)))


@pytest.mark.parametrize("kind", KINDS)
def test_scene_geometry_within_specification(kind):
    for seed in range(3):
        sc = make_scene(kind, seed, "medium")
        P = sc.seam_points_mm
        assert P.shape[1] == 3 and len(P) > 400
        assert 100.0 <= sc.length_mm <= 250.0
        assert arc_length(P) == pytest.approx(sc.length_mm, rel=2e-3)
        assert 0.3 <= sc.gap_mm <= 1.2
        steps = np.linalg.norm(np.diff(P, axis=0), axis=1)
        assert steps.max() < 0.25 and steps.min() > 0.1  # dense and ordered end to end
        assert np.linalg.norm(sc.centre_mm - DEFAULT_CENTRE_MM) < sc.length_mm
        assert np.all(np.linalg.norm(P - sc.centre_mm, axis=1) <= sc.region_radius_mm)
        n = sc.normal_at(P[::50])
        assert np.allclose(np.linalg.norm(n, axis=1), 1.0)
        rise = P[:, 2].max() - P[:, 2].min()
        if kind == "nonplanar":
            assert 10.0 - 1e-6 <= rise <= 40.0 + 1e-6
            assert P[len(P) // 2, 2] - P[0, 2] == pytest.approx(rise, abs=0.5)
        else:
            assert rise < 1e-9


def test_shapes_really_curve():
    arc = make_scene("arc", 1).seam_points_mm
    s = make_scene("s_curve", 1).seam_points_mm
    straight = make_scene("straight", 1).seam_points_mm

    def max_dev(P):
        d = P[-1] - P[0]
        d /= np.linalg.norm(d)
        v = P - P[0]
        return np.linalg.norm(v - np.outer(v @ d, d), axis=1).max()

    assert max_dev(straight) < 1e-6
    assert max_dev(arc) > 10.0
    assert max_dev(s) > 5.0


def test_seeded_and_deterministic():
    a = make_scene("arc", 7, "hard")
    b = make_scene("arc", 7, "hard")
    c = make_scene("arc", 8, "hard")
    assert np.array_equal(a.seam_points_mm, b.seam_points_mm)
    assert a.decals == b.decals
    assert not np.array_equal(a.seam_points_mm.shape, c.seam_points_mm.shape) or \
        not np.allclose(a.seam_points_mm, c.seam_points_mm)


def test_difficulty_adds_clutter_and_noise():
    easy = [make_scene("straight", s, "easy") for s in range(5)]
    hard = [make_scene("straight", s, "hard") for s in range(5)]

    def marks(sc):
        return sum(d.layer == "part" for d in sc.decals)

    assert np.mean([marks(s) for s in hard]) > 2 * np.mean([marks(s) for s in easy])
    assert min(s.noise_dn for s in hard) > max(s.noise_dn for s in easy)
    assert any(d.kind == "pen" for s in hard for d in s.decals)
    assert all(d.kind != "pen" for s in easy for d in s.decals)


def test_overrides_and_errors():
    sc = make_scene("straight", 0, gap_mm=0.3, length_mm=100.0, clutter=False)
    assert sc.gap_mm == 0.3 and sc.decals == ()
    assert arc_length(sc.seam_points_mm) == pytest.approx(100.0, rel=1e-3)
    with pytest.raises(ConfigError, match="kind"):
        make_scene("zigzag", 0)
    with pytest.raises(ConfigError, match="difficulty"):
        make_scene("arc", 0, "insane")
    with pytest.raises(ConfigError, match="unknown override"):
        make_scene("arc", 0, colour="red")
    with pytest.raises(ConfigError, match="gap_mm"):
        make_scene("arc", 0, gap_mm=2.0)
    with pytest.raises(ConfigError, match="length_mm"):
        make_scene("arc", 0, length_mm=300.0)
    assert set(DIFFICULTIES) == {"easy", "medium", "hard"}


def test_nominal_region_for_the_job_file():
    sc = make_scene("s_curve", 3)
    reg = sc.nominal_region()
    assert len(reg["centre_mm"]) == 3 and reg["radius_mm"] > sc.length_mm / 2 * 0.6
