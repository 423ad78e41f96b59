"""The guidance pipeline: from views to the located seam and the weld path, one way for everyone.

Detect the seam in each view (inside the job's nominal region when there is one), make the
observations (camera model, ``T_base_cam``, seam pixels), triangulate and check the seam
(:func:`~controller.stereo.locate.locate_seam`), plan the weld (:func:`plan_weld`). The weld cycle
runs :func:`locate_views` in its ``locating`` state and :func:`plan_path` in ``planning`` (a state
change, and the robot's joints read back, sit between them); ``seamguide locate`` runs both
through :func:`guide`; the dry run is a cycle. All of them take their limits and parameters from
one :class:`GuidanceSettings`, made from the job (:func:`settings_from_job`) or, without a job,
the defaults a job file has when it says nothing: what ``locate`` measures is what the cell welds.

Each view carries its own camera model and pose, so views from several cameras (each with its own
calibration, a view naming its camera) go through the same functions.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from controller.cell.job import Job
from controller.cell.other_view import OtherViewSeam, seam_from_other_view
from controller.errors import AmbiguousSeam, SeamguideError, SeamNotFound
from controller.geometry.camera_model import CameraModel
from controller.geometry.kinematics import RobotModel, irb2400
from controller.geometry.poses import Pose
from controller.path.path_fit import PathTolerance, fit_segments
from controller.path.weld_path import WeldParams, WeldPath, WorkspaceBox, plan_weld
from controller.stereo.locate import QualityLimits, Seam3D, ViewObservation, locate_seam
from controller.stereo.seam_curve import resample_curve
from controller.stereo.view_geometry import nominal_normal_from_views, view_layout_warning
from controller.vision.seam_params import DetectParams
from controller.vision.seam_scale import DEFAULT_GAP_MM, params_for_scale, px_per_mm_at

log = logging.getLogger(__name__)

F64 = NDArray[np.float64]
#: A seam detector: ``detector(image, camera=..., roi=...)`` -> a seam detection
#: (:func:`controller.vision.seam_detect.detect_seam` by default); with a nominal region it is
#: also given ``params=`` (the view's :class:`DetectParams`, :func:`view_params`), with a nominal
#: line ``hint=`` (:func:`nominal_hint`).
Detector = Callable[..., Any]
#: Per view: region of interest, detector parameters, nominal line px (:func:`search_args`).
SearchArgs = tuple[list[Any], list[DetectParams | None], list[Any] | None]


@dataclass(frozen=True)
class ViewInput:
    """One view to guide from: its name, the image, its camera's model and ``T_base_cam`` (mm)."""

    name: str
    image: NDArray[Any]
    camera: CameraModel
    T_base_cam: Pose


@dataclass(frozen=True)
class GuidanceSettings:
    """Everything the pipeline needs besides the views; the defaults are a job file's defaults.

    ``spacing_mm`` / ``count``: resampling of the seam points (``count`` wins when given);
    ``nominal_centre_mm`` + ``nominal_radius_mm`` (base frame, mm): where the seam must be (also
    the detectors' region of interest); ``normal``: out of the part (None: from the views);
    ``path_tolerance``: how closely the segments sent to the controller follow the path;
    ``clip_unseen_ends``: an end no view saw is cut at the nominal region (the job allows it);
    ``gap_mm``: the expected gap (narrowest, widest, mm) that, with each view's working distance
    to the nominal centre, sets the detector's pixel scales and the widest dark band taken for
    the gap, and the narrowest core split off a band as the gap (:func:`view_params`); None
    (the job does not say): the scales of
    :data:`~controller.vision.seam_scale.DEFAULT_GAP_MM` and neither limit;
    ``nominal_line_mm`` (base frame, mm, two or more points in order along the seam) and
    ``line_tolerance_mm``: the seam as drawn, seen from each view as the detector's nominal
    seam, and how far the real one may lie from it (:func:`nominal_hint`, :func:`view_params`);
    the located 3D seam must lie that close to the line too (``locate_seam``'s ``nominal_line``).
    """

    quality: QualityLimits = QualityLimits()
    spacing_mm: float | None = 2.0
    count: int | None = None
    nominal_centre_mm: tuple[float, float, float] | None = None
    nominal_radius_mm: float | None = None
    normal: tuple[float, float, float] | None = None
    weld: WeldParams = field(default_factory=WeldParams)
    workspace: WorkspaceBox = WorkspaceBox()
    path_tolerance: PathTolerance = field(default_factory=PathTolerance)
    clip_unseen_ends: bool = False
    gap_mm: tuple[float, float] | None = None
    nominal_line_mm: tuple[tuple[float, float, float], ...] | None = None
    line_tolerance_mm: float = 10.0

    @property
    def nominal_region(self) -> tuple[F64, float] | None:
        """(centre mm, radius mm) of the nominal seam sphere, or None."""
        if self.nominal_centre_mm is None or self.nominal_radius_mm is None:
            return None
        return np.asarray(self.nominal_centre_mm, dtype=np.float64), float(self.nominal_radius_mm)


