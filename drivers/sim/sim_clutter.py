"""Marks on the simulated sheets and table (decals), in the scene's local (a, b) frame (mm).

:func:`classic_clutter` is the classic scenes' clutter (marker dots, scratches, short pen marks,
a 40-60 mm hole grid, other plates). :func:`wide_clutter` adds what a :class:`Look` asks for:
pen, marker and soapstone lines parallel to the joint (and some crossing it), 3D-scanner marker
dots, table kinds (perforated, slotted, engraved grid, plain, dark), pitting, and the blobs that
lie *over* the joint (tack welds, spatter balls), with the seam arc-length spans they cover.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np


class Scene(Protocol):
    """What the clutter reads of a :class:`drivers.sim.sim_scene.Scene` (mm, the sheet frame).

    A protocol rather than an import: sim_scene builds its clutter with this module.
    """

    @property
    def chord_mm(self) -> float:
        """Chord of the seam (mm)."""

    @property
    def gap_mm(self) -> float:
        """Gap width (mm)."""

    @property
    def look(self) -> Any:
        """The scene's :class:`~drivers.sim.sim_look.Look`, or None for the classic look."""

    @property
    def b_range_mm(self) -> tuple[float, float]:
        """Lateral extent of the seam (mm)."""

    def arc_table(self) -> tuple[Any, Any]:
        """Arc parameter and arc length along the seam (mm)."""

    def seam_b(self, a: Any) -> Any:
        """Lateral offset of the seam at ``a`` (mm)."""

    def seam_db(self, a: Any) -> Any:
        """Slope of the seam at ``a``."""


