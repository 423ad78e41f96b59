"""``seamguide fk`` and ``seamguide ik``: the robot model by hand."""

from __future__ import annotations

import argparse
from typing import Any

from controller.jsonio import emit_json


def register(sub: Any) -> None:
    """Add the ``fk`` and ``ik`` subcommands to ``sub`` (an argparse subparsers object)."""
    fk = sub.add_parser("fk", help="flange pose for controller joint values (degrees)",
                        description="Forward kinematics of the IRB 2400: prints the flange (tool0) "
                        "pose in the base frame for controller joint values in degrees.")
    fk.add_argument("joints", nargs=6, type=float, metavar="J", help="axes 1-6 in degrees")
    fk.add_argument("--output", help="write the JSON here instead of stdout")
    fk.set_defaults(func=_fk)

    ik = sub.add_parser("ik", help="every joint solution for a flange pose",
                        description="Inverse kinematics of the IRB 2400: lists every controller "
                        "joint solution (degrees) within limits for a flange pose given as "
                        "position (mm) and quaternion (w, x, y, z).")
    ik.add_argument("pose", nargs=7, type=float, metavar="V", help="X Y Z QW QX QY QZ")
    ik.add_argument("--output", help="write the JSON here instead of stdout")
    ik.set_defaults(func=_ik)


def _fk(args: argparse.Namespace) -> int:
    from controller.geometry.kinematics import flange_pose, irb2400
    from controller.geometry.poses import pose_to_dict

    emit_json(pose_to_dict(flange_pose(irb2400(), args.joints)), args.output)
    return 0


def _ik(args: argparse.Namespace) -> int:
    from controller.geometry.kinematics import inverse_kinematics, irb2400
    from controller.geometry.poses import pose_from_pos_quat

    T = pose_from_pos_quat(args.pose[:3], args.pose[3:], "pose")
    sols = inverse_kinematics(irb2400(), T)
    emit_json({"solutions_deg": [[round(float(v), 6) for v in s] for s in sols]}, args.output)
    return 0 if sols else 12