def settings_from_job(job: Job) -> GuidanceSettings:
    """The pipeline settings of ``job``: quality limits, seam sampling and region, weld, box."""
    s = job.seam
    return GuidanceSettings(quality=job.quality, spacing_mm=s.spacing_mm, count=s.count,
                            nominal_centre_mm=s.nominal_centre_mm,
                            nominal_radius_mm=s.nominal_radius_mm, normal=s.normal,
                            weld=job.weld_params(), workspace=job.workspace(),
                            path_tolerance=job.path_tolerance(),
                            clip_unseen_ends=s.clip_unseen_ends, gap_mm=s.gap_mm,
                            nominal_line_mm=s.nominal_line_mm,
                            line_tolerance_mm=s.line_tolerance_mm)


@dataclass
class Located:
    """The located seam with what led to it: detections and observations in view order."""

    seam: Seam3D
    detections: list[Any]
    observations: list[ViewObservation]
    warning: str | None = None


@dataclass
class Guidance:
    """The pipeline's result: the located seam and the weld path (or why there is none)."""

    located: Located
    path: WeldPath | None = None
    path_error: SeamguideError | None = None


def nominal_roi(camera: CameraModel, T_base_cam: Pose, centre_mm: F64,
                radius_mm: float) -> tuple[int, int, int, int] | None:
    """Bounding box (x0, y0, x1, y1 px) of the nominal seam sphere seen from ``T_base_cam``.

    None when the sphere is not in front of the camera or its box is under 16 px a side.
    """
    c = np.asarray(centre_mm, dtype=np.float64)
    pts = c + radius_mm * np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1)
                                    for sz in (-1, 1)], dtype=np.float64)
    uv = camera.project(pts, T_base_cam)
    if np.any(~np.isfinite(uv)):
        return None
    x0, y0 = np.clip(np.floor(uv.min(axis=0)), 0, [camera.width - 1, camera.height - 1])
    x1, y1 = np.clip(np.ceil(uv.max(axis=0)), 0, [camera.width - 1, camera.height - 1])
    if x1 - x0 < 16 or y1 - y0 < 16:
        return None
    return int(x0), int(y0), int(x1), int(y1)


def nominal_hint(camera: CameraModel, T_base_cam: Pose,
                 line_mm: Sequence[Sequence[float]]) -> F64 | None:
    """The nominal seam ``line_mm`` (base frame, mm) seen from ``T_base_cam``: (N, 2) px.

    Sampled about every mm along it and projected (distortion included); points behind the
    camera are left out. None when fewer than two remain.
    """
    dense = resample_curve(np.asarray(line_mm, dtype=np.float64), spacing_mm=1.0)
    uv = camera.project(dense, T_base_cam)
    uv = uv[np.all(np.isfinite(uv), axis=1)]
    return uv if len(uv) >= 2 else None


