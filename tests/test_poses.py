import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from controller.errors import InputError
from controller.geometry.poses import (
    canonical_quat_wxyz,
    check_pose,
    check_quat_wxyz,
    compose,
    interpolate,
    invert,
    make_pose,
    matrix_to_quat_wxyz,
    pos_quat_from_pose,
    pose_error,
    pose_from_dict,
    pose_from_pos_quat,
    pose_from_rvec_tvec,
    pose_to_dict,
    pose_to_rvec_tvec,
    quat_wxyz_to_matrix,
    rotation_error_deg,
    transform_points,
)

finite = st.floats(-2000, 2000, allow_nan=False)
unit = st.floats(-1, 1, allow_nan=False)


@st.composite
def poses(draw):
    q = np.array([draw(unit) for _ in range(4)])
    if np.linalg.norm(q) < 1e-3:
        q = np.array([1.0, 0, 0, 0])
    q = q / np.linalg.norm(q)
    t = np.array([draw(finite) for _ in range(3)])
    return make_pose(quat_wxyz_to_matrix(q), t)


@given(poses())
def test_inverse_composes_to_identity(T):
    assert np.allclose(compose(T, invert(T)), np.eye(4), atol=1e-9)
    assert np.allclose(compose(invert(T), T), np.eye(4), atol=1e-9)


@given(poses(), poses(), poses())
def test_composition_is_associative_and_maps_points(A, B, C):
    assert np.allclose(compose(compose(A, B), C), compose(A, compose(B, C)), atol=1e-6)
    p = np.array([[1.0, 2.0, 3.0], [-50.0, 10.0, 400.0]])
    assert np.allclose(transform_points(compose(A, B), p),
                       transform_points(A, transform_points(B, p)), atol=1e-6)


@given(poses())
def test_pos_quat_round_trip_and_canonical_sign(T):
    p, q = pos_quat_from_pose(T)
    assert q[0] >= -1e-12  # w is only "zero" to rounding at 180 deg turns
    assert abs(np.linalg.norm(q) - 1) < 1e-12
    back = pose_from_pos_quat(p, q)
    assert np.allclose(back, T, atol=1e-9)
    # -q is the same rotation and must give the same written form
    assert np.allclose(canonical_quat_wxyz(-q), q)


@given(poses())
def test_rapid_dict_round_trip(T):
    back = pose_from_dict(pose_to_dict(T))
    d_mm, d_deg = pose_error(back, T)
    assert d_mm < 1e-5 and d_deg < 1e-6


@given(poses())
def test_rvec_tvec_round_trip(T):
    r, t = pose_to_rvec_tvec(T)
    assert np.allclose(pose_from_rvec_tvec(r, t), T, atol=1e-9)


def test_quaternion_order_is_wxyz_against_scipy():
    # 90 deg about z: scipy writes (0, 0, s, c) in x, y, z, w order
    R = Rotation.from_euler("z", 90, degrees=True).as_matrix()
    q = matrix_to_quat_wxyz(R)
    assert np.allclose(q, [np.sqrt(0.5), 0, 0, np.sqrt(0.5)])


def test_interpolate_endpoints_and_midpoint():
    A = make_pose(np.eye(3), [0, 0, 0])
    B = make_pose(Rotation.from_euler("x", 90, degrees=True).as_matrix(), [10, 20, 30])
    assert np.allclose(interpolate(A, B, 0.0), A)
    assert np.allclose(interpolate(A, B, 1.0), B)
    M = interpolate(A, B, 0.5)
    assert np.allclose(M[:3, 3], [5, 10, 15])
    assert abs(rotation_error_deg(A, M) - 45) < 1e-9


@pytest.mark.parametrize("q", [[1, 1, 0, 0], [0, 0, 0, 0], [0.5, 0.5, 0.5, 0.4]])
def test_non_unit_quaternion_refused(q):
    with pytest.raises(InputError, match="quaternion"):
        check_quat_wxyz(q, "view.quaternion_wxyz")


def test_nearly_unit_quaternion_is_normalised():
    q = check_quat_wxyz([0.70711, 0, 0.70711, 0])
    assert abs(np.linalg.norm(q) - 1) < 1e-12


@pytest.mark.parametrize("bad", [np.eye(3), np.diag([1, 1, -1, 1.0]), np.full((4, 4), np.nan)])
def test_check_pose_rejects_non_rigid(bad):
    with pytest.raises(InputError, match="T_test"):
        check_pose(bad, "T_test")


def test_pose_from_dict_names_the_input():
    with pytest.raises(InputError, match="flange_pose"):
        pose_from_dict({"position_mm": [1, 2]}, "flange_pose")
    with pytest.raises(InputError, match="flange_pose.position_mm"):
        pose_from_dict({"position_mm": [1, 2], "quaternion_wxyz": [1, 0, 0, 0]}, "flange_pose")


def test_quaternion_conversions_are_scipys():
    """poses converts with numpy (no scipy import on the CLI's path); the numbers are scipy's."""
    from scipy.spatial.transform import Rotation

    from controller.geometry.poses import (
        canonical_quat_wxyz,
        matrix_to_quat_wxyz,
        quat_wxyz_to_matrix,
        rotation_about,
        rotation_error_deg,
    )

    rng = np.random.default_rng(11)
    qs = list(rng.normal(size=(500, 4))) + [np.array(v, float) for v in
                                            ([1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 0, 1],
                                             [0.7071, 0, 0.7071, 0], [1e-9, 1, 1e-9, 0])]
    for q in qs:
        q = q / np.linalg.norm(q)
        R = Rotation.from_quat([q[1], q[2], q[3], q[0]]).as_matrix()
        assert np.allclose(quat_wxyz_to_matrix(q), R, rtol=0, atol=1e-15)
        x, y, z, w = Rotation.from_matrix(R).as_quat()
        assert np.allclose(matrix_to_quat_wxyz(R), canonical_quat_wxyz([w, x, y, z]), atol=1e-15)
        noisy = R + 1e-8 * rng.normal(size=(3, 3))  # not orthogonal: projected, as scipy does
        x, y, z, w = Rotation.from_matrix(noisy).as_quat()
        assert np.allclose(matrix_to_quat_wxyz(noisy), canonical_quat_wxyz([w, x, y, z]),
                           atol=1e-15)
    axis, ang = np.array([0.3, -1.0, 2.0]), 2.5
    ref = Rotation.from_rotvec(axis / np.linalg.norm(axis) * ang).as_matrix()
    assert np.allclose(rotation_about(axis, ang), ref, atol=1e-15)
    Ta, Tb = np.eye(4), np.eye(4)
    Tb[:3, :3] = ref
    assert abs(rotation_error_deg(Ta, Tb) - np.degrees(ang)) < 1e-12
    with pytest.raises(InputError):
        matrix_to_quat_wxyz(-np.eye(3))
