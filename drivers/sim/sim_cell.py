"""The simulated welding cell: where the camera and the torch sit on the flange, and the lens.

Used by the dry run, the tests and the benchmarks together with the scene renderer
(:mod:`drivers.sim.sim_render`) and the mock controller. ``T_flange_cam`` here is the *true*
hand-eye
transform of the simulated cell; the product only knows what its calibration file says, which for
the dry run is either this exact value or the result of a simulated teach session.

What it does not model: the camera cable, collisions between the torch, the camera and the part
(the view poses keep the torch tip well above the part), and thermal drift of the mount.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from controller.geometry.camera_model import CameraModel, default_camera
from controller.geometry.poses import make_pose, rotation_about

F64 = NDArray[np.float64]


@dataclass(frozen=True)
class SimCell:
    """The simulated cell's camera (intrinsics), true hand-eye and torch (mm)."""

    camera: CameraModel
    T_flange_cam: F64
    T_flange_tcp: F64


def default_sim_cell(width: int = 2272, height: int = 1704) -> SimCell:
    """The cell of the dry run: the published 2272x1704 camera beside a straight 350 mm torch.

    The camera looks along the torch (flange z), 80 mm to the side and 250 mm out from the flange,
    with a small mounting tilt so that the hand-eye rotation is not trivially the identity.
    """
    R = rotation_about([1, 0, 0], np.radians(1.5)) @ rotation_about([0, 1, 0], np.radians(-0.8))
    T_flange_cam = make_pose(R, [-80.0, 4.0, 250.0])
    return SimCell(camera=default_camera(width, height), T_flange_cam=T_flange_cam,
                   T_flange_tcp=make_pose(np.eye(3), [0.0, 0.0, 350.0]))
