"""The sheets' grain beside a seam: a shadow in its band, or one surface on both sides.

Two things one image's levels cannot tell, its texture can (README, *The sheets' grain*).

*A shadow in the band.* A plate edge standing higher than the other casts a shadow on the lower
sheet beside the gap. Where the shadow is about as dark as the gap's floor, the profiles fit one
dark band, gap and shadow together, and its middle lies up to half the shadow's width off the
joint (20 of the 39 wrong views of the extended tuning part). A shadow darkens the sheet it falls
on, whose grain (brushing and rolling marks, grit) runs on across the shadow's edge, scaled; at
the gap's edge one sheet ends and its grain stops (:func:`edge_grain`, :func:`shadow_side`).

*One surface on both sides.* A joint separates two sheets, whose grains do not continue each
other; a line drawn, scratched or cut into one sheet or into the table (a pen line, a slot) has
the same surface on both sides, and its grain runs on across the line (:func:`across_grain`).

Lines parallel to the seam are read past the band's edges (found on its median profile, each
line past the edge's blur), each as its fine texture (log radiance less its running mean over
:data:`HIGHPASS_PX`, which keeps the marks and drops light falloff and an edge's slow wander),
and compared at the slant the grain shows between two lines on one side alone (as far apart).
:func:`no_grain_across` asks both questions of the seam chosen, :func:`no_one_surface` the second
of a seam read on the image shrunk.

Pixels are (u, v) of the image searched; levels are linear radiance.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from controller.errors import AmbiguousSeam, SeamNotFound
from controller.vision.seam_decision import orient, points_summary, summary_px
from controller.vision.seam_detection import SeamDetection
from controller.vision.seam_params import F64, Candidate, DetectParams
from controller.vision.seam_profiles import bilinear, linear_lut, resample

#: Bands at least this share of the widest gap (``p.max_gap_px``) wide are read: a narrower
#: band's middle is within a tolerance's 3 px of the gap whatever part of it is shadow.
MIN_BAND_SHARE = 0.4
HIGHPASS_PX = 9  # running mean taken off the log radiance along a line (px)
CLIP_MADS = 2.5  # texture values clipped at this many robust standard deviations
BLURS = 1.5  # lines read this many edge widths (20-80 %) from an edge: past its blur
SLANT_PX = 30  # the grain's shift along the band, between lines a few px apart, looked for (px)
_SHIFTS = range(-SLANT_PX, SLANT_PX + 1)
SLANT_AGREE_PX = 2  # two shifts of the grain over the same distance agree within this (px)
#: The grain runs on across an edge: correlation at least this, and at least ``ON_SHARE`` of the
#: sheet's own between two lines as far apart, which is itself at least ``SHEET_MIN``.
ON_MIN = 0.2
ON_SHARE = 0.5
SHEET_MIN = 0.2
#: A shadow the grain shows through leaves the sheet at least this share of its light (the
#: simulator's shadows 0.2-0.7, a fill light's); a gap's floor is often near black, where the
#: log of the few levels left magnifies noise and JPEG ringing shared across the edge (real
#: photograph 1_x3 of ../shared/data/real-seams: 0.01, grain "running on" at 0.27 of 0.34).
LIT_MIN = 0.1
OFF_MAX = 0.12  # the grain stops at the other edge: correlation under this
_PROFILE_EVERY = 8  # the band's median profile is read at every 8th px along it, each px across
_SHEET_PX = (8.0, 15.0)  # beyond the band's half width: where a sheet's level is read


def _texture(v: F64, ok: NDArray[np.bool_]) -> tuple[F64, NDArray[np.bool_]]:
    """Fine texture of a line's samples: log radiance less its running mean; where it is whole.

    A sample counts where the whole :data:`HIGHPASS_PX` window around it is ``ok``. Clipped at
    :data:`CLIP_MADS` robust deviations: a spot, a hole or a tack weld's edge crossing the
    line would otherwise make the whole correlation.
    """
    lg = np.log(np.where(ok, v, 1.0) + 1e-3)
    k = np.ones(HIGHPASS_PX) / HIGHPASS_PX
    whole = np.convolve(ok.astype(np.float64), k, mode="same") > 1.0 - 1e-9
    t = lg - np.convolve(lg, k, mode="same")
    if whole.sum() >= 10:
        lim = CLIP_MADS * 1.4826 * float(np.median(np.abs(t[whole] - np.median(t[whole]))))
        t = np.clip(t, -lim, lim)
    return np.where(whole, t, 0.0), whole


def _spectra(t: F64, m: NDArray[np.bool_], size: int) -> NDArray[np.complex128]:
    """(3, size // 2 + 1): FFTs of a line's mask, texture and squared texture.

    Each 0 where not ``m``, zero-padded to ``size``: what :func:`_corr` correlates.
    """
    f = m.astype(np.float64)
    t = t * f
    return np.asarray(np.fft.rfft(np.stack([f, t, t * t]), size, axis=1), np.complex128)


def _corr(sa: NDArray[np.complex128], sb: NDArray[np.complex128], size: int,
          shifts: range) -> F64:
    """Pearson correlation of texture ``a[i]`` with ``b[i + k]`` per shift ``k`` of ``shifts``.

    ``sa``, ``sb``: the two lines' :func:`_spectra` (``size`` at least the lines' length plus
    the largest shift). Over the pairs where both are usable; -1 where fewer than 50. Every
    sum over the pairs is a cross-correlation, all shifts at once.
    """
    prod = np.conj(sa[[0, 1, 0, 1, 2, 0]]) * sb[[0, 0, 1, 1, 0, 2]]
    k = np.arange(shifts.start, shifts.stop) % size
    n, s_a, s_b, s_ab, s_aa, s_bb = np.fft.irfft(prod, size, axis=1)[:, k]
    with np.errstate(divide="ignore", invalid="ignore"):
        var = (s_aa - s_a * s_a / n) * (s_bb - s_b * s_b / n)
        r = (s_ab - s_a * s_b / n) / np.sqrt(var)
    return np.asarray(np.where((n >= 50 - 1e-6) & (var > 0.0), r, -1.0), np.float64)


Line = Callable[..., tuple[F64, NDArray[np.bool_]]]


def _sampler(grey: NDArray[np.uint8], lut: F64, points: F64,
             keep: NDArray[np.bool_] | None) -> tuple[Line, int] | None:
    """Lines parallel to ``points`` (a sample per px along it): offset px -> (levels, usable).

    Usable: inside the image and at a point of ``keep``; ``every``: only every so many samples.
    With the number of samples a line has; None for a line under 100 px.
    """
    pts, nrm = resample(points, 1.0, extend=0.0)
    if len(pts) < 100:
        return None
    ok = np.ones(len(pts), bool)
    if keep is not None and len(keep) == len(points):
        seg = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))]
        idx = np.clip(np.searchsorted(seg, np.arange(len(pts)) * 1.0), 0, len(points) - 1)
        ok &= keep[idx]

    def line(off: float | F64, every: int = 1) -> tuple[F64, NDArray[np.bool_]]:
        o = np.asarray(off, np.float64)[..., None]  # one offset, or (M, 1): (M, samples)
        q, n = pts[::every], nrm[::every]
        val, inside = bilinear(grey, lut, q[:, 0] + o * n[:, 0], q[:, 1] + o * n[:, 1])
        shape = o.shape[:-1] + (len(q),)
        return val.reshape(shape), (inside & ok[::every]).reshape(shape)

    return line, len(pts)


def _edges(line: Line, width_px: float) -> dict[int, tuple[float, float]] | None:
    """Per side (-1, +1): (the band's edge, offset px from its middle; how far past it to read).

    The edge is where the band's median profile has risen half-way to the sheet's level, which
    is read ``_SHEET_PX`` beyond the band's half width; a line is read :data:`BLURS` times the
    rise's 20-80 % width (at least 2 px) from it. None where too little of the band is in the
    image or a side shows no sheet brighter than the band.
    """
    h = 0.5 * width_px
    offs = np.arange(-h - _SHEET_PX[1], h + _SHEET_PX[1] + 1e-9, 1.0)
    val, inside = line(offs, _PROFILE_EVERY)
    m = np.all(inside, axis=0)  # samples every offset of the profile reads
    if int(m.sum()) < 100 // _PROFILE_EVERY:
        return None
    prof = np.median(val[:, m], axis=1)
    floor = float(prof[np.abs(offs) <= max(h, 1.0)].min())
    out = {}
    for side in (-1, 1):
        o = side * offs
        order = np.argsort(o)
        o_s, p_s = o[order], prof[order]
        p_s, o_s = p_s[o_s >= 0.0], o_s[o_s >= 0.0]
        sheet = float(np.median(p_s[(o_s >= h + _SHEET_PX[0]) & (o_s <= h + _SHEET_PX[1])]))
        if sheet <= floor:
            return None
        f = (p_s - floor) / (sheet - floor)
        if not (f > 0.8).any():
            return None
        a20, a80 = _crossing(o_s, f, 0.2), _crossing(o_s, f, 0.8)
        out[side] = (0.5 * (a20 + a80), max(2.0, BLURS * max(a80 - a20, 0.5)))
    return out


def _crossing(o: F64, f: F64, level: float) -> float:
    """Where ``f`` (at offsets ``o``, rising outward) first passes ``level``.

    Linearly between the samples on either side.
    """
    i = int(np.argmax(f > level))
    if i == 0:
        return float(o[0])
    return float(o[i - 1] + (o[i] - o[i - 1]) * (level - f[i - 1]) / max(f[i] - f[i - 1], 1e-12))


class _Band:
    """A band's lines, read once each: its sampler, its edges, each line's texture by offset."""

    def __init__(self, line: Line, edges: dict[int, tuple[float, float]], n: int) -> None:
        self.line, self.edges = line, edges
        self.size = 1 << int(np.ceil(np.log2(n + SLANT_PX + 2)))
        self._seen: dict[float, tuple[F64, NDArray[np.bool_], NDArray[np.complex128]]] = {}

    def read(self, off: float) -> tuple[F64, NDArray[np.bool_], NDArray[np.complex128]]:
        """(levels, usable, the texture's :func:`_spectra`) of the line at ``off`` px."""
        key = round(off, 6)
        if key not in self._seen:
            v, m = self.line(off)
            self._seen[key] = (v, m, _spectra(*_texture(v, m), self.size))
        return self._seen[key]

    def best_shift(self, a: float, b: float, shifts: range) -> tuple[float, int]:
        """(highest correlation of line ``b``'s texture with line ``a``'s, the shift it is at)."""
        c = _corr(self.read(a)[2], self.read(b)[2], self.size, shifts)
        k = int(np.argmax(c))
        return float(c[k]), shifts[k]


def _band(grey: NDArray[np.uint8], lut: F64, points: F64, width_px: float,
          keep: NDArray[np.bool_] | None) -> _Band | None:
    """The band along ``points`` (its sampler and edges), or None as :func:`_edges` says."""
    sampler = _sampler(grey, lut, points, keep)
    edges = None if sampler is None else _edges(sampler[0], width_px)
    if sampler is None or edges is None:
        return None
    return _Band(sampler[0], edges, sampler[1])


def edge_grain(grey: NDArray[np.uint8], lut: F64, points: F64, width_px: float,
               keep: NDArray[np.bool_] | None = None) -> dict[int, tuple[float, float]] | None:
    """Per side (-1, +1 along the left normal of ``points``): (grain across the edge, on sheet).

    ``points`` (K, 2) px, the band's centreline; ``width_px`` its median width; ``keep`` (K,)
    the points to read at (not a covered span: a tack weld's bead lies across both edges).
    Each: the correlation of a line inside the band's edge with one outside it, and of that one
    with a line as far again out on the sheet (its best over :data:`SLANT_PX` of shift; the
    edge's taken at that shift, +-1 px). The lines lie :data:`BLURS` edge widths (20-80 % of
    the rise on the band's median profile; at least 2 px) from the edge, the inner one not past
    the band's middle: nearer, the blur carries the sheet's texture into the band and the two
    lines correlate at any edge. The edge's is 0 where the line inside has under
    :data:`LIT_MIN` of the light of the one outside. None where too little of the band is in
    the image, or a side shows no sheet brighter than the band.
    """
    band = _band(grey, lut, points, width_px, keep)
    return None if band is None else _edge_grain(band)


def _edge_grain(band: _Band) -> dict[int, tuple[float, float]]:
    out: dict[int, tuple[float, float]] = {}
    for side, (edge, reach) in band.edges.items():
        d_in = min(reach, max(edge, 0.0))
        inner, outer = side * (edge - d_in), side * (edge + reach)
        sheet, k = band.best_shift(outer, side * (edge + 2 * reach + d_in), _SHIFTS)
        (vi, mi), (vo, mo) = band.read(inner)[:2], band.read(outer)[:2]
        lit = float(np.median(vi[mi]) / max(float(np.median(vo[mo])), 1e-9))
        on = band.best_shift(inner, outer, range(k - 1, k + 2))[0] if lit >= LIT_MIN else 0.0
        out[side] = (on, sheet)
    return out


def across_grain(grey: NDArray[np.uint8], lut: F64, points: F64, width_px: float,
                 keep: NDArray[np.bool_] | None = None) -> tuple[float, float, bool] | None:
    """(grain across the whole line, the lower of the two sides' own, at the same slant).

    Lines read past each edge of the line's dark band as in :func:`edge_grain`; the texture of
    one compared with the other's (best over :data:`SLANT_PX` of shift) and each with a line as
    far again out on its own side. The third item: the grain's shift across the line agrees,
    within :data:`SLANT_AGREE_PX`, with the shift each side's own pair shows (the grain is
    straight: a line drawn on one surface shifts it as the surface itself does). None as for
    :func:`edge_grain`.
    """
    band = _band(grey, lut, points, width_px, keep)
    return None if band is None else _across_grain(band)


def _across_grain(band: _Band) -> tuple[float, float, bool]:
    at = {side: side * (e + r) for side, (e, r) in band.edges.items()}
    sep = at[1] - at[-1]
    across, k = band.best_shift(at[-1], at[1], _SHIFTS)
    own = {side: band.best_shift(at[side], at[side] + side * sep, _SHIFTS) for side in (-1, 1)}
    agree = (abs(k - own[1][1]) <= SLANT_AGREE_PX and abs(k + own[-1][1]) <= SLANT_AGREE_PX)
    return across, min(own[1][0], own[-1][0]), agree


def _runs_on(corr: float, own: float) -> bool:
    """Whether a correlation ``corr`` across a line or an edge says the grain runs on across it.

    ``own``: the grain's correlation over as far on one side alone (the one compared).
    """
    return own >= SHEET_MIN and corr >= ON_MIN and corr >= ON_SHARE * own


def shadow_side(grain: dict[int, tuple[float, float]]) -> int | None:
    """The side whose sheet's grain runs on into the band while the other edge's stops, or None."""
    for side in (-1, 1):
        if _runs_on(*grain[side]) and grain[-side][0] < OFF_MAX:
            return side
    return None


def _oriented(points: F64, keep: NDArray[np.bool_] | None
              ) -> tuple[F64, NDArray[np.bool_] | None]:
    """``points`` (and ``keep``) in the detector's order (:func:`seam_decision.orient`).

    The lines are sampled a px apart from the first point: the same seam read from either end
    would be sampled half a px apart and correlate a little differently.
    """
    pts = orient(points)
    if pts is points or keep is None:
        return pts, keep
    return pts, keep[::-1]


def no_grain_across(grey: NDArray[np.uint8], lut: F64, best: Candidate, p: DetectParams,
                    x0: int, y0: int) -> None:
    """Refuse ``best`` where the grain runs on across it or across one edge of its band.

    Across the whole line: :func:`no_one_surface`. Across one edge, for bands of
    ``MIN_BAND_SHARE * p.max_gap_px`` or wider not split into a core and a shadow already
    (``best.band_points``, :mod:`controller.vision.seam_shadow`): the gap with one sheet in
    shadow beside it (:func:`shadow_side`), :class:`AmbiguousSeam`. Neither where ``p.grain``
    is off (the search on the image shrunk).
    """
    if not p.grain or best.points is None or best.width is None:
        return
    width = float(np.median(best.width))
    keep = None if best.bridged is None else ~np.asarray(best.bridged, bool)
    pts, keep = _oriented(best.points, keep)
    band = _band(grey, lut, pts, width, keep)
    if band is None:
        return
    _one_surface(band, best.points, x0, y0)
    if best.band_points is not None or width < MIN_BAND_SHARE * p.max_gap_px:
        return
    grain = _edge_grain(band)
    if (side := shadow_side(grain)) is None:
        return
    on, sheet = grain[side]
    raise AmbiguousSeam(
        f"the dark band ({width:.1f} px wide) is the gap with one sheet in shadow beside it: "
        f"that sheet's grain runs on into the band across one edge (correlation {on:.2f}, "
        f"{sheet:.2f} on the sheet itself) and stops at the other ({grain[-side][0]:.2f}), so "
        "the band's middle is off the joint by up to half the shadow's width and one image "
        "cannot tell how much; refusing: light the joint so that neither plate edge shades it "
        "(from above, or from the lower sheet's side)",
        best_px=summary_px(best, x0, y0), band_width_px=round(width, 1),
        grain=[round(on, 2), round(sheet, 2), round(grain[-side][0], 2)])


def no_one_surface(grey: NDArray[np.uint8], det: SeamDetection, p: DetectParams, x0: int,
                   y0: int) -> None:
    """Raise :class:`SeamNotFound` where the seam ``det`` (px of ``grey``) has one surface.

    The grain of each side runs on across it (:func:`across_grain`). A line drawn, scratched
    or cut into one sheet or into the table (a pen or soapstone line, a scratch, a table's slot
    or grid line) has the same surface on both sides; a joint has two sheets, whose grains do
    not continue each other. Asked where the grain on each side, at the distance across the
    line, correlates at :data:`SHEET_MIN` or more, at the same slant. Not where ``p.grain`` is
    off.
    """
    if not p.grain:
        return
    pts, keep = _oriented(det.points_px, ~det.occluded)
    band = _band(grey, linear_lut(p.gamma), pts, det.gap_width_px, keep)
    if band is not None:
        _one_surface(band, det.points_px, x0, y0)


def _one_surface(band: _Band, points: F64, x0: int, y0: int) -> None:
    """:func:`no_one_surface` on ``band``, along ``points`` (px, reported with ``x0, y0``)."""
    across, own, agree = _across_grain(band)
    if agree and _runs_on(across, own):
        raise SeamNotFound(
            f"the line chosen has one surface on both sides: the grain runs on across it "
            f"(correlation {across:.2f}, at the slant each side shows; {own:.2f} or more on "
            "each side itself), so it is a line drawn, scratched or cut into one sheet or the "
            "table (a pen or soapstone line, a scratch, a table's slot), not a joint between "
            "two sheets; check that the joint is in view, or give a --roi around it",
            best_px=points_summary(points, x0, y0), grain=[round(across, 2), round(own, 2)])
