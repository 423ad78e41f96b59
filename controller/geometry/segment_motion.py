"""How a controller moves the TCP along one ``MoveL`` or ``MoveC`` segment, as pure functions.

One model, used by the path fitter (to check a segment against the planned path), by the mock
controller's simulated arm (to execute it) and by anything that must predict what the robot does
between two sent targets. Poses are ``T_base_tcp`` (mm); ``s`` is the fraction of the segment in
[0, 1], which is also the fraction of its duration at constant TCP speed.

* ``MoveL`` from ``T0`` to ``T1``: the TCP position moves on the straight line, the orientation
  turns about one fixed axis at a constant rate (quaternion slerp), as ABB's MoveL does.
* ``MoveC`` from ``T0`` through the circle point ``via_mm`` to ``T1``: the position moves on the
  circle through the three points, at a constant angular rate, from ``T0`` to ``T1`` the way that
  passes ``via_mm``. The orientation turns *with the path*: the tool keeps its orientation relative
  to the circle's path frame (tangent, radius, normal) and the rest of the change from ``T0`` to
  ``T1`` in that frame is slerped, so a torch that keeps its angles to a circular seam needs no
  orientation in the circle point. This is ABB's default circle reorientation (``CirPathMode
  PathFrame`` on RobotWare 5 and later); the circle point's own orientation is not used.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from controller.errors import InputError
from controller.geometry.poses import Pose, make_pose

F64 = NDArray[np.float64]

#: Three points closer to a line than this (mm, the circle point's distance from the chord) do
#: not define a circle: send a MoveL instead.
MIN_ARC_HEIGHT_MM = 1e-3


def rotvec_to_matrix(rv: ArrayLike) -> F64:
    """Rotation matrices (N, 3, 3) of rotation vectors (N, 3) (axis times angle, rad): Rodrigues.

    Plain numpy for the fitter's inner loop (scipy's ``Rotation`` costs ~50 us a call).
    """
    v = np.atleast_2d(np.asarray(rv, dtype=np.float64))
    th = np.linalg.norm(v, axis=1)
    small = th < 1e-12
    k = v / np.where(small, 1.0, th)[:, None]
    K = np.zeros((len(v), 3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -k[:, 2], k[:, 1], -k[:, 0]
    K[:, 1, 0], K[:, 2, 0], K[:, 2, 1] = k[:, 2], -k[:, 1], k[:, 0]
    s, c = np.sin(th)[:, None, None], (1.0 - np.cos(th))[:, None, None]
    return np.asarray(np.eye(3)[None] + s * K + c * (K @ K), dtype=np.float64)


def matrix_to_rotvec(R: ArrayLike) -> F64:
    """Rotation vector (3,) of one rotation matrix (angle in [0, pi], rad)."""
    M = np.asarray(R, dtype=np.float64)
    c = (np.trace(M) - 1.0) / 2.0
    if c < -0.99:  # near a half turn the skew part vanishes: leave it to scipy
        return np.asarray(Rotation.from_matrix(M).as_rotvec(), dtype=np.float64)
    th = float(np.arccos(min(1.0, c)))
    w = np.array([M[2, 1] - M[1, 2], M[0, 2] - M[2, 0], M[1, 0] - M[0, 1]])
    if th < 1e-9:
        return 0.5 * w
    return np.asarray(w * (th / (2.0 * np.sin(th))), dtype=np.float64)


def cross3(a: F64, b: F64) -> F64:
    """Cross product of two 3-vectors (``np.cross`` costs ~10 us of axis handling a call)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                     a[0] * b[1] - a[1] * b[0]])


@dataclass(frozen=True)
class Circle:
    """The arc from ``start`` through a circle point to the end.

    Centre and radius (mm), unit ``normal`` (right-handed with the direction of travel) and the
    swept angle ``sweep_rad`` in (0, 2 pi).
    """

    centre: F64
    radius_mm: float
    normal: F64
    sweep_rad: float
    start: F64

    def point(self, s: ArrayLike) -> F64:
        """Positions (mm, base) at fractions ``s`` (scalar or (N,)) of the arc: shape (N, 3)."""
        ss = np.atleast_1d(np.asarray(s, dtype=np.float64))
        u = self.start - self.centre
        v = cross3(self.normal, u)
        a = ss * self.sweep_rad
        return np.asarray(self.centre + np.cos(a)[:, None] * u + np.sin(a)[:, None] * v,
                          dtype=np.float64)

    def axis_extreme_fractions(self) -> F64:
        """Fractions (0..1, sorted) inside the arc where a base coordinate is at a turning point.

        Along the arc, coordinate k is ``c_k + u_k cos a + v_k sin a``: extreme at
        ``a = atan2(v_k, u_k)`` (its maximum) and that plus pi (its minimum), wherever those fall
        within the sweep. With the arc's two ends they bound the arc exactly: the box that holds
        these points holds the whole arc (a sample of the arc may miss its bulge).
        """
        u = self.start - self.centre
        v = cross3(self.normal, u)
        top = np.arctan2(v, u)
        angles = np.concatenate([top, top + np.pi]) % (2.0 * np.pi)
        inside = angles[angles <= self.sweep_rad]
        return np.asarray(np.sort(inside / self.sweep_rad), dtype=np.float64)

    def fraction_of(self, points_mm: ArrayLike) -> F64:
        """Fraction (0..1, clipped) of the arc nearest to each point (N, 3).

        That is its angle from the start about the centre, in the circle's plane.
        """
        p = np.atleast_2d(np.asarray(points_mm, dtype=np.float64)) - self.centre
        u = self.start - self.centre
        u = u / np.linalg.norm(u)
        v = cross3(self.normal, u)
        ang = np.arctan2(p @ v, p @ u) % (2.0 * np.pi)
        # an angle past the end is nearer the end or the start: pick by the angular distance
        past = ang > self.sweep_rad
        to_start = 2.0 * np.pi - ang
        to_end = ang - self.sweep_rad
        frac = ang / self.sweep_rad
        frac[past & (to_end <= to_start)] = 1.0
        frac[past & (to_end > to_start)] = 0.0
        return np.asarray(frac, dtype=np.float64)


