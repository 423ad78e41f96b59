"""Render a simulated workpiece as the wrist camera sees it, with truth.

The workpiece is a :mod:`drivers.sim.sim_scene` scene.

:func:`render` casts the ray through every pixel of a
:class:`~controller.geometry.camera_model.CameraModel`
(its distortion included: pixels are undistorted once per camera and cached) from the pose
``T_base_cam`` onto the sheets' surface and the table, and shades each hit:

- the gap between the sheets is drawn *analytically*: the signed distance ``d`` (mm, in the table
  plane) from the hit to the seam curve and its change from pixel to pixel give the fraction of
  the pixel's footprint that falls in the gap (a box filter), so both gap edges and hence the
  centreline are anti-aliased without bias; ``ss > 1`` adds supersampling on top (each pixel is
  rendered as ss x ss sub-pixels and box-averaged), used by the tests to check the analytic
  coverage;
- brushed-metal texture per sheet (anisotropic noise along its own brushing direction), marker
  dots, scratches and pen lines on the sheets; table holes and other plates on the table;
- lighting: ambient + Lambert diffuse from a point light, uneven (low-frequency) light, Phong
  specular glare on the metal (it can saturate), vignetting, exposure;
- then defocus (Gaussian blur), a camera response (gamma :data:`GAMMA`: the image holds
  ``255 * radiance ** (1 / GAMMA)``) and sensor noise (Gaussian, ``noise_dn`` grey levels),
  quantised to uint8.

The ground truth is the scene's seam centreline projected with ``CameraModel.project`` (the same
distortion model), clipped to the image: ``Rendered.seam_px`` with ``Rendered.seam_points_mm``.

What this does not model: shadows and inter-reflections, occlusion of the table or the seam by the
part, colour, motion blur, rolling shutter, JPEG artefacts, the gap floor's own shape (it is a
uniformly dark slot), bright bevels on the sheet edges.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from controller.errors import ConfigError
from controller.geometry.camera_model import CameraModel
from controller.geometry.poses import invert, look_at
from drivers.sim.sim_scene import Decal, Scene

F64 = NDArray[np.float64]
F32 = NDArray[np.float32]

#: Camera response: stored grey level = 255 * radiance ** (1 / GAMMA), radiance in 0..1.
GAMMA = 2.2
#: Texel size (mm) of the decal and brushing textures.
TEX_MM = 0.2
_LIGHT_STEP = 4  # lighting is smooth: evaluated on every 4th pixel and interpolated


@dataclass(frozen=True, eq=False)
class Rendered:
    """One rendered image and its ground truth.

    ``image`` is uint8 greyscale (H, W). ``seam_px`` (M, 2) is the true projection (u, v) of the
    visible part of the seam centreline, ordered as ``scene.seam_points_mm``; ``seam_points_mm``
    (M, 3) are those points in the base frame; ``seam_index`` (M,) their indices in the scene's
    polyline. ``ends_in_image`` says whether the seam's first and last true end points are in the
    image (when not, the visible end lies on the image border). ``gap_px`` is the gap's apparent
    width (median, px).
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


# ---------------------------------------------------------------------------------------------
# Cached per-camera and per-scene data
# ---------------------------------------------------------------------------------------------
@functools.lru_cache(maxsize=4)
def _rays_cached(width: int, height: int, K: bytes, dist: bytes) -> tuple[F32, F32]:
    cam = CameraModel(width, height, np.frombuffer(K).reshape(3, 3).copy(),
                      np.frombuffer(dist).copy())
    v, u = np.mgrid[0:height, 0:width]
    # Newton converges quadratically: 6 steps reach ~1e-15 for a calibrated lens (NaN if not).
    xy = cam.pixels_to_normalized(np.column_stack([u.ravel(), v.ravel()]).astype(np.float64),
                                  iterations=6)
    if not np.all(np.isfinite(xy)):
        raise ConfigError(f"camera {cam.name}: distortion is not invertible over the whole image; "
                          "check the calibration's distortion coefficients")
    return (xy[:, 0].reshape(height, width).astype(np.float32),
            xy[:, 1].reshape(height, width).astype(np.float32))


def _rays(cam: CameraModel) -> tuple[F32, F32]:
    return _rays_cached(cam.width, cam.height, cam.K.tobytes(), cam.dist.tobytes())


