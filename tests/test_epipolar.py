import numpy as np

from controller.geometry.poses import look_at
from controller.stereo.epipolar import (
    epipolar_lines,
    match_curves,
    point_on_polyline,
    relative_pose,
)


def setup():
    c = np.array([0.0, 0, 0])
    T1 = look_at([-100, 0, 300], c, up=(1, 0, 0))
    T2 = look_at([100, 0, 300], c, up=(1, 0, 0))
    return T1, T2


def normalized(P, T):
    Pc = (P - T[:3, 3]) @ T[:3, :3]
    return Pc[:, :2] / Pc[:, 2:]


def test_epipolar_line_passes_through_the_true_match():
    T1, T2 = setup()
    P = np.random.default_rng(0).uniform(-50, 50, (20, 3))
    x1, x2 = normalized(P, T1), normalized(P, T2)
    lines = epipolar_lines(x1, relative_pose(T1, T2))
    d = np.einsum("ij,ij->i", lines, np.column_stack([x2, np.ones(20)]))
    assert np.max(np.abs(d)) < 1e-12


def test_multiple_crossings_keep_the_continuous_one():
    T1, T2 = setup()
    # a hook: the seam runs across the baseline, then curls back so that the epipolar lines of
    # its straight part cross the hook again
    s = np.linspace(0, 1, 600)
    straight = np.column_stack([-60 + 0 * s[:400], np.linspace(-80, 40, 400), 0 * s[:400]])
    a = np.linspace(0, 1.2 * np.pi, 200)
    hook = np.column_stack([-60 + 30 - 30 * np.cos(a), 40 + 30 * np.sin(a), 0 * a])
    P = np.vstack([straight, hook[1:]])
    x1, x2 = normalized(P, T1), normalized(P, T2)
    m = match_curves(x1, x2, relative_pose(T1, T2))
    assert m.ambiguous.any()
    good = np.isfinite(m.t) & ~m.degenerate
    assert good.mean() > 0.8
    assert np.allclose(point_on_polyline(x2, m.t[good]), x2[good], atol=1e-6)
