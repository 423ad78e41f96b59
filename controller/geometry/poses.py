"""Rigid transforms as 4x4 homogeneous numpy arrays, named ``T_a_b``.

``T_a_b`` is the pose of frame b expressed in frame a: it maps coordinates in b to coordinates in a,
so adjacent subscripts cancel (``T_base_cam = T_base_flange @ T_flange_cam``). Translations are in
millimetres, angles in radians unless a name says ``_deg``.

Quaternions are written w, x, y, z everywhere (files, protocol, CLI), as ABB RAPID does. The
quaternion <-> matrix conversions are numpy here (scipy's algorithm, so that a command that prints
a pose does not pay for importing scipy.spatial); scipy (x, y, z, w) is imported only by the
functions that need its ``Rotation`` (slerp, rotation vectors) and converts inside them.
Pinocchio ``SE3`` conversion lives in :mod:`controller.geometry.kinematics`, the one place that sees
Pinocchio's metres.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from controller.errors import InputError

Pose = NDArray[np.float64]

#: A quaternion whose norm is further than this from 1 is refused rather than normalised.
QUAT_NORM_TOLERANCE = 1e-3
_ORTHO_TOLERANCE = 1e-6


def _as_vector(value: ArrayLike, length: int, name: str) -> NDArray[np.float64]:
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise InputError(f"{name} must be {length} numbers, got {value!r}") from err
    if arr.shape != (length,):
        raise InputError(f"{name} must be {length} numbers, got shape {arr.shape}: {value!r}")
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{name} must be finite numbers, got {value!r}")
    return arr


def canonical_quat_wxyz(q_wxyz: ArrayLike) -> NDArray[np.float64]:
    """Return the unit quaternion (w, x, y, z) with the canonical sign: w > 0.

    When w is 0 the first non-zero of x, y, z is made positive, so that a rotation has exactly one
    written form (q and -q are the same rotation).
    """
    q = np.asarray(q_wxyz, dtype=np.float64)
    q = q / np.linalg.norm(q)
    for c in q:
        if abs(c) > 1e-12:
            return q if c > 0 else -q
    return q


def check_quat_wxyz(q_wxyz: ArrayLike, name: str = "quaternion_wxyz") -> NDArray[np.float64]:
    """Validate a written quaternion (w, x, y, z) and return it normalised and canonical.

    Raises :class:`InputError` naming ``name`` when it is not 4 finite numbers or its norm is
    further than :data:`QUAT_NORM_TOLERANCE` from 1 (a typo, not rounding).
    """
    q = _as_vector(q_wxyz, 4, name)
    norm = float(np.linalg.norm(q))
    if abs(norm - 1.0) > QUAT_NORM_TOLERANCE:
        raise InputError(
            f"{name} {list(q)} is not a rotation: its norm is {norm:.6f}, it must be 1 "
            f"(within {QUAT_NORM_TOLERANCE}); give w, x, y, z of a unit quaternion",
            value=list(q),
        )
    return canonical_quat_wxyz(q)


def quat_wxyz_to_matrix(q_wxyz: ArrayLike) -> NDArray[np.float64]:
    """3x3 rotation matrix from a unit quaternion written (w, x, y, z) (normalised first)."""
    q = np.asarray(q_wxyz, dtype=np.float64)
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([
        [w * w + x * x - y * y - z * z, 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), w * w - x * x + y * y - z * z, 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), w * w - x * x - y * y + z * z]])


def matrix_to_quat_wxyz(R: ArrayLike) -> NDArray[np.float64]:
    """Canonical unit quaternion (w, x, y, z) of a 3x3 rotation matrix.

    As scipy's ``Rotation.from_matrix``: a matrix that is not orthogonal (to 1e-12) is replaced by
    the nearest orthogonal one (SVD); a non-positive determinant raises :class:`InputError`.
    """
    m = np.asarray(R, dtype=np.float64)
    if m.shape != (3, 3) or not np.all(np.isfinite(m)) or np.linalg.det(m) <= 0:
        raise InputError(f"not a rotation matrix (3x3, finite, determinant > 0): {m.tolist()}")
    if not np.allclose(m @ m.T, np.eye(3), rtol=0.0, atol=1e-12):
        U, _, Vt = np.linalg.svd(m)
        m = U @ Vt
    # Shepperd's method: build the quaternion from its largest component.
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    decision = [m[0, 0], m[1, 1], m[2, 2], trace]
    i = int(np.argmax(decision))
    xyzw = np.empty(4)
    if i == 3:
        xyzw[:] = (m[2, 1] - m[1, 2], m[0, 2] - m[2, 0], m[1, 0] - m[0, 1], 1 + trace)
    else:
        j, k = (i + 1) % 3, (i + 2) % 3
        xyzw[i] = 1 - trace + 2 * m[i, i]
        xyzw[j] = m[j, i] + m[i, j]
        xyzw[k] = m[k, i] + m[i, k]
        xyzw[3] = m[k, j] - m[j, k]
    x, y, z, w = xyzw / np.linalg.norm(xyzw)
    return canonical_quat_wxyz([w, x, y, z])


def make_pose(R: ArrayLike | None = None, t_mm: ArrayLike | None = None) -> Pose:
    """4x4 pose from a 3x3 rotation (default identity) and a translation in mm (default zero)."""
    T = np.eye(4)
    if R is not None:
        T[:3, :3] = np.asarray(R, dtype=np.float64)
    if t_mm is not None:
        T[:3, 3] = np.asarray(t_mm, dtype=np.float64)
    return T


def check_pose(T: ArrayLike, name: str = "pose") -> Pose:
    """Validate a 4x4 homogeneous transform and return it as float64.

    Raises :class:`InputError` naming ``name`` if the shape is wrong, a value is not finite, the
    last row is not (0, 0, 0, 1) or the rotation block is not a proper rotation.
    """
    arr = np.asarray(T, dtype=np.float64)
    if arr.shape != (4, 4):
        raise InputError(f"{name} must be a 4x4 transform, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{name} holds non-finite values")
    if not np.allclose(arr[3], [0, 0, 0, 1], atol=_ORTHO_TOLERANCE):
        raise InputError(f"{name} last row must be 0 0 0 1, got {arr[3].tolist()}")
    R = arr[:3, :3]
    if not np.allclose(R.T @ R, np.eye(3), atol=_ORTHO_TOLERANCE) or np.linalg.det(R) < 0:
        raise InputError(f"{name} rotation block is not a proper rotation matrix")
    return arr


def invert(T: ArrayLike) -> Pose:
    """Inverse of a rigid transform: ``invert(T_a_b) == T_b_a``, exact for rotations."""
    T = np.asarray(T, dtype=np.float64)
    R = T[:3, :3]
    out = np.eye(4)
    out[:3, :3] = R.T
    out[:3, 3] = -R.T @ T[:3, 3]
    return out


def compose(*poses: ArrayLike) -> Pose:
    """Product of transforms left to right: ``compose(T_a_b, T_b_c) == T_a_c``."""
    out = np.eye(4)
    for T in poses:
        out = out @ np.asarray(T, dtype=np.float64)
    return out


def transform_points(T_a_b: ArrayLike, points_b: ArrayLike) -> NDArray[np.float64]:
    """Map (N, 3) points from frame b to frame a (mm)."""
    T = np.asarray(T_a_b, dtype=np.float64)
    P = np.asarray(points_b, dtype=np.float64).reshape(-1, 3)
    return P @ T[:3, :3].T + T[:3, 3]


def interpolate(T0: ArrayLike, T1: ArrayLike, s: float) -> Pose:
    """Pose at fraction ``s`` in [0, 1] between T0 and T1: linear position, slerp rotation."""
    from scipy.spatial.transform import Rotation, Slerp

    A = np.asarray(T0, dtype=np.float64)
    B = np.asarray(T1, dtype=np.float64)
    slerp = Slerp([0.0, 1.0], Rotation.from_matrix(np.stack([A[:3, :3], B[:3, :3]])))
    return make_pose(slerp([s]).as_matrix()[0], (1.0 - s) * A[:3, 3] + s * B[:3, 3])


def pose_from_pos_quat(position_mm: ArrayLike, quaternion_wxyz: ArrayLike,
                       name: str = "pose") -> Pose:
    """Pose from an ABB robtarget/tooldata style position (mm) and quaternion (w, x, y, z).

    Both inputs are validated; errors name ``name``.
    """
    p = _as_vector(position_mm, 3, f"{name}.position_mm")
    q = check_quat_wxyz(quaternion_wxyz, f"{name}.quaternion_wxyz")
    return make_pose(quat_wxyz_to_matrix(q), p)


def pos_quat_from_pose(T: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(position_mm, canonical quaternion_wxyz) of a pose, the ABB robtarget way."""
    A = np.asarray(T, dtype=np.float64)
    return A[:3, 3].copy(), matrix_to_quat_wxyz(A[:3, :3])


