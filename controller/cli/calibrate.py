"""``seamguide calibrate``: intrinsics, hand-eye, and the teach-pose routine.

Three sources, one solver (calibration/teach.py)::

    seamguide calibrate --from-folder DIR --board SPEC --output C.yaml [--eye-to-hand]
    seamguide calibrate --images 'GLOB' --board SPEC --output C.yaml        # intrinsics only
    seamguide calibrate --port URL --camera URL --board SPEC --output C.yaml [--auto N]
                        [--eye-to-hand] [--save-views DIR]

The calibration file is written only when the solve and its checks pass; an existing file is kept
as ``<name>.prev.yaml``. The report (JSON) goes to ``--report`` or stdout; progress to stderr.
"""

from __future__ import annotations

import argparse
import glob
import sys
from typing import Any

from controller.errors import CalibrationError, ConfigError
from controller.jsonio import emit_json


def register(sub: Any) -> None:
    """Add the ``calibrate`` subcommand to ``sub`` (an argparse subparsers object)."""
    p = sub.add_parser(
        "calibrate", help="camera intrinsics, hand-eye, and the teach-pose routine",
        description="Calibrate the camera: intrinsics from images of a board, hand-eye from "
        "views with robot poses (a recorded folder, or taught live on the robot). Writes the "
        "calibration file (YAML, DESIGN.md) only when every check passes, keeping the previous "
        "file as NAME.prev.yaml. See docs/calibration.md.")
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--from-folder", metavar="DIR",
                     help="folder of view files (*.json with image + flange_pose or joints_deg)")
    src.add_argument("--images", metavar="GLOB",
                     help="images of the board (quote the glob): intrinsics only")
    src.add_argument("--port", metavar="URL",
                     help="robot link URL (e.g. /dev/ttyS0, socket://host:port, mock://): teach")
    p.add_argument("--camera", metavar="URL",
                   help="camera URL for teaching (opencv:0, sim:, simboard: for a simulated "
                   "board in the cell)")
    p.add_argument("--board", required=True, metavar="SPEC",
                   help="chessboard:COLSxROWS:SQUARE_MM (inner corners) or "
                   "charuco:COLSxROWS:SQUARE_MM:MARKER_MM:DICT")
    p.add_argument("--output", required=True, metavar="C.yaml", help="calibration file to write")
    p.add_argument("--report", metavar="R.json", help="write the report JSON here (else stdout)")
    p.add_argument("--eye-to-hand", action="store_true",
                   help="the camera is fixed in the cell and the robot holds the board: writes "
                   "camera_pose (T_base_cam) instead of hand_eye")
    p.add_argument("--auto", type=int, metavar="N",
                   help="teach: generate N poses around the first taught pose and drive there")
    p.add_argument("--confirm", choices=("enter", "controller"), default="enter",
                   help="teach: take a view on Enter (default) or on a controller request "
                   "(cycle_request event: job 'take', 'done' or 'abort')")
    p.add_argument("--first-joints", metavar="J1,...,J6",
                   help="teach: move to these controller joints (deg) before the first view")
    p.add_argument("--save-views", metavar="DIR",
                   help="teach: also record every image and view file in DIR")
    p.add_argument("--holdout-every", type=int, default=5, metavar="K",
                   help="validate on every K-th good view held out (default 5; 0 = no)")
    p.add_argument("--intrinsics", metavar="FILE",
                   help="a calibration file (YAML) whose camera model is used as it is: the "
                   "intrinsics are not refined (default: refined jointly with the hand-eye)")
    p.add_argument("--robot-sigma-mm", type=float, default=None,
                   help="robot pose noise per axis, mm (default: estimated from the data)")
    p.add_argument("--robot-sigma-deg", type=float, default=None,
                   help="robot orientation noise per axis, deg (default: estimated)")
    p.add_argument("--max-rms-px", type=float, default=None,
                   help="refuse a hand-eye whose reprojection RMS (recorded poses) is above this "
                   "(default 0.25 %% of the image diagonal: 5.7 px at 1920x1200)")
    p.add_argument("--max-consistency", type=float, nargs=2, default=[3.0, 0.5],
                   metavar=("MM", "DEG"),
                   help="refuse a hand-eye whose robot poses and images disagree by more than "
                   "this RMS (default 3 mm 0.5 deg)")
    p.add_argument("--pivot-mm", type=float, default=350.0,
                   help="--auto: distance along tool z about which poses are tilted (default 350)")
    p.add_argument("--workspace", metavar="X0,Y0,Z0,X1,Y1,Z1",
                   help="--auto: workspace box for the flange (mm); default first pose +-400 mm")
    p.add_argument("--export", action="append", default=[], metavar="FORMAT:FILE",
                   help="also write the hand-eye as FORMAT (easy_handeye, tf, matrix, "
                   "abb_tooldata) to FILE; repeatable")
    p.set_defaults(func=_run)


