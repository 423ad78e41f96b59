"""Synthetic seams and camera poses with exact ground truth for the geometry tests."""

import numpy as np

from controller.geometry.camera_model import default_camera
from controller.geometry.poses import look_at
from controller.stereo.locate import ViewObservation

CENTRE = np.array([1000.0, 0.0, 300.0])


def seam_curve(kind: str, n: int = 3000) -> np.ndarray:
    s = np.linspace(-1, 1, n)
    zero = 0 * s
    if kind == "straight":
        P = np.column_stack([zero, 90 * s, zero])
    elif kind == "arc":
        P = np.column_stack([-120 + 120 * np.cos(s), 120 * np.sin(s), zero])
    elif kind == "s_curve":
        P = np.column_stack([25 * np.sin(np.pi * s), 100 * s, zero])
    elif kind == "nonplanar":
        P = np.column_stack([zero, 100 * s, 30 * np.cos(np.pi * s / 2) ** 2])
    else:
        raise ValueError(kind)
    return P + CENTRE


def camera_poses(P: np.ndarray, baseline_mm: float = 240.0, standoff_mm: float = 330.0,
                 along: np.ndarray | None = None) -> list[np.ndarray]:
    """Two cameras looking at the seam centre, displaced across (default) or along the seam."""
    c = P.mean(axis=0)
    d = np.array([1.0, 0, 0]) if along is None else along
    return [look_at(c + s * baseline_mm / 2 * d + [0, 0, standoff_mm], c, up=(1, 0, 0))
            for s in (-1, 1)]


def observe(P, poses, noise_px=0.0, seed=0, camera=None, step=3):
    cam = camera or default_camera()
    rng = np.random.default_rng(seed)
    out = []
    for i, T in enumerate(poses):
        uv = cam.project(P, T)
        uv = uv[cam.in_image(uv)][::step]
        uv = uv + rng.normal(0, noise_px, uv.shape)
        out.append(ViewObservation(cam, T, uv, f"view{i + 1}"))
    return out
