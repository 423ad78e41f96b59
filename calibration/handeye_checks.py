"""Degeneracy checks on the robot poses of a hand-eye calibration (before any solving)."""

from __future__ import annotations

from collections.abc import Sequence
from itertools import combinations

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from controller.errors import CalibrationError
from controller.geometry.poses import Pose, pose_error

F64 = NDArray[np.float64]

#: Fewest views for a hand-eye calibration (3 give two motions; more average the noise).
MIN_VIEWS = 5
#: A robot "did not move" when every pose is within these of the first.
STILL_MM, STILL_DEG = 1.0, 0.2
#: The largest rotation between any two views must reach this (degrees).
MIN_ROTATION_DEG = 5.0
#: Two relative rotation axes count as different when at least this far apart (degrees).
MIN_AXIS_SPREAD_DEG = 10.0


def check_motions(T_base_flange: Sequence[Pose], names: Sequence[str], *,
                  min_views: int = MIN_VIEWS, min_rotation_deg: float = MIN_ROTATION_DEG,
                  min_axis_spread_deg: float = MIN_AXIS_SPREAD_DEG) -> dict[str, float]:
    """Refuse robot poses from which AX = XB cannot be solved; return the motion statistics.

    Raises :class:`CalibrationError` naming the views when there are fewer than ``min_views``,
    when the robot did not move (all within :data:`STILL_MM` / :data:`STILL_DEG` of the first),
    when no two views differ by ``min_rotation_deg`` of rotation, or when all rotations between
    views are about one axis (closer than ``min_axis_spread_deg``).
    """
    n = len(T_base_flange)
    listed = ", ".join(names)
    if n < min_views:
        raise CalibrationError(f"hand-eye needs at least {min_views} good views, got {n} "
                               f"({listed or 'none'}); take more views", views=list(names))
    d = [pose_error(T_base_flange[0], T) for T in T_base_flange]
    if max(x[0] for x in d) < STILL_MM and max(x[1] for x in d) < STILL_DEG:
        raise CalibrationError(
            f"the robot did not move: views {listed} were all taken within {STILL_MM} mm / "
            f"{STILL_DEG} deg of each other; jog the robot to a different pose for every view",
            views=list(names))
    rel = []
    for i, j in combinations(range(n), 2):
        Ri = np.asarray(T_base_flange[i])[:3, :3]
        Rj = np.asarray(T_base_flange[j])[:3, :3]
        rv = Rotation.from_matrix(Ri.T @ Rj).as_rotvec()
        rel.append((float(np.degrees(np.linalg.norm(rv))), rv, i, j))
    max_rot = max(r[0] for r in rel)
    if max_rot < min_rotation_deg:
        raise CalibrationError(
            f"too little rotation between views {listed}: they differ by at most {max_rot:.2f} "
            f"deg (need {min_rotation_deg} deg, better 20-40 deg); hand-eye is degenerate for "
            f"pure translations: tilt the camera about two different axes between views",
            views=list(names), max_rotation_deg=max_rot)
    axes = [r[1] / np.linalg.norm(r[1]) for r in rel if r[0] >= min_rotation_deg]
    spread = 0.0
    a0 = axes[0]
    for a in axes[1:]:
        ang = float(np.degrees(np.arccos(min(1.0, abs(float(a0 @ a))))))
        spread = max(spread, ang)
    if spread < min_axis_spread_deg:
        raise CalibrationError(
            f"views {listed} rotate only about one axis (axes within {spread:.1f} deg): hand-eye "
            f"is degenerate; tilt the camera about a second, different axis too",
            views=list(names), axis_spread_deg=spread)
    return {"max_rotation_deg": max_rot, "axis_spread_deg": spread}

