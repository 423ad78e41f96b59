"""Textures of the simulated scene: pixel rays, brushed metal, decals, the over-joint layer, rust.

Everything here is cached per camera (rays) or per scene (textures) and sampled by
:mod:`drivers.sim.sim_radiance` at the local (a, b) coordinates (mm) where each pixel's ray hits.
Texel size :data:`TEX_MM`.
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
from drivers.sim.sim_scene import Decal, Scene

F32 = NDArray[np.float32]

#: Texel size (mm) of the decal and brushing textures.
TEX_MM = 0.2
#: Texel size (mm) of the rust map (rust blotches are mm to cm wide).
RUST_MM = 0.5
#: Texel size (mm) of the mottle map (the ``rough`` look's brightness changes over 0.3-8 mm).
MOTTLE_MM = 0.25


@functools.lru_cache(maxsize=4)
def rays_cached(width: int, height: int, K: bytes, dist: bytes) -> tuple[F32, F32]:
    """Normalised ray coordinates (x, y) of every pixel of a camera given by its bytes."""
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


def rays(cam: CameraModel) -> tuple[F32, F32]:
    """Normalised ray coordinates (x, y), each (H, W), of every pixel of ``cam`` (cached)."""
    return rays_cached(cam.width, cam.height, cam.K.tobytes(), cam.dist.tobytes())


@dataclass(frozen=True, eq=False)
class Textures:
    """A scene's textures; the local (a, b) of texel (0, 0) is (a0, b0) mm.

    Two brushed-metal tiles, the decal planes (value and alpha of the part and table layers),
    the over-joint layer (value, alpha) or None, the rust map or None, the mottle map or None.
    """

    brush_a: F32
    brush_b: F32
    decals: NDArray[np.uint8]  # (H, W, 4): value_part, alpha_part, value_table, alpha_table
    a0: float
    b0: float
    over: NDArray[np.uint8] | None = None  # (H, W, 2): value, alpha of tack welds and spatter
    rust: F32 | None = None  # (h, w) 0..1 at RUST_MM per texel
    mottle: F32 | None = None  # (h, w, 2) log-brightness gain of sheets A, B at MOTTLE_MM


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
def textures(scene: Scene) -> Textures:
    """The scene's textures (cached: a scene is immutable)."""
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

    over: list[NDArray[np.uint8]] = []
    for d in scene.decals:
        if d.layer == "over":
            if not over:
                over = [np.zeros((h, w), np.uint8) for _ in range(2)]
            _draw(over[0], over[1], d, pt, scale, shift)
            continue
        layers = {"part": [(0, 1)], "table": [(2, 3)], "all": [(0, 1), (2, 3)]}[d.layer]
        for cv, ca in layers:
            _draw(planes[cv], planes[ca], d, pt, scale, shift)
    brush_a, brush_b = _brush(rng), _brush(rng)
    rust = None
    if scene.look is not None and scene.look.rust > 0:
        rust = _rust_map(np.random.default_rng(np.random.SeedSequence([scene.seed, 79])),
                         int(w * TEX_MM / RUST_MM) + 1, int(h * TEX_MM / RUST_MM) + 1,
                         scene.look.rust)
    mottle = None
    if scene.look is not None and scene.look.mottle > 0:
        mottle = _mottle_map(np.random.default_rng(np.random.SeedSequence([scene.seed, 83])),
                             int(w * TEX_MM / MOTTLE_MM) + 1, int(h * TEX_MM / MOTTLE_MM) + 1,
                             scene.look.mottle, scene.look.mottle_mm)
        if scene.look.marks > 0:
            mottle += _marks_map(np.random.default_rng(np.random.SeedSequence([scene.seed, 89])),
                                 mottle.shape[1], mottle.shape[0], scene.look.marks)
    return Textures(brush_a, brush_b, np.asarray(cv2.merge(planes), np.uint8), a0, b0,
                    np.asarray(cv2.merge(over), np.uint8) if over else None, rust, mottle)


