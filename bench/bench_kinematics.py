"""Foundation figures: FK against an independent DH chain, IK round trips, camera round trips.

    .venv/bin/python bench/bench_kinematics.py
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

from test_kinematics import dh_flange  # noqa: E402

from controller.geometry.camera_model import default_camera  # noqa: E402
from controller.geometry.kinematics import flange_pose, inverse_kinematics, irb2400  # noqa: E402
from controller.geometry.poses import look_at, pose_error  # noqa: E402


def main() -> int:
    robot = irb2400()
    rng = np.random.default_rng(2024)
    J = rng.uniform(robot.limits_deg[:, 0], robot.limits_deg[:, 1], (1000, 6))
    fk_mm, fk_deg, ik_mm, n_sol, found = 0.0, 0.0, 0.0, [], 0
    t_fk = t_ik = 0.0
    for j in J:
        t0 = time.perf_counter()
        T = flange_pose(robot, j)
        t_fk += time.perf_counter() - t0
        d_mm, d_deg = pose_error(T, dh_flange(j))
        fk_mm, fk_deg = max(fk_mm, d_mm), max(fk_deg, d_deg)
        t0 = time.perf_counter()
        sols = inverse_kinematics(robot, T)
        t_ik += time.perf_counter() - t0
        n_sol.append(len(sols))
        found += any(np.max(np.abs(s - j)) < 1e-6 for s in sols)
        for s in sols:
            ik_mm = max(ik_mm, pose_error(flange_pose(robot, s), T)[0])
    cam = default_camera()
    u, v = np.meshgrid(np.arange(0, cam.width, 8.0), np.arange(0, cam.height, 8.0))
    uv = np.column_stack([u.ravel(), v.ravel()])
    T = look_at([1000, 0, 650], [1000, 0, 300], up=(1, 0, 0))
    o, d = cam.pixel_rays(uv, T)
    back = cam.project(o + d * 400.0, T)
    print(f"FK vs hand-built DH chain, 1000 random joint sets: max {fk_mm:.2e} mm, "
          f"{fk_deg:.2e} deg")
    print(f"IK: 1000 random reachable poses, {np.mean(n_sol):.1f} solutions on average "
          f"(min {min(n_sol)}, max {max(n_sol)}), original joints found {found}/1000, worst FK "
          f"of a solution {ik_mm:.2e} mm")
    print(f"time: FK {1e6 * t_fk / 1000:.0f} us, IK {1e3 * t_ik / 1000:.2f} ms per pose")
    print(f"camera: project(back-project) over {len(uv)} pixels of the 2272x1704 image: "
          f"max {np.max(np.abs(back - uv)):.2e} px")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
