"""``seamguide dry-run``, ``seamguide teach-view`` and ``seamguide locate``."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from controller.errors import SeamguideError
from controller.jsonio import emit_json


def register(sub: Any) -> None:
    """Add the ``dry-run``, ``teach-view`` and ``locate`` subcommands."""
    p = sub.add_parser("dry-run", help="a full weld cycle against the mock robot and simulated "
                       "camera", description="Runs one complete weld cycle: the mock controller "
                       "on a pseudo-terminal driven by the real client, a simulated camera that "
                       "renders the workpiece from the mock robot's pose, detection, "
                       "triangulation, planning and the weld pass. Prints a summary with the "
                       "error against the simulator's truth and writes the cycle record.")
    p.add_argument("--output", default="dry-run", help="folder for cycle records "
                   "(default: ./dry-run)")
    p.add_argument("--scene", default="s_curve",
                   choices=["straight", "arc", "s_curve", "nonplanar", "tack_open", "open_ends"],
                   help="seam shape; tack_open: a long tack-welded seam whose ends leave both "
                   "images; open_ends: the same seam without the tack welds")
    p.add_argument("--clip-unseen-ends", action="store_true",
                   help="the job allows clipping a seam whose ends no view sees to its nominal "
                   "region (job key [seam] clip_unseen_ends; default: refuse such a seam)")
    p.add_argument("--nominal-line", action="store_true",
                   help="the job states the seam's nominal line (job keys [seam] nominal_line_mm "
                   "and line_tolerance_mm: the scene's seam moved by up to 2 mm per axis, as a "
                   "drawing would place it): a seam found far from it is refused")
    p.add_argument("--seed", type=int, default=1, help="scene seed (default 1)")
    p.add_argument("--difficulty", default="medium", choices=["easy", "medium", "hard"])
    p.add_argument("--calibration", action="append", metavar="[CAMERA=]FILE",
                   help="use this calibration file instead of the exact one (fixed-stereo: "
                   "CAMERA=FILE per camera, left and right)")
    p.add_argument("--cell", default="wrist", choices=["wrist", "fixed-stereo"],
                   help="wrist: one camera on the flange, two views (default); fixed-stereo: "
                   "two fixed cameras with different lenses, the robot only welds")
    p.add_argument("--robot-options", default="", help="mock URL options, e.g. "
                   "'drop=0.01&corrupt=0.02' (fault injection)")
    p.add_argument("--camera-options", default="", help="simulated camera URL options")
    p.add_argument("--speedup", type=float, default=50.0,
                   help="simulated motion runs this many times faster than real time")
    p.add_argument("--json", action="store_true", help="print the report as JSON on stdout")
    p.set_defaults(func=_dry_run)

    t = sub.add_parser("teach-view", help="store the robot's current joints as a job's view",
                       description="Reads the controller's joints over the link and stores them "
                       "as view NAME of the job file (replacing it if it exists).")
    t.add_argument("job", help="job file (TOML)")
    t.add_argument("name", help="view name, e.g. view1")
    t.add_argument("--port", required=True, help="robot URL (/dev/ttyS0, socket://..., mock://)")
    t.add_argument("--speed", type=float, help="speed to move to this view, mm/s")
    t.set_defaults(func=_teach_view)

    loc = sub.add_parser("locate", help="the 3D seam from two or more views",
                         description="Detects the seam in each view's image, triangulates it in "
                         "the robot base frame and plans the weld path. Output: seam_points_mm "
                         "(base frame, ordered, before the tool offset), weld_path, quality.")
    loc.add_argument("--calibration", required=True, action="append", dest="calibrations",
                     metavar="[CAMERA=]FILE", help="calibration file (YAML); with several "
                     "cameras one per camera, CAMERA=FILE, the name the views give as \"camera\"")
    loc.add_argument("--view", action="append", required=True, dest="views",
                     help="view file (JSON); give two or more")
    loc.add_argument("--job", help="job file: nominal seam region, normal, weld parameters, "
                     "quality limits")
    loc.add_argument("--spacing", type=float, help="weld point spacing, mm (default 2)")
    loc.add_argument("--count", type=int, help="number of weld points instead of a spacing")
    loc.add_argument("--no-path", action="store_true", help="skip weld path planning")
    loc.add_argument("--output", help="write the JSON here instead of stdout")
    loc.add_argument("--overlay-dir", help="write an overlay PNG per view here: its seam, or "
                     "why it was refused")
    loc.set_defaults(func=_locate)


def _dry_run(args: argparse.Namespace) -> int:
    from controller.cell.dry_run import run_dry_run, summary_text

    calibration: Any = None
    if args.calibration:
        given = parse_calibration_args(args.calibration)
        # One unnamed file (the wrist cell), or CAMERA=FILE per camera (fixed-stereo).
        calibration = given.pop(None, None) or given
    rep = run_dry_run(args.output, scene_kind=args.scene, seed=args.seed,
                      difficulty=args.difficulty, calibration=calibration,
                      robot_options=args.robot_options, camera_options=args.camera_options,
                      speedup=args.speedup, cell=args.cell,
                      clip_unseen_ends=args.clip_unseen_ends, nominal_line=args.nominal_line)
    print(summary_text(rep), file=sys.stderr)
    if args.json:
        r = rep.result
        emit_json({"status": r.status, "reason": r.reason,
                   "record": str(r.record_path) if r.record_path else None,
                   "seam_rms_mm": rep.seam_rms_mm, "seam_max_mm": rep.seam_max_mm,
                   "path_rms_mm": rep.path_rms_mm, "path_max_mm": rep.path_max_mm,
                   "states": [s for s, _ in r.state_history], "cell": rep.cell,
                   "robot_motions_before_weld": rep.motions_before_weld,
                   "capture_skew_ms": [round(1000 * s, 3) for s in r.capture_skews_s]}, None)
    if rep.result.ok:
        return 0
    err = rep.result.error
    return err.exit_code if isinstance(err, SeamguideError) else 1


def _teach_view(args: argparse.Namespace) -> int:
    import numpy as np

    from controller.cell.job import teach_view
    from drivers.robot import open_robot

    with open_robot(args.port) as robot:
        joints = np.asarray(robot.read_joints())
    job = teach_view(args.job, args.name, joints, args.speed)
    print(f"view {args.name} of job {job.name} set to {[round(float(v), 4) for v in joints]} deg",
          file=sys.stderr)
    return 0


def _save_overlay(path: Path, image: Any, det: Any) -> None:
    import cv2

    from controller.errors import InputError
    from controller.jsonio import atomic_write_bytes
    from controller.vision.seam_overlay import outcome_overlay

    ok, buf = cv2.imencode(".png", outcome_overlay(image, det))
    if not ok:
        raise InputError(f"could not encode the overlay {path}")
    atomic_write_bytes(path, buf.tobytes())


def parse_calibration_args(items: list[str]) -> dict[str | None, str]:
    """``--calibration`` values to {camera name or None: file}; :class:`InputError` on misuse.

    ``FILE`` is one calibration for every view (key None); ``NAME=FILE`` is camera NAME's. A value
    that is an existing file is a file even if its name holds ``=``.
    """
    from controller.errors import InputError
    from controller.geometry.view_file import camera_name_problem

    out: dict[str | None, str] = {}
    for item in items:
        name: str | None = None
        path = item
        if "=" in item and not Path(item).is_file():
            name, path = item.split("=", 1)
            if (problem := camera_name_problem(name)) is not None:
                raise InputError(f"--calibration {item}: {problem}")
        if name in out:
            raise InputError(f"--calibration {item}: "
                             + (f"camera {name!r} is given twice" if name else
                                "give one unnamed calibration, or CAMERA=FILE per camera"))
        out[name] = path
    if None in out and len(out) > 1:
        raise InputError("--calibration: give one unnamed calibration (every view) or "
                         "CAMERA=FILE per camera, not both")
    return out


def _locate(args: argparse.Namespace) -> int:
    """Load the files, run the guidance pipeline the cell runs (guide), write the contract."""
    import dataclasses

    from calibration.calibration_file import Calibration, load_calibration
    from controller.cell.guidance import (
        GuidanceSettings,
        ViewInput,
        guide,
        locate_output,
        settings_from_job,
    )
    from controller.cell.job import load_job
    from controller.geometry.view_file import load_view
    from controller.stereo.view_geometry import calibration_for_view, camera_pose
    from controller.vision.image_io import load_image

    calibs: dict[str | None, Calibration] = {
        name: load_calibration(f) for name, f in parse_calibration_args(args.calibrations).items()}
    settings = settings_from_job(load_job(args.job)) if args.job else GuidanceSettings()
    if args.spacing is not None or args.count is not None:
        settings = dataclasses.replace(
            settings, spacing_mm=args.spacing if args.spacing is not None else settings.spacing_mm,
            count=args.count if args.count is not None else settings.count)
    views = []
    for vpath in args.views:
        view = load_view(vpath)
        calib = calibration_for_view(view, calibs)
        views.append(ViewInput(view.name, load_image(view.image_path, camera=calib.camera),
                               calib.camera, camera_pose(view, calib)))

    def overlays(dets: list[Any]) -> None:
        if args.overlay_dir:
            for v, det in zip(views, dets, strict=True):
                _save_overlay(Path(args.overlay_dir) / f"{v.name}_overlay.png", v.image, det)

    result = guide(views, settings, plan=not args.no_path, on_detections=overlays)
    doc = locate_output(result.located.seam, result.path)
    refused = result.path_error
    if refused is not None:
        # locate is a measuring tool too: the seam is written even when it cannot be welded.
        doc["weld_path"] = None
        doc["weld_path_error"] = {"error": type(refused).__name__, "reason": str(refused),
                                  "exit_code": refused.exit_code}
    emit_json(doc, args.output)
    if refused is not None:
        print(f"seamguide locate: the seam was located and written, but no weld path: {refused}",
              file=sys.stderr)
        return refused.exit_code
    return 0
