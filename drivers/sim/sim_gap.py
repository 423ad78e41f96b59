"""The gap of a wide-look scene, across the seam: edges, cut faces, ridge, shadow, ground strips.

Along the seam the gap's edges are ``e_lo(a) < 0 < e_hi(a)`` (mm of signed distance ``d`` from
the seam curve): the nominal half gap, a taper end to end, and a zero-mean jag per edge (so the
centreline, the truth, is the middle of the *nominal* gap; the local midpoint of a ragged gap
wanders about it by up to about the jag amplitude). Across the seam a pixel's footprint
``[d - w/2, d + w/2]`` is integrated exactly over piecewise-constant bands:

    sheet A | ridge A | (shadow A) | cut face A | gap floor | cut face B | (shadow B) | ridge B | B

The cut faces are the sheets' edges seen through the gap: a ray that slopes across the seam by
``s`` mm per mm of depth sees ``thickness * (s - tan(tilt))`` of the far wall (a tilted sheet's wall
leans). A plate edge standing higher than the other casts a shadow band on the other side of the
gap (the lopsided gaps of the real photographs).
"""

from __future__ import annotations

import functools
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from drivers.sim.sim_scene import Scene

F32 = NDArray[np.float32]
_JAG_MM = 0.05  # sampling step (mm) of the edge jag along the chord


@functools.lru_cache(maxsize=8)
def _jag(scene: Scene) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """(a grid, jag of edge A, jag of edge B) in mm; zero-mean noise at 0.5 and 2 mm scales."""
    look = scene.look
    assert look is not None
    n = int(scene.chord_mm / _JAG_MM) + 3
    a = np.linspace(-scene.chord_mm / 2 - _JAG_MM, scene.chord_mm / 2 + _JAG_MM, n)
    rng = np.random.default_rng(np.random.SeedSequence([scene.seed, 83]))
    out = []
    for _ in range(2):
        fine = cv2.GaussianBlur(rng.standard_normal((1, n)), (0, 0), 0.5 / _JAG_MM)[0]
        coarse = cv2.GaussianBlur(rng.standard_normal((1, n)), (0, 0), 2.0 / _JAG_MM)[0]
        j = fine / (fine.std() + 1e-12) + 0.7 * coarse / (coarse.std() + 1e-12)
        out.append(look.ragged_mm * j / 1.5)
    return a, out[0], out[1]


def edges(scene: Scene, a: NDArray[Any]) -> tuple[NDArray[Any], NDArray[Any]]:
    """(e_lo, e_hi): signed distance (mm) of sheet A's and sheet B's gap edge at chord ``a``."""
    look = scene.look
    assert look is not None
    g2 = 0.5 * scene.gap_mm * (1.0 + look.taper * np.asarray(a, np.float64) / scene.chord_mm)
    if look.ragged_mm <= 0:
        return -g2, g2
    ag, ja, jb = _jag(scene)
    ja_ = np.maximum(np.interp(a, ag, ja), -0.8 * g2)
    jb_ = np.maximum(np.interp(a, ag, jb), -0.8 * g2)
    return -g2 - ja_, g2 + jb_


def gap_band_mm(scene: Scene) -> float:
    """Half width (mm of |d|) of the band around the seam drawn by :func:`gap_profile`."""
    look = scene.look
    assert look is not None
    g2 = 0.5 * scene.gap_mm * (1 + abs(look.taper))
    return float(max(3.0, g2 + 4 * look.ragged_mm + max(look.ridge_mm, look.step_shadow_mm) + 1.5,
                     2 * scene.gap_mm))


def _cov(dd: NDArray[Any], w: NDArray[Any], lo: Any, hi: Any) -> NDArray[Any]:
    """Share of the footprint [dd - w/2, dd + w/2] inside [lo, hi]."""
    return np.asarray(np.clip(np.minimum(dd + w / 2, hi) - np.maximum(dd - w / 2, lo), 0, None) / w)