@dataclass(frozen=True, eq=False)
class _Textures:
    brush_a: F32
    brush_b: F32
    decals: NDArray[np.uint8]  # (H, W, 4): value_part, alpha_part, value_table, alpha_table
    a0: float
    b0: float


def _brush(rng: np.random.Generator, size: int = 1024) -> F32:
    """A tileable brushed-metal pattern: noise stretched along the texture's u axis, zero mean.

    Blurred by a periodic Gaussian in the Fourier domain (cv2 filters have no wrap-around border).
    """
    f = np.fft.fftfreq(size)
    fy, fx = np.meshgrid(f, f, indexing="ij")

    def blur(noise: NDArray[Any], sx: float, sy: float) -> NDArray[Any]:
        g = np.exp(-2 * np.pi**2 * ((fx * sx) ** 2 + (fy * sy) ** 2))
        return np.real(np.fft.ifft2(np.fft.fft2(noise) * g))

    t = blur(rng.standard_normal((size, size)), 40.0, 0.8)
    t2 = blur(rng.standard_normal((size, size)), 6.0, 6.0)
    t = t / (t.std() + 1e-9) + 0.4 * t2 / (t2.std() + 1e-9)
    return (t / (t.std() + 1e-9)).astype(np.float32)


@functools.lru_cache(maxsize=4)
def _textures(scene: Scene) -> _Textures:
    rng = np.random.default_rng(np.random.SeedSequence([scene.seed, 77]))
    half = scene.chord_mm / 2
    b_lo, b_hi = scene.b_range_mm
    margin = 220.0
    a0, b0 = -half - margin, b_lo - margin
    w = int(np.ceil((2 * half + 2 * margin) / TEX_MM))
    h = int(np.ceil((b_hi - b_lo + 2 * margin) / TEX_MM))
    planes = [np.zeros((h, w), np.uint8) for _ in range(4)]
    shift = 4  # cv2 drawing with 4 fractional bits: 1/16 texel
    scale = 16.0 / TEX_MM

    def pt(a: float, b: float) -> tuple[int, int]:
        return int(round((a - a0) * scale)), int(round((b - b0) * scale))

    for d in scene.decals:
        layers = {"part": [(0, 1)], "table": [(2, 3)], "all": [(0, 1), (2, 3)]}[d.layer]
        for cv, ca in layers:
            _draw(planes[cv], planes[ca], d, pt, scale, shift)
    return _Textures(_brush(rng), _brush(rng), np.asarray(cv2.merge(planes), np.uint8), a0, b0)


def _draw(plane_v: NDArray[np.uint8], plane_a: NDArray[np.uint8], d: Decal, pt: Any,
          scale: float, shift: int) -> None:
    val = int(round(255 * min(max(d.value, 0.0), 1.0)))
    for plane, colour in ((plane_v, val), (plane_a, 255)):
        if d.shape == "dot":
            cv2.circle(plane, pt(*d.p0), int(round(d.radius_mm * scale)), colour, -1,
                       cv2.LINE_AA, shift)
        elif d.shape == "line":
            thick = max(1, int(round(d.width_mm / TEX_MM)))
            if d.width_mm / TEX_MM < 1.5:
                colour = int(colour * d.width_mm / TEX_MM / 1.5) if plane is plane_a else colour
            cv2.line(plane, pt(*d.p0), pt(*d.p1), colour, thick, cv2.LINE_AA, shift)
        elif d.shape == "rect":
            c = ((d.p0[0] + d.p1[0]) / 2, (d.p0[1] + d.p1[1]) / 2)
            hw, hh = abs(d.p1[0] - d.p0[0]) / 2, abs(d.p1[1] - d.p0[1]) / 2
            ca_, sa_ = np.cos(d.angle_rad), np.sin(d.angle_rad)
            corners = [pt(c[0] + x * ca_ - y * sa_, c[1] + x * sa_ + y * ca_)
                       for x, y in ((-hw, -hh), (hw, -hh), (hw, hh), (-hw, hh))]
            cv2.fillPoly(plane, [np.array(corners, np.int32)], colour, cv2.LINE_AA, shift)


