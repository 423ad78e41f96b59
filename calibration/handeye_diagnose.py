"""The usual mistakes in hand-eye input, recognised and named.

When the robot poses and the board poses do not fit together at all, the cause is rarely the
robot: it is a convention. :func:`diagnose_poses` tries each usual mistake on the data and, when
undoing one makes the views agree, says which one it was and what to change:

- robot positions in metres (a view file takes mm);
- quaternions written x, y, z, w (a view file takes w, x, y, z, as ABB's q1..q4);
- inverted poses (``T_flange_base`` given for ``T_base_flange``);
- the board's square size in other units than the robot's positions (the camera moves k times
  more, by the images, than the flange does).

Each hypothesis is judged by OpenCV's Park closed form and how far apart the views then put the
board (the consistency, mm RMS of the board's corners): a fix must bring it down five-fold and
under :data:`EXPLAINED_MM`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from itertools import combinations

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from calibration.closed_form import _consistency, closed_form
from controller.errors import CalibrationError
from controller.geometry.poses import Pose, invert, make_pose

F64 = NDArray[np.float64]

#: The views are "inconsistent" (worth a diagnosis) when the board spreads more than this (mm RMS).
INCONSISTENT_MM = 20.0
#: A fix explains the data when the spread falls under this (mm RMS) and five-fold.
EXPLAINED_MM = 10.0

_BOARD = np.array([[-100, -100, 0], [100, -100, 0], [100, 100, 0], [-100, 100, 0], [0, 0, 0]],
                  float)


def board_spread_mm(A: Sequence[Pose], T_cb: Sequence[Pose], eye_to_hand: bool) -> float:
    """How far apart the views put the board with Park's closed form: median mm over views.

    Each view's distance is the RMS over the points of a 200 mm square; inf when the closed
    form fails.
    """
    try:
        X, Y = closed_form(A, T_cb, method="park", eye_to_hand=eye_to_hand)
    except CalibrationError:
        return float("inf")
    motions = list(A) if eye_to_hand else [invert(T) for T in A]
    mm, _ = _consistency(motions, T_cb, X, Y, _BOARD)
    return float(np.median(mm))


def _xyzw(T: Pose) -> Pose:
    """The pose whose quaternion was read w,x,y,z from a file that wrote it x,y,z,w."""
    q_as_read = Rotation.from_matrix(T[:3, :3]).as_quat()  # x, y, z, w of what we built
    wxyz = np.roll(q_as_read, 1)  # the four numbers as they stood in the file
    return make_pose(Rotation.from_quat(wxyz).as_matrix(), T[:3, 3])  # read them as x,y,z,w


def _scale_ratio(A: Sequence[Pose], T_cb: Sequence[Pose], eye_to_hand: bool) -> float:
    """Median over view pairs of (camera or board displacement by the images) / (by the robot).

    About 1 when both are in mm: the camera centre moves with the flange give or take the
    hand-eye's lever arm.
    """
    if eye_to_hand:  # the board moves with the flange; the camera sees its origin move
        seen = [np.asarray(T)[:3, 3] for T in T_cb]
    else:  # the camera centre in the board frame
        seen = [invert(np.asarray(T))[:3, 3] for T in T_cb]
    robot = [np.asarray(T)[:3, 3] for T in A]
    ratios = []
    for i, j in combinations(range(len(A)), 2):
        d_robot = float(np.linalg.norm(robot[i] - robot[j]))
        if d_robot > 1e-9:
            ratios.append(float(np.linalg.norm(seen[i] - seen[j])) / d_robot)
    return float(np.median(ratios)) if ratios else 1.0


def diagnose_poses(A: Sequence[Pose], T_cb: Sequence[Pose], eye_to_hand: bool = False
                   ) -> str | None:
    """A sentence naming the input mistake that makes these views disagree, or None.

    ``A``: recorded flange poses (4x4, as given, mm); ``T_cb``: board poses from the images
    (4x4, mm, by the given square size).
    """
    A = [np.asarray(T, float) for T in A]
    given = board_spread_mm(A, T_cb, eye_to_hand)
    if given < INCONSISTENT_MM:
        return None
    positions = np.array([T[:3, 3] for T in A])
    fixes: list[tuple[str, Callable[[Pose], Pose]]] = [
        ("the robot positions look like metres (the largest is "
         f"{np.abs(positions).max():.3g} from the base): view files take mm; multiply by 1000",
         lambda T: make_pose(T[:3, :3], 1000.0 * T[:3, 3])),
        ("the quaternions look written x, y, z, w: view files take w, x, y, z (scalar first, as "
         "ABB's q1..q4); move the last number to the front", _xyzw),
        ("the poses look inverted (the base in the flange frame, T_flange_base): view files take "
         "the flange (tool0) in the base frame, as the controller's CRobT gives it", invert),
    ]
    for sentence, fix in fixes:
        spread = board_spread_mm([fix(T) for T in A], T_cb, eye_to_hand)
        if spread < EXPLAINED_MM and spread * 5 < given:
            return (f"the views do not fit together (the board spreads {given:.0f} mm between "
                    f"them); {sentence} (then it spreads {spread:.1f} mm)")
    ratio = _scale_ratio(A, T_cb, eye_to_hand)
    if not 1 / 3 < ratio < 3:
        return (f"the views do not fit together (the board spreads {given:.0f} mm between them), "
                f"and by the images the camera moves {ratio:.3g} times as far as the robot says "
                f"the flange does: the board's square size and the robot's positions are in "
                f"different units (both must be mm; a square of 25 mm is 25, not 0.025 or 1)")
    return None