def _workspace(text: str | None) -> tuple[Any, Any]:
    import numpy as np

    if text is None:
        return None, None
    try:
        v = [float(x) for x in text.split(",")]
    except ValueError as err:
        raise ConfigError(f"--workspace {text!r}: must be six numbers X0,Y0,Z0,X1,Y1,Z1 (mm)") \
            from err
    if len(v) != 6 or any(v[i] >= v[i + 3] for i in range(3)):
        raise ConfigError(f"--workspace {text!r}: must be six numbers X0,Y0,Z0,X1,Y1,Z1 (mm) "
                          f"with X0<X1, Y0<Y1, Z0<Z1")
    return np.array(v[:3]), np.array(v[3:])


def _run(args: argparse.Namespace) -> int:
    from calibration.export import FORMATS
    from calibration.targets import parse_board_spec

    board = parse_board_spec(args.board)
    exports = []
    for e in args.export:
        fmt, _, path = e.partition(":")
        if fmt not in FORMATS or not path:
            raise ConfigError(f"--export {e!r}: use FORMAT:FILE with FORMAT one of "
                              f"{', '.join(FORMATS)}")
        exports.append((fmt, path))
    solve_kw: dict[str, Any] = {
        "holdout_every": args.holdout_every, "robot_sigma_mm": args.robot_sigma_mm,
        "robot_sigma_deg": args.robot_sigma_deg, "max_rms_px": args.max_rms_px,
        "max_consistency_mm": args.max_consistency[0],
        "max_consistency_deg": args.max_consistency[1], "log": _stderr_line}
    if args.intrinsics is not None:
        from calibration.calibration_file import load_calibration

        if args.images is not None:
            raise ConfigError("--intrinsics fixes the camera model for a hand-eye; --images "
                              "calibrates the intrinsics themselves: give one or the other")
        solve_kw["intrinsics"] = load_calibration(args.intrinsics).camera
        solve_kw["intrinsics_source"] = str(args.intrinsics)
    try:
        return _solve_and_write(args, board, exports, solve_kw)
    except CalibrationError as err:
        # A refusal writes its report too: what was found, why it stopped, what would change it.
        report = dict(err.details.get("report") or {})
        report.update({"status": "refused", "error": str(err),
                       "options": list(err.details.get("options", [])),
                       "details": {k: v for k, v in err.details.items()
                                   if k not in ("report", "options")}})
        emit_json(report, args.report)
        if report["options"]:
            _stderr_line("would change the outcome: " + "; ".join(report["options"]))
        raise


def _stderr_line(line: str) -> None:
    if line:
        print(line, file=sys.stderr, flush=True)


