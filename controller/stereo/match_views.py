"""Two or more views of one seam matched along epipolar lines and triangulated, point by point.

The first view is the reference: its curve is sampled every ``sample_px`` and each sample's ray is
met by the matching point of every other view's curve (:mod:`controller.stereo.epipolar`). What
comes out is raw: no smoothing, no quality judgement (:mod:`controller.stereo.locate` does both).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from controller.errors import InputError
from controller.geometry.camera_model import CameraModel
from controller.stereo.epipolar import match_curves, point_on_polyline, relative_pose
from controller.stereo.triangulate import resample_polyline, triangulate_rays

F64 = NDArray[np.float64]


@dataclass(frozen=True)
class ViewObservation:
    """One view of the seam: camera, its pose in the base frame, the detected curve (px)."""

    camera: CameraModel
    T_base_cam: F64
    seam_px: F64
    name: str = "view"
    #: What each end of ``seam_px`` is (first point first): ``joint_end`` (a real end of the
    #: joint) or ``image_border`` (the seam leaves the image); None: judged by the border margin.
    end_kinds: tuple[str, str] | None = None
    #: The detected gap's median width (px), when the detector measured it; None: not checked.
    gap_width_px: float | None = None
    #: Where the detector split a shadow off the dark band: the whole band's centreline (px, in
    #: the order of ``seam_px``) and median width (px); :mod:`controller.stereo.band_check`
    #: decides which reading the views agree on. None: nothing split off.
    band_px: F64 | None = None
    band_width_px: float | None = None


@dataclass
class Triangulated:
    """Raw triangulation of the reference view's samples (base frame, mm; px)."""

    curves: list[F64]  # each view's detected curve (px), checked
    ref_px: F64  # (n, 2) reference samples
    X: F64  # (n, 3) triangulated points, NaN where unmatched
    rms_gap: F64  # (n,) RMS distance of the rays from X (mm)
    angle: F64  # (n,) largest angle between the rays (deg)
    degenerate: NDArray[np.bool_]  # (n,) the curve runs along an epipolar line in some view

    @property
    def ok(self) -> NDArray[np.bool_]:
        """(n,) samples with a triangulated point."""
        return np.isfinite(self.X[:, 0])


def check_observation(obs: ViewObservation) -> F64:
    """The view's curve as an (N, 2) float array; :class:`InputError` naming the view if bad."""
    px = np.asarray(obs.seam_px, dtype=np.float64)
    if px.ndim != 2 or px.shape[1] != 2 or len(px) < 2:
        raise InputError(f"{obs.name}: seam_px must be an ordered list of at least two [u, v] "
                         f"points, got shape {px.shape}")
    if not np.all(np.isfinite(px)):
        raise InputError(f"{obs.name}: seam_px holds non-finite values")
    return px


def triangulate_views(views: list[ViewObservation], min_angle_deg: float,
                      sample_px: float = 2.0) -> Triangulated:
    """Match every view's curve to the first view's samples and triangulate (module doc).

    ``min_angle_deg``: a match whose epipolar line runs within this angle of the curve is
    degenerate (not used). Raises :class:`InputError` for fewer than two views or a bad curve.
    """
    if len(views) < 2:
        raise InputError(f"locating a seam needs at least two views, got {len(views)}")
    curves = [check_observation(v) for v in views]
    ref_px = resample_polyline(curves[0], sample_px)
    n = len(ref_px)
    normalized = [views[0].camera.pixels_to_normalized(ref_px)]
    normalized += [v.camera.pixels_to_normalized(c) for v, c in zip(views[1:], curves[1:],
                                                                     strict=True)]
    V = len(views)
    origins = np.zeros((V, 3))
    dirs = np.full((V, n, 3), np.nan)
    valid = np.zeros((V, n), dtype=bool)
    degenerate_any = np.zeros(n, dtype=bool)
    T0 = np.asarray(views[0].T_base_cam, dtype=np.float64)
    origins[0], dirs[0] = views[0].camera.pixel_rays(ref_px, T0)
    for k in range(1, V):
        Tk = np.asarray(views[k].T_base_cam, dtype=np.float64)
        m = match_curves(normalized[0], normalized[k], relative_pose(T0, Tk), min_angle_deg)
        good = np.isfinite(m.t) & ~m.degenerate
        xy = point_on_polyline(normalized[k], m.t)
        origins[k] = Tk[:3, 3]
        d = np.column_stack([xy, np.ones(n)])
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        dirs[k] = d @ Tk[:3, :3].T
        valid[k] = good
        degenerate_any |= m.degenerate
    valid[0] = valid[1:].any(axis=0)
    X, rms_gap, angle = triangulate_rays(origins, dirs, valid)
    return Triangulated(curves, ref_px, X, rms_gap, angle, degenerate_any)