def view_params(camera: CameraModel, T_base_cam: Pose, settings: GuidanceSettings,
                roi: tuple[int, int, int, int] | None = None) -> DetectParams | None:
    """The detector's parameters for one view, scaled to its working distance; None: defaults.

    The scale is ``fx / Z`` px per mm, ``Z`` (mm) the nominal seam centre's depth in front of
    the camera at ``T_base_cam`` (base frame, mm); the seam's expected length in the image is
    the nominal sphere's diameter at that scale, at most the diagonal of ``roi`` (or of the
    image); with a nominal line, how far the seam may lie from it is ``line_tolerance_mm`` at
    that scale. None without a nominal region or when its centre is not in front of the camera.
    """
    region = settings.nominal_region
    if region is None:
        return None
    centre, radius = region
    s = px_per_mm_at(camera.fx, T_base_cam, centre)
    if s is None:
        return None
    x0, y0, x1, y1 = roi if roi is not None else (0, 0, camera.width, camera.height)
    length = min(2.0 * radius * s, float(np.hypot(x1 - x0, y1 - y0)))
    gap = settings.gap_mm or DEFAULT_GAP_MM
    p = params_for_scale(s, gap, seam_length_px=length, limit_band=settings.gap_mm is not None)
    if settings.nominal_line_mm is not None:
        p = replace(p, hint_tol_px=settings.line_tolerance_mm * s)
    log.info("%.2f px/mm at %.0f mm (gap %g-%g mm%s): widest gap %.1f px, profiles +-%.1f px, "
             "shortest seam %.0f px%s", s, camera.fx / s, *gap,
             "" if settings.gap_mm is not None else ", the default",
             p.max_gap_px, p.half_width_px, p.min_length_px,
             f", widest dark band {p.max_band_px:.1f} px" if p.max_band_px else "")
    return p


def search_args(views: Sequence[ViewInput], settings: GuidanceSettings) -> SearchArgs:
    """Per view: region of interest, detector parameters and nominal line px for the search.

    The region is the nominal region's box, the parameters :func:`view_params`'s, the line
    :func:`nominal_hint`'s (None for all views: the job draws no line).
    """
    region = settings.nominal_region
    rois = [nominal_roi(v.camera, v.T_base_cam, *region) if region is not None else None
            for v in views]
    params = [view_params(v.camera, v.T_base_cam, settings, roi)
              for v, roi in zip(views, rois, strict=True)]
    hints = None
    if settings.nominal_line_mm is not None:
        hints = [nominal_hint(v.camera, v.T_base_cam, settings.nominal_line_mm) for v in views]
        for v, h in zip(views, hints, strict=True):
            if h is None:
                log.warning("%s: the job's nominal line is not in front of this camera; the "
                            "seam found in this view is not checked against it", v.name)
    return rois, params, hints


def detect_views(views: Sequence[ViewInput], settings: GuidanceSettings,
                 detector: Detector | None = None, outcomes: list[Any] | None = None,
                 args: SearchArgs | None = None) -> list[Any]:
    """The seam in each view (in view order), inside the nominal region's box when there is one.

    Two views at a time (:func:`detect_seams`), each with its own camera model and the pixel
    scales of its working distance (:func:`view_params`). Raises what the detector raises (seam
    not found, ambiguous seam), the message starting with the view's name; ``outcomes`` (if
    given) then holds every view's detection or error; ``args``: :func:`search_args`'s, if known.
    """
    from controller.vision.seam_views import detect_seams

    rois, params, hints = args or search_args(views, settings)
    return detect_seams([v.image for v in views], camera=[v.camera for v in views], rois=rois,
                        detector=detector, names=[v.name for v in views], params=params,
                        hints=hints, outcomes=outcomes)


