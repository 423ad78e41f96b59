"""Simulated workpiece: two metal sheets meeting along a seam on a cluttered table (base frame, mm).

:func:`make_scene` builds a seeded, frozen :class:`Scene`: the seam's shape (``straight``, ``arc``,
``s_curve``, ``nonplanar``), its length, the gap between the sheets, the two sheets' reflectance
and brushing direction, the light, and the clutter drawn on the sheets and the table. A difficulty
knob (``easy``, ``medium``, ``hard``) sets how much clutter, glare, uneven light, noise and
defocus there is. :mod:`drivers.sim.sim_render` turns a scene into an image.

Varieties. ``classic`` (the default) is the scene the detector was first tuned on, unchanged for a
given seed: length 100-250 mm, gap 0.3-1.2 mm, marker dots, scratches, short pen marks, a hole
grid table, other plates. ``wide`` and ``pen`` draw a :class:`~drivers.sim.sim_look.Look` (gap
1-30 px from barely darker than the sheet to black, thick tilted sheets with visible cut faces,
bow, ragged edges, parallel pen lines, scanner dots, perforated and other tables, a key light's
shadow, ring glare, colour casts, JPEG, and the real photographs' tack welds, spatter, ground
strips, rust, pitting, lopsided gaps, rounded corners, dark close-ups), split into a tuning and a
held-out part (:func:`drivers.sim.sim_look.split_of`). The preset ``tack_open`` is a straight
tack-welded seam 460-520 mm long whose ends leave both images of the dry run.

Geometry. The scene has a *local* frame: origin at the seam's chord midpoint on the sheets' top
surface, ``a`` along the chord, ``b`` across it in the table plane, ``z`` up. The seam is the curve
``b = f(a)`` for ``|a| <= chord/2`` on the surface ``z = H(a)`` (``H = 0`` except for the
``nonplanar`` kind, whose sheets rise 10-40 mm in the middle like a joint between a flat and a
bent sheet). Sheet A lies at ``b < f(a)``, sheet B at ``b > f(a)``; both end at ``a = +-chord/2``
so the seam runs from one sheet border to the other (rounded corners end it a little earlier:
:attr:`Scene.a_end_mm`). The table is ``thickness_mm`` below. ``T_base_local`` places the part in
the robot base frame (default centre (1000, 0, 300) mm, a random yaw).

Truth: ``seam_points_mm`` (the centreline of the nominal gap on the sheets' top surface; a
ragged gap's local midpoint wanders about it), ``occluded_spans_mm`` (tack welds and spatter on
the joint), :meth:`Scene.pen_lines_mm` (lines a detector must not return).

What this does not model: sheet bevels, sheets that do not touch the table, a height step between
the sheets (only its shadow is drawn), weld beads other than tacks, occlusion of the seam by the
part, shadows cast by the raised sheets of the ``nonplanar`` kind.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from controller.errors import ConfigError
from controller.geometry.poses import make_pose, rotation_about, transform_points
from drivers.sim.sim_clutter import PEN_KINDS, Decal, classic_clutter, wide_clutter
from drivers.sim.sim_look import VARIETIES, Look, draw_look
from drivers.sim.sim_shapes import arc_length, chord_for_length, height, shape_f

F64 = NDArray[np.float64]

KINDS = ("straight", "arc", "s_curve", "nonplanar")
#: Named scenes: (shape kind, variety). ``tack_open``: a straight tack-welded seam 460-520 mm long
#: whose ends leave both images of the dry run's views.
PRESETS = {"tack_open": ("straight", "tack_open")}
DIFFICULTIES = ("easy", "medium", "hard")

#: Default seam centre in the robot base frame (mm): on a table in front of the IRB 2400.
DEFAULT_CENTRE_MM = (1000.0, 0.0, 300.0)


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
    variety: str = "classic"
    look: Look | None = None
    #: Seam arc-length spans (mm from the first truth point) covered by tack welds or spatter.
    occluded_spans_mm: tuple[tuple[float, float], ...] = ()
    #: Chord coordinate |a| (mm) of the truth seam's ends: chord/2 less the rounded corners.
    a_end_mm: float | None = None
    #: How far (mm, along the seam) a rounded corner leaves the end position in doubt.
    end_tol_mm: float = 0.0

    # ------------------------------------------------------------------ seam shape (local frame)
    @property
    def bow_mm(self) -> float:
        """The joint's bow (mm) at its middle (0 for classic scenes)."""
        return self.look.bow_mm if self.look is not None else 0.0

    def seam_b(self, a: NDArray[Any]) -> NDArray[Any]:
        """Across-chord offset b = f(a) (mm) of the seam at chord coordinate ``a`` (mm)."""
        return shape_f(self.kind, self.shape_mm, self.chord_mm, a, self.bow_mm)[0]

    def seam_db(self, a: NDArray[Any]) -> NDArray[Any]:
        """Slope df/da of the seam in the table plane at ``a``."""
        return shape_f(self.kind, self.shape_mm, self.chord_mm, a, self.bow_mm)[1]

    def seam_ddb(self, a: NDArray[Any]) -> NDArray[Any]:
        """Second derivative d2f/da2 (1/mm) of the seam at ``a``."""
        return shape_f(self.kind, self.shape_mm, self.chord_mm, a, self.bow_mm)[2]

    def height(self, a: NDArray[Any]) -> NDArray[Any]:
        """Surface height H(a) (mm, local z) of the sheets at chord coordinate ``a``."""
        return height(self.kind, self.shape_mm, self.chord_mm, a)[0]

    def height_slope(self, a: NDArray[Any]) -> NDArray[Any]:
        """dH/da of the sheets' surface at ``a``."""
        return height(self.kind, self.shape_mm, self.chord_mm, a)[1]

    def surface_z(self, a: NDArray[Any], b: NDArray[Any]) -> NDArray[Any]:
        """Local z (mm) of the sheets' top at (a, b).

        H(a), lowered by each sheet's tilt away from its joint edge (the tilt hinges on the edge,
        so the seam itself stays at H(a)).
        """
        z = self.height(a)
        if self.look is None or not (self.look.tilt_a_rad or self.look.tilt_b_rad):
            return z
        d = np.asarray(b) - self.seam_b(a)
        g2 = self.gap_mm / 2
        za = np.tan(self.look.tilt_a_rad) * np.maximum(-d - g2, 0.0)
        zb = np.tan(self.look.tilt_b_rad) * np.maximum(d - g2, 0.0)
        return np.asarray(z - za - zb)

    def arc_table(self) -> tuple[F64, F64]:
        """Dense (a, seam arc length in mm from the first truth point) for the whole chord."""
        a, s = arc_length(self.kind, self.shape_mm, self.chord_mm, bow=self.bow_mm)
        a_end = self.chord_mm / 2 if self.a_end_mm is None else self.a_end_mm
        return a, s - float(np.interp(-a_end, a, s))

    def pen_lines_mm(self) -> list[F64]:
        """Lines drawn on the sheets that a detector must not return (pen, marker, soapstone).

        Each is an (N, 3) polyline in the base frame (mm) on the sheets' top surface.
        """
        out = []
        for d in self.decals:
            if d.kind in PEN_KINDS:
                P = np.asarray(d.points, dtype=np.float64)
                local = np.column_stack([P, self.surface_z(P[:, 0], P[:, 1])])
                out.append(transform_points(self.T_base_local, local))
        return out

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
                "blur_px", "exposure", "clutter", "light_power", "ambient", "brush_contrast",
                "look"}


