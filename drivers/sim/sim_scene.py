"""Simulated workpiece: two metal sheets meeting along a seam on a cluttered table (base frame, mm).

:func:`make_scene` builds a seeded, frozen :class:`Scene`: the seam's shape (``straight``, ``arc``,
``s_curve``, ``nonplanar``), its length (100-250 mm of arc length), the gap between the sheets
(0.3-1.2 mm), the two sheets' reflectance and brushing direction, the light, and the clutter drawn
on the sheets and the table (marker dots, scratches, pen lines, table holes and slots, other
plates). A difficulty knob (``easy``, ``medium``, ``hard``) sets how much clutter, glare, uneven
light, noise and defocus there is. :mod:`drivers.sim.sim_render` turns a scene into an image.

Geometry. The scene has a *local* frame: origin at the seam's chord midpoint on the sheets' top
surface, ``a`` along the chord, ``b`` across it in the table plane, ``z`` up. The seam is the curve
``b = f(a)`` for ``|a| <= chord/2`` on the surface ``z = H(a)`` (``H = 0`` except for the
``nonplanar`` kind, whose sheets rise 10-40 mm in the middle like a joint between a flat and a
bent sheet). Sheet A lies at ``b < f(a)``, sheet B at ``b > f(a)``; both end at ``a = +-chord/2``
so the seam runs from one sheet border to the other. The table is ``thickness_mm`` below.
``T_base_local`` places the part in the robot base frame (default centre (1000, 0, 300) mm, a
random yaw).

What this does not model: sheet bevels and tack welds, sheets that do not touch the table, the gap
varying along the seam, shadows cast by the raised sheets, occlusion of the seam by the part.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from controller.errors import ConfigError
from controller.geometry.poses import make_pose, rotation_about, transform_points

F64 = NDArray[np.float64]

KINDS = ("straight", "arc", "s_curve", "nonplanar")
DIFFICULTIES = ("easy", "medium", "hard")

#: Default seam centre in the robot base frame (mm): on a table in front of the IRB 2400.
DEFAULT_CENTRE_MM = (1000.0, 0.0, 300.0)


@dataclass(frozen=True)
class Decal:
    """A mark on the sheets or the table, in local (a, b) mm: a dot, a line or a rectangle.

    ``shape`` is ``"dot"`` (centre ``p0``, ``radius_mm``), ``"line"`` (``p0`` to ``p1``,
    ``width_mm``) or ``"rect"`` (corners ``p0``, ``p1``, rotated by ``angle_rad`` about its
    centre). ``value`` is the reflectance (0..1) painted there; ``layer`` is ``"part"``
    (drawn only on the sheets), ``"table"`` (only on the table) or ``"all"``.
    """

    shape: str
    p0: tuple[float, float]
    p1: tuple[float, float] = (0.0, 0.0)
    radius_mm: float = 0.0
    width_mm: float = 0.0
    angle_rad: float = 0.0
    value: float = 0.0
    layer: str = "part"
    kind: str = ""


@dataclass(frozen=True, eq=False)
class Scene:
    """A workpiece on a table, seen by :func:`drivers.sim.sim_render.render`; build with make_scene.

    Lengths in mm, angles in rad, reflectances 0..1. ``seam_points_mm`` is the true centreline of
    the gap on the sheets' top surface, (N, 3) in the base frame, ordered from the end at
    ``a = -chord/2`` to the end at ``a = +chord/2``, about 0.2 mm apart.
    """

    kind: str
    seed: int
    difficulty: str
    length_mm: float
    gap_mm: float
    chord_mm: float
    shape_mm: float  # arc: radius; s_curve: amplitude; nonplanar: rise; straight: 0
    T_base_local: F64
    sheet_a_width_mm: float
    sheet_b_width_mm: float
    thickness_mm: float
    albedo_a: float
    albedo_b: float
    albedo_table: float
    gap_floor: float
    brush_angle_a_rad: float
    brush_angle_b_rad: float
    brush_contrast: float
    light_local_mm: F64
    light_power: float
    ambient: float
    glare: float
    uneven_light: float
    vignetting: float
    noise_dn: float
    blur_px: float
    exposure: float
    decals: tuple[Decal, ...] = ()
    seam_points_mm: F64 = field(default_factory=lambda: np.zeros((0, 3)))

    # ------------------------------------------------------------------ seam shape (local frame)
    def seam_b(self, a: NDArray[Any]) -> NDArray[Any]:
        """Across-chord offset b = f(a) (mm) of the seam at chord coordinate ``a`` (mm)."""
        return _shape_f(self.kind, self.shape_mm, self.chord_mm, a)[0]

    def seam_db(self, a: NDArray[Any]) -> NDArray[Any]:
        """Slope df/da of the seam in the table plane at ``a``."""
        return _shape_f(self.kind, self.shape_mm, self.chord_mm, a)[1]

    def seam_ddb(self, a: NDArray[Any]) -> NDArray[Any]:
        """Second derivative d2f/da2 (1/mm) of the seam at ``a``."""
        return _shape_f(self.kind, self.shape_mm, self.chord_mm, a)[2]

    def height(self, a: NDArray[Any]) -> NDArray[Any]:
        """Surface height H(a) (mm, local z) of the sheets at chord coordinate ``a``."""
        return _height(self.kind, self.shape_mm, self.chord_mm, a)[0]

    def height_slope(self, a: NDArray[Any]) -> NDArray[Any]:
        """dH/da of the sheets' surface at ``a``."""
        return _height(self.kind, self.shape_mm, self.chord_mm, a)[1]

    @property
    def b_range_mm(self) -> tuple[float, float]:
        """(min, max) across-chord coordinate (mm) of the part: the sheets' outer borders."""
        a = np.linspace(-self.chord_mm / 2, self.chord_mm / 2, 401)
        f = self.seam_b(a)
        return float(f.min() - self.sheet_a_width_mm), float(f.max() + self.sheet_b_width_mm)

    # ------------------------------------------------------------------ base-frame views
    @property
    def surface_normal(self) -> F64:
        """Nominal unit surface normal (3,) in the base frame (pointing up, away from the table)."""
        return self.T_base_local[:3, 2].copy()

    def normal_at(self, points_mm: NDArray[Any]) -> F64:
        """Unit surface normals (N, 3) in the base frame at base-frame points (N, 3) on the part."""
        P = transform_points(np.linalg.inv(self.T_base_local), np.asarray(points_mm).reshape(-1, 3))
        s = self.height_slope(P[:, 0])
        n = np.column_stack([-s, np.zeros_like(s), np.ones_like(s)])
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        return np.asarray(n @ self.T_base_local[:3, :3].T)

    @property
    def centre_mm(self) -> F64:
        """The seam's middle point (by arc length) in the base frame (mm)."""
        return self.seam_points_mm[len(self.seam_points_mm) // 2].copy()

    @property
    def region_radius_mm(self) -> float:
        """Radius (mm) of a sphere about :attr:`centre_mm` that holds the whole seam, plus 10 mm."""
        return float(np.linalg.norm(self.seam_points_mm - self.centre_mm, axis=1).max() + 10.0)

    def nominal_region(self) -> dict[str, Any]:
        """The nominal seam region for a job file: ``{"centre_mm": [x, y, z], "radius_mm": r}``."""
        return {"centre_mm": [round(float(v), 3) for v in self.centre_mm],
                "radius_mm": round(self.region_radius_mm, 3)}


# ---------------------------------------------------------------------------------------------
# Shape functions
# ---------------------------------------------------------------------------------------------
def _shape_f(kind: str, shape: float, chord: float,
             a: NDArray[Any]) -> tuple[NDArray[Any], NDArray[Any], NDArray[Any]]:
    a = np.asarray(a)
    if kind == "arc":
        # Circle of radius `shape` through (+-chord/2, 0), bulging toward +b.
        R = shape
        h0 = np.sqrt(R * R - (chord / 2) ** 2)
        r = np.sqrt(np.maximum(R * R - a * a, 1e-9))
        return r - h0, -a / r, -(R * R) / r**3
    if kind == "s_curve":
        k = 2 * np.pi / chord
        return shape * np.sin(k * a), shape * k * np.cos(k * a), -shape * k * k * np.sin(k * a)
    zero = np.zeros_like(a, dtype=np.float64 if a.dtype == np.float64 else np.float32)
    return zero, zero, zero


def _height(kind: str, shape: float, chord: float,
            a: NDArray[Any]) -> tuple[NDArray[Any], NDArray[Any]]:
    a = np.asarray(a)
    if kind != "nonplanar":
        zero = np.zeros_like(a, dtype=np.float64 if a.dtype == np.float64 else np.float32)
        return zero, zero
    # A smooth rise of `shape` mm in the middle: cos^2 over the chord, flat (H = 0) beyond.
    k = np.pi / chord
    inside = np.abs(a) <= chord / 2
    c = np.cos(k * a)
    H = np.where(inside, shape * c * c, 0.0)
    dH = np.where(inside, -shape * k * 2 * c * np.sin(k * a), 0.0)
    return H.astype(a.dtype, copy=False), dH.astype(a.dtype, copy=False)


def _arc_length(kind: str, shape: float, chord: float, n: int = 4001) -> tuple[F64, F64]:
    """Dense (a, cumulative 3D arc length) along the seam."""
    a = np.linspace(-chord / 2, chord / 2, n)
    b = _shape_f(kind, shape, chord, a)[0]
    z = _height(kind, shape, chord, a)[0]
    seg = np.sqrt(np.diff(a) ** 2 + np.diff(b) ** 2 + np.diff(z) ** 2)
    return a, np.concatenate([[0.0], np.cumsum(seg)])


def _chord_for_length(kind: str, shape_of_chord: Any, length: float) -> tuple[float, float]:
    """Chord (and shape value) giving the wanted arc length, by fixed-point iteration."""
    chord = length
    shape = shape_of_chord(chord)
    for _ in range(60):
        shape = shape_of_chord(chord)
        s = _arc_length(kind, shape, chord)[1][-1]
        chord *= length / s
    return chord, shape_of_chord(chord)


# ---------------------------------------------------------------------------------------------
# Builder
# ---------------------------------------------------------------------------------------------
_DIFF = {
    #           dots  scratches pens  holes plates glare  uneven noise blur      floor
    "easy":   dict(dots=(2, 5), scratches=(0, 4), pens=(0, 0), plates=(1, 2), glare=(0.05, 0.25),
                   uneven=(0.05, 0.2), noise=(0.8, 1.5), blur=(0.5, 0.7), floor=(0.03, 0.08),
                   contrast=(0.04, 0.08), gap=(0.5, 1.2)),
    "medium": dict(dots=(4, 9), scratches=(4, 12), pens=(1, 2), plates=(2, 4), glare=(0.2, 0.6),
                   uneven=(0.15, 0.35), noise=(1.5, 2.5), blur=(0.6, 0.9), floor=(0.04, 0.12),
                   contrast=(0.06, 0.12), gap=(0.3, 1.2)),
    "hard":   dict(dots=(8, 16), scratches=(10, 25), pens=(2, 4), plates=(3, 6), glare=(0.5, 1.5),
                   uneven=(0.3, 0.55), noise=(2.5, 4.0), blur=(0.8, 1.2), floor=(0.08, 0.2),
                   contrast=(0.1, 0.18), gap=(0.3, 1.2)),
}

_OVERRIDABLE = {"length_mm", "gap_mm", "shape_mm", "centre_mm", "yaw_rad", "albedo_a", "albedo_b",
                "albedo_table", "gap_floor", "glare", "uneven_light", "vignetting", "noise_dn",
                "blur_px", "exposure", "clutter", "light_power", "ambient", "brush_contrast"}


def make_scene(kind: str, seed: int, difficulty: str = "medium", **overrides: Any) -> Scene:
    """A seeded workpiece scene in the robot base frame (mm); same arguments, same scene.

    ``kind`` is one of :data:`KINDS`, ``difficulty`` one of :data:`DIFFICULTIES`. Overrides (any of
    ``length_mm``, ``gap_mm``, ``shape_mm`` (arc radius, S amplitude or non-planar rise),
    ``centre_mm`` (3,), ``yaw_rad``, ``albedo_a``, ``albedo_b``, ``albedo_table``, ``gap_floor``,
    ``glare``, ``uneven_light``, ``vignetting``, ``noise_dn``, ``blur_px``, ``exposure``,
    ``light_power``, ``ambient``, ``brush_contrast``, ``clutter`` (False: no decals)) replace the
    drawn values. Raises :class:`ConfigError` for an unknown kind, difficulty or override, or a
    value out of range (length 100-250 mm, gap 0.3-1.2 mm are the specified ranges; others are
    accepted with a warning-free clamp-free check that they are positive).
    """
    if kind not in KINDS:
        raise ConfigError(f"scene kind {kind!r} unknown; use one of {', '.join(KINDS)}")
    if difficulty not in DIFFICULTIES:
        raise ConfigError(f"scene difficulty {difficulty!r} unknown; use one of "
                          f"{', '.join(DIFFICULTIES)}")
    unknown = set(overrides) - _OVERRIDABLE
    if unknown:
        raise ConfigError(f"make_scene: unknown override(s) {sorted(unknown)}; known: "
                          f"{sorted(_OVERRIDABLE)}")
    cfg: dict[str, Any] = _DIFF[difficulty]
    # One generator per aspect, so that overriding one value does not reshuffle the others.
    ss = np.random.SeedSequence([int(seed), KINDS.index(kind), DIFFICULTIES.index(difficulty)])
    g_shape, g_look, g_clutter = (np.random.default_rng(s) for s in ss.spawn(3))

    def u(rng: np.random.Generator, lo_hi: tuple[float, float]) -> float:
        return float(rng.uniform(*lo_hi))

    length = float(overrides.get("length_mm", u(g_shape, (100.0, 250.0))))
    gap = float(overrides.get("gap_mm", u(g_shape, cfg["gap"])))
    if not 100.0 <= length <= 250.0:
        raise ConfigError(f"make_scene: length_mm {length} outside 100-250 mm")
    if not 0.3 <= gap <= 1.2:
        raise ConfigError(f"make_scene: gap_mm {gap} outside 0.3-1.2 mm")
    shape_draw = {"straight": 0.0,
                  "arc": u(g_shape, (0.75, 1.6)),        # radius as a multiple of the chord
                  "s_curve": u(g_shape, (0.06, 0.14)),   # amplitude as a fraction of the chord
                  "nonplanar": u(g_shape, (10.0, 40.0))}[kind]
    yaw = float(overrides.get("yaw_rad", u(g_shape, (-np.pi, np.pi))))
    if "shape_mm" in overrides:
        fixed = float(overrides["shape_mm"])
        chord, shape = _chord_for_length(kind, lambda c: fixed, length)
    elif kind in ("arc", "s_curve"):
        chord, shape = _chord_for_length(kind, lambda c: shape_draw * c, length)
    else:
        chord, shape = _chord_for_length(kind, lambda c: shape_draw, length)
    if kind == "arc" and shape <= chord / 2:
        raise ConfigError(f"make_scene: arc radius {shape:.1f} mm must exceed half the chord "
                          f"{chord / 2:.1f} mm (at most a half circle)")
    centre = np.asarray(overrides.get("centre_mm", DEFAULT_CENTRE_MM), dtype=np.float64)
    T_base_local = make_pose(rotation_about((0.0, 0.0, 1.0), yaw), centre)

    albedo_a = float(overrides.get("albedo_a", u(g_look, (0.35, 0.7))))
    albedo_b = float(overrides.get("albedo_b", albedo_a * u(g_look, (0.55, 0.9))))
    if g_look.random() < 0.5 and "albedo_a" not in overrides and "albedo_b" not in overrides:
        albedo_a, albedo_b = albedo_b, albedo_a
    look: dict[str, Any] = dict(
        albedo_a=albedo_a, albedo_b=albedo_b,
        albedo_table=float(overrides.get("albedo_table", u(g_look, (0.15, 0.35)))),
        gap_floor=float(overrides.get("gap_floor", u(g_look, cfg["floor"]))),
        brush_angle_a_rad=u(g_look, (-np.pi, np.pi)), brush_angle_b_rad=u(g_look, (-np.pi, np.pi)),
        brush_contrast=float(overrides.get("brush_contrast", u(g_look, cfg["contrast"]))),
        light_local_mm=np.array([u(g_look, (-250, 250)), u(g_look, (-250, 250)),
                                 u(g_look, (500, 900))]),
        light_power=float(overrides.get("light_power", u(g_look, (0.4, 0.65)))),
        ambient=float(overrides.get("ambient", u(g_look, (0.1, 0.2)))),
        glare=float(overrides.get("glare", u(g_look, cfg["glare"]))),
        uneven_light=float(overrides.get("uneven_light", u(g_look, cfg["uneven"]))),
        vignetting=float(overrides.get("vignetting", u(g_look, (0.1, 0.35)))),
        noise_dn=float(overrides.get("noise_dn", u(g_look, cfg["noise"]))),
        blur_px=float(overrides.get("blur_px", u(g_look, cfg["blur"]))),
        exposure=float(overrides.get("exposure", u(g_look, (0.85, 1.1)))),
    )
    for key in ("gap_floor", "light_power", "noise_dn", "blur_px", "exposure"):
        if not np.isfinite(look[key]) or look[key] < 0:
            raise ConfigError(f"make_scene: {key} must be a finite number >= 0, got {look[key]}")

    wa, wb = u(g_shape, (60.0, 110.0)), u(g_shape, (60.0, 110.0))
    scene = Scene(kind=kind, seed=int(seed), difficulty=difficulty, length_mm=length, gap_mm=gap,
                  chord_mm=chord, shape_mm=shape, T_base_local=T_base_local,
                  sheet_a_width_mm=wa, sheet_b_width_mm=wb, thickness_mm=3.0, **look)
    pts = _seam_points(scene)
    decals: tuple[Decal, ...] = ()
    if overrides.get("clutter", True):
        decals = _clutter(scene, cfg, g_clutter)
    return replace(scene, seam_points_mm=pts, decals=decals)


def _seam_points(scene: Scene, step_mm: float = 0.2) -> F64:
    a_dense, s_dense = _arc_length(scene.kind, scene.shape_mm, scene.chord_mm)
    n = max(int(np.ceil(s_dense[-1] / step_mm)) + 1, 2)
    a = np.interp(np.linspace(0.0, s_dense[-1], n), s_dense, a_dense)
    local = np.column_stack([a, scene.seam_b(a), scene.height(a)])
    return transform_points(scene.T_base_local, local)


def _clutter(scene: Scene, cfg: dict[str, Any], rng: np.random.Generator) -> tuple[Decal, ...]:
    """Marker dots, scratches and pen lines on the sheets; holes, slots, plates on the table."""
    half = scene.chord_mm / 2
    b_lo, b_hi = scene.b_range_mm
    out: list[Decal] = []

    def on_sheet(clearance: float) -> tuple[float, float]:
        for _ in range(100):
            a = float(rng.uniform(-half + 3, half - 3))
            b = float(rng.uniform(b_lo + 3, b_hi - 3))
            if abs(b - float(scene.seam_b(np.array([a]))[0])) > clearance:
                return a, b
        return a, b

    for _ in range(int(rng.integers(cfg["dots"][0], cfg["dots"][1] + 1))):
        r = float(rng.uniform(2.0, 5.0))
        a, b = on_sheet(r + 2.0)
        val = 0.03 if rng.random() < 0.6 else 0.95
        out.append(Decal("dot", (a, b), radius_mm=r, value=val, kind="marker"))
    for _ in range(int(rng.integers(cfg["scratches"][0], cfg["scratches"][1] + 1))):
        a, b = on_sheet(1.0)
        ang = float(rng.uniform(-np.pi, np.pi))
        ln = float(rng.uniform(5.0, 60.0))
        a1, b1 = a + ln * np.cos(ang), b + ln * np.sin(ang)
        val = float(rng.uniform(0.3, 0.95))
        out.append(Decal("line", (a, b), (a1, b1), width_mm=float(rng.uniform(0.1, 0.3)),
                         value=val, kind="scratch"))
    for _ in range(int(rng.integers(cfg["pens"][0], cfg["pens"][1] + 1))):
        a, b = on_sheet(6.0)
        # Pen marks are often drawn parallel to the joint (a hand-drawn guide line).
        ang = float(rng.uniform(-0.3, 0.3)) if rng.random() < 0.5 else float(rng.uniform(-1.5, 1.5))
        ln = float(rng.uniform(8.0, 35.0))
        out.append(Decal("line", (a, b), (a + ln * np.cos(ang), b + ln * np.sin(ang)),
                         width_mm=float(rng.uniform(0.4, 0.8)), value=0.08, kind="pen"))
    # Table: a grid of holes (a welding table), long slots, other plates lying around.
    pitch = float(rng.uniform(40.0, 60.0))
    off = rng.uniform(0, pitch, 2)
    rad = float(rng.uniform(6.0, 9.0))
    span = half + 200.0
    for ga in np.arange(-span + off[0], span, pitch):
        for gb in np.arange(b_lo - 200 + off[1], b_hi + 200, pitch):
            out.append(Decal("dot", (float(ga), float(gb)), radius_mm=rad, value=0.02,
                             layer="table", kind="hole"))
    for _ in range(int(rng.integers(cfg["plates"][0], cfg["plates"][1] + 1))):
        side = rng.choice([-1, 1])
        cb = (b_hi + rng.uniform(15, 80)) if side > 0 else (b_lo - rng.uniform(15, 80))
        ca = float(rng.uniform(-half - 60, half + 60))
        w, h = float(rng.uniform(20, 90)), float(rng.uniform(10, 60))
        out.append(Decal("rect", (ca - w / 2, float(cb) - h / 2), (ca + w / 2, float(cb) + h / 2),
                         angle_rad=float(rng.uniform(0, np.pi)), value=float(rng.uniform(0.3, 0.8)),
                         layer="table", kind="plate"))
    return tuple(out)
