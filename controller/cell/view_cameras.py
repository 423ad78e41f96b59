"""Which of the cell's cameras takes which view of a job, and whether that view needs a motion.

A job's view names a camera of the cell (``camera = "left"``); in a one-camera cell it may name
none. A camera on the flange (its calibration has ``hand_eye``) needs the view's taught joints: the
robot moves there first. A fixed camera (``camera_pose``) needs no motion: the views of fixed
cameras are captured together. Everything is checked here once, for ``check-config`` and before a
cycle moves anything; each problem names the job, the view and the camera.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from controller.cell.job import Job
from controller.errors import ConfigError


@dataclass(frozen=True)
class ViewCamera:
    """A job's view resolved against the cell: its camera's name and whether it is fixed."""

    view: str
    camera: str
    fixed: bool
    joints_deg: tuple[float, ...] | None


def view_camera_problems(job: Job, calibrations: Mapping[str, Any]) -> list[str]:
    """Every problem of ``job``'s views against the cell's cameras (their calibrations by name).

    A view naming a camera the cell does not have, a view naming none in a cell of several
    cameras, a camera whose calibration holds neither ``hand_eye`` nor ``camera_pose``, and a
    view of a camera on the flange without joints. Empty when the job can run.
    """
    problems = []
    names = sorted(calibrations)
    for v in job.views:
        cam = v.camera
        if cam is None:
            if len(names) != 1:
                problems.append(f"job {job.name}: view {v.name} does not name its camera and the "
                                f"cell has {len(names)} ({', '.join(names)}): add "
                                f"camera = \"NAME\" to the view")
                continue
            cam = names[0]
        if cam not in calibrations:
            problems.append(f"job {job.name}: view {v.name}: camera {cam!r} is not a camera of "
                            f"this cell (cameras: {', '.join(names)}); add [cameras.{cam}] with "
                            f"its url and calibration to the cell configuration, or fix the name")
            continue
        calib = calibrations[cam]
        if calib.T_flange_cam is None and calib.T_base_cam is None:
            problems.append(f"job {job.name}: view {v.name}: camera {cam}'s calibration holds "
                            f"neither hand_eye nor camera_pose; calibrate where the camera sits "
                            f"(`seamguide calibrate`, --eye-to-hand for a fixed camera)")
        elif calib.T_flange_cam is not None and v.joints_deg is None:
            problems.append(f"job {job.name}: view {v.name}: camera {cam} is on the flange and "
                            f"the view has no joints; jog the robot there and run `seamguide "
                            f"teach-view JOB {v.name}`")
    if len(job.views) < 2:
        problems.append(f"job {job.name}: needs at least two views, has {len(job.views)}")
    return problems


def resolve_view_cameras(job: Job, calibrations: Mapping[str, Any]) -> list[ViewCamera]:
    """The camera of each of ``job``'s views, in job order; :class:`ConfigError` listing problems.

    ``calibrations`` maps the cell's camera names to their calibrations (``T_flange_cam`` /
    ``T_base_cam``). Raised before anything moves.
    """
    problems = view_camera_problems(job, calibrations)
    if problems:
        raise ConfigError("; ".join(problems), job=job.name, problems=problems)
    only = next(iter(calibrations)) if len(calibrations) == 1 else None
    out = []
    for v in job.views:
        cam = v.camera or only
        assert cam is not None
        out.append(ViewCamera(v.name, cam, calibrations[cam].T_base_cam is not None,
                              v.joints_deg))
    return out


def capture_groups(views: list[ViewCamera]) -> list[list[int]]:
    """Indices of the views captured together, in job order.

    A flange camera's view is alone (after its motion); consecutive views of fixed cameras without
    joints are captured at once (no motion before them).
    """
    groups: list[list[int]] = []
    for i, v in enumerate(views):
        together = v.fixed and v.joints_deg is None
        if together and groups and views[groups[-1][-1]].fixed and \
                views[groups[-1][-1]].joints_deg is None:
            groups[-1].append(i)
        else:
            groups.append([i])
    return groups