def make_scene(kind: str, seed: int, difficulty: str = "medium", variety: str = "classic",
               **overrides: Any) -> Scene:
    """A seeded workpiece scene in the robot base frame (mm); same arguments, same scene.

    ``kind`` is one of :data:`KINDS` or a preset of :data:`PRESETS`, ``difficulty`` one of
    :data:`DIFFICULTIES`, ``variety`` one of :data:`drivers.sim.sim_look.VARIETIES` (``classic``:
    the scenes the detector was first tuned on, unchanged; ``wide``, ``pen``: see
    :mod:`drivers.sim.sim_look`). Overrides (any of ``length_mm``, ``gap_mm``, ``shape_mm`` (arc
    radius, S amplitude or non-planar rise), ``centre_mm`` (3,), ``yaw_rad``, ``albedo_a``,
    ``albedo_b``, ``albedo_table``, ``gap_floor``, ``glare``, ``uneven_light``, ``vignetting``,
    ``noise_dn``, ``blur_px``, ``exposure``, ``light_power``, ``ambient``, ``brush_contrast``,
    ``clutter`` (False: no decals), ``look`` (a dict of :class:`Look` fields, not classic))
    replace the drawn values. Raises :class:`ConfigError` for an unknown kind, difficulty, variety
    or override, or a value out of range (classic: length 100-250 mm, gap 0.3-1.2 mm; other
    varieties: length 50-600 mm, gap 0.05-5 mm).
    """
    if kind in PRESETS:
        kind, variety = PRESETS[kind]
    if kind not in KINDS:
        raise ConfigError(f"scene kind {kind!r} unknown; use one of "
                          f"{', '.join(KINDS + tuple(PRESETS))}")
    if difficulty not in DIFFICULTIES:
        raise ConfigError(f"scene difficulty {difficulty!r} unknown; use one of "
                          f"{', '.join(DIFFICULTIES)}")
    if variety not in VARIETIES:
        raise ConfigError(f"scene variety {variety!r} unknown; use one of {', '.join(VARIETIES)}")
    unknown = set(overrides) - _OVERRIDABLE
    if unknown or ("look" in overrides and variety == "classic"):
        raise ConfigError(f"make_scene: unknown override(s) {sorted(unknown or {'look'})}; known: "
                          f"{sorted(_OVERRIDABLE)} ('look' not with the classic variety)")
    cfg: dict[str, Any] = _DIFF[difficulty]
    # One generator per aspect, so that overriding one value does not reshuffle the others.
    ss = np.random.SeedSequence([int(seed), KINDS.index(kind), DIFFICULTIES.index(difficulty)])
    g_shape, g_look, g_clutter = (np.random.default_rng(s) for s in ss.spawn(3))

    def u(rng: np.random.Generator, lo_hi: tuple[float, float]) -> float:
        return float(rng.uniform(*lo_hi))

    length = float(overrides.get("length_mm", u(g_shape, (100.0, 250.0))))
    gap = float(overrides.get("gap_mm", u(g_shape, cfg["gap"])))
    shape_draw = {"straight": 0.0,
                  "arc": u(g_shape, (0.75, 1.6)),        # radius as a multiple of the chord
                  "s_curve": u(g_shape, (0.06, 0.14)),   # amplitude as a fraction of the chord
                  "nonplanar": u(g_shape, (10.0, 40.0))}[kind]
    yaw = float(overrides.get("yaw_rad", u(g_shape, (-np.pi, np.pi))))
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
    wa, wb = u(g_shape, (60.0, 110.0)), u(g_shape, (60.0, 110.0))
    thickness, wide = 3.0, None
    if variety != "classic":
        g_wide = np.random.default_rng(np.random.SeedSequence(
            [int(seed), KINDS.index(kind), DIFFICULTIES.index(difficulty),
             1000 + VARIETIES.index(variety)]))
        wide, base = draw_look(g_wide, int(seed), difficulty, variety, min(albedo_a, albedo_b))
        try:
            wide = replace(wide, **dict(overrides.get("look", {})))
        except TypeError as err:
            raise ConfigError(f"make_scene: look override: {err}") from err
        for key, val in base.items():
            if key == "length_mm":
                length = float(overrides.get(key, val))
            elif key == "gap_mm":
                gap = float(overrides.get(key, val))
            elif key not in overrides:
                look[key] = val
        if "gap_floor" not in overrides:
            look["gap_floor"] = min(albedo_a, albedo_b) * (1.0 - wide.gap_contrast)
        if wide.table == "dark" and "albedo_table" not in overrides:
            look["albedo_table"] = float(g_wide.uniform(0.03, 0.08))
        thickness = float(g_wide.uniform(2.0, 6.0))
    lo_len, hi_len, lo_gap, hi_gap = (100.0, 250.0, 0.3, 1.2) if wide is None else \
        (50.0, 600.0, 0.05, 5.0)
    if not lo_len <= length <= hi_len:
        raise ConfigError(f"make_scene: length_mm {length} outside {lo_len:g}-{hi_len:g} mm")
    if not lo_gap <= gap <= hi_gap:
        raise ConfigError(f"make_scene: gap_mm {gap} outside {lo_gap:g}-{hi_gap:g} mm")
    for key in ("gap_floor", "light_power", "noise_dn", "blur_px", "exposure"):
        if not np.isfinite(look[key]) or look[key] < 0:
            raise ConfigError(f"make_scene: {key} must be a finite number >= 0, got {look[key]}")
    bow = wide.bow_mm if wide is not None else 0.0
    if "shape_mm" in overrides:
        fixed = float(overrides["shape_mm"])
        chord, shape = chord_for_length(kind, lambda c: fixed, length, bow)
    elif kind in ("arc", "s_curve"):
        chord, shape = chord_for_length(kind, lambda c: shape_draw * c, length, bow)
    else:
        chord, shape = chord_for_length(kind, lambda c: shape_draw, length, bow)
    if kind == "arc" and shape <= chord / 2:
        raise ConfigError(f"make_scene: arc radius {shape:.1f} mm must exceed half the chord "
                          f"{chord / 2:.1f} mm (at most a half circle)")
    a_end, end_tol = _corner_trim(chord, gap, wide.corner_mm if wide is not None else 0.0)
    scene = Scene(kind=kind, seed=int(seed), difficulty=difficulty, length_mm=length, gap_mm=gap,
                  chord_mm=chord, shape_mm=shape, T_base_local=T_base_local,
                  sheet_a_width_mm=wa, sheet_b_width_mm=wb, thickness_mm=thickness, **look,
                  variety=variety, look=wide, a_end_mm=a_end, end_tol_mm=end_tol)
    pts = _seam_points(scene)
    decals: tuple[Decal, ...] = ()
    spans: tuple[tuple[float, float], ...] = ()
    if overrides.get("clutter", True):
        if wide is None:
            decals = classic_clutter(scene, cfg, g_clutter)
        else:
            decals, spans = wide_clutter(scene, np.random.default_rng(
                np.random.SeedSequence([int(seed), KINDS.index(kind), 77, _CLUTTER_STREAM])))
    return replace(scene, seam_points_mm=pts, decals=decals, occluded_spans_mm=spans)


