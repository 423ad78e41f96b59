"""Ray casting and shading of the simulated scene: the linear radiance seen by each pixel.

Each pixel's ray (distortion included) hits the sheets' top surface (``z = H(a)``, tilted sheets
by fixed-point iteration) or the table ``thickness_mm`` below. The gap between the sheets is drawn
*analytically*: the signed distance ``d`` (mm, in the table plane) from the hit to the seam curve
and its change from pixel to pixel give the fraction of the pixel's footprint in the gap (a box
filter), so the edges and hence the centreline are anti-aliased without bias. A wide look draws
the gap through :func:`drivers.sim.sim_gap.gap_profile` instead (ragged edges, cut faces, ridge,
plate-edge shadow), adds ground strips, rust, the over-joint layer (tack welds, spatter) and
rounded plate corners.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from controller.geometry.camera_model import CameraModel
from controller.geometry.poses import invert
from drivers.sim.sim_gap import corner_cover, gap_band_mm, gap_profile, ground_edge, ground_gain
from drivers.sim.sim_light import lighting
from drivers.sim.sim_scene import Scene
from drivers.sim.sim_texture import (
    MOTTLE_MM,
    RUST_MM,
    TEX_MM,
    rays,
    sample_brush,
    sample_decals,
    sample_map,
    textures,
)

F64 = NDArray[np.float64]
F32 = NDArray[np.float32]


def radiance(scene: Scene, cam: CameraModel, T_base_cam: F64) -> tuple[F32, float, F32 | None]:
    """Linear radiance (float32, 0..~1.5), the gap's apparent width (px) and the rust cover.

    The width is the median over the gap's pixels; the rust cover is 0..1 per pixel (for the
    colour tint), None without rust.
    """
    xn, yn = rays(cam)
    look = scene.look
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
    if look is not None and (look.tilt_a_rad or look.tilt_b_rad):
        # Tilted sheets: z = surface_z(a, b). One fixed-point step: it contracts by ~0.05 (slope
        # tan 4 deg x the ray's drift), leaving < 0.1 mm where a pen line is drawn.
        for _ in range(1):
            t = (scene.surface_z(a, b).astype(np.float32) - cz) * inv_dz
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
    d = b - scene.seam_b(a).astype(np.float32)
    if look is not None and look.corner_mm > 0:
        inside = np.minimum(inside, corner_cover(scene, a, d))
    if look is not None and look.tee_mm > 0:
        # A T-corner: a third plate across the joint's end, beyond the crossbar gap.
        sa = np.float32(look.tee_end) * a - half
        tee = np.minimum(np.minimum(sa - np.float32(look.tee_mm),
                                    np.float32(look.tee_mm + look.tee_plate_mm) - sa),
                         np.minimum(b - b_lo + np.float32(30.0), b_hi + np.float32(30.0) - b))
        inside = np.maximum(inside, tee)
    part_cov = np.clip(inside / (1.5 * fp) + 0.5, 0.0, 1.0)
    part_cov = np.nan_to_num(part_cov, nan=0.0)

    # Signed distance to the seam (table plane), exact in a band around it.
    gap_cov = np.zeros_like(d)
    band = np.abs(d) < (max(3.0, 2 * scene.gap_mm) if look is None else gap_band_mm(scene))
    band &= np.abs(a) < half + 2.0
    if look is not None and look.tee_mm > 0:
        # Not on the third plate: the gap stops at the crossbar.
        band &= np.float32(look.tee_end) * a < half + np.float32(0.5 * look.tee_mm)
    band &= np.isfinite(d)
    rr, cc = np.nonzero(band)
    gap_w_px = float("nan")
    wpx = np.zeros(0, np.float32)
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

    tex = textures(scene)
    sheet_a = d < 0
    if look is not None and look.tee_mm > 0:
        sheet_a |= np.float32(look.tee_end) * a > half  # the third plate: one metal, no seam
    brush_a = sample_brush(tex.brush_a, a, b, scene.brush_angle_a_rad)
    brush_b = sample_brush(tex.brush_b, a, b, scene.brush_angle_b_rad)
    c = np.float32(scene.brush_contrast)
    dec_p = sample_decals(tex, a, b)
    dec_t = sample_decals(tex, at, bt)
    alpha_p = dec_p[:, :, 1].astype(np.float32) / 255.0
    alpha_t = dec_t[:, :, 3].astype(np.float32) / 255.0
    table = np.float32(scene.albedo_table) * (1 + np.float32(0.05) * brush_b[::-1, ::-1])
    table = table * (1 - alpha_t) + dec_t[:, :, 2].astype(np.float32) / 255.0 * alpha_t
    gain, spec = lighting(scene, cam, a, b, t, xn, yn, T_local_cam)
    metal = 1 - alpha_p
    rust_w = None
    if look is None:
        albedo = np.where(sheet_a, np.float32(scene.albedo_a) * (1 + c * brush_a),
                          np.float32(scene.albedo_b) * (1 + c * brush_b))
        albedo = albedo * (1 - alpha_p) + dec_p[:, :, 0].astype(np.float32) / 255.0 * alpha_p
        rad_part = albedo * gain + spec * metal
        rad_part = rad_part * (1 - gap_cov) + np.float32(scene.gap_floor) * gain * gap_cov
    else:
        dec_v = dec_p[:, :, 0].astype(np.float32) / 255.0 * alpha_p
        ground = ground_gain(scene, a, d)
        edge = ground_edge(scene, a, d)
        if tex.rust is not None:
            rust_w = sample_map(tex.rust, a, b, tex.a0, tex.b0, RUST_MM) * (ground <= 1.0)
        # 0 outside the map: a gain of 1.
        mottle = (None if tex.mottle is None else
                  np.exp(sample_map(tex.mottle, a, b, tex.a0, tex.b0, MOTTLE_MM)))
        sides: list[F32] = []
        for k, (alb, br) in enumerate(((scene.albedo_a, brush_a), (scene.albedo_b, brush_b))):
            al = np.float32(alb) * (1 + c * br) * ground * edge
            if rust_w is not None:
                al = al * (1 - np.float32(0.65) * rust_w)
            if mottle is not None:
                al = al * mottle[:, :, k]
            sides.append(((al * (1 - alpha_p) + dec_v) * gain + spec * metal * ground)
                         .astype(np.float32))
        rad_part = np.where(sheet_a, sides[0], sides[1])
        if rr.size:
            rad_part[rr, cc] = gap_profile(scene, a, d, rr, cc, wpx, (Dx, Dy, Dz), sides, gain)
        if tex.over is not None:
            ov = sample_map(tex.over, a, b, tex.a0, tex.b0, TEX_MM)
            al_o = ov[:, :, 1].astype(np.float32) / 255.0
            val_o = ov[:, :, 0].astype(np.float32) / 255.0
            rad_part = rad_part * (1 - al_o) + (val_o * gain + 0.5 * spec) * al_o
    rad_table = table * gain + np.float32(0.1) * spec
    rad = part_cov * rad_part + (1 - part_cov) * rad_table
    rad = np.nan_to_num(rad, nan=0.0)
    if rust_w is not None:
        rust_w = np.nan_to_num(rust_w * part_cov, nan=0.0).astype(np.float32)
    return rad.astype(np.float32), gap_w_px, rust_w


def _exact_distance(scene: Scene, a: F32, b: F32, d: F32, rr: NDArray[Any],
                    cc: NDArray[Any]) -> F32:
    """Signed distance (mm) to the seam curve by Newton on the closest point, in the band only."""
    if scene.kind in ("straight", "nonplanar") and not scene.bow_mm:
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
