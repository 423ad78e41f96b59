import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from controller.errors import ConfigError, InputError
from controller.geometry.poses import make_pose
from controller.geometry.segment_motion import segment_poses
from controller.path.path_fit import PathTolerance, axis_spin_deg, fit_segments
from controller.path.weld_path import WeldParams, seam_normals, torch_poses

UP = np.array([0.0, 0.0, 1.0])
CENTRE = np.array([1000.0, 0.0, 300.0])


def dense_path(points):
    """The planner's torch poses (tangent-following, 10 deg push) along seam points (mm)."""
    pts = np.asarray(points, dtype=np.float64)
    return torch_poses(pts, seam_normals(pts, UP), WeldParams())


def arc_points(radius, start_deg, sweep_deg, step_mm=2.0, centre=CENTRE, sign=1.0):
    n = int(round(np.radians(abs(sweep_deg)) * radius / step_mm)) + 1
    a = np.radians(start_deg + sign * np.linspace(0.0, abs(sweep_deg), n))
    return centre + np.c_[radius * np.cos(a), radius * np.sin(a), np.zeros(n)]


def s_curve(amplitude=15.0, chord=180.0, step_mm=2.0, noise_mm=0.0, seed=0):
    x = np.linspace(-chord / 2, chord / 2, int(chord / step_mm) + 1)
    y = amplitude * np.sin(2 * np.pi * x / chord)
    pts = CENTRE + np.c_[x, y, np.zeros_like(x)]
    return pts + np.random.default_rng(seed).normal(0.0, noise_mm, pts.shape)


def to_polyline(points, poly):
    """Distance (mm) of each point to the polyline, the nearest chord and the fraction along it."""
    a, ab = poly[:-1], poly[1:] - poly[:-1]
    L2 = np.einsum("kj,kj->k", ab, ab)
    t = np.clip(np.einsum("mkj,kj->mk", points[:, None] - a[None], ab) /
                np.where(L2 > 0, L2, 1.0), 0, 1)
    d = np.linalg.norm(a[None] + t[..., None] * ab[None] - points[:, None], axis=2)
    k = d.argmin(axis=1)
    return d.min(axis=1), k, t[np.arange(len(points)), k]


def executed_deviation(dense, segments):
    """Independent check: the executed path sampled every 0.05 mm against the dense polyline (with
    its orientation slerped along each chord), and every dense point against the executed
    polyline (mm, torch axis deg, spin deg)."""
    D = np.asarray(dense)
    start = D[0]
    samples = []
    for seg in segments:
        n = max(2, int(np.linalg.norm(seg.T_end[:3, 3] - start[:3, 3]) / 0.05) + 2)
        samples.append(segment_poses(start, seg.T_end, np.linspace(0, 1, n), seg.via_mm))
        start = seg.T_end
    E = np.concatenate(samples)
    P = D[:, :3, 3]
    d, k, tk = to_polyline(E[:, :3, 3], P)
    R = Rotation.from_matrix(D[:, :3, :3])
    rel = (R[:-1].inv() * R[1:]).as_rotvec()
    planned = (R[k] * Rotation.from_rotvec(tk[:, None] * rel[k])).as_matrix()
    ax, sp = axis_spin_deg(E[:, :3, :3], planned)
    back = to_polyline(P, E[:, :3, 3])[0]
    return max(d.max(), back.max()), ax.max(), sp.max()


def test_straight_seam_is_one_movel():
    pts = CENTRE + np.c_[np.linspace(-90, 90, 91), np.zeros(91), np.zeros(91)]
    segs = fit_segments(dense_path(pts))
    assert [s.kind for s in segs] == ["MoveL"]
    assert (segs[0].first, segs[0].last) == (0, 90)


def test_circular_seam_is_one_movec_within_tolerance():
    dense = dense_path(arc_points(80.0, -30.0, 100.0))
    segs = fit_segments(dense)
    assert [s.kind for s in segs] == ["MoveC"]
    assert np.allclose(segs[0].T_end, dense[-1])
    tol = PathTolerance()
    assert tol.admits(executed_deviation(dense, segs))


def test_two_arcs_bending_opposite_ways_are_two_movec():
    a1 = arc_points(60.0, -90.0, 60.0)
    end = a1[-1]
    # the second arc continues tangentially, bending the other way
    d = end - CENTRE
    c2 = CENTRE + 2 * d
    a2 = arc_points(60.0, np.degrees(np.arctan2(-d[1], -d[0])), 60.0, centre=c2, sign=-1.0)
    dense = dense_path(np.vstack([a1, a2[1:]]))
    segs = fit_segments(dense)
    # the planner's tangent blends the two arcs' orientations over its span at the inflection:
    # at most one short piece between the two circles
    assert [s.kind for s in segs][0] == [s.kind for s in segs][-1] == "MoveC"
    assert len(segs) <= 3
    assert PathTolerance().admits(executed_deviation(dense, segs))


def test_corner_is_two_movel_split_at_the_corner():
    leg1 = CENTRE + np.c_[np.linspace(0, 60, 31), np.zeros(31), np.zeros(31)]
    leg2 = leg1[-1] + np.c_[np.zeros(30), np.linspace(2, 60, 30), np.zeros(30)]
    pts = np.vstack([leg1, leg2])
    # constant orientation (a corner seam welded without turning the torch)
    dense = [make_pose(np.diag([1.0, -1.0, -1.0]), p) for p in pts]
    segs = fit_segments(dense)
    assert [(s.kind, s.first, s.last) for s in segs] == [("MoveL", 0, 30), ("MoveL", 30, 60)]


@pytest.mark.parametrize("noise_mm", [0.0, 0.01])
def test_s_curve_few_segments_all_within_tolerance(noise_mm):
    dense = dense_path(s_curve(noise_mm=noise_mm, seed=4))
    tol = PathTolerance()
    segs = fit_segments(dense, tol)
    assert len(segs) <= 12  # 90 dense points
    for s in segs:
        assert tol.admits(s.deviation)
    assert tol.admits(executed_deviation(dense, segs))
    # a tighter tolerance costs segments but is still met
    tight = PathTolerance(0.02, 0.1, 0.1)
    segs_tight = fit_segments(dense, tight)
    assert len(segs_tight) > len(segs)
    assert tight.admits(executed_deviation(dense, segs_tight))


def test_tolerance_refuses_nonsense_and_short_paths():
    for bad in ({"position_mm": 0.0}, {"orientation_deg": -1.0}, {"spin_deg": float("nan")}):
        with pytest.raises(ConfigError, match="path tolerance"):
            PathTolerance(**bad)
    with pytest.raises(InputError):
        fit_segments([make_pose()])
