import numpy as np
import pytest

from controller.errors import InputError
from controller.geometry.poses import make_pose, rotation_about, rotation_error_deg
from controller.geometry.segment_motion import (
    circle_through,
    matrix_to_rotvec,
    rotvec_to_matrix,
    segment_length_mm,
    segment_pose,
    segment_poses,
)


def on_circle(c, r, ang):
    return np.array([c[0] + r * np.cos(ang), c[1] + r * np.sin(ang), c[2]])


@pytest.mark.parametrize("sweep_deg", [30.0, 170.0, 250.0])
def test_circle_through_three_points(sweep_deg):
    c, r = np.array([900.0, 50.0, 300.0]), 80.0
    sweep = np.radians(sweep_deg)
    a, v, b = (on_circle(c, r, t) for t in (0.2, 0.2 + 0.3 * sweep, 0.2 + sweep))
    circ = circle_through(a, v, b)
    assert np.allclose(circ.centre, c, atol=1e-9)
    assert circ.radius_mm == pytest.approx(r)
    assert np.degrees(circ.sweep_rad) == pytest.approx(sweep_deg)
    assert np.allclose(circ.point([0.0, 0.3, 1.0]), [a, v, b], atol=1e-9)
    # the other way round: same circle, the normal flips, the sweep is the same
    back = circle_through(b, v, a)
    assert np.allclose(back.normal, -circ.normal)
    assert np.degrees(back.sweep_rad) == pytest.approx(sweep_deg)
    assert segment_length_mm(make_pose(t_mm=a), make_pose(t_mm=b), v) == pytest.approx(r * sweep)


def test_fraction_of_points_on_and_off_the_arc():
    c, r = np.zeros(3), 50.0
    circ = circle_through(on_circle(c, r, 0.0), on_circle(c, r, 0.5), on_circle(c, r, 1.0))
    pts = np.array([on_circle(c, r + 3.0, 0.25), on_circle(c, r, -0.1), on_circle(c, r, 1.2)])
    assert np.allclose(circ.fraction_of(pts), [0.25, 0.0, 1.0])


@pytest.mark.parametrize("seed", range(8))
def test_the_turning_points_and_ends_bound_the_whole_arc(seed):
    # random tilted circles, sweeps 20-340 deg: the box of the ends and the turning points is
    # the box of the arc sampled every 0.003 deg (what the safety box check relies on)
    rng = np.random.default_rng(seed)
    c = rng.uniform(-500.0, 500.0, 3)
    r = rng.uniform(5.0, 300.0)
    R = make_pose(rotation_about(rng.normal(size=3), rng.uniform(0.0, np.pi)))[:3, :3]
    a0, sweep = rng.uniform(0.0, 2.0 * np.pi), np.radians(rng.uniform(20.0, 340.0))

    def at(t):
        return c + R @ (r * np.array([np.cos(t), np.sin(t), 0.0]))

    circ = circle_through(at(a0), at(a0 + 0.4 * sweep), at(a0 + sweep))
    fractions = circ.axis_extreme_fractions()
    assert np.all((fractions >= 0.0) & (fractions <= 1.0)) and np.all(np.diff(fractions) >= 0)
    key = circ.point(np.concatenate([[0.0, 1.0], fractions]))
    dense = circ.point(np.linspace(0.0, 1.0, 100_001))
    assert np.allclose(key.min(axis=0), dense.min(axis=0), atol=1e-6)
    assert np.allclose(key.max(axis=0), dense.max(axis=0), atol=1e-6)


def test_a_turning_point_more_than_half_a_turn_into_the_arc_is_found():
    # a 300 deg arc in the x-y plane from 100 deg: x is greatest at 360 deg, 260 deg into it
    c, r = np.array([900.0, 50.0, 300.0]), 80.0
    circ = circle_through(*(on_circle(c, r, np.radians(a)) for a in (100.0, 250.0, 400.0)))
    f = circ.axis_extreme_fractions()
    assert np.min(np.abs(f - 260.0 / 300.0)) < 1e-9
    assert circ.point(f)[:, 0].max() == pytest.approx(c[0] + r, abs=1e-9)


def test_collinear_points_are_no_circle():
    with pytest.raises(InputError, match="use a MoveL"):
        circle_through([0, 0, 0], [1, 1, 1], [2, 2, 2.0000001])
    with pytest.raises(InputError):
        circle_through([0, 0, 0], [1, 0, 0], [0, 0, 0])


def test_movel_straight_line_and_slerp():
    T0 = make_pose(np.eye(3), [0.0, 0.0, 0.0])
    T1 = make_pose(rotation_about([0, 0, 1], np.radians(40.0)), [100.0, 20.0, -10.0])
    P = segment_poses(T0, T1, [0.0, 0.25, 1.0])
    assert np.allclose(P[0], T0) and np.allclose(P[2], T1)
    assert np.allclose(P[1][:3, 3], [25.0, 5.0, -2.5])
    assert rotation_error_deg(P[1], T0) == pytest.approx(10.0)


def test_movec_torch_turns_with_the_circle():
    # a torch tilted against the circle's tangent keeps its tilt all along the arc
    c, r = np.array([1000.0, 0.0, 200.0]), 60.0
    z = np.array([0.0, 0.0, 1.0])
    tilt = rotation_about([0, 1, 0], np.radians(15.0))

    def torch(ang):
        R_path = rotation_about(z, ang) @ np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0],
                                                   [0.0, 0.0, 1.0]])
        return make_pose(R_path @ tilt, on_circle(c, r, ang))

    T0, T1 = torch(0.0), torch(np.radians(120.0))
    via = on_circle(c, r, np.radians(35.0))  # anywhere on the arc
    for s in (0.1, 0.5, 0.9):
        assert np.allclose(segment_pose(T0, T1, s, via), torch(s * np.radians(120.0)),
                           atol=1e-9)


def test_movec_slerps_what_the_circle_does_not_turn():
    c, r = np.zeros(3), 40.0
    T0 = make_pose(np.eye(3), on_circle(c, r, 0.0))
    extra = rotation_about([1, 0, 0], np.radians(8.0))
    T1 = make_pose(rotation_about([0, 0, 1], np.pi / 2) @ extra, on_circle(c, r, np.pi / 2))
    P = segment_poses(T0, T1, np.linspace(0, 1, 5), on_circle(c, r, np.pi / 4))
    assert np.allclose(P[-1], T1, atol=1e-9)
    mid = rotation_about([0, 0, 1], np.pi / 4) @ rotation_about([1, 0, 0], np.radians(4.0))
    assert np.allclose(P[2][:3, :3], mid, atol=1e-9)


def test_rotvec_helpers_agree_with_each_other():
    rng = np.random.default_rng(3)
    rv = rng.normal(size=(20, 3))
    rv *= (rng.uniform(0.0, 3.0, 20) / np.linalg.norm(rv, axis=1))[:, None]
    M = rotvec_to_matrix(rv)
    assert np.allclose(M @ np.transpose(M, (0, 2, 1)), np.eye(3), atol=1e-12)
    back = np.array([matrix_to_rotvec(m) for m in M])
    assert np.allclose(back, rv, atol=1e-9)