def circle_through(p0: ArrayLike, via: ArrayLike, p1: ArrayLike) -> Circle:
    """The arc from ``p0`` through ``via`` to ``p1`` (mm).

    Raises :class:`InputError` when the three points are (nearly) on one line or two coincide:
    no circle is defined by them and the motion must be a MoveL.
    """
    a, b, c = (np.asarray(x, dtype=np.float64).reshape(3) for x in (p0, via, p1))
    ab, ac = b - a, c - a
    n = cross3(ab, ac)
    nn = float(np.linalg.norm(n))
    chord = float(np.linalg.norm(ac))
    if chord < 1e-9 or nn / max(chord, 1e-12) < MIN_ARC_HEIGHT_MM:
        raise InputError(f"the circle point {b.tolist()} is on the line from {a.tolist()} to "
                         f"{c.tolist()} (or two points coincide): no circle; use a MoveL")
    # circumcentre of the triangle
    centre = a + (np.dot(ac, ac) * cross3(n, ab) + np.dot(ab, ab) * cross3(ac, n)) / (
        2.0 * nn * nn)
    normal = n / nn  # a -> b -> c turns positively about n
    u = a - centre
    w = c - centre
    sweep = float(np.arctan2(np.dot(cross3(u, w), normal), np.dot(u, w))) % (2.0 * np.pi)
    return Circle(centre=centre, radius_mm=float(np.linalg.norm(u)), normal=normal,
                  sweep_rad=sweep, start=a)


def _rotations(T0: ArrayLike, T1: ArrayLike, s: F64, circle: Circle | None) -> F64:
    R0 = np.asarray(T0, dtype=np.float64)[:3, :3]
    R1 = np.asarray(T1, dtype=np.float64)[:3, :3]
    if circle is None:
        rest = matrix_to_rotvec(R0.T @ R1)
        return np.asarray(R0[None] @ rotvec_to_matrix(s[:, None] * rest[None, :]))
    turn = circle.sweep_rad * circle.normal
    A1 = rotvec_to_matrix(turn)[0]
    rest = matrix_to_rotvec(R0.T @ A1.T @ R1)
    A = rotvec_to_matrix(s[:, None] * turn[None, :])
    return np.asarray(A @ R0[None] @ rotvec_to_matrix(s[:, None] * rest[None, :]))


def segment_poses(T0: ArrayLike, T1: ArrayLike, s: ArrayLike, via_mm: ArrayLike | None = None,
                  circle: Circle | None = None) -> F64:
    """TCP poses (N, 4, 4) at fractions ``s`` of the segment from ``T0`` to ``T1``.

    ``via_mm`` None is a MoveL, else the MoveC circle point (its orientation is not used);
    ``circle`` is its :func:`circle_through` when already known. Raises :class:`InputError` for a
    circle point on the line (see :func:`circle_through`).
    """
    ss = np.clip(np.atleast_1d(np.asarray(s, dtype=np.float64)), 0.0, 1.0)
    A = np.asarray(T0, dtype=np.float64)
    B = np.asarray(T1, dtype=np.float64)
    if via_mm is not None and circle is None:
        circle = circle_through(A[:3, 3], via_mm, B[:3, 3])
    if via_mm is None:
        circle = None
        pos = (1.0 - ss)[:, None] * A[:3, 3] + ss[:, None] * B[:3, 3]
    else:
        assert circle is not None
        pos = circle.point(ss)
    rot = _rotations(A, B, ss, circle)
    out = np.zeros((len(ss), 4, 4))
    out[:, 3, 3] = 1.0
    out[:, :3, :3] = rot
    out[:, :3, 3] = pos
    return out


def segment_pose(T0: ArrayLike, T1: ArrayLike, s: float, via_mm: ArrayLike | None = None) -> Pose:
    """One TCP pose at fraction ``s`` of the segment (see :func:`segment_poses`)."""
    P = segment_poses(T0, T1, [s], via_mm)[0]
    return make_pose(P[:3, :3], P[:3, 3])


def segment_length_mm(T0: ArrayLike, T1: ArrayLike, via_mm: ArrayLike | None = None) -> float:
    """Length (mm) of the TCP's path along the segment: the chord, or the arc."""
    a = np.asarray(T0, dtype=np.float64)[:3, 3]
    b = np.asarray(T1, dtype=np.float64)[:3, 3]
    if via_mm is None:
        return float(np.linalg.norm(b - a))
    c = circle_through(a, via_mm, b)
    return c.radius_mm * c.sweep_rad