#: The wide clutter's stream (it was ``len(VARIETIES)`` when there were four varieties): kept, so
#: that adding a variety changes no scene already drawn.
_CLUTTER_STREAM = 4


def _corner_trim(chord: float, gap: float, r: float) -> tuple[float | None, float]:
    """(|a| of the truth ends, their doubt in mm) for plate corners rounded with radius ``r``.

    A rounded corner widens the gap toward the sheet border; the truth end is where the gap is
    twice its width, and the doubt is half the distance between 1.25x and 2x the width.
    """
    if r <= gap:
        return None, 0.0

    def x_at(widen: float) -> float:  # distance from the border where each edge recedes by widen
        return float(r - np.sqrt(max(r * r - (r - widen) ** 2, 0.0)))

    x_end = x_at(gap / 2)
    return chord / 2 - x_end, (x_at(gap / 8) - x_end) / 2


def _seam_points(scene: Scene, step_mm: float = 0.2) -> F64:
    a_dense, s_dense = arc_length(scene.kind, scene.shape_mm, scene.chord_mm, bow=scene.bow_mm)
    if scene.a_end_mm is not None:
        s0, s1 = (float(v) for v in np.interp([-scene.a_end_mm, scene.a_end_mm], a_dense,
                                              s_dense))
    else:
        s0, s1 = 0.0, float(s_dense[-1])
    n = max(int(np.ceil((s1 - s0) / step_mm)) + 1, 2)
    a = np.interp(np.linspace(s0, s1, n), s_dense, a_dense)
    local = np.column_stack([a, scene.seam_b(a), scene.height(a)])
    return transform_points(scene.T_base_local, local)