def pose_to_dict(T: ArrayLike, decimals: int = 6) -> dict[str, list[float]]:
    """JSON-ready ``{"position_mm": [...], "quaternion_wxyz": [...]}`` as in DESIGN.md."""
    p, q = pos_quat_from_pose(T)
    return {"position_mm": [round(float(v), decimals) for v in p],
            "quaternion_wxyz": [round(float(v), 9) for v in q]}


def pose_from_dict(d: object, name: str = "pose") -> Pose:
    """Inverse of :func:`pose_to_dict`; raises :class:`InputError` naming ``name`` if malformed."""
    if not isinstance(d, dict) or "position_mm" not in d or "quaternion_wxyz" not in d:
        raise InputError(
            f"{name} must be an object with position_mm and quaternion_wxyz, got {d!r}")
    return pose_from_pos_quat(d["position_mm"], d["quaternion_wxyz"], name)


def pose_from_rvec_tvec(rvec: ArrayLike, tvec_mm: ArrayLike) -> Pose:
    """Pose from an OpenCV Rodrigues vector (rad) and translation (mm), as solvePnP returns them.

    solvePnP returns ``T_cam_object``: the object frame expressed in the camera frame.
    """
    from scipy.spatial.transform import Rotation

    r = np.asarray(rvec, dtype=np.float64).reshape(3)
    return make_pose(Rotation.from_rotvec(r).as_matrix(), np.asarray(tvec_mm, float).reshape(3))