@dataclass(frozen=True)
class Decal:
    """A mark on the sheets or the table, in local (a, b) mm.

    ``shape`` is ``"dot"`` (centre ``p0``, ``radius_mm``), ``"line"`` (``p0`` to ``p1``,
    ``width_mm``), ``"rect"`` (corners ``p0``, ``p1``, rotated by ``angle_rad`` about its
    centre), ``"ellipse"`` (centre ``p0``, semi-axes ``p1``, rotated by ``angle_rad``) or
    ``"polyline"`` (``points``, ``width_mm``). ``value`` is the reflectance (0..1) painted there;
    ``layer`` is ``"part"`` (drawn only on the sheets), ``"table"`` (only on the table), ``"all"``,
    or ``"over"`` (on the sheets *and over the gap*: tack welds, spatter).
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
    points: tuple[tuple[float, float], ...] = ()


#: Decal kinds that are lines drawn on one sheet (or across the joint) a detector must not return.
PEN_KINDS = ("pen_parallel", "pen_cross")


def classic_clutter(scene: Scene, cfg: dict[str, Any],
                    rng: np.random.Generator) -> tuple[Decal, ...]:
    """Marker dots, scratches and pen lines on the sheets; holes, slots, plates on the table."""
    half = scene.chord_mm / 2
    b_lo, b_hi = scene.b_range_mm
    out: list[Decal] = []
    on_sheet = _on_sheet(scene, rng)
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
    out += _hole_grid(rng, half, b_lo, b_hi, (40.0, 60.0), (6.0, 9.0), relative=False)
    out += _plates(rng, half, b_lo, b_hi, cfg["plates"])
    return tuple(out)


def _on_sheet(scene: Scene, rng: np.random.Generator) -> Any:
    half = scene.chord_mm / 2
    b_lo, b_hi = scene.b_range_mm

    def on_sheet(clearance: float) -> tuple[float, float]:
        for _ in range(100):
            a = float(rng.uniform(-half + 3, half - 3))
            b = float(rng.uniform(b_lo + 3, b_hi - 3))
            if abs(b - float(scene.seam_b(np.array([a]))[0])) > clearance:
                return a, b
        return a, b
    return on_sheet


def _hole_grid(rng: np.random.Generator, half: float, b_lo: float, b_hi: float,
               pitch_range: tuple[float, float], rad_range: tuple[float, float],
               relative: bool) -> list[Decal]:
    """A grid of round table holes; ``relative``: the radius range is a fraction of the pitch."""
    pitch = float(rng.uniform(*pitch_range))
    off = rng.uniform(0, pitch, 2)
    rad = float(rng.uniform(*rad_range)) * (pitch if relative else 1.0)
    span = half + 200.0
    return [Decal("dot", (float(ga), float(gb)), radius_mm=rad, value=0.02, layer="table",
                  kind="hole")
            for ga in np.arange(-span + off[0], span, pitch)
            for gb in np.arange(b_lo - 200 + off[1], b_hi + 200, pitch)]


def _plates(rng: np.random.Generator, half: float, b_lo: float, b_hi: float,
            count: tuple[int, int]) -> list[Decal]:
    out = []
    for _ in range(int(rng.integers(count[0], count[1] + 1))):
        side = rng.choice([-1, 1])
        cb = (b_hi + rng.uniform(15, 80)) if side > 0 else (b_lo - rng.uniform(15, 80))
        ca = float(rng.uniform(-half - 60, half + 60))
        w, h = float(rng.uniform(20, 90)), float(rng.uniform(10, 60))
        out.append(Decal("rect", (ca - w / 2, float(cb) - h / 2), (ca + w / 2, float(cb) + h / 2),
                         angle_rad=float(rng.uniform(0, np.pi)), value=float(rng.uniform(0.3, 0.8)),
                         layer="table", kind="plate"))
    return out


def _table(scene: Scene, rng: np.random.Generator, kind: str) -> list[Decal]:
    half = scene.chord_mm / 2
    b_lo, b_hi = scene.b_range_mm
    if kind == "holes":
        return _hole_grid(rng, half, b_lo, b_hi, (40.0, 60.0), (6.0, 9.0), relative=False)
    if kind == "perforated":
        return _hole_grid(rng, half, b_lo, b_hi, (8.0, 25.0), (0.15, 0.35), relative=True)
    out: list[Decal] = []
    if kind == "slotted":
        # Slots from 0.6 mm (a thin dark line on the table, as thin as a gap) to 12 mm wide,
        # log-uniform: the tuning part's analogue of the held-out part's engraved grid lines.
        pitch, w = float(rng.uniform(30, 60)), float(np.exp(rng.uniform(np.log(0.6), np.log(12))))
        for ga in np.arange(-half - 200 + rng.uniform(0, pitch), half + 200, pitch):
            out.append(Decal("rect", (float(ga) - w / 2, b_lo - 200), (float(ga) + w / 2,
                             b_hi + 200), value=0.02, layer="table", kind="slot"))
    elif kind == "grid_lines":
        pitch, w = float(rng.choice([50.0, 100.0])), float(rng.uniform(0.5, 1.5))
        for ga in np.arange(-half - 200 + rng.uniform(0, pitch), half + 200, pitch):
            out.append(Decal("line", (float(ga), b_lo - 200), (float(ga), b_hi + 200),
                             width_mm=w, value=0.05, layer="table", kind="grid"))
        for gb in np.arange(b_lo - 200 + rng.uniform(0, pitch), b_hi + 200, pitch):
            out.append(Decal("line", (-half - 200, float(gb)), (half + 200, float(gb)),
                             width_mm=w, value=0.05, layer="table", kind="grid"))
    return out


def wide_clutter(scene: Scene, rng: np.random.Generator
                 ) -> tuple[tuple[Decal, ...], tuple[tuple[float, float], ...]]:
    """Decals of a wide-look scene and the occluded spans (seam arc length, mm, from its start)."""
    look = scene.look
    assert look is not None
    half = scene.chord_mm / 2
    b_lo, b_hi = scene.b_range_mm
    g2 = scene.gap_mm / 2
    out: list[Decal] = []
    on_sheet = _on_sheet(scene, rng)
    for _ in range(int(rng.integers(1, 6))):  # a few marker dots and scratches, as in classic
        r = float(rng.uniform(2.0, 5.0))
        a, b = on_sheet(r + 2.0)
        out.append(Decal("dot", (a, b), radius_mm=r, value=0.03 if rng.random() < 0.6 else 0.95,
                         kind="marker"))
    for _ in range(int(rng.integers(0, 12))):
        a, b = on_sheet(1.0)
        ang, ln = float(rng.uniform(-np.pi, np.pi)), float(rng.uniform(5.0, 60.0))
        out.append(Decal("line", (a, b), (a + ln * np.cos(ang), b + ln * np.sin(ang)),
                         width_mm=float(rng.uniform(0.1, 0.3)), value=float(rng.uniform(0.3, 0.95)),
                         kind="scratch"))
    for _ in range(look.scanner_dots):
        r = float(rng.uniform(3.0, 5.0))
        a, b = on_sheet(r + 1.5)
        out.append(Decal("dot", (a, b), radius_mm=r, value=0.03, kind="scanner"))
        out.append(Decal("dot", (a, b), radius_mm=r * float(rng.uniform(0.4, 0.6)), value=0.95,
                         kind="scanner"))
    n_pits = int(look.pits * (scene.chord_mm * (b_hi - b_lo)) / 100.0)
    for _ in range(n_pits):
        a, b = on_sheet(g2 + 0.5)
        out.append(Decal("dot", (a, b), radius_mm=float(rng.uniform(0.08, 0.35)),
                         value=float(rng.uniform(0.03, 0.15)), kind="pit"))
    out += _pens(scene, rng)
    out += _table(scene, rng, look.table)
    out += _plates(rng, half, b_lo, b_hi, (0, 4))
    blobs, spans = _on_joint(scene, rng)
    return tuple(out + blobs), spans


def _pens(scene: Scene, rng: np.random.Generator) -> list[Decal]:
    """Lines drawn parallel to the joint on one sheet (ending inside it), and some crossing it."""
    from drivers.sim.sim_look import _binned

    look = scene.look
    assert look is not None
    half = scene.chord_mm / 2
    g2 = scene.gap_mm / 2
    out: list[Decal] = []
    for _ in range(look.pens):
        side = float(rng.choice([-1.0, 1.0]))
        off = side * (g2 + _binned(rng, 3.0, 20.0, look.split))
        ln = float(rng.uniform(0.3, 0.9)) * (2 * half - 12.0)
        a0 = float(rng.uniform(-half + 6.0, half - 6.0 - ln))
        a = np.linspace(a0, a0 + ln, max(int(ln / 2.0), 2))
        wob = 0.3 * np.sin(a / float(rng.uniform(15, 40)) + float(rng.uniform(0, 6)))
        b = scene.seam_b(a) + off + wob
        r = rng.random()
        value = float(rng.uniform(0.02, 0.1)) if r < 0.6 else (
            float(rng.uniform(0.85, 0.97)) if r < 0.85 else float(rng.uniform(0.2, 0.4)))
        width = _binned(rng, 0.3, 2.5, look.split)
        out.append(Decal("polyline", (float(a[0]), float(b[0])), width_mm=width, value=value,
                         kind="pen_parallel",
                         points=tuple((float(x), float(y)) for x, y in zip(a, b, strict=True))))
    if look.pen_cross and look.pens:
        # (On a joint shorter than the line would be, the line is as long as the joint allows.)
        ln = min(float(rng.uniform(20.0, 80.0)), 2 * half - 12.0)
        ac = float(rng.uniform(-half + ln / 2 + 5, half - ln / 2 - 5))
        ang = float(rng.uniform(0.05, 0.5)) * float(rng.choice([-1.0, 1.0]))
        a = np.linspace(ac - ln / 2 * np.cos(ang), ac + ln / 2 * np.cos(ang), 20)
        b = scene.seam_b(np.array([ac]))[0] + (a - ac) * np.tan(ang)
        out.append(Decal("polyline", (float(a[0]), float(b[0])),
                         width_mm=float(rng.uniform(0.4, 1.5)), value=float(rng.uniform(0.02, 0.1)),
                         kind="pen_cross",
                         points=tuple((float(x), float(y)) for x, y in zip(a, b, strict=True))))
    return out


def _on_joint(scene: Scene, rng: np.random.Generator
              ) -> tuple[list[Decal], tuple[tuple[float, float], ...]]:
    """Tack welds and spatter balls on the joint (layer ``over``) and the seam spans they cover."""
    look = scene.look
    assert look is not None
    half = scene.chord_mm / 2
    a_dense, s_dense = scene.arc_table()
    out: list[Decal] = []
    spans: list[tuple[float, float]] = []
    n = look.tacks
    slots = np.linspace(-half, half, n + 2)[1:-1] if n else np.zeros(0)
    for ac in slots + rng.uniform(-0.3, 0.3, n) * (2 * half / (n + 1)):
        sa = float(rng.uniform(3.0, 7.5))  # half length along the seam
        sb = max(float(rng.uniform(2.0, 4.0)), 1.5 * scene.gap_mm)
        off = float(rng.uniform(-0.2, 0.2)) * sb
        out += _blob(scene, float(ac), off, sa, sb, rng, "tack")
        spans.append(_span(a_dense, s_dense, float(ac), sa * np.sqrt(1 - (off / sb) ** 2)))
    for _ in range(look.spatter):
        ac = float(rng.uniform(-half + 5, half - 5))
        r = float(rng.uniform(0.3, 1.5)) + 0.5 * scene.gap_mm
        if rng.random() < 0.5:  # on the joint: occludes it
            off = float(rng.uniform(-0.5, 0.5)) * r
            spans.append(_span(a_dense, s_dense, ac, float(np.sqrt(r * r - off * off))))
        else:  # beside it, on a sheet
            off = float(rng.choice([-1.0, 1.0])) * (scene.gap_mm / 2 + r + rng.uniform(0.3, 8.0))
        out += _blob(scene, ac, off, r, r, rng, "spatter")
    merged: list[tuple[float, float]] = []
    for s0, s1 in sorted(spans):
        if merged and s0 <= merged[-1][1]:
            merged[-1] = (merged[-1][0], max(merged[-1][1], s1))
        else:
            merged.append((s0, s1))
    return out, tuple(merged)


def _blob(scene: Scene, ac: float, off: float, sa: float, sb: float, rng: np.random.Generator,
          kind: str) -> list[Decal]:
    """A tack weld (a bright ragged bead, often with a dark crater) or a spatter ball."""
    bc = float(scene.seam_b(np.array([ac]))[0]) + off
    ang = float(np.arctan(scene.seam_db(np.array([ac]))[0]))
    out = [Decal("ellipse", (ac, bc), (sa, sb), angle_rad=ang, value=float(rng.uniform(0.7, 0.95)),
                 layer="over", kind=kind)]
    if kind == "tack":
        for _ in range(int(rng.integers(4, 10))):  # ragged rim: beads around the outline
            t = float(rng.uniform(0, 2 * np.pi))
            x, y = sa * np.cos(t), sb * np.sin(t)
            pa = ac + x * np.cos(ang) - y * np.sin(ang)
            pb = bc + x * np.sin(ang) + y * np.cos(ang)
            out.append(Decal("dot", (float(pa), float(pb)), radius_mm=float(rng.uniform(0.5, 1.5)),
                             value=float(rng.uniform(0.6, 1.0)), layer="over", kind=kind))
        if rng.random() < 0.7:
            out.append(Decal("ellipse", (ac, bc), (0.5 * sa, 0.55 * sb), angle_rad=ang,
                             value=float(rng.uniform(0.03, 0.12)), layer="over", kind=kind))
    else:
        out.append(Decal("dot", (ac - 0.3 * sa, bc - 0.3 * sb), radius_mm=0.3 * sa, value=1.0,
                         layer="over", kind=kind))
    return out


def _span(a_dense: Any, s_dense: Any, ac: float, half_len: float) -> tuple[float, float]:
    s = float(np.interp(ac, a_dense, s_dense))
    return float(max(s - half_len, 0.0)), float(min(s + half_len, float(s_dense[-1])))