def gap_profile(scene: Scene, a: F32, d: F32, rr: NDArray[Any], cc: NDArray[Any], wpx: F32,
                D: tuple[F32, F32, F32], sides: list[F32], gain: F32) -> F32:
    """Radiance of the band pixels (rr, cc): the footprint integrated over the bands (module doc).

    ``sides`` are the full-image radiance of sheet A and sheet B (texture, decals, light).
    """
    look = scene.look
    assert look is not None
    pa = a[rr, cc].astype(np.float64)
    dd = d[rr, cc].astype(np.float64)
    w = wpx.astype(np.float64)
    e_lo, e_hi = edges(scene, pa)
    f1 = scene.seam_db(pa)
    nrm = np.sqrt(1 + f1 * f1)
    Dx, Dy, Dz = (x[rr, cc].astype(np.float64) for x in D)
    s = (Dy - Dx * f1) / nrm / np.maximum(-Dz, 1e-6)  # across-seam drift per mm of depth
    gapw = e_hi - e_lo
    T = scene.thickness_mm
    w_b = np.clip(T * (s - np.tan(look.tilt_b_rad)), 0, None)
    w_a = np.clip(T * (-s - np.tan(look.tilt_a_rad)), 0, None)
    k = np.minimum(1.0, gapw / np.maximum(w_a + w_b, 1e-9))
    w_a, w_b = w_a * k, w_b * k
    rad_a = sides[0][rr, cc].astype(np.float64)
    rad_b = sides[1][rr, cc].astype(np.float64)
    gn = gain[rr, cc].astype(np.float64)
    floor = scene.gap_floor * gn
    face_a = look.face_a * scene.albedo_a * gn
    face_b = look.face_b * scene.albedo_b * gn
    rg = 1.0 + look.ridge_gain
    ridge = look.ridge_mm
    sw = max(look.step_shadow_mm, ridge)
    sh_a = 1.0 - look.step_depth if (look.step_side < 0 and look.step_shadow_mm > 0) else 1.0
    sh_b = 1.0 - look.step_depth if (look.step_side > 0 and look.step_shadow_mm > 0) else 1.0
    inf = 1e9
    out = (_cov(dd, w, -inf, e_lo - sw) * rad_a
           + _cov(dd, w, e_lo - sw, e_lo - ridge) * rad_a * sh_a
           + _cov(dd, w, e_lo - ridge, e_lo) * rad_a * rg * sh_a
           + _cov(dd, w, e_lo, e_lo + w_a) * face_a
           + _cov(dd, w, e_lo + w_a, e_hi - w_b) * floor
           + _cov(dd, w, e_hi - w_b, e_hi) * face_b
           + _cov(dd, w, e_hi, e_hi + ridge) * rad_b * rg * sh_b
           + _cov(dd, w, e_hi + ridge, e_hi + sw) * rad_b * sh_b
           + _cov(dd, w, e_hi + sw, inf) * rad_b)
    return out.astype(np.float32)


def _ground_width(scene: Scene, a: F32, d: F32) -> F32:
    """Width (mm) of the ground strip on each point's side of the joint, wavy along it."""
    look = scene.look
    assert look is not None
    ph = float(np.random.default_rng(scene.seed).uniform(0, 2 * np.pi))
    wav = np.float32(look.ground_wave_mm) * np.sin(a / np.float32(17.0) + np.float32(ph))
    return np.where(d < 0, np.float32(look.ground_mm[0]), np.float32(look.ground_mm[1])) + wav


def ground_gain(scene: Scene, a: F32, d: F32) -> F32:
    """Brightness gain of the ground strips (>= 1) and of the sheet beyond them.

    The strips beside the gap have wavy soft outer edges; beyond them the sheet is unground
    (``Look.unground`` times as bright, 1 unless the look says).
    """
    look = scene.look
    assert look is not None
    if look.ground_mm == (0.0, 0.0):
        return np.ones_like(d)
    m = np.nan_to_num(np.clip(_ground_width(scene, a, d) - np.abs(d) + 0.5, 0.0, 1.0))
    g = 1.0 + np.float32(look.ground_gain - 1.0) * m
    if look.unground != 1.0:
        # Beyond the strips the sheet is unground: mill scale and rust, darker than the metal.
        g = g * (m + (1.0 - m) * np.float32(look.unground))
    return np.asarray(g, np.float32)


def ground_edge(scene: Scene, a: F32, d: F32) -> F32:
    """Brightness factor (<= 1) of the thin dark line at each ground strip's outer edge.

    The line is centred on the middle of the strip's soft edge (where :func:`ground_gain` is
    half way), ``ground_edge_mm`` wide at half depth, darkening by ``ground_edge_depth``.
    """
    look = scene.look
    assert look is not None
    if look.ground_mm == (0.0, 0.0) or look.ground_edge_mm <= 0.0:
        return np.ones_like(d)
    off = (np.abs(d) - _ground_width(scene, a, d)) / np.float32(look.ground_edge_mm / 2)
    line = np.exp(np.float32(-np.log(2.0)) * np.nan_to_num(off, nan=1e3) ** 2)
    return np.asarray(1.0 - np.float32(look.ground_edge_depth) * line, np.float32)


def corner_cover(scene: Scene, a: F32, d: F32) -> F32:
    """Signed distance (mm, > 0 inside) to the sheets' rounded corners at the joint's ends."""
    look = scene.look
    assert look is not None
    r = np.float32(look.corner_mm)
    x = np.float32(scene.chord_mm / 2) - np.abs(a)
    y = np.abs(d) - np.float32(scene.gap_mm / 2)
    y = np.minimum(y, r)
    inside = r - np.sqrt((r - np.minimum(x, r)) ** 2 + (r - y) ** 2)
    return np.asarray(np.where(x < r, inside, np.float32(1e6)), np.float32)
