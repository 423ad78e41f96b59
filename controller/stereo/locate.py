"""The 3D seam from its image curves in two or more views: match, triangulate, smooth, judge.

Input: per view the camera model, the camera pose ``T_base_cam`` (from FK and hand-eye, or given)
and the detected seam polyline in pixels. Output: a :class:`Seam3D` in the base frame (mm) with the
per-point quality, or :class:`TriangulationError` with the numbers when a quality limit fails:
nothing doubtful is handed on to the weld.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from controller.errors import TriangulationError
from controller.geometry.poses import invert, transform_points
from controller.stereo.band_check import band_or_core
from controller.stereo.match_views import ViewObservation, triangulate_views
from controller.stereo.seam_curve import arc_length, end_bend_mm, resample_curve, smooth_curve
from controller.stereo.seam_ends import (
    clip_to_region,
    judge_ends,
    overlap_coverage,
    trim_to_margin,
    unseen_ends_problem,
    view_end_cut,
)
from controller.stereo.triangulate import PolylineDistance

__all__ = ["QualityLimits", "Seam3D", "ViewObservation", "locate_seam", "gap_width_mm"]

F64 = NDArray[np.float64]


@dataclass(frozen=True)
class QualityLimits:
    """Limits a triangulated seam must meet before anything is welded (mm, px, deg)."""

    max_ray_gap_mm: float = 0.5
    max_reprojection_rms_px: float = 1.0
    max_reprojection_px: float = 4.0
    min_angle_deg: float = 8.0
    min_coverage: float = 0.9
    max_degenerate_fraction: float = 0.15
    max_endpoint_gap_mm: float = 1.0
    max_gap_width_diff_mm: float = 0.3
    max_end_bend_mm: float = 0.5
    min_length_mm: float = 10.0
    require_ends_in_view: bool = True
    border_margin_px: float = 12.0


@dataclass
class Seam3D:
    """The located seam: ordered points in the base frame (mm), dense and resampled, and quality."""

    points_mm: F64
    dense_points_mm: F64
    ray_gap_mm: F64
    reprojection_px: F64  # (V, N) distance of each dense point's projection to each view's curve
    angle_deg: F64
    quality: dict[str, Any] = field(default_factory=dict)

    @property
    def length_mm(self) -> float:
        """Length of the seam (mm) along the smoothed curve."""
        return float(arc_length(self.dense_points_mm)[-1])


def _runs(mask: NDArray[np.bool_]) -> list[tuple[int, int]]:
    """Index ranges [start, stop) of consecutive True values."""
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist(),
                    strict=True))


def locate_seam(views: list[ViewObservation], limits: QualityLimits = QualityLimits(),
                spacing_mm: float | None = 2.0, count: int | None = None,
                sample_px: float = 2.0,
                nominal_region: tuple[F64, float] | None = None,
                clip_unseen_ends: bool = False, normal: F64 | None = None,
                nominal_line: tuple[F64, float] | None = None) -> Seam3D:
    """Triangulate a seam seen in two or more views; the first view is the reference.

    ``spacing_mm`` / ``count`` set the resampling of the output points (see
    :func:`controller.stereo.seam_curve.resample_curve`); ``sample_px`` the spacing of the reference
    curve samples; ``nominal_region`` = (centre mm, radius mm) from the job: every seam point must
    lie inside that sphere (it catches a wrong curve matched consistently, and gross calibration
    errors that no two-view check can see). ``nominal_line`` = (points (M, 3) mm, tolerance mm),
    the seam as the job draws it: every seam point must lie within the tolerance of it. It
    catches what clipping to the region hides: one view's curve leaving the seam along another
    line near an end no view sees triangulates to a curve that runs off the seam toward the
    region's edge (cut there, the rest kept). Raises :class:`TriangulationError` with the
    failing numbers in ``details``.

    Ends (:mod:`controller.stereo.seam_ends`): each end of the 3D seam must be seen by a view (a
    ``joint_end`` there). An end no view sees (the seam runs out of the images, or out of the
    stereo overlap) is clipped to ``nominal_region`` when ``clip_unseen_ends`` (the job allows
    it) and refused otherwise; ``quality["ends"]`` says which, per end.

    Where the views carry the detected gap's width, the widths in mm must agree
    (``max_gap_width_diff_mm``, or half the narrower): a view that took a shadow band or a cut
    face beside the gap for part of it has its centreline off by half of that, which shifts the
    triangulated seam along the other view's rays by a millimetre without tripping the
    reprojection limits. For the same reason an end that turns off the seam's own course
    (``max_end_bend_mm``, :func:`controller.stereo.seam_curve.end_bend_mm`) is refused. Where
    every view split a shadow off the gap, both readings are triangulated and the one the
    views' geometry supports is located (:mod:`controller.stereo.band_check`,
    ``quality["band_reading"]``; ``normal``: the sheets' normal in the base frame from the job,
    None: from the views), or the seam is refused where it supports neither.
    """
    views, band_reading, tri = band_or_core(views, limits.min_angle_deg, sample_px, normal)
    if band_reading is not None and band_reading["reading"] == "undecided":
        raise TriangulationError(
            f"every view split the gap's dark band into a darker core and a lighter band, and "
            f"the two readings lie {band_reading['offset_mm']:.2f} mm apart at "
            f"{band_reading['angle_deg']:.0f} deg from the sheet normal: neither a shadow beside "
            f"the gap (across the seam) nor a cut face inside it (along the normal). State the "
            f"joint's gap ([seam] gap_mm) and the sheets' normal ([seam] normal) in the job, "
            f"and see the overlays", band_reading=band_reading,
            views=[v.name for v in views])
    if tri is None:  # (the shadow-or-cut-face decision triangulated the reading it chose)
        tri = triangulate_views(views, limits.min_angle_deg, sample_px)
    curves, ref_px, X, rms_gap, angle = tri.curves, tri.ref_px, tri.X, tri.rms_gap, tri.angle
    degenerate_any, n, V = tri.degenerate, len(tri.ref_px), len(views)
    T0 = np.asarray(views[0].T_base_cam, dtype=np.float64)
    ok = np.isfinite(X[:, 0])
    details: dict[str, Any] = {"views": [v.name for v in views]}
    if ok.sum() < 5 and degenerate_any.sum() >= 5:
        baseline = views[1].T_base_cam[:3, 3] - T0[:3, 3]
        raise TriangulationError(
            f"the seam runs along the epipolar lines of {views[0].name} and {views[1].name} "
            f"({int(degenerate_any.sum())} of {n} samples): its depth cannot be triangulated. The "
            f"baseline between the cameras runs along {np.round(baseline, 1).tolist()} mm, along "
            f"the seam; teach view 2 displaced across the seam instead, or add a third view",
            degenerate_samples=int(degenerate_any.sum()), **details)
    if ok.sum() < 5:
        raise TriangulationError(
            "the seam curves of the views do not correspond: fewer than 5 points could be "
            "matched along epipolar lines; check that both views show the same seam and that the "
            "calibration and view poses are right", matched_points=int(ok.sum()), **details)
    first, last = int(np.flatnonzero(ok)[0]), int(np.flatnonzero(ok)[-1])
    span = slice(first, last + 1)
    s_ref = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(ref_px, axis=0), axis=1))])
    # Smooth over the reference image arc length, then fill degenerate gaps from the spline.
    good_idx = np.flatnonzero(ok)
    smooth_good = smooth_curve(s_ref[good_idx], X[good_idx])
    dense = np.column_stack([np.interp(s_ref[span], s_ref[good_idx], smooth_good[:, k])
                             for k in range(3)])
    ends = judge_ends(views, curves, dense, limits.border_margin_px)
    unseen = [e for e in ends if not e["seen_by"]]
    if unseen and clip_unseen_ends and limits.require_ends_in_view and nominal_region is not None:
        dense, kept = clip_to_region(dense, nominal_region, unseen)
        span = slice(first + kept[0], first + kept[1])
        dense, kept = trim_to_margin(dense, views, unseen, limits.border_margin_px)
        span = slice(span.start + kept[0], span.start + kept[1])
    reproj = np.full((V, len(dense)), np.nan)
    for k, v in enumerate(views):
        uv = v.camera.project(dense, v.T_base_cam)
        reproj[k] = PolylineDistance(curves[k])(uv)
    gap_mm = 2.0 * rms_gap[span] if V == 2 else rms_gap[span]
    in_span = np.zeros(n, dtype=bool)
    in_span[span] = True
    coverage, coverage_ref = overlap_coverage(s_ref, first, last, ends)
    degenerate_fraction = float(np.mean(degenerate_any[span] & ~ok[span]))
    endpoint_gaps = [e["ray_gap_mm"] if e["status"] == "seen" else 0.0 for e in ends]
    cut = [f"{v.name} ({'start' if e == 0 else 'end'})" for v, c in zip(views, curves, strict=True)
           for e in (0, -1) if view_end_cut(v, c, e, limits.border_margin_px)]
    quality = {
        "views": V,
        "points_triangulated": int(ok.sum()),
        "coverage": coverage,
        "coverage_of_reference": coverage_ref,
        "degenerate_fraction": degenerate_fraction,
        "ray_gap_mm_max": float(np.nanmax(gap_mm)),
        "ray_gap_mm_rms": float(np.sqrt(np.nanmean(gap_mm**2))),
        "reprojection_px_rms": [float(np.sqrt(np.nanmean(r**2))) for r in reproj],
        "reprojection_px_max": [float(np.nanmax(r)) for r in reproj],
        "angle_deg_min": float(np.nanmin(angle[span])),
        "angle_deg_median": float(np.nanmedian(angle[span])),
        "endpoint_gap_mm": endpoint_gaps,
        "ends_cut_by_image_border": cut,
        "ends": ends,
        "length_mm": float(arc_length(dense)[-1]),
        "end_bend_mm": end_bend_mm(dense),
        "gap_width_mm": [gap_width_mm(v, dense) for v in views],
    }
    if band_reading is not None:
        quality["band_reading"] = band_reading
    if nominal_region is not None:
        centre = np.asarray(nominal_region[0], dtype=np.float64)
        quality["distance_from_nominal_mm_max"] = float(
            np.max(np.linalg.norm(dense - centre, axis=1)))
        quality["nominal_radius_mm"] = float(nominal_region[1])
    if nominal_line is not None:
        line = np.asarray(nominal_line[0], dtype=np.float64)
        quality["distance_from_nominal_line_mm_max"] = float(
            np.max(PolylineDistance(line)(dense)))
        quality["line_tolerance_mm"] = float(nominal_line[1])
    _judge(quality, limits, degenerate_any & in_span, dense, s_ref, span.start, views, details)
    points = resample_curve(dense, spacing_mm, count)
    return Seam3D(points_mm=points, dense_points_mm=dense, ray_gap_mm=gap_mm,
                  reprojection_px=reproj, angle_deg=angle[span], quality=quality)


def gap_width_mm(view: ViewObservation, dense: F64) -> float | None:
    """The view's detected gap width (``gap_width_px``) in mm at the seam's median depth.

    ``dense``: the 3D seam (base frame, mm). Width px x depth / fx: the width across the line
    of sight (a gap seen obliquely looks narrower by the cosine, up to ~15 % at the views'
    usual 30 deg). None when the view carries no width.
    """
    if view.gap_width_px is None:
        return None
    z = transform_points(invert(view.T_base_cam), dense)[:, 2]
    return float(view.gap_width_px * np.median(z) / view.camera.fx)


def _split_hint(views: list[ViewObservation], dense: F64) -> str:
    """What to say where some views (not all) split a shadow off the gap: which, and what helps.

    With one view split and the other not, the two readings differ only along the other
    view's rays, so no 3D check tells a shadow from a cut face (:mod:`band_check`).
    """
    split = [v for v in views if v.band_px is not None and v.band_width_px is not None]
    if not split or len(split) == len(views):
        return ""
    parts = []
    for v in split:
        whole = gap_width_mm(replace(v, gap_width_px=v.band_width_px), dense)
        parts.append(f"{v.name} (whole band {whole:.2f} mm)")
    names = ", ".join(parts)
    return (f"; {names} split its dark band into a darker core and a lighter part where the "
            f"other views see one band: a shadow beside the gap, or the far sheet's cut face "
            f"inside a wide gap, which these views cannot tell apart. A job that states the "
            f"joint's gap ([seam] gap_mm) decides it")


def _judge(q: dict[str, Any], lim: QualityLimits, degenerate: NDArray[np.bool_], dense: F64,
           s_ref: F64, first: int, views: list[ViewObservation],
           details: dict[str, Any]) -> None:
    problems = []
    if q["coverage"] < lim.min_coverage:
        problems.append(f"only {q['coverage']:.0%} of the seam was matched between the views "
                        f"(limit {lim.min_coverage:.0%}): where neither runs out of its image, "
                        f"one view's curve stops short of the other's (a detection that stopped "
                        f"early, or the views took different lines; see the overlays)")
    if q["degenerate_fraction"] > lim.max_degenerate_fraction:
        runs = _runs(degenerate)
        i0, i1 = max(runs, key=lambda r: r[1] - r[0]) if runs else (first, first + 1)
        a = min(max(i0 - first, 0), len(dense) - 1)
        b = min(max(i1 - 1 - first, 0), len(dense) - 1)
        fix = np.cross(dense[b] - dense[a], views[1].T_base_cam[:3, 2])
        norm = float(np.linalg.norm(fix))
        # No direction from a stretch too short to have one (a single sample): no hint then.
        hint = (f": move view 2 so that the baseline between the cameras runs along "
                f"{(fix / norm).round(2).tolist()} (across the seam)"
                if np.isfinite(norm) and norm > 1e-6 else
                ": move view 2 so that the baseline between the cameras runs across the seam")
        problems.append(
            f"{q['degenerate_fraction']:.0%} of the seam runs along the epipolar lines between "
            f"the first two views (from {dense[a].round(1).tolist()} to "
            f"{dense[b].round(1).tolist()} mm){hint}")
    if q["angle_deg_min"] < lim.min_angle_deg:
        problems.append(f"the views see the seam from too similar directions: triangulation "
                        f"angle {q['angle_deg_min']:.1f} deg < {lim.min_angle_deg} deg")
    if q["ray_gap_mm_max"] > lim.max_ray_gap_mm:
        problems.append(f"rays miss each other by up to {q['ray_gap_mm_max']:.2f} mm "
                        f"(limit {lim.max_ray_gap_mm} mm)")
    rms, mx = max(q["reprojection_px_rms"]), max(q["reprojection_px_max"])
    if rms > lim.max_reprojection_rms_px or mx > lim.max_reprojection_px:
        problems.append(f"the 3D seam reprojects {rms:.2f} px RMS / {mx:.2f} px max from the "
                        f"detected curves (limits {lim.max_reprojection_rms_px} / "
                        f"{lim.max_reprojection_px} px)")
    if q["endpoint_gap_mm"] and max(q["endpoint_gap_mm"]) > lim.max_endpoint_gap_mm:
        problems.append(f"the views disagree about where the seam ends by "
                        f"{max(q['endpoint_gap_mm']):.2f} mm (limit {lim.max_endpoint_gap_mm} mm):"
                        f" either a detection stopped short of the seam's end (see the overlays)"
                        f" or the hand-eye calibration or view poses are wrong")
    if q.get("distance_from_nominal_mm_max", 0.0) > q.get("nominal_radius_mm", np.inf):
        problems.append(f"the seam lies up to {q['distance_from_nominal_mm_max']:.1f} mm from the "
                        f"job's nominal seam centre, outside its {q['nominal_radius_mm']:.0f} mm "
                        f"region: another edge was probably taken for the seam, or the part is "
                        f"not where the job expects it")
    if q.get("distance_from_nominal_line_mm_max", 0.0) > q.get("line_tolerance_mm", np.inf):
        problems.append(f"the seam lies up to {q['distance_from_nominal_line_mm_max']:.1f} mm "
                        f"from the job's nominal line (tolerance {q['line_tolerance_mm']:.1f} "
                        f"mm): a view's curve left the seam along another line (see the "
                        f"overlays), or the part is not where the job draws it")
    widths = [(v.name, w) for v, w in zip(views, q.get("gap_width_mm") or [None] * len(views),
                                          strict=True) if w is not None]
    if len(widths) >= 2:
        lo, hi = min(w for _, w in widths), max(w for _, w in widths)
        if hi - lo > max(lim.max_gap_width_diff_mm, 0.5 * lo):
            seen = ", ".join(f"{w:.2f} mm in {n}" for n, w in widths)
            problems.append(f"the views see the gap at different widths ({seen}; limit "
                            f"{lim.max_gap_width_diff_mm} mm or half the narrower): one of them "
                            f"took a shadow or a cut face beside the gap for part of it, so its "
                            f"centreline is off the joint (see the overlays)" + _split_hint(views,
                                                                                          dense))
    bends = [(e, b) for e, b in zip(("start", "end"), q.get("end_bend_mm") or (None, None),
                                           strict=True)
             if b is not None and b > lim.max_end_bend_mm]
    if bends:
        where = " and ".join(f"{b:.2f} mm at its {e}" for e, b in bends)
        problems.append(f"the 3D seam turns off its own course in its last 1.5 mm ({where}; "
                        f"limit {lim.max_end_bend_mm} mm): a view's curve leaves the gap near "
                        f"that end (a rounded corner, a ragged or covered end; see the overlays), "
                        f"which moves the end along the other view's rays")
    unseen = [e for e in q["ends"] if e["status"] == "unseen"]
    if lim.require_ends_in_view and unseen:
        problems.append(unseen_ends_problem(unseen))
    if q["length_mm"] < lim.min_length_mm:
        problems.append(f"the located seam is only {q['length_mm']:.1f} mm long")
    if problems:
        raise TriangulationError("3D seam failed its quality checks: " + "; ".join(problems),
                                 quality=q, problems=problems, **details)