def _mottle_map(rng: np.random.Generator, w: int, h: int, spread: float,
                scale_mm: float) -> F32:
    """Log-brightness gain per sheet, (h, w, 2): A in channel 0, B in 1, independent.

    Each a smooth field of scales ``scale_mm`` and 4 x that, std ``spread``, mean
    ``-spread**2 / 2`` (the gain ``exp(field)`` averages 1).
    """
    out = []
    for _ in range(2):
        fields = [cv2.GaussianBlur(rng.standard_normal((h, w)).astype(np.float32), (0, 0),
                                   k * scale_mm / MOTTLE_MM) for k in (1.0, 4.0)]
        n = sum(f / (f.std() + 1e-9) for f in fields)
        out.append(spread * n / (n.std() + 1e-9) - spread**2 / 2)
    return np.asarray(cv2.merge(out), np.float32)


def _marks_map(rng: np.random.Generator, w: int, h: int, per_100mm2: float) -> F32:
    """Log-brightness of thin dark marks per sheet, (h, w, 2) at MOTTLE_MM texels.

    Scratches (1-8 mm long, one texel wide, any direction) and pits (0.1-0.4 mm radius), each
    0.4-1.5 darker (log), ``per_100mm2`` of them per 100 mm^2 of each sheet's map.
    """
    out = []
    n = int(per_100mm2 * w * h * MOTTLE_MM**2 / 100.0)
    for _ in range(2):
        # Darkness x 100 in 8 bits: cv2 draws anti-aliased lines into 8-bit images only.
        canvas = np.zeros((h, w), np.uint8)
        for _ in range(n):
            dark = int(round(100 * rng.uniform(0.4, 1.5)))
            c = rng.uniform((0.0, 0.0), (w, h))
            if rng.random() < 0.6:
                ang = rng.uniform(0.0, np.pi)
                half = rng.uniform(0.5, 4.0) / MOTTLE_MM * np.array([np.cos(ang), np.sin(ang)])
                p0, p1 = (c - half) * 16, (c + half) * 16
                cv2.line(canvas, tuple(int(v) for v in p0), tuple(int(v) for v in p1), dark,
                         1, cv2.LINE_AA, 4)
            else:
                cv2.circle(canvas, tuple(int(v) for v in c * 16),
                           int(round(rng.uniform(0.1, 0.4) / MOTTLE_MM * 16)), dark, -1,
                           cv2.LINE_AA, 4)
        out.append(-canvas.astype(np.float32) / 100.0)
    return np.asarray(cv2.merge(out), np.float32)


def _rust_map(rng: np.random.Generator, w: int, h: int, amount: float) -> F32:
    """Rust cover 0..1: blotches of 5-40 mm where a smooth noise exceeds a level, plus speckle."""
    coarse = cv2.GaussianBlur(rng.standard_normal((h, w)).astype(np.float32), (0, 0), 20.0)
    mid = cv2.GaussianBlur(rng.standard_normal((h, w)).astype(np.float32), (0, 0), 4.0)
    n = coarse / (coarse.std() + 1e-9) + 0.6 * mid / (mid.std() + 1e-9)
    level = float(np.quantile(n, 1.0 - amount))
    cover = np.clip((n - level) / 0.6, 0.0, 1.0)
    speck = rng.random((h, w)).astype(np.float32) < 0.05 * amount
    return np.asarray(np.clip(cover + 0.5 * speck, 0.0, 1.0), np.float32)