def pose_to_rvec_tvec(T: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(rvec, tvec_mm) in OpenCV's convention, inverse of :func:`pose_from_rvec_tvec`."""
    from scipy.spatial.transform import Rotation

    A = np.asarray(T, dtype=np.float64)
    return Rotation.from_matrix(A[:3, :3]).as_rotvec(), A[:3, 3].copy()


def rotation_about(axis: Sequence[float], angle: float) -> NDArray[np.float64]:
    """3x3 rotation of ``angle`` (rad) about a unit ``axis``."""
    a = np.asarray(axis, dtype=np.float64)
    a = a / np.linalg.norm(a)
    return quat_wxyz_to_matrix([np.cos(angle / 2), *(np.sin(angle / 2) * a)])


def translation_error_mm(Ta: ArrayLike, Tb: ArrayLike) -> float:
    """Distance between the origins of two poses (mm)."""
    return float(np.linalg.norm(np.asarray(Ta)[:3, 3] - np.asarray(Tb)[:3, 3]))


def rotation_error_deg(Ta: ArrayLike, Tb: ArrayLike) -> float:
    """Angle of the relative rotation between two poses (degrees, in [0, 180])."""
    Ra = np.asarray(Ta, dtype=np.float64)[:3, :3]
    Rb = np.asarray(Tb, dtype=np.float64)[:3, :3]
    q = matrix_to_quat_wxyz(Ra.T @ Rb)
    return float(np.degrees(2 * np.arctan2(np.linalg.norm(q[1:]), abs(q[0]))))


def pose_error(Ta: ArrayLike, Tb: ArrayLike) -> tuple[float, float]:
    """(translation error mm, rotation error deg) between two poses."""
    return translation_error_mm(Ta, Tb), rotation_error_deg(Ta, Tb)


def look_at(eye_mm: ArrayLike, target_mm: ArrayLike, up: ArrayLike = (0.0, 0.0, 1.0)) -> Pose:
    """Camera pose ``T_base_cam`` (OpenCV optical frame) at ``eye_mm`` looking at ``target_mm``.

    The image's "up" (minus the camera y axis) points as close to ``up`` as possible. Raises
    :class:`InputError` when ``up`` is parallel to the viewing direction.
    """
    eye = np.asarray(eye_mm, dtype=np.float64)
    z = np.asarray(target_mm, dtype=np.float64) - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, np.asarray(up, dtype=np.float64))
    if np.linalg.norm(x) < 1e-9:
        raise InputError(f"look_at: up {list(np.asarray(up))} is parallel to the view direction")
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return make_pose(np.column_stack([x, y, z]), eye)