def _solve_and_write(args: argparse.Namespace, board: Any, exports: list[tuple[str, str]],
                     solve_kw: dict[str, Any]) -> int:
    from calibration.calibration_file import save_calibration
    from calibration.export import export_hand_eye

    if args.images is not None:
        from calibration.teach import calibrate_images

        if args.eye_to_hand or args.auto:
            raise ConfigError("--images calibrates intrinsics only; --eye-to-hand and --auto "
                              "need robot poses (--from-folder or --port)")
        paths = sorted(glob.glob(args.images))
        if not paths:
            raise ConfigError(f"--images {args.images!r} matches no file; quote the glob and "
                              f"check the folder")
        calib, report = calibrate_images(paths, board, log=_stderr_line)
        if exports:
            raise ConfigError("--export needs a hand-eye result; --images gives intrinsics only")
    elif args.from_folder is not None:
        from calibration.teach import calibrate_from_folder

        calib, report = calibrate_from_folder(args.from_folder, board, args.eye_to_hand,
                                              **solve_kw)
    else:
        calib, report = _teach(args, board, solve_kw)
    prev = save_calibration(args.output, calib)
    for fmt, path in exports:
        from controller.jsonio import atomic_write_text

        atomic_write_text(path, export_hand_eye(calib, fmt))
    report["status"] = "written"
    report["output"] = str(args.output)
    report["previous_file_kept"] = None if prev is None else str(prev)
    print(f"seamguide calibrate: wrote {args.output}"
          + (f" (previous kept as {prev})" if prev else ""), file=sys.stderr)
    emit_json(report, args.report)
    return 0


def _teach(args: argparse.Namespace, board: Any, solve_kw: dict[str, Any]) -> tuple[Any, Any]:
    import numpy as np

    from calibration.teach import run_teach
    from controller.geometry.camera_model import default_camera

    if args.camera is None:
        raise ConfigError("--port needs --camera URL (the camera to teach with)")
    first = None
    if args.first_joints is not None:
        try:
            first = np.array([float(v) for v in args.first_joints.split(",")])
        except ValueError as err:
            raise ConfigError(f"--first-joints {args.first_joints!r}: six numbers (deg) "
                              f"separated by commas") from err
        if first.shape != (6,):
            raise ConfigError(f"--first-joints {args.first_joints!r}: needs six values")
    robot = open_teach_robot(args.port)
    camera: Any = None
    try:
        if first is not None:
            robot.move_joints(first, 120.0)
        camera = open_teach_camera(args.camera, robot, board, default_camera(),
                                   eye_to_hand=args.eye_to_hand)
        lo, hi = _workspace(args.workspace)
        identity = {"robot": robot.identity(),
                    "camera": getattr(camera, "identity", lambda: {"url": args.camera})()}
        confirm = robot.controller_confirm() if args.confirm == "controller" else None
        return run_teach(robot, camera, board, auto_n=args.auto, eye_to_hand=args.eye_to_hand,
                         confirm=confirm,
                         save_dir=args.save_views, pivot_mm=args.pivot_mm,
                         workspace_min_mm=lo, workspace_max_mm=hi, identity=identity,
                         **solve_kw)
    finally:
        robot.close()
        if camera is not None:
            camera.close()


# ---------------------------------------------------------------------------------------------
# Adapters: the link's robot and the camera drivers seen through the teach routine's interfaces
# ---------------------------------------------------------------------------------------------
class TeachRobotAdapter:
    """A :class:`drivers.robot.Robot` seen as :class:`calibration.teach.TeachRobot`."""

    def __init__(self, robot: Any, url: str, speed_mm_s: float = 100.0) -> None:
        self.robot = robot
        self.url = url
        self.speed_mm_s = speed_mm_s

    def joints_deg(self) -> Any:
        """Current controller joints (deg)."""
        import numpy as np

        return np.asarray(self.robot.read_joints(), float)

    def flange_pose(self) -> Any:
        """Current flange pose (4x4, mm) as the controller reports it (tool0, wobj0)."""
        import numpy as np

        return np.asarray(self.robot.read_pose(), float)

    def move_joints(self, joints_deg: Any, timeout_s: float) -> None:
        """Move (checked by the link before sending) and wait until the controller says done."""
        import numpy as np

        self.robot.move_joints(np.asarray(joints_deg, float), self.speed_mm_s).wait(timeout_s)

    def identity(self) -> dict[str, Any]:
        """The controller's identity for the calibration metadata."""
        info = self.robot.identify()
        return {"url": self.url, **(info if isinstance(info, dict) else {"info": str(info)})}

    def controller_confirm(self, poll_s: float = 0.5) -> Any:
        """A ``confirm`` callable answered by the controller: a ``cycle_request`` event.

        The pendant program asks for job ``take`` (or any other name) to take a view, ``done``
        to solve, ``abort`` to stop.
        """
        def confirm(progress: Any) -> str:
            while True:
                ev = self.robot.poll_event(poll_s)
                if ev is not None and ev.kind == "cycle_request":
                    job = str(ev.job).strip().lower()
                    return job if job in ("done", "abort") else "take"
        return confirm

    def close(self) -> None:
        """Close the link."""
        self.robot.close()