def locate_views(views: Sequence[ViewInput], settings: GuidanceSettings, *,
                 detector: Detector | None = None,
                 on_detections: Callable[[list[Any]], None] | None = None,
                 note: Callable[..., None] | None = None,
                 check: Callable[[], Any] | None = None) -> Located:
    """Detect the seam in every view and triangulate it (base frame, mm): the first stage.

    ``on_detections`` gets the detections before the seam is located (records, overlays: they
    are kept when locating fails); when a view is refused, it gets every view's detection or
    error (a :class:`SeamguideError`) before the error is raised, so that a record still shows
    every view; ``note`` is told ``view_layout_warning=...`` about views
    rolled alike (also logged), ``seam_ends=...``, how each end of the seam was seen, and
    ``band_reading=...`` where every view split a shadow off the gap (which reading was kept);
    ``check`` runs between the steps (timeouts, aborts). Raises :class:`SeamguideError`
    subclasses: seam not found or ambiguous in a view, triangulation quality, seam outside the
    nominal region.
    """
    warning = view_layout_warning([v.T_base_cam for v in views])
    if warning is not None:
        log.warning("%s", warning)
        if note is not None:
            note(view_layout_warning=warning)
    outcomes: list[Any] = []
    other: OtherViewSeam | None = None
    args = search_args(views, settings)
    try:
        detections: list[Any] = detect_views(views, settings, detector, outcomes, args)
    except SeamguideError as err:
        if detector is None and len(outcomes) == len(views):
            other = _other_view(views, settings, outcomes, args)
        if other is None:
            if on_detections is not None and len(outcomes) == len(views):
                on_detections(outcomes)
            raise
        log.warning("%s; of the lines it measured, the one whose ends meet the seam found in "
                    "the other view is taken (%d looked at)", err, other.tried)
        detections = other.marked(outcomes)
    if on_detections is not None:
        on_detections(detections)
    if check is not None:
        check()
    if other is None:
        observations = [observation(v, d) for v, d in zip(views, detections, strict=True)]
        seam = locate_with(observations, settings)
    else:
        observations = [other.observation if isinstance(d, SeamguideError) else observation(v, d)
                        for v, d in zip(views, detections, strict=True)]
        seam = other.seam
        if note is not None:
            note(other_view=other.note(detections))
    ends = seam.quality.get("ends", [])
    clipped = [e for e in ends if e["status"] == "clipped"]
    if clipped:
        log.warning("seam %s", "; ".join(
            f"{e['end']} not seen by any view ({'; '.join(e['not_seen'])}): clipped to the "
            f"nominal region and off the image borders ({e['clipped_mm']:.1f} mm cut, "
            f"{e.get('border_trimmed_mm', 0.0):.1f} mm of it at the borders)" for e in clipped))
        if settings.nominal_line_mm is None:
            # The sphere's check does not see what clipping cut (README, *Twenty-fourth session*).
            log.warning("the job draws no nominal seam line ([seam] nominal_line_mm): a view's "
                        "curve that left the seam near a clipped end would not be caught; draw "
                        "the seam in the job to have the located seam held to it")
    band = seam.quality.get("band_reading")
    if band is not None and band["reading"] == "band":
        log.info("the lighter part of the dark band beside the gap is a cut face inside it, not "
                 "a shadow (the two readings lie %.2f mm apart along the sheet normal): the seam "
                 "is the whole band's middle", band["along_normal_mm"])
    if note is not None:
        note(seam_ends=ends, **({} if band is None else {"band_reading": band}))
    return Located(seam, list(detections), observations, warning)


def locate_with(observations: list[ViewObservation], settings: GuidanceSettings) -> Seam3D:
    """:func:`locate_seam` with the job's limits, region, clipping, normal and nominal line."""
    return locate_seam(observations, settings.quality, spacing_mm=settings.spacing_mm,
                       count=settings.count, nominal_region=settings.nominal_region,
                       clip_unseen_ends=settings.clip_unseen_ends,
                       normal=None if settings.normal is None else np.asarray(settings.normal),
                       nominal_line=None if settings.nominal_line_mm is None else (
                           np.asarray(settings.nominal_line_mm, dtype=np.float64),
                           settings.line_tolerance_mm))


