"""Lighting of the simulated scene: ambient, a point key light, glare, vignetting and exposure.

Computed on every :data:`LIGHT_STEP`-th pixel and interpolated (light is smooth). Classic scenes:
ambient + Lambert diffuse from the point light, uneven (low-frequency) light, Phong glare,
vignetting, exposure. A wide look adds: the two sheets tilted (each its own normal, so they shade
differently), a soft shadow of the key light (a half-plane with a penumbra), a ring light's
specular ring around the camera's mirror point, and a spot light's fall-off.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from controller.geometry.camera_model import CameraModel
from drivers.sim.sim_scene import Scene

F32 = NDArray[np.float32]
F64 = NDArray[np.float64]

LIGHT_STEP = 4  # lighting is smooth: evaluated on every 4th pixel and interpolated


def lighting(scene: Scene, cam: CameraModel, a: F32, b: F32, t: F32, xn: F32, yn: F32,
             T_local_cam: F64) -> tuple[F32, F32]:
    """Diffuse gain and specular radiance (H, W) at the pixels whose rays hit local (a, b)."""
    _ = (cam, t)
    s = LIGHT_STEP
    A = np.nan_to_num(a[::s, ::s].astype(np.float64))
    B = np.nan_to_num(b[::s, ::s].astype(np.float64))
    Z = scene.height(A)
    slope = scene.height_slope(A)
    look = scene.look
    tilt = np.zeros_like(A)
    if look is not None and (look.tilt_a_rad or look.tilt_b_rad):
        side_b = scene.seam_b(A) < B
        tilt = np.where(side_b, np.tan(look.tilt_b_rad), -np.tan(look.tilt_a_rad))
        Z = scene.surface_z(A, B)
    n = np.stack([-slope, tilt, np.ones_like(slope)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    P = np.stack([A, B, Z], axis=-1)
    L = scene.light_local_mm - P
    L /= np.linalg.norm(L, axis=-1, keepdims=True)
    V = T_local_cam[:3, 3] - P
    dist = np.linalg.norm(V, axis=-1, keepdims=True)
    V /= dist
    Hv = L + V
    Hv /= np.linalg.norm(Hv, axis=-1, keepdims=True)
    diffuse = np.clip(np.sum(n * L, axis=-1), 0, 1)
    rng = np.random.default_rng(np.random.SeedSequence([scene.seed, 31]))
    ph = rng.uniform(0, 2 * np.pi, 4)
    lam = rng.uniform(90, 220, 2)
    uneven = 1 + scene.uneven_light * (0.6 * np.sin(A / lam[0] + ph[0]) * np.cos(B / lam[1] + ph[1])
                                       + 0.4 * np.sin((A + B) / (0.7 * lam[0]) + ph[2]))
    if look is not None and look.key_shadow:
        a_s, b_s, ang, pen, depth = look.key_shadow
        sd = ((A - a_s) * np.cos(ang) + (B - b_s) * np.sin(ang)) / pen
        m = np.clip(0.5 + 0.5 * sd, 0.0, 1.0)
        diffuse = diffuse * (1.0 - depth * m * m * (3 - 2 * m))  # smoothstep penumbra
    gain = (scene.ambient + scene.light_power * diffuse) * uneven
    nh = np.clip(np.sum(n * Hv, axis=-1), 0, 1)
    spec = scene.glare * (nh ** 80 + 0.3 * nh ** 12)
    if look is not None and look.ring_glare > 0:
        # A ring light round the lens (radius ~40 mm) mirrors as a bright ring where the normal
        # is half the ring's angular radius off the line of sight.
        theta = np.arccos(np.clip(np.sum(n * V, axis=-1), -1.0, 1.0))
        th0 = 0.5 * np.arctan(40.0 / dist[..., 0])
        spec = spec + look.ring_glare * np.exp(-(((theta - th0) / (0.35 * th0 + 0.004)) ** 2))
    # Vignetting: cos^4-like fall-off with the normalised radius from the principal point.
    xc, yc = xn[::s, ::s].astype(np.float64), yn[::s, ::s].astype(np.float64)
    r2 = (xc * xc + yc * yc) / max(float(np.max(xc * xc + yc * yc)), 1e-9)
    vig = (1 - scene.vignetting * r2) * scene.exposure
    if look is not None and look.spot > 0:
        gain = gain * np.exp(-2.0 * look.spot * r2)
    size = (a.shape[1], a.shape[0])
    g = cv2.resize((gain * vig).astype(np.float32), size, interpolation=cv2.INTER_LINEAR)
    sp = cv2.resize((spec * vig).astype(np.float32), size, interpolation=cv2.INTER_LINEAR)
    return g, sp
