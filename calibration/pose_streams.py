"""Pairing a robot pose stream with a board pose stream sampled at other instants."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from controller.errors import CalibrationError
from controller.geometry.poses import Pose, make_pose

F64 = NDArray[np.float64]


def _angular_speed(slerp: Any, t: F64, h: float) -> F64:
    return np.asarray((slerp(t + h) * slerp(t - h).inv()).magnitude() / (2 * h))


def pair_pose_streams(t_robot_s: F64, T_base_flange: Sequence[Pose], t_cam_s: F64,
                      T_cam_board: Sequence[Pose], n: int = 40, *,
                      max_offset_s: float = 1.0) -> tuple[list[Pose], list[Pose], float, float]:
    """Pair a robot pose stream with a board pose stream sampled at other instants.

    The unknown time offset is found by correlating the angular speeds of the two streams (the
    same rigid motion seen from two frames has the same angular speed): ``t_cam = t_robot +
    offset``, searched within +-``max_offset_s`` at 1 ms. Then ``n`` board samples are taken, the
    stillest of each of ``n`` equal time bins (least harm from a residual offset), with the robot
    pose interpolated at their instants (linear position, slerp rotation).

    Returns (T_base_flange list, T_cam_board list, offset_s, correlation). Raises
    :class:`CalibrationError` when the streams do not overlap or do not correlate (< 0.5).
    """
    from scipy.spatial.transform import Slerp

    tr = np.asarray(t_robot_s, float)
    tc = np.asarray(t_cam_s, float)
    Rr = Rotation.from_matrix(np.stack([np.asarray(T)[:3, :3] for T in T_base_flange]))
    Rc = Rotation.from_matrix(np.stack([np.asarray(T)[:3, :3] for T in T_cam_board]))
    pr = np.stack([np.asarray(T)[:3, 3] for T in T_base_flange])
    sr, sc = Slerp(tr, Rr), Slerp(tc, Rc)
    lo = max(tr[0], tc[0]) + max_offset_s + 0.5
    hi = min(tr[-1], tc[-1]) - max_offset_s - 0.5
    if hi - lo < 2.0:
        raise CalibrationError("the robot and board pose streams overlap by less than 2 s")
    grid = np.arange(lo, hi, 0.01)
    ref = _angular_speed(sr, grid, 0.2)
    # The board stream's speed once on a 1 ms grid; each offset is then an interpolation.
    fine = np.arange(lo - max_offset_s, hi + max_offset_s, 0.001)
    fine_speed = _angular_speed(sc, fine, 0.2)
    best = (-1.0, 0.0)
    for off in np.arange(-max_offset_s, max_offset_s, 0.001):
        c = float(np.corrcoef(ref, np.interp(grid + off, fine, fine_speed))[0, 1])
        if c > best[0]:
            best = (c, float(off))
    corr, off = best
    if not corr >= 0.5:
        raise CalibrationError(f"the pose streams' angular speeds do not correlate (best "
                               f"{corr:.2f}): are they of the same motion?")
    idx = np.arange(1, len(tc) - 1)
    idx = idx[(tc[idx] - off > tr[0]) & (tc[idx] - off < tr[-1])]
    bins = np.linspace(tc[idx[0]], tc[idx[-1]], n + 1)
    A: list[Pose] = []
    B: list[Pose] = []
    for k in range(n):
        inb = idx[(tc[idx] >= bins[k]) & (tc[idx] < bins[k + 1])]
        if not len(inb):
            continue
        i = int(inb[np.argmin(_angular_speed(sc, tc[inb], 0.05))])
        t = tc[i] - off
        A.append(make_pose(sr([t]).as_matrix()[0], [np.interp(t, tr, pr[:, j]) for j in range(3)]))
        B.append(np.asarray(T_cam_board[i], float))
    return A, B, off, corr