# ---------------------------------------------------------------------------------------------
# Rendering
# ---------------------------------------------------------------------------------------------
def render(scene: Scene, camera: CameraModel, T_base_cam: NDArray[Any], *, seed: int,
           ss: int = 1) -> Rendered:
    """Render ``scene`` seen by ``camera`` at pose ``T_base_cam`` (base frame, mm); deterministic.

    ``seed`` drives the sensor noise only (the scene holds everything else). ``ss`` is the
    supersampling factor per axis (1 is enough for unbiased gap edges; see the module doc).
    Returns a :class:`Rendered` with a uint8 greyscale image of ``camera.width x camera.height``.
    Raises :class:`ConfigError` for ``ss < 1`` or a pose that is not 4x4.
    """
    T = np.asarray(T_base_cam, dtype=np.float64)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise ConfigError("render: T_base_cam must be a finite 4x4 pose")
    if int(ss) < 1:
        raise ConfigError(f"render: ss must be an integer >= 1, got {ss}")
    ss = int(ss)
    cam_ss = camera if ss == 1 else _supersampled(camera, ss)
    rad, gap_w = _radiance(scene, cam_ss, T)
    if ss > 1:
        rad = np.asarray(cv2.resize(rad, (camera.width, camera.height),
                                    interpolation=cv2.INTER_AREA), np.float32)
        gap_w /= ss
    if scene.blur_px > 0:
        rad = np.asarray(cv2.GaussianBlur(rad, (0, 0), scene.blur_px), np.float32)
    rng = np.random.default_rng(np.random.SeedSequence([scene.seed, int(seed), 5]))
    lut = (255.0 * np.linspace(0.0, 1.0, 4096) ** (1.0 / GAMMA)).astype(np.float32)
    idx = np.clip(rad * 4095.0 + 0.5, 0, 4095).astype(np.int32)
    out = lut[idx]
    if scene.noise_dn > 0:
        out += scene.noise_dn * rng.standard_normal(out.shape, dtype=np.float32)
    image = np.clip(out + 0.5, 0, 255).astype(np.uint8)

    uv = camera.project(scene.seam_points_mm, T)
    vis = np.isfinite(uv[:, 0]) & camera.in_image(uv)
    idx_vis = _longest_run(vis)
    return Rendered(image=image, seam_px=uv[idx_vis], seam_points_mm=scene.seam_points_mm[idx_vis],
                    seam_index=idx_vis,
                    ends_in_image=(bool(vis[0]), bool(vis[-1])), gap_px=float(gap_w),
                    T_base_cam=T, camera=camera, scene=scene)


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