def _draw(plane_v: NDArray[np.uint8], plane_a: NDArray[np.uint8], d: Decal, pt: Any,
          scale: float, shift: int) -> None:
    val = int(round(255 * min(max(d.value, 0.0), 1.0)))
    for plane, colour in ((plane_v, val), (plane_a, 255)):
        if d.shape == "dot":
            cv2.circle(plane, pt(*d.p0), int(round(d.radius_mm * scale)), colour, -1,
                       cv2.LINE_AA, shift)
        elif d.shape in ("line", "polyline"):
            thick = max(1, int(round(d.width_mm / TEX_MM)))
            if d.width_mm / TEX_MM < 1.5:
                colour = int(colour * d.width_mm / TEX_MM / 1.5) if plane is plane_a else colour
            if d.shape == "line":
                cv2.line(plane, pt(*d.p0), pt(*d.p1), colour, thick, cv2.LINE_AA, shift)
            else:
                P = np.array([pt(*p) for p in d.points], np.int32)
                cv2.polylines(plane, [P], False, colour, thick, cv2.LINE_AA, shift)
        elif d.shape == "ellipse":
            axes = (int(round(d.p1[0] / TEX_MM)), int(round(d.p1[1] / TEX_MM)))
            c = pt(*d.p0)
            cv2.ellipse(plane, (c[0] >> shift, c[1] >> shift), axes,
                        float(np.degrees(d.angle_rad)), 0, 360, colour, -1, cv2.LINE_AA)
        elif d.shape == "rect":
            c = ((d.p0[0] + d.p1[0]) / 2, (d.p0[1] + d.p1[1]) / 2)
            hw, hh = abs(d.p1[0] - d.p0[0]) / 2, abs(d.p1[1] - d.p0[1]) / 2
            ca_, sa_ = np.cos(d.angle_rad), np.sin(d.angle_rad)
            corners = [pt(c[0] + x * ca_ - y * sa_, c[1] + x * sa_ + y * ca_)
                       for x, y in ((-hw, -hh), (hw, -hh), (hw, hh), (-hw, hh))]
            cv2.fillPoly(plane, [np.array(corners, np.int32)], colour, cv2.LINE_AA, shift)


def sample_brush(tex: F32, a: F32, b: F32, angle: float) -> F32:
    """A brushing tile sampled at local (a, b) mm, brushed along ``angle`` (rad), wrapped."""
    ca, sa = np.float32(np.cos(angle)), np.float32(np.sin(angle))
    mx = (ca * a + sa * b) / np.float32(TEX_MM)
    my = (-sa * a + ca * b) / np.float32(TEX_MM)
    mx = np.nan_to_num(mx, nan=0.0)
    my = np.nan_to_num(my, nan=0.0)
    return np.asarray(cv2.remap(tex, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_WRAP),
                      np.float32)


def sample_decals(tex: Textures, a: F32, b: F32) -> NDArray[np.uint8]:
    """The four decal planes sampled at local (a, b) mm (zero outside the texture)."""
    mx = np.nan_to_num((a - np.float32(tex.a0)) / np.float32(TEX_MM), nan=-10.0)
    my = np.nan_to_num((b - np.float32(tex.b0)) / np.float32(TEX_MM), nan=-10.0)
    mx = np.clip(mx, -10, 1e6).astype(np.float32)
    my = np.clip(my, -10, 1e6).astype(np.float32)
    return np.asarray(cv2.remap(tex.decals, mx, my, cv2.INTER_LINEAR,
                                borderMode=cv2.BORDER_CONSTANT, borderValue=(0, 0, 0, 0)),
                      np.uint8)


def sample_map(tex: NDArray[Any], a: F32, b: F32, a0: float, b0: float, texel_mm: float,
               interpolation: int = cv2.INTER_LINEAR) -> NDArray[Any]:
    """A texture (value 0 outside) sampled at local (a, b) mm; texel (0, 0) at (a0, b0)."""
    mx = np.nan_to_num((a - np.float32(a0)) / np.float32(texel_mm), nan=-10.0)
    my = np.nan_to_num((b - np.float32(b0)) / np.float32(texel_mm), nan=-10.0)
    mx = np.clip(mx, -10, 1e6).astype(np.float32)
    my = np.clip(my, -10, 1e6).astype(np.float32)
    return np.asarray(cv2.remap(tex, mx, my, interpolation, borderMode=cv2.BORDER_CONSTANT,
                                borderValue=0))