def _other_view(views: Sequence[ViewInput], settings: GuidanceSettings, outcomes: list[Any],
                args: SearchArgs) -> OtherViewSeam | None:
    """The refused view's line whose ends meet the other view's seam, or None.

    Two views, one refused (seam not found, ambiguous), the other found:
    :mod:`controller.cell.other_view`.
    """
    from controller.vision.seam_lines import measured_lines

    refused = [i for i, d in enumerate(outcomes) if isinstance(d, (SeamNotFound, AmbiguousSeam))]
    if len(views) != 2 or len(refused) != 1 or any(
            isinstance(d, SeamguideError) for i, d in enumerate(outcomes) if i != refused[0]):
        return None
    b = refused[0]
    rois, params, hints = args
    lines = measured_lines(views[b].image, camera=views[b].camera, roi=rois[b], params=params[b],
                           hint=None if hints is None else hints[b])
    found = observation(views[1 - b], outcomes[1 - b])
    like = ViewObservation(views[b].camera, views[b].T_base_cam, found.seam_px, views[b].name)
    return seam_from_other_view(lines, like, found, b == 0,
                                lambda obs: locate_with(obs, settings))


def observation(view: ViewInput, detection: Any) -> ViewObservation:
    """What locating takes from one view and its detection.

    ``detection``: a :class:`SeamDetection`, or any object with ``points_px``. The centreline
    (px), and where the detector gives them its end kinds, the gap's width and the whole band's
    reading where a shadow was split off.
    """
    return ViewObservation(view.camera, view.T_base_cam, detection.points_px, view.name,
                           getattr(detection, "end_kinds", None),
                           getattr(detection, "gap_width_px", None),
                           getattr(detection, "band_px", None),
                           getattr(detection, "band_width_px", None))


def plan_path(located: Located, settings: GuidanceSettings, model: RobotModel | None = None,
              start_joints_deg: F64 | None = None) -> WeldPath:
    """The weld path over the located seam: the second stage (torch poses, tool offset, reach).

    The seam normal is the settings' or, without one, minus the views' mean optical axis. The weld
    targets are fitted with the fewest MoveL / MoveC segments within the settings' tolerance
    (``path.segments``: the controller interpolates lines and circles).
    ``start_joints_deg`` (controller axes, deg) picks the IK branch nearest the robot's joints.
    Raises :class:`ReachabilityError` / :class:`ConfigError` naming the first bad target.
    """
    if settings.normal is not None:
        normal = np.asarray(settings.normal, dtype=np.float64)
    else:
        normal = nominal_normal_from_views([o.T_base_cam for o in located.observations])
    path = plan_weld(model if model is not None else irb2400(), located.seam.points_mm, normal,
                     settings.weld, settings.workspace, start_joints_deg=start_joints_deg)
    path.segments = fit_segments([t.T_base_tcp for t in path.weld_targets],
                                 settings.path_tolerance)
    return path


def guide(views: Sequence[ViewInput], settings: GuidanceSettings, *, plan: bool = True,
          model: RobotModel | None = None, detector: Detector | None = None,
          on_detections: Callable[[list[Any]], None] | None = None) -> Guidance:
    """Both stages: the located seam and, when ``plan``, its weld path.

    A seam that cannot be welded is still returned, with the planner's error in ``path_error``
    (the cycle, which must not weld it, raises instead). Locating errors are raised.
    """
    located = locate_views(views, settings, detector=detector, on_detections=on_detections)
    if not plan:
        return Guidance(located)
    try:
        return Guidance(located, plan_path(located, settings, model))
    except SeamguideError as err:
        return Guidance(located, None, err)


def locate_output(seam: Seam3D, path: WeldPath | None) -> dict[str, Any]:
    """The ``seamguide locate`` output contract: seam points (base frame, mm), path, quality."""
    return {"seam_points_mm": [[round(float(v), 4) for v in p] for p in seam.points_mm],
            "weld_path": path.to_json() if path is not None else [],
            "quality": seam.quality}