def open_teach_robot(url: str) -> TeachRobotAdapter:
    """Open the robot at ``url`` through the link's registry (``drivers.robot.open_robot``)."""
    from drivers.robot import open_robot

    robot = open_robot(url)
    robot.open()
    return TeachRobotAdapter(robot, url)


class TeachCameraAdapter:
    """A camera from ``drivers.cameras.open_camera`` seen as a teach camera."""

    def __init__(self, camera: Any, url: str) -> None:
        self.camera = camera
        self.url = url

    def grab(self, timeout_s: float = 5.0) -> Any:
        """One frame (the driver applies its own deadline; CameraError if none comes)."""
        import numpy as np

        return np.asarray(self.camera.grab())

    def close(self) -> None:
        """Release the camera."""
        self.camera.close()

    def identity(self) -> dict[str, Any]:
        """The camera's identity for the calibration metadata."""
        return {"url": self.url, "driver": type(self.camera).__name__}


def open_teach_camera(url: str, robot: TeachRobotAdapter, board: Any, model: Any, *,
                      eye_to_hand: bool = False) -> Any:
    """The camera at ``url``; ``simboard:[?width=W&height=H&seed=S]`` renders the board.

    ``simboard:`` is the simulated board in the cell (drivers/sim/sim_board.py), rendered from the
    robot's reported flange pose, so that the whole routine runs without hardware.
    """
    import numpy as np

    if url.startswith("simboard:"):
        from urllib.parse import parse_qs, urlsplit

        from drivers.sim.sim_board import SimBoardCamera

        opts = {k: v[-1] for k, v in parse_qs(urlsplit(url).query).items()}
        unknown = set(opts) - {"width", "height", "seed"}
        if unknown:
            raise ConfigError(f"camera URL {url!r}: unknown option(s) {sorted(unknown)}; "
                              f"simboard: takes width, height, seed")
        w = int(opts.get("width", 640))
        h = int(opts.get("height", round(w * model.height / model.width)))
        cam = model.scaled(w / model.width) if w != model.width else model
        if h != cam.height:
            raise ConfigError(f"camera URL {url!r}: height must keep the aspect ratio")
        if eye_to_hand:
            from drivers.sim.sim_board import look_at

            T_base_cam = look_at(np.array([1500.0, -300.0, 1000.0]),
                                 np.array([1000.0, 0.0, 650.0]), 0.0, up=np.array([0, 0, 1.0]))
            from controller.geometry.poses import make_pose, rotation_about

            Rfb = rotation_about([1, 0, 0], np.pi)
            cb = board.object_points().mean(axis=0)
            return SimBoardCamera(cam, board, robot.flange_pose, T_base_cam=T_base_cam,
                                  T_flange_board=make_pose(Rfb, np.array([0, 0, 150.0]) - Rfb @ cb),
                                  seed=int(opts.get("seed", 0)))
        return SimBoardCamera(cam, board, robot.flange_pose, seed=int(opts.get("seed", 0)))
    from drivers.cameras import open_camera

    return TeachCameraAdapter(open_camera(url), url)
