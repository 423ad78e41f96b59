"""The simulated fixed-stereo cell: two cameras with different lenses on stands, no wrist camera.

The first published cell: two fixed cameras look at the part from two sides, each calibrated on
its own, and the robot only welds. Here the ``left`` camera is the dry run's 2272x1704 camera
(44 deg lens, mild barrel distortion) and ``right`` a 2048x1536 camera with a longer lens
(37 deg), stronger barrel distortion, tangential terms and an off-centre principal point, placed
farther away so that both see about 280 mm of the part. The stands are placed for the scene (as
a fixture holds the part where the cameras look): the cameras are displaced across the seam and
the right one is rolled so that the seam runs along its image diagonal (two views rolled alike
cannot show a wrong camera pose; see the README's stereo section).

What it does not model: the robot or the torch hiding the part from a camera, vibration of the
stands, and the cameras' exposure timing (the cycle records the software trigger skew only).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from controller.geometry.camera_model import CameraModel, default_camera
from controller.geometry.poses import make_pose, rotation_about

F64 = NDArray[np.float64]

#: Working distance of the left camera (mm); the right one stands farther by its focal ratio.
LEFT_STANDOFF_MM = 350.0
#: Distance between the two cameras across the seam at the left camera's working distance (mm).
BASELINE_MM = 200.0


def right_camera() -> CameraModel:
    """The right camera: 2048x1536, fx = fy = 1.5 x width, barrel + tangential distortion."""
    w, h = 2048, 1536
    f = 1.5 * w
    K = np.array([[f, 0.0, (w - 1) / 2 - 6.4], [0.0, f * 1.0005, (h - 1) / 2 + 4.1],
                  [0.0, 0.0, 1.0]])
    return CameraModel(w, h, K, np.array([-0.15, 0.12, -0.0006, 0.0008, -0.02]), name="right")


def left_camera() -> CameraModel:
    """The left camera: the dry run's 2272x1704 camera (44 deg lens)."""
    cam = default_camera()
    return CameraModel(cam.width, cam.height, cam.K, cam.dist, name="left")


@dataclass(frozen=True)
class FixedStereoCell:
    """Two fixed cameras (name -> intrinsics, true ``T_base_cam`` in mm) and the robot's torch."""

    cameras: dict[str, CameraModel]
    T_base_cam: dict[str, F64]
    T_flange_tcp: F64 = field(default_factory=lambda: make_pose(np.eye(3), [0.0, 0.0, 350.0]))


def stand_poses(scene: object, cameras: dict[str, CameraModel]) -> dict[str, F64]:
    """``T_base_cam`` (mm) of the ``left`` and ``right`` stands for ``scene``.

    Both look at the seam's middle, displaced across the seam by :data:`BASELINE_MM` (scaled
    with the distance); each stands at :data:`LEFT_STANDOFF_MM` times its focal length over the
    left camera's, so both see the same width of the part; the right camera is rolled about its
    optical axis so that the seam runs along its image diagonal.
    """
    from drivers.sim.sim_render import suggest_view_poses

    out: dict[str, F64] = {}
    f_left = cameras["left"].fx / cameras["left"].width
    for i, name in enumerate(("left", "right")):
        cam = cameras[name]
        s = LEFT_STANDOFF_MM * (cam.fx / cam.width) / f_left
        T = suggest_view_poses(scene, cam, n=2, standoff_mm=s,  # type: ignore[arg-type]
                               baseline_mm=BASELINE_MM * s / LEFT_STANDOFF_MM)[i]
        if i == 1:
            roll = float(np.arctan2(cam.height, cam.width))
            T = T @ make_pose(rotation_about([0, 0, 1], roll))
        out[name] = T
    return out


def fixed_stereo_cell(scene: object) -> FixedStereoCell:
    """The simulated fixed-stereo cell with its stands placed for ``scene``."""
    cameras = {"left": left_camera(), "right": right_camera()}
    return FixedStereoCell(cameras, stand_poses(scene, cameras))