def _radiance(scene: Scene, cam: CameraModel, T_base_cam: F64) -> tuple[F32, float]:
    """Linear radiance image (float32, 0..~1.5) and the gap's median apparent width (px)."""
    xn, yn = _rays(cam)
    T_local_cam = invert(scene.T_base_local) @ T_base_cam
    R = T_local_cam[:3, :3].astype(np.float32)
    C = T_local_cam[:3, 3]
    Dx = R[0, 0] * xn + R[0, 1] * yn + R[0, 2]
    Dy = R[1, 0] * xn + R[1, 1] * yn + R[1, 2]
    Dz = R[2, 0] * xn + R[2, 1] * yn + R[2, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        inv_dz = np.where(Dz < -1e-6, 1.0 / Dz, np.nan).astype(np.float32)
    cx, cy, cz = (np.float32(v) for v in C)
    # Part surface z = H(a): fixed-point iteration (converges: the view is steeper than the slope).
    t = (0.0 - cz) * inv_dz
    a = cx + t * Dx
    if scene.kind == "nonplanar":
        # Newton on g(t) = H(cx + t Dx) - (cz + t Dz): converges in a few steps from the plane.
        for _ in range(4):
            t = t - (scene.height(a) - (cz + t * Dz)) / (scene.height_slope(a) * Dx - Dz)
            a = cx + t * Dx
    b = cy + t * Dy
    tt = (np.float32(-scene.thickness_mm) - cz) * inv_dz
    at = cx + tt * Dx
    bt = cy + tt * Dy

    half = np.float32(scene.chord_mm / 2)
    b_lo, b_hi = (np.float32(v) for v in scene.b_range_mm)
    # Pixel footprint on the part (mm per px), for anti-aliasing the sheet borders.
    fp = np.abs(t) * np.sqrt(Dx * Dx + Dy * Dy + Dz * Dz) / np.float32(cam.fx)
    inside = np.minimum(np.minimum(half - np.abs(a), b - b_lo), b_hi - b)
    part_cov = np.clip(inside / (1.5 * fp) + 0.5, 0.0, 1.0)
    part_cov = np.nan_to_num(part_cov, nan=0.0)

    # Signed distance to the seam (table plane), exact in a band around it.
    d = b - scene.seam_b(a).astype(np.float32)
    gap_cov = np.zeros_like(d)
    band = np.abs(d) < max(3.0, 2 * scene.gap_mm)
    band &= np.abs(a) < half + 2.0
    band &= np.isfinite(d)
    rr, cc = np.nonzero(band)
    gap_w_px = float("nan")
    if rr.size:
        d = _exact_distance(scene, a, b, d, rr, cc)
        H, W = d.shape
        r0, r1 = np.maximum(rr - 1, 0), np.minimum(rr + 1, H - 1)
        c0, c1 = np.maximum(cc - 1, 0), np.minimum(cc + 1, W - 1)
        gu = (d[rr, c1] - d[rr, c0]) / np.maximum(c1 - c0, 1)
        gv = (d[r1, cc] - d[r0, cc]) / np.maximum(r1 - r0, 1)
        wpx = np.abs(gu) + np.abs(gv) + 1e-9  # mm of d swept by one pixel (box filter)
        dd = d[rr, cc]
        g2 = np.float32(scene.gap_mm / 2)
        cov = (np.minimum(dd + wpx / 2, g2) - np.maximum(dd - wpx / 2, -g2)) / wpx
        gap_cov[rr, cc] = np.clip(cov, 0.0, 1.0)
        gap_w_px = float(np.median(scene.gap_mm / np.sqrt(gu * gu + gv * gv + 1e-12)))

    tex = _textures(scene)
    sheet_a = d < 0
    brush_a = _sample_brush(tex.brush_a, a, b, scene.brush_angle_a_rad)
    brush_b = _sample_brush(tex.brush_b, a, b, scene.brush_angle_b_rad)
    c = np.float32(scene.brush_contrast)
    albedo = np.where(sheet_a, np.float32(scene.albedo_a) * (1 + c * brush_a),
                      np.float32(scene.albedo_b) * (1 + c * brush_b))
    dec_p = _sample_decals(tex, a, b)
    dec_t = _sample_decals(tex, at, bt)
    alpha_p = dec_p[:, :, 1].astype(np.float32) / 255.0
    albedo = albedo * (1 - alpha_p) + dec_p[:, :, 0].astype(np.float32) / 255.0 * alpha_p
    alpha_t = dec_t[:, :, 3].astype(np.float32) / 255.0
    table = np.float32(scene.albedo_table) * (1 + np.float32(0.05) * brush_b[::-1, ::-1])
    table = table * (1 - alpha_t) + dec_t[:, :, 2].astype(np.float32) / 255.0 * alpha_t

    gain, spec = _lighting(scene, cam, a, b, t, xn, yn, T_local_cam)
    metal = 1 - alpha_p
    rad_part = albedo * gain + spec * metal
    rad_part = rad_part * (1 - gap_cov) + np.float32(scene.gap_floor) * gain * gap_cov
    rad_table = table * gain + np.float32(0.1) * spec
    rad = part_cov * rad_part + (1 - part_cov) * rad_table
    rad = np.nan_to_num(rad, nan=0.0)
    return rad.astype(np.float32), gap_w_px


def _exact_distance(scene: Scene, a: F32, b: F32, d: F32, rr: NDArray[Any],
                    cc: NDArray[Any]) -> F32:
    """Signed distance (mm) to the seam curve by Newton on the closest point, in the band only."""
    if scene.kind in ("straight", "nonplanar"):
        return d
    pa = a[rr, cc].astype(np.float64)
    pb = b[rr, cc].astype(np.float64)
    a0 = pa.copy()
    for _ in range(4):
        f, f1, f2 = scene.seam_b(a0), scene.seam_db(a0), scene.seam_ddb(a0)
        g = (a0 - pa) + (f - pb) * f1
        gp = 1 + f1 * f1 + (f - pb) * f2
        a0 = a0 - g / gp
    f = scene.seam_b(a0)
    dist = np.hypot(pa - a0, pb - f) * np.sign(pb - scene.seam_b(pa))
    out = d.copy()
    out[rr, cc] = dist.astype(np.float32)
    return out


def _sample_brush(tex: F32, a: F32, b: F32, angle: float) -> F32:
    ca, sa = np.float32(np.cos(angle)), np.float32(np.sin(angle))
    mx = (ca * a + sa * b) / np.float32(TEX_MM)
    my = (-sa * a + ca * b) / np.float32(TEX_MM)
    mx = np.nan_to_num(mx, nan=0.0)
    my = np.nan_to_num(my, nan=0.0)
    return np.asarray(cv2.remap(tex, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_WRAP),
                      np.float32)


def _sample_decals(tex: _Textures, a: F32, b: F32) -> NDArray[np.uint8]:
    mx = np.nan_to_num((a - np.float32(tex.a0)) / np.float32(TEX_MM), nan=-10.0)
    my = np.nan_to_num((b - np.float32(tex.b0)) / np.float32(TEX_MM), nan=-10.0)
    mx = np.clip(mx, -10, 1e6).astype(np.float32)
    my = np.clip(my, -10, 1e6).astype(np.float32)
    return np.asarray(cv2.remap(tex.decals, mx, my, cv2.INTER_LINEAR,
                                borderMode=cv2.BORDER_CONSTANT, borderValue=(0, 0, 0, 0)),
                      np.uint8)


def _lighting(scene: Scene, cam: CameraModel, a: F32, b: F32, t: F32, xn: F32, yn: F32,
              T_local_cam: F64) -> tuple[F32, F32]:
    """Diffuse gain and specular radiance, computed on a coarse grid and interpolated."""
    s = _LIGHT_STEP
    A = np.nan_to_num(a[::s, ::s].astype(np.float64))
    B = np.nan_to_num(b[::s, ::s].astype(np.float64))
    Z = scene.height(A)
    slope = scene.height_slope(A)
    n = np.stack([-slope, np.zeros_like(slope), np.ones_like(slope)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    P = np.stack([A, B, Z], axis=-1)
    L = scene.light_local_mm - P
    L /= np.linalg.norm(L, axis=-1, keepdims=True)
    V = T_local_cam[:3, 3] - P
    V /= np.linalg.norm(V, axis=-1, keepdims=True)
    Hv = L + V
    Hv /= np.linalg.norm(Hv, axis=-1, keepdims=True)
    diffuse = np.clip(np.sum(n * L, axis=-1), 0, 1)
    rng = np.random.default_rng(np.random.SeedSequence([scene.seed, 31]))
    ph = rng.uniform(0, 2 * np.pi, 4)
    lam = rng.uniform(90, 220, 2)
    uneven = 1 + scene.uneven_light * (0.6 * np.sin(A / lam[0] + ph[0]) * np.cos(B / lam[1] + ph[1])
                                       + 0.4 * np.sin((A + B) / (0.7 * lam[0]) + ph[2]))
    gain = (scene.ambient + scene.light_power * diffuse) * uneven
    nh = np.clip(np.sum(n * Hv, axis=-1), 0, 1)
    spec = scene.glare * (nh ** 80 + 0.3 * nh ** 12)
    # Vignetting: cos^4-like fall-off with the normalised radius from the principal point.
    xc, yc = xn[::s, ::s].astype(np.float64), yn[::s, ::s].astype(np.float64)
    r2 = (xc * xc + yc * yc) / max(float(np.max(xc * xc + yc * yc)), 1e-9)
    vig = (1 - scene.vignetting * r2) * scene.exposure
    size = (a.shape[1], a.shape[0])
    g = cv2.resize((gain * vig).astype(np.float32), size, interpolation=cv2.INTER_LINEAR)
    sp = cv2.resize((spec * vig).astype(np.float32), size, interpolation=cv2.INTER_LINEAR)
    return g, sp


# ---------------------------------------------------------------------------------------------
# View poses
# ---------------------------------------------------------------------------------------------
def suggest_view_poses(scene: Scene, camera: CameraModel, n: int = 2, standoff_mm: float = 350.0,
                       baseline_mm: float = 200.0) -> list[F64]:
    """``n`` camera poses ``T_base_cam`` looking at the seam's middle from different directions.

    The cameras sit ``standoff_mm`` from the seam's middle point (base frame, mm), spread over a
    ``baseline_mm`` line across the seam (so that epipolar lines cross the seam), and are rolled
    so that the image's long axis runs along the seam's chord (the seam fills the image). Raises
    :class:`ConfigError` for ``n < 1`` or non-positive distances.
    """
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
