"""The wide look of a simulated scene: what the classic renderer fixes, drawn at random.

A :class:`Look` holds every phenomenon the classic scenes do not have; a scene without one
(``Scene.look is None``, the ``classic`` variety) renders exactly as before. :func:`draw_look`
draws one for a variety and difficulty:

- ``wide``: any look. The gap is 1-30 px wide at the scene's viewing distance and from barely
  darker than the sheets to black; sheets 2-6 mm thick, tilted up to 4 deg, their cut faces seen
  inside the gap; a bow of up to 1.5 mm; ragged and tapering gap edges; parallel pen, marker or
  soapstone lines; scanner marker dots; perforated and other tables; a key light's soft shadow;
  ring-light glare; colour casts; JPEG. One draw in four takes the *shop* look of the real
  photographs (tack welds and spatter on the joint, ground strips with a bright ridge, rust and
  pitting, a plate edge shadowing one side of the gap, rounded plate corners) and one in six the
  *close-up* look (a dark, noisy, defocused view from 150-220 mm under a tinted spot light).
- ``pen``: a wide look with 1-3 lines drawn parallel to the joint 3-20 mm beside it on one
  sheet, often darker and wider than the gap, sometimes crossing it.
- ``rough``: a wide look whose sheets' brightness changes over a few mm as much as the real
  photographs' do (``bench/detect_realism.py``: every photograph changed along its joint more
  than any wide view): a log-normal mottle (rust, scale, grinding marks, glare patches) of
  ``mottle`` (log-brightness spread 0.5-1.1) at ``mottle_mm`` (0.3-2 mm) and four times that,
  drawn apart for the two sheets, over them and their ground strips; the gap's floor stays
  under the mottle's darkest patches (two spreads down), so that a person still sees it. In the
  field, ``marks`` thin dark scratches and pits per 100 mm^2 (2-26; the photographs' sheets
  offer the detector's profile test five to ten times as many gap-like places as a wide view's:
  ``detect_realism``'s ``look_alike``).
- ``tack_open``: the dry run's tack-welded seam (a classic look plus tack welds and spatter).
- ``tee``: a close-up (any difficulty) whose joint ends at a T-corner at one end: a third plate
  lies across the joint's end beyond a crossbar gap as wide as the joint's (0.7-1.5 x), its
  edge square to the joint; the sheets' corners there are square and the three plates flat, the
  third one sheet A's metal (the held-back close-ups: one end a T-corner, the other leaving the
  image).
- ``strip``: the shop look as the real photographs show it where the detector refuses them
  (``../shared/data/real-seams`` 1_x2, 1_x5): the joint runs through both images (a joint
  longer than the view), between two ground strips whose outer edges are crisp dark lines as
  long as the joint, beyond them the sheet unground (mill scale and rust, ``unground`` times as
  bright), the strips' edges nearly straight. A line as strong as the joint, on one sheet.

**Tuning and held-out parts.** :func:`split_of` puts every seed in one of two parts by a hash
(about half each). Besides the seeds, the parts draw from *disjoint* ranges: each split parameter
(gap width in px, gap contrast, tilt, bow, pen offset and width, JPEG quality, the colour cast's
hue) has its range cut into 6 bins, tuning scenes use bins 0, 2, 4 and held-out scenes bins 1, 3,
5; the table kinds ``slotted`` (tuning) and ``grid_lines`` (held-out) appear in one part only.
Thresholds may be fitted on tuning scenes only; held-out scenes measure.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from typing import Any

import numpy as np

SPLITS = ("tuning", "heldout")
VARIETIES = ("classic", "wide", "pen", "tack_open", "tee", "rough", "strip")
#: Table kinds: holes (classic 40-60 mm grid), perforated (hole grid, pitch 8-25 mm), slotted,
#: plain, dark, grid_lines (engraved lines).
TABLES_TUNING = ("holes", "perforated", "slotted", "plain", "dark")
TABLES_HELDOUT = ("holes", "perforated", "grid_lines", "plain", "dark")
#: Nominal focal length (px) used to turn a gap width in px into mm at the viewing distance:
#: the default 2272x1704 camera's.
FX_NOMINAL = 1.25 * 2272


def split_of(seed: int) -> str:
    """``"tuning"`` or ``"heldout"``: the part of the scene space a seed belongs to (see module)."""
    h = hashlib.sha256(f"seamguide-sim-split:{int(seed)}".encode()).digest()
    return SPLITS[h[0] & 1]


def seeds_in(split: str, n: int, start: int = 0) -> list[int]:
    """The first ``n`` seeds >= ``start`` that belong to ``split``."""
    out: list[int] = []
    s = start
    while len(out) < n:
        if split_of(s) == split:
            out.append(s)
        s += 1
    return out


@dataclass(frozen=True)
class Look:
    """Phenomena beyond the classic scene (lengths mm, angles rad, gains relative to the sheet).

    ``gap_contrast``: 1 - gap floor / sheet reflectance. ``bow_mm``: the joint's bow at its middle.
    ``ragged_mm``: amplitude of each gap edge's jag (zero-mean about the nominal edge); ``taper``:
    relative gap change end to end. ``tilt_a/b_rad``: sheet tilt about its joint edge (> 0: the
    sheet falls away from the joint). ``face_a/b``: cut-face brightness. ``step_shadow_mm``: width
    of the shadow a higher plate edge casts beside the gap on side ``step_side`` (-1 sheet A,
    +1 sheet B), darkened by ``step_depth``. ``ground_mm``: ground strip width per side,
    ``ground_gain`` its brightness, ``ground_edge_mm``/``ground_edge_depth`` the width and
    darkening of the thin dark line the grinder leaves at the strip's outer edge (a small step
    down into the strip: a crisp line parallel to the joint, bright strip on one side, rusty
    sheet on the other; 0: none), ``ridge_mm``/``ridge_gain`` the bright specular ridge at the
    gap edge. ``rust``: 0..1 rust cover; ``pits``: pits per 100 mm^2. ``corner_mm``: radius of the
    plate corners at the joint's ends. ``key_shadow``: (a, b, angle, penumbra_mm, depth) of a soft
    half-plane shadow or ``()``. ``ring_glare``: ring-light specular strength. ``spot``: a spot
    light's fall-off (0: none). ``cast_bgr``: colour gains (None: greyscale image).
    ``jpeg_quality``: 0 for none. ``standoff_mm``: the viewing distance the look is made for.
    ``tee_mm``: width of the crossbar gap of a T-corner at the joint's end ``tee_end`` (+1: the
    end at a = +chord/2, -1: at -chord/2), beyond which a plate ``tee_plate_mm`` long lies across
    the joint (0: no T-corner). ``mottle``: spread (standard deviation) of the sheets'
    log-brightness, a smooth random field of scales ``mottle_mm`` and four times that (0: none).
    ``marks``: thin dark marks (scratches 1-8 mm long, pits) in that field, per 100 mm^2 of
    each sheet (0: none). ``unground``: brightness factor of the sheets beyond the ground strips
    (mill scale, rust; 1: as the sheet). ``ground_wave_mm``: amplitude of the strips' wavy outer
    edges.
    """

    variety: str = "wide"
    split: str = "tuning"
    family: str = "plain"
    gap_contrast: float = 0.9
    bow_mm: float = 0.0
    ragged_mm: float = 0.0
    taper: float = 0.0
    tilt_a_rad: float = 0.0
    tilt_b_rad: float = 0.0
    face_a: float = 0.3
    face_b: float = 0.3
    step_shadow_mm: float = 0.0
    step_side: int = 1
    step_depth: float = 0.0
    ground_mm: tuple[float, float] = (0.0, 0.0)
    ground_gain: float = 1.0
    ground_edge_mm: float = 0.0
    ground_edge_depth: float = 0.0
    ridge_mm: float = 0.0
    ridge_gain: float = 0.0
    rust: float = 0.0
    pits: float = 0.0
    corner_mm: float = 0.0
    key_shadow: tuple[float, ...] = ()
    ring_glare: float = 0.0
    spot: float = 0.0
    cast_bgr: tuple[float, float, float] | None = None
    jpeg_quality: int = 0
    standoff_mm: float = 350.0
    table: str = "holes"
    tacks: int = 0
    spatter: int = 0
    pens: int = 0
    pen_cross: bool = False
    scanner_dots: int = 0
    tee_mm: float = 0.0
    tee_end: int = 1
    tee_plate_mm: float = 0.0
    mottle: float = 0.0
    mottle_mm: float = 2.0
    marks: float = 0.0
    unground: float = 1.0
    ground_wave_mm: float = 1.5


#: Per difficulty: (noise DN, blur px, min visibility of the gap as valley depth / noise, chance
#: of each optional phenomenon, clutter scale).
_WIDE = {
    "easy": dict(noise=(0.8, 2.0), blur=(0.5, 1.0), gap_px=(2.0, 12.0), contrast=(0.35, 1.0),
                 p=0.3, glare=(0.05, 0.4), uneven=(0.05, 0.25), vis=12.0),
    "medium": dict(noise=(1.5, 3.0), blur=(0.6, 1.4), gap_px=(1.3, 20.0), contrast=(0.22, 1.0),
                   p=0.5, glare=(0.2, 0.8), uneven=(0.15, 0.4), vis=8.0),
    "hard": dict(noise=(2.5, 4.5), blur=(0.8, 2.0), gap_px=(1.0, 28.0), contrast=(0.15, 1.0),
                 p=0.7, glare=(0.4, 1.5), uneven=(0.25, 0.55), vis=5.0),
}


def _binned(rng: np.random.Generator, lo: float, hi: float, split: str, bins: int = 6) -> float:
    """Uniform in the bins of [lo, hi] that belong to ``split`` (even bins tuning, odd held-out)."""
    k = int(rng.integers(0, bins // 2)) * 2 + (0 if split == "tuning" else 1)
    w = (hi - lo) / bins
    return float(lo + w * (k + rng.uniform()))


def gap_valley_dn(albedo: float, contrast: float, width_px: float, blur_px: float,
                  gain: float = 0.55) -> float:
    """Rough depth (grey levels) of the gap's valley after blur and the camera's gamma curve."""
    lit = albedo * gain
    full = 255.0 * (lit ** (1 / 2.2) - (lit * (1 - contrast)) ** (1 / 2.2))
    return float(full * min(1.0, width_px / (2.5 * max(blur_px, 0.3))))


def draw_look(rng: np.random.Generator, seed: int, difficulty: str, variety: str,
              albedo: float) -> tuple[Look, dict[str, Any]]:
    """A seeded :class:`Look` and the base scene values it replaces (gap_mm, noise_dn, ...).

    ``albedo`` is the darker sheet's reflectance (the gap's contrast and visibility are checked
    against it). Returns (look, base) where base holds ``gap_mm``, ``noise_dn``, ``blur_px``,
    ``glare``, ``uneven_light``, ``exposure``, ``ambient``, ``light_power``, ``length_mm``.
    """
    split = split_of(seed)
    c: dict[str, Any] = _WIDE[difficulty]
    p = float(c["p"])
    if variety == "tack_open":
        return Look(variety=variety, split=split, family="shop", tacks=int(rng.integers(4, 7)),
                    spatter=int(rng.integers(3, 9)), gap_contrast=float(rng.uniform(0.7, 0.95)),
                    ragged_mm=0.05), {"length_mm": float(rng.uniform(460.0, 520.0))}
    r = rng.random()
    family = "shop" if r < 0.25 else ("closeup" if r < 0.42 and difficulty != "easy" else "plain")
    if variety == "tee":
        family = "closeup"
    if variety == "strip":
        family = "shop"
    standoff = float(rng.uniform(300.0, 450.0)) if family != "closeup" else \
        float(rng.uniform(150.0, 220.0))
    base: dict[str, Any] = {
        "noise_dn": float(rng.uniform(*c["noise"])), "blur_px": float(rng.uniform(*c["blur"])),
        "glare": float(rng.uniform(*c["glare"])), "uneven_light": float(rng.uniform(*c["uneven"])),
        "exposure": float(rng.uniform(0.75, 1.15)), "length_mm": float(rng.uniform(100.0, 400.0))}
    lo, hi = c["gap_px"]
    if family == "closeup":
        lo, hi = 14.0, 28.0
        base.update(noise_dn=float(rng.uniform(4.0, 8.0)), blur_px=float(rng.uniform(2.0, 4.0)),
                    exposure=float(rng.uniform(0.25, 0.45)))
    gap_px = float(np.exp(_binned(rng, np.log(lo), np.log(hi), split)))
    contrast = _binned(rng, c["contrast"][0], 1.0, split)
    # The gap must stay visible to a person: deepen it until its valley stands out of the noise.
    for _ in range(20):
        depth = gap_valley_dn(albedo * base["exposure"], contrast, gap_px, base["blur_px"])
        if depth >= c["vis"] * base["noise_dn"] or contrast >= 0.99:
            break
        contrast = min(1.0, contrast + 0.05)
        gap_px = min(gap_px * 1.1, hi) if gap_px < 3 else gap_px
    base["gap_mm"] = gap_px * standoff / FX_NOMINAL
    tables = TABLES_TUNING if split == "tuning" else TABLES_HELDOUT

    def maybe(q: float = 1.0) -> bool:
        return bool(rng.random() < p * q)

    tilt_sign = rng.choice([-1.0, 1.0], 2)
    look: dict[str, Any] = dict(
        variety=variety, split=split, family=family, gap_contrast=contrast,
        bow_mm=_binned(rng, 0.0, 1.5, split) if maybe() else 0.0,
        ragged_mm=float(rng.uniform(0.05, 0.3)) * base["gap_mm"] + 0.02 if maybe() else 0.0,
        taper=float(rng.uniform(-0.4, 0.4)) if maybe(0.5) else 0.0,
        tilt_a_rad=float(np.radians(_binned(rng, 0.0, 4.0, split)) * tilt_sign[0]),
        tilt_b_rad=float(np.radians(_binned(rng, 0.0, 4.0, split)) * tilt_sign[1]),
        face_a=float(rng.uniform(0.05, 0.5)), face_b=float(rng.uniform(0.05, 0.5)),
        table=str(rng.choice(tables)), standoff_mm=standoff,
        key_shadow=(float(rng.uniform(-60, 60)), float(rng.uniform(-60, 60)),
                    float(rng.uniform(-np.pi, np.pi)), float(rng.uniform(3.0, 30.0)),
                    float(rng.uniform(0.3, 0.7))) if maybe(0.6) else (),
        ring_glare=float(rng.uniform(0.3, 1.5)) if maybe(0.5) else 0.0,
        jpeg_quality=int(_binned(rng, 35.0, 95.0, split)) if maybe(1.2) else 0,
        scanner_dots=int(rng.integers(8, 40)) if maybe(0.6) else 0,
        pens=int(rng.integers(1, 3)) if (variety == "pen" or maybe(0.5)) else 0,
        pen_cross=bool(rng.random() < 0.3),
        step_shadow_mm=float(rng.uniform(0.3, 2.5)) if maybe(0.5) else 0.0,
        step_side=int(rng.choice([-1, 1])), step_depth=float(rng.uniform(0.3, 0.8)),
        corner_mm=float(rng.uniform(3.0, 25.0)) if maybe(0.5) else 0.0, cast_bgr=None)
    if variety == "pen":
        look["pens"] = int(rng.integers(1, 4))
    if maybe(0.8):
        hue = _binned(rng, 0.0, 2 * np.pi, split)
        amp = float(rng.uniform(0.1, 0.45))
        look["cast_bgr"] = tuple(float(1.0 + amp * np.cos(hue + k * 2 * np.pi / 3))
                                 for k in range(3))
    if family == "shop":
        look.update(tacks=int(rng.integers(1, 4)), spatter=int(rng.integers(2, 12)),
                    ground_mm=(float(rng.uniform(5, 35)), float(rng.uniform(5, 35))),
                    ground_gain=float(rng.uniform(1.2, 1.8)), ridge_mm=float(rng.uniform(0.2, 1.0)),
                    ridge_gain=float(rng.uniform(0.3, 1.2)), rust=float(rng.uniform(0.3, 0.9)),
                    pits=float(rng.uniform(0.5, 4.0)),
                    ragged_mm=float(rng.uniform(0.1, 0.3)) * base["gap_mm"] + 0.03)
        if look["cast_bgr"] is None:
            look["cast_bgr"] = (0.85, 0.95, 1.05)
        # Drawn from a stream of its own: every scene drawn before the edge line was added keeps
        # all its other values.
        erng = np.random.default_rng([seed, 0x9E])
        if erng.random() < 0.7:
            look.update(ground_edge_mm=float(erng.uniform(0.15, 0.5)),
                        ground_edge_depth=float(erng.uniform(0.3, 0.85)))
    if family == "closeup":
        look.update(spot=float(rng.uniform(0.5, 1.5)), cast_bgr=(
            float(rng.uniform(0.45, 0.7)), 1.0, float(rng.uniform(0.4, 0.65))),
            corner_mm=float(rng.uniform(0.5, 3.0)), table="dark")
        base["length_mm"] = float(rng.uniform(100.0, 200.0))
    if variety == "rough":
        # A stream of its own: the look drawn before it is the wide look of the same seed.
        mrng = np.random.default_rng([seed, 0x6D])
        look.update(mottle=_binned(mrng, 0.5, 1.1, split),
                    mottle_mm=float(mrng.uniform(0.3, 2.0)))
        # Drawn after the mottle's values, so that those stay as they were before marks.
        look["marks"] = _binned(mrng, 2.0, 26.0, split)
        # Visible to a person: the gap's floor under the darkest patches of the mottle (two
        # spreads below the sheet's mean), not only out of the sensor's noise.
        look["gap_contrast"] = max(look["gap_contrast"],
                                   1.0 - float(np.exp(-2.0 * look["mottle"])))
    if variety == "strip":
        # A stream of its own, as the edge line's: the shop look's values drawn before it stay
        # as they are, these replace some of them.
        srng = np.random.default_rng([seed, 0x57])
        look.update(ground_edge_mm=float(srng.uniform(0.3, 0.7)),
                    ground_edge_depth=float(srng.uniform(0.6, 0.9)),
                    unground=_binned(srng, 0.3, 0.65, split),
                    ground_wave_mm=float(srng.uniform(0.0, 0.4)),
                    rust=float(srng.uniform(0.5, 1.0)), corner_mm=0.0)
        # Longer than the view: the joint leaves both images, as in the photographs.
        base["length_mm"] = float(srng.uniform(520.0, 600.0))
    if variety == "tee":
        # A stream of its own, as the edge line's.
        trng = np.random.default_rng([seed, 0x7E])
        look.update(tee_mm=base["gap_mm"] * float(trng.uniform(0.7, 1.5)),
                    tee_end=int(trng.choice([-1, 1])),
                    tee_plate_mm=float(trng.uniform(40.0, 120.0)), corner_mm=0.0,
                    tilt_a_rad=0.0, tilt_b_rad=0.0)
    return Look(**look), base
