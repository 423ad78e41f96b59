"""The planned dense weld path as the fewest ``MoveL`` / ``MoveC`` segments within a tolerance.

The planner (:mod:`controller.path.weld_path`) makes a torch pose every ~2 mm. Sending each one
costs two lines on a 9600-baud link; the controller can interpolate lines and circles itself.
:func:`fit_segments` chooses segment ends among the dense poses so that the motion the controller
makes between them (:mod:`controller.geometry.segment_motion`: straight line with slerped
orientation, or a circle with the orientation turning with the path) stays within
:class:`PathTolerance` of the planned path, each segment as long as it can be (a MoveL where a line
fits, a MoveC where only a circle does).

Deviation of a segment from the planned path (both ways, so neither a bulge between two dense
points nor a dense point the segment passes by is missed): every dense point to the nearest point
of the segment (position, and orientation there), and the segment a quarter, half and three
quarters of the way between the dense points to the planned polyline's chord (position, and the
chord's slerped orientation there). Frames: every pose is ``T_base_tcp`` (mm).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from controller.errors import ConfigError, InputError
from controller.geometry.segment_motion import (
    Circle,
    circle_through,
    cross3,
    matrix_to_rotvec,
    rotvec_to_matrix,
    segment_poses,
)

F64 = NDArray[np.float64]

#: Largest arc one MoveC may sweep (deg); ABB allows up to 240, a torch has no use for more.
MAX_SWEEP_DEG = 180.0
#: Ends tried past the farthest one bisection found (noise makes the fit not strictly monotone).
_LOOK_PAST = 1


@dataclass(frozen=True)
class PathTolerance:
    """How far the controller's motion may leave the planned path.

    ``position_mm``: the torch tip. ``orientation_deg``: the torch axis (TCP z), which sets the
    work and travel angles. ``spin_deg``: the turn about the torch axis, which a round torch does
    not see (it only turns axis 6 a little); set it equal to ``orientation_deg`` to hold the whole
    orientation that tightly (about twice the segments on a curved seam).
    """

    position_mm: float = 0.05
    orientation_deg: float = 0.2
    spin_deg: float = 2.0

    def __post_init__(self) -> None:
        for name, lo, hi, unit in (("position_mm", 0.001, 5.0, "mm"),
                                   ("orientation_deg", 0.001, 10.0, "deg"),
                                   ("spin_deg", 0.001, 30.0, "deg")):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and np.isfinite(v) and lo <= v <= hi):
                raise ConfigError(f"path tolerance {name} = {v!r} must be in [{lo}, {hi}] {unit}")

    def admits(self, dev: tuple[float, float, float]) -> bool:
        """True when a deviation (mm, axis deg, spin deg) is within the tolerance."""
        return (dev[0] <= self.position_mm and dev[1] <= self.orientation_deg
                and dev[2] <= self.spin_deg)


@dataclass(frozen=True)
class Segment:
    """One motion to ``T_end`` (``T_base_tcp``, mm): a MoveL, or a MoveC through ``via_mm``.

    ``first`` and ``last`` are the dense indices it runs between (its end is dense pose ``last``);
    ``deviation`` its largest distance from the planned path: (mm, torch axis deg, spin deg).
    """

    T_end: F64
    via_mm: F64 | None
    first: int
    last: int
    deviation: tuple[float, float, float]

    @property
    def kind(self) -> str:
        """``MoveL`` or ``MoveC``."""
        return "MoveL" if self.via_mm is None else "MoveC"

    def to_dict(self) -> dict[str, object]:
        """JSON form: kind, the dense indices it spans, its deviation (mm, deg)."""
        return {"kind": self.kind, "dense_from": self.first, "dense_to": self.last,
                "deviation_mm": round(self.deviation[0], 4),
                "deviation_axis_deg": round(self.deviation[1], 4),
                "deviation_spin_deg": round(self.deviation[2], 4)}


def axis_spin_deg(Ra: ArrayLike, Rb: ArrayLike) -> tuple[F64, F64]:
    """(torch axis angle, spin) in degrees between two stacks of orientations (N, 3, 3).

    The axis angle is between the two TCP z axes (the torch axis: what sets the work and travel
    angles); the spin is the twist about the torch axis left in the relative rotation once the
    axes are aligned (swing-twist decomposition).
    """
    M = np.einsum("nji,njk->nik", np.asarray(Ra, dtype=np.float64),
                  np.asarray(Rb, dtype=np.float64))
    axis = np.degrees(np.arccos(np.clip(M[:, 2, 2], -1.0, 1.0)))
    w = 0.5 * np.sqrt(np.clip(1.0 + np.trace(M, axis1=1, axis2=2), 0.0, None))
    z4 = M[:, 1, 0] - M[:, 0, 1]  # 4 w z
    spin = np.degrees(2.0 * np.arctan2(np.abs(z4), np.abs(4.0 * w)))
    return np.asarray(axis, dtype=np.float64), np.asarray(spin, dtype=np.float64)


def _fractions(T0: F64, T1: F64, circle: Circle | None, P: F64) -> F64 | None:
    """Fraction of the segment nearest each dense position; None when they run backwards."""
    a, b = T0[:3, 3], T1[:3, 3]
    if circle is None:
        d = b - a
        s = np.clip((P - a) @ d / float(d @ d), 0.0, 1.0)
    else:
        s = circle.fraction_of(P)
    if np.any(np.diff(s) < -1e-9):
        return None
    return np.asarray(s, dtype=np.float64)


def chord_turns(dense: ArrayLike) -> F64:
    """Rotation vectors (N-1, 3) from each dense pose's orientation to the next one's (local)."""
    R = np.asarray(dense, dtype=np.float64)[:, :3, :3]
    return np.array([matrix_to_rotvec(m) for m in np.einsum("nji,njk->nik", R[:-1], R[1:])]
                    ).reshape(-1, 3)


def deviation(T0: ArrayLike, T1: ArrayLike, via_mm: ArrayLike | None, dense: ArrayLike,
              turns: F64 | None = None) -> tuple[float, float, float]:
    """How far a segment leaves the planned path: (mm, torch axis deg, spin deg).

    The segment runs from ``T0`` to ``T1`` (MoveL, or MoveC through ``via_mm``) and replaces the
    planned ``dense`` poses (N, 4, 4), ``dense[0]`` at its start and ``dense[-1]`` at its end.
    Angles as :func:`axis_spin_deg`. Infinite when the segment runs backwards along them.
    ``turns`` are :func:`chord_turns` of ``dense`` when already known.
    """
    A = np.asarray(T0, dtype=np.float64)
    B = np.asarray(T1, dtype=np.float64)
    D = np.asarray(dense, dtype=np.float64)
    via = None if via_mm is None else np.asarray(via_mm, dtype=np.float64)
    circle = None if via is None else circle_through(A[:3, 3], via, B[:3, 3])
    P, R = D[:, :3, 3], D[:, :3, :3]
    s = _fractions(A, B, circle, P)
    if s is None:
        return float("inf"), float("inf"), float("inf")
    n = len(D)
    # the segment at each dense point's nearest fraction, and between the dense points (a
    # quarter, half and three quarters of the way) against the planned chord there
    f = np.array([0.25, 0.5, 0.75])
    sq = (s[:-1, None] + f[None, :] * (s[1:] - s[:-1])[:, None]).ravel()
    k = np.repeat(np.arange(n - 1), len(f))
    poses = segment_poses(A, B, np.concatenate([s, sq]), via, circle)
    at, mid = poses[:n], poses[n:]
    q = mid[:, :3, 3]
    c = (P[1:] - P[:-1])[k]
    cc = np.einsum("ij,ij->i", c, c)
    t = np.clip(np.einsum("ij,ij->i", q - P[k], c) / np.where(cc > 0, cc, 1.0), 0.0, 1.0)
    dev_mm = max(float(np.max(np.linalg.norm(at[:, :3, 3] - P, axis=1))),
                 float(np.max(np.linalg.norm(P[k] + t[:, None] * c - q, axis=1))))
    rel = (chord_turns(D) if turns is None else turns)[k]
    chord_R = np.einsum("nij,njk->nik", R[k], rotvec_to_matrix(t[:, None] * rel))
    ax, sp = axis_spin_deg(poses[:, :3, :3], np.concatenate([R, chord_R]))
    return dev_mm, float(np.max(ax)), float(np.max(sp))


def fit_circle_point(P: F64, axis: F64 | None = None) -> F64 | None:
    """The circle point (mm) of the arc from ``P[0]`` to ``P[-1]`` that best fits all of ``P``.

    The circle's plane holds the chord; it is normal to ``axis`` when given (the torch's turn from
    start to end: a circle the tool turns with must turn about that axis, and a plane fitted to a
    few noisy points of a short arc can tilt by a degree), else the plane the points spread in.
    In that plane, least squares on the circle's algebraic residual with both ends held (the
    centre is then on the chord's bisector, one unknown); the circle point is the arc's middle.
    None when the points do not bend away from the chord (a line fits them as well).
    """
    a, b = P[0], P[-1]
    d = b - a
    L = float(np.linalg.norm(d))
    if L < 1e-6 or len(P) < 3:
        return None
    dh = d / L
    m = 0.5 * (a + b)
    q = P - m
    x = q @ dh
    perp = q - x[:, None] * dh
    w = None
    if axis is not None:
        w = cross3(axis, dh)
        w = w / np.linalg.norm(w) if np.linalg.norm(w) > 0.1 * np.linalg.norm(axis) else None
    if w is None:
        # the bulge direction: the principal direction of the points off the chord
        _, sv, vt = np.linalg.svd(perp, full_matrices=False)
        if sv[0] < 1e-9:
            return None
        w = vt[0] - (vt[0] @ dh) * dh
        w /= np.linalg.norm(w)
    y = q @ w
    den = 2.0 * float(y @ y)
    if den < 1e-18:
        return None
    h = 0.5 * L
    s = float((x * x + y * y - h * h) @ y) / den
    r = float(np.hypot(h, s))
    side = 1.0 if float(np.mean(y)) >= 0 else -1.0
    return np.asarray(m + w * (s + side * r), dtype=np.float64)


def _try(D: F64, turns: F64, i: int, j: int, tol: PathTolerance) -> Segment | None:
    """A MoveL from dense pose i to j if it fits, else a MoveC if it fits, else None."""
    sub = D[i:j + 1]
    P = sub[:, :3, 3]
    chord = P[-1] - P[0]
    off = np.cross(P - P[0], chord) / max(float(np.linalg.norm(chord)), 1e-12)
    if float(np.max(np.linalg.norm(off, axis=1))) <= tol.position_mm:  # else no line fits
        dev = deviation(D[i], D[j], None, sub, turns[i:j])
        if tol.admits(dev):
            return Segment(D[j].copy(), None, i, j, dev)
    if j - i < 2:
        return None
    turn = matrix_to_rotvec(D[j][:3, :3] @ D[i][:3, :3].T)
    # the plane the torch turns in; the plane of the points only when the torch hardly turns
    for axis in ((turn,) if np.linalg.norm(turn) > np.radians(0.5) else (None,)):
        via = fit_circle_point(sub[:, :3, 3], axis)
        if via is None:
            continue
        try:
            circle = circle_through(D[i][:3, 3], via, D[j][:3, 3])
        except InputError:
            continue
        if np.degrees(circle.sweep_rad) > MAX_SWEEP_DEG:
            continue
        dev = deviation(D[i], D[j], via, sub, turns[i:j])
        if tol.admits(dev):
            return Segment(D[j].copy(), via, i, j, dev)
    return None


def _farthest(D: F64, turns: F64, i: int, tol: PathTolerance) -> Segment:
    """The segment from dense pose ``i`` that reaches farthest.

    Doubling, then bisection, then a few ends past the one found (noise makes the fit not
    strictly monotone in the end).
    """
    n = len(D)
    good = _try(D, turns, i, i + 1, tol)
    assert good is not None  # two neighbours: the dense path itself
    lo, step = i + 1, 2
    hi = n  # first end known (or assumed, past the last pose) not to fit
    while lo + step < n:
        seg = _try(D, turns, i, lo + step, tol)
        if seg is None:
            hi = lo + step
            break
        good, lo, step = seg, lo + step, step * 2
    while hi - lo > 1:
        mid = (lo + hi) // 2
        seg = _try(D, turns, i, mid, tol)
        if seg is None:
            hi = mid
        else:
            good, lo = seg, mid
    for j in range(lo + 2, min(n, lo + 2 + _LOOK_PAST)):
        seg = _try(D, turns, i, j, tol)
        if seg is not None:
            good = seg
    return good


def fit_segments(dense: Sequence[ArrayLike], tol: PathTolerance = PathTolerance()
                 ) -> list[Segment]:
    """Few segments from ``dense[0]`` through the dense poses to the last, each within ``tol``.

    ``dense`` are ``T_base_tcp`` poses (mm) in path order, at least 2. The robot is at
    ``dense[0]`` when the first segment starts. Greedy: each segment reaches as far along the
    dense path as a MoveL, else a MoveC, stays within ``tol`` of it (:func:`deviation`); that is
    the fewest segments when a segment that fits also fits over any part of its stretch. Two
    neighbouring dense poses always fit (a MoveL between them is the dense path itself), so a fit
    always exists. Raises :class:`InputError` for fewer than 2 poses.
    """
    D = np.asarray([np.asarray(T, dtype=np.float64) for T in dense])
    n = len(D)
    if n < 2 or D.shape[1:] != (4, 4):
        raise InputError(f"a path fit needs at least 2 poses (N, 4, 4), got shape {D.shape}")
    turns = chord_turns(D)
    out: list[Segment] = []
    i = 0
    while i < n - 1:
        seg = _farthest(D, turns, i, tol)
        out.append(seg)
        i = seg.last
    return out
