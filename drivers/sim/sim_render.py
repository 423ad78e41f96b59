"""Render a simulated workpiece as the wrist camera sees it, with truth.

The workpiece is a :mod:`drivers.sim.sim_scene` scene. :func:`render` casts the ray through every
pixel of a :class:`~controller.geometry.camera_model.CameraModel` (its distortion included: pixels
are undistorted once per camera and cached) from the pose ``T_base_cam`` onto the sheets and the
table and shades each hit (:mod:`drivers.sim.sim_radiance`: the gap drawn analytically with
unbiased anti-aliased edges, ``ss > 1`` adds supersampling on top; textures in
:mod:`drivers.sim.sim_texture`, light in :mod:`drivers.sim.sim_light`, the wide look's gap in
:mod:`drivers.sim.sim_gap`), then applies the camera (:func:`sensor`): defocus (Gaussian blur),
a colour cast (wide looks), a camera response (gamma :data:`GAMMA`: the image holds
``255 * radiance ** (1 / GAMMA)``), sensor noise (Gaussian, ``noise_dn`` grey levels), uint8, and
JPEG compression (wide looks).

The ground truth (:class:`Rendered`) is the scene's seam centreline projected with
``CameraModel.project`` (the same distortion model), clipped to the image, each end's kind
(``joint_end``: the sheets stop facing each other in the image; ``image_border``: the seam leaves
the image), the spans covered by tack welds and spatter (the centreline runs straight through
them), and the lines drawn on the sheets (pen, marker, soapstone) as image polylines.

What this does not model: inter-reflections, occlusion of the table or the seam by the part (a
raised sheet hiding the gap), motion blur, rolling shutter, weld seams (only tacks), the height
step between two sheets (only its shadow), lens flare, a camera's demosaicing.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np
from numpy.typing import NDArray

from controller.errors import ConfigError
from controller.geometry.camera_model import CameraModel
from controller.geometry.poses import look_at
from drivers.sim.sim_radiance import radiance
from drivers.sim.sim_scene import Scene

F64 = NDArray[np.float64]
F32 = NDArray[np.float32]

#: Camera response: stored grey level = 255 * radiance ** (1 / GAMMA), radiance in 0..1.
GAMMA = 2.2
#: Colour of rust relative to bare steel (B, G, R gains).
RUST_BGR = (0.55, 0.75, 1.05)


@dataclass(frozen=True, eq=False)
class Rendered:
    """One rendered image and its ground truth.

    ``image`` is uint8 greyscale (H, W), or BGR (H, W, 3) for a wide look with a colour cast.
    ``seam_px`` (M, 2) is the true projection (u, v) of the visible part of the seam centreline,
    ordered as ``scene.seam_points_mm``; ``seam_points_mm`` (M, 3) are those points in the base
    frame; ``seam_index`` (M,) their indices in the scene's polyline. ``ends_in_image`` says
    whether the seam's first and last true end points are in the image; ``end_kinds`` gives each
    visible end's kind, ``joint_end`` or ``image_border``, in the order of ``seam_px``;
    ``end_tol_px`` how far (px, along the seam) a rounded plate corner leaves the joint ends in
    doubt. ``gap_px`` is the gap's apparent width (median, px). ``occluded_spans_px``: (s0, s1)
    arc-length ranges (px from ``seam_px[0]``) covered by tack welds or spatter.
    ``pen_lines_px``: the lines drawn on the sheets, each (K, 2) px, clipped to the image.
    """

    image: NDArray[np.uint8]
    seam_px: F64
    seam_points_mm: F64
    seam_index: NDArray[np.int64]
    ends_in_image: tuple[bool, bool]
    gap_px: float
    T_base_cam: F64
    camera: CameraModel
    scene: Scene
    end_kinds: tuple[str, str] = ("joint_end", "joint_end")
    end_tol_px: float = 0.0
    occluded_spans_px: tuple[tuple[float, float], ...] = ()
    pen_lines_px: list[F64] = field(default_factory=list)


def render(scene: Scene, camera: CameraModel, T_base_cam: NDArray[np.float64], *, seed: int,
           ss: int = 1) -> Rendered:
    """Render ``scene`` seen by ``camera`` at pose ``T_base_cam`` (base frame, mm); deterministic.

    ``seed`` drives the sensor noise only (the scene holds everything else). ``ss`` is the
    supersampling factor per axis (1 is enough for unbiased gap edges; see the module doc).
    Returns a :class:`Rendered` with a uint8 image of ``camera.width x camera.height``.
    Raises :class:`ConfigError` for ``ss < 1`` or a pose that is not 4x4.
    """
    T = np.asarray(T_base_cam, dtype=np.float64)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise ConfigError("render: T_base_cam must be a finite 4x4 pose")
    if int(ss) < 1:
        raise ConfigError(f"render: ss must be an integer >= 1, got {ss}")
    ss = int(ss)
    cam_ss = camera if ss == 1 else _supersampled(camera, ss)
    rad, gap_w, rust_w = radiance(scene, cam_ss, T)
    if ss > 1:
        size = (camera.width, camera.height)
        rad = np.asarray(cv2.resize(rad, size, interpolation=cv2.INTER_AREA), np.float32)
        if rust_w is not None:
            rust_w = np.asarray(cv2.resize(rust_w, size, interpolation=cv2.INTER_AREA), np.float32)
        gap_w /= ss
    image = sensor(scene, rad, rust_w, np.random.default_rng(
        np.random.SeedSequence([scene.seed, int(seed), 5])))
    return _truth(scene, camera, T, image, gap_w)


def sensor(scene: Scene, rad: F32, rust_w: F32 | None,
           rng: np.random.Generator) -> NDArray[np.uint8]:
    """The camera: blur, colour (wide looks), gamma, noise, uint8, JPEG (wide looks)."""
    if scene.blur_px > 0:
        rad = np.asarray(cv2.GaussianBlur(rad, (0, 0), scene.blur_px), np.float32)
    look = scene.look
    if look is not None and look.cast_bgr is not None:
        tint = np.ones(3, np.float32) if rust_w is None else np.asarray(RUST_BGR, np.float32)
        rust = np.zeros_like(rad) if rust_w is None else rust_w
        if rust_w is not None and scene.blur_px > 0:
            rust = np.asarray(cv2.GaussianBlur(rust, (0, 0), scene.blur_px), np.float32)
        rad = (rad[..., None] * np.asarray(look.cast_bgr, np.float32)
               * (1 + rust[..., None] * (tint - 1))).astype(np.float32)
    lut = (255.0 * np.linspace(0.0, 1.0, 4096) ** (1.0 / GAMMA)).astype(np.float32)
    idx = np.clip(rad * 4095.0 + 0.5, 0, 4095).astype(np.int32)
    out = lut[idx]
    if scene.noise_dn > 0:
        out += scene.noise_dn * rng.standard_normal(out.shape, dtype=np.float32)
    image = np.clip(out + 0.5, 0, 255).astype(np.uint8)
    if look is not None and look.jpeg_quality > 0:
        ok, buf = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, int(look.jpeg_quality)])
        assert ok, "cv2.imencode failed on a uint8 image"
        flag = cv2.IMREAD_COLOR if image.ndim == 3 else cv2.IMREAD_GRAYSCALE
        image = np.asarray(cv2.imdecode(buf, flag), np.uint8)
    return image


def _truth(scene: Scene, camera: CameraModel, T: F64, image: NDArray[np.uint8],
           gap_w: float) -> Rendered:
    uv = camera.project(scene.seam_points_mm, T)
    vis = np.isfinite(uv[:, 0]) & camera.in_image(uv)
    idx = _longest_run(vis)
    px = uv[idx]
    n = len(scene.seam_points_mm)
    kinds = ("joint_end", "joint_end")
    spans: list[tuple[float, float]] = []
    tol_px = 0.0
    if len(idx) >= 2:
        kinds = ("joint_end" if idx[0] == 0 else "image_border",
                 "joint_end" if idx[-1] == n - 1 else "image_border")
        s_mm = np.concatenate([[0.0], np.cumsum(np.linalg.norm(
            np.diff(scene.seam_points_mm, axis=0), axis=1))])
        s_px = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(px, axis=0), axis=1))])
        s_vis = s_mm[idx]
        for s0, s1 in scene.occluded_spans_mm:
            if s1 < s_vis[0] or s0 > s_vis[-1]:
                continue
            p0, p1 = np.interp([max(s0, s_vis[0]), min(s1, s_vis[-1])], s_vis, s_px)
            spans.append((float(p0), float(p1)))
        tol_px = scene.end_tol_mm * float(s_px[-1] / max(s_vis[-1] - s_vis[0], 1e-9))
    pens = []
    for P in scene.pen_lines_mm():
        q = camera.project(P, T)
        run = _longest_run(np.isfinite(q[:, 0]) & camera.in_image(q))
        if len(run) >= 2:
            pens.append(q[run])
    return Rendered(image=image, seam_px=px, seam_points_mm=scene.seam_points_mm[idx],
                    seam_index=idx, ends_in_image=(bool(vis[0]), bool(vis[-1])),
                    gap_px=float(gap_w), T_base_cam=T, camera=camera, scene=scene,
                    end_kinds=kinds, end_tol_px=tol_px, occluded_spans_px=tuple(spans),
                    pen_lines_px=pens)


def _supersampled(camera: CameraModel, ss: int) -> CameraModel:
    K = camera.K.copy()
    K[:2, :2] *= ss
    K[0, 2] = ss * (K[0, 2] + 0.5) - 0.5
    K[1, 2] = ss * (K[1, 2] + 0.5) - 0.5
    return CameraModel(camera.width * ss, camera.height * ss, K, camera.dist.copy(), camera.name)


def _longest_run(mask: NDArray[np.bool_]) -> NDArray[np.int64]:
    if not mask.any():
        return np.zeros(0, np.int64)
    m = np.concatenate([[False], mask, [False]]).astype(np.int8)
    starts = np.flatnonzero(np.diff(m) == 1)
    ends = np.flatnonzero(np.diff(m) == -1)
    k = int(np.argmax(ends - starts))
    return np.arange(starts[k], ends[k], dtype=np.int64)


# ---------------------------------------------------------------------------------------------
# View poses
# ---------------------------------------------------------------------------------------------
def suggest_view_poses(scene: Scene, camera: CameraModel, n: int = 2,
                       standoff_mm: float | None = None, baseline_mm: float = 200.0) -> list[F64]:
    """``n`` camera poses ``T_base_cam`` looking at the seam's middle from different directions.

    The cameras sit ``standoff_mm`` from the seam's middle point (base frame, mm), spread over a
    ``baseline_mm`` line across the seam (so that epipolar lines cross the seam), and are rolled
    so that the image's long axis runs along the seam's chord (the seam fills the image). Raises
    :class:`ConfigError` for ``n < 1`` or non-positive distances. The default standoff is the
    look's (:attr:`Look.standoff_mm`), 350 mm for a classic scene.
    """
    if standoff_mm is None:
        standoff_mm = scene.look.standoff_mm if scene.look is not None else 350.0
    if n < 1 or standoff_mm <= 0 or baseline_mm < 0:
        raise ConfigError(f"suggest_view_poses: need n >= 1, standoff_mm > 0, baseline_mm >= 0; "
                          f"got n={n}, standoff_mm={standoff_mm}, baseline_mm={baseline_mm}")
    P = scene.seam_points_mm
    centre = P[len(P) // 2]
    chord = P[-1] - P[0]
    normal = scene.surface_normal
    chord -= normal * (chord @ normal)
    chord /= np.linalg.norm(chord)
    across = np.cross(normal, chord)
    offsets = [0.0] if n == 1 else list(np.linspace(-baseline_mm / 2, baseline_mm / 2, n))
    poses = []
    for off in offsets:
        along = np.sqrt(max(standoff_mm**2 - off**2, 1.0))
        eye = centre + normal * along + across * off
        poses.append(look_at(eye, centre, up=across))
    _ = camera  # the field of view is not used yet: the default lens sees ~280 mm at 350 mm
    return poses
