"""A shadow beside the gap or a cut face inside it: the reading the views agree on in 3D.

Where a dark band has a darker core on one side, the detector takes the core for the gap and the
lighter rest for a shadow beside it (:mod:`controller.vision.seam_shadow`) and also returns the
whole band's centreline. One view cannot tell which it is; 3D can (sheet top at depth 0, gap
``g`` wide, lateral position across the seam):

- a **shadow** of a higher plate edge lies on the lower sheet: the core runs from one top edge
  to the other (middle at ``g/2``), the band on to the shadow's edge ``s`` further (middle at
  ``(g+s)/2``), both at the same depth. The two readings triangulate ``s/2`` apart *across* the
  seam, along the sheet; the core is the gap.
- a **cut face** (the far sheet's edge, ``t`` thick, seen inside the gap from an oblique view):
  the core runs from the near top edge to the face's foot (middle at ``g/2``, depth ``t/2``),
  the band between the two top edges (middle at ``g/2``, depth 0). The readings triangulate
  ``t/2`` apart *along the sheet normal*; the band is the gap, and the core reading would weld
  half a sheet thickness too deep (the dry run's open_ends seed 3: 1.06 mm).

So both readings are triangulated and their offset (per point, the component along the seam
removed; medians over the seam) is compared with the sheet normal: the job's (``[seam]
normal``) or, without one, minus the views' mean optical axis (as the planner takes it). Within
``DECIDED_DEG`` of the normal the band is the gap; within ``DECIDED_DEG`` of the sheet, the core.
The two cases give 0 and 90 deg up to the normal's error (the views' mean axis is off the
sheet's normal by the views' asymmetry, 10-20 deg in the dry run's cell); an offset in between is
neither, and the seam is refused rather than guessed (``"undecided"``). A split
in only some views cannot be decided this way (the unsplit view's line is the band under either
reading, so the two pairs differ only along its rays); it is left to the stereo checks, where the
gap widths in mm disagree and the pair is refused.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from controller.stereo.match_views import Triangulated, ViewObservation, triangulate_views
from controller.stereo.view_geometry import nominal_normal_from_views

F64 = NDArray[np.float64]

#: Largest angle (deg) between the readings' offset and the normal (a cut face) or the sheet (a
#: shadow) that decides; in between, neither: refused. The pure cases lie at 0 deg (a cut face)
#: and 90 deg (a shadow) up to the normal's error; each is given a third of the quadrant.
DECIDED_DEG = 30.0


def band_or_core(views: list[ViewObservation], min_angle_deg: float, sample_px: float = 2.0,
                 normal: F64 | None = None
                 ) -> tuple[list[ViewObservation], dict[str, Any] | None, Triangulated | None]:
    """The views to locate with (the cores' or the whole bands' centrelines), and why.

    The third value is those views' triangulation where it was made here (the reading chosen,
    or the cores), so that the caller does not make it again; None: not made.

    ``normal``: the sheet's normal in the base frame (the job's), None: minus the views' mean
    optical axis. Returns ``views`` unchanged and None unless every view carries a band
    (``band_px``). Else the record: ``reading`` ("core": a shadow beside the gap; "band": a cut
    face inside it; "undecided": neither, the caller refuses), ``offset_mm`` (how far apart the
    readings lie, median), its median components ``along_normal_mm`` (band minus core, toward
    the cameras) and ``across_mm``, and ``angle_deg`` from the normal. Where either reading
    cannot be triangulated (fewer than 5 points) the cores are kept and ``reading`` is "core
    (not triangulated)": the stereo checks then judge the cores.
    """
    band_px = [v.band_px for v in views]
    if len(views) < 2 or any(b is None for b in band_px):
        return views, None, None
    bands = [dataclasses.replace(v, seam_px=b, gap_width_px=v.band_width_px)
             for v, b in zip(views, band_px, strict=True) if b is not None]
    core = triangulate_views(views, min_angle_deg, sample_px)
    band = triangulate_views(bands, min_angle_deg, sample_px)
    Xc, Xb = core.X[core.ok], band.X[band.ok]
    if len(Xc) < 5 or len(Xb) < 5:
        return views, {"reading": "core (not triangulated)"}, core
    _, nearest = cKDTree(Xb).query(Xc)
    d = Xb[nearest] - Xc
    tangent = np.gradient(Xc, axis=0)
    tangent /= np.maximum(np.linalg.norm(tangent, axis=1, keepdims=True), 1e-12)
    d -= np.sum(d * tangent, axis=1, keepdims=True) * tangent
    if normal is None:
        normal = nominal_normal_from_views([v.T_base_cam for v in views])
    normal = np.asarray(normal, dtype=np.float64) / np.linalg.norm(normal)
    # Per point, then the median: on a curved seam the across direction turns along it.
    d_along = d @ normal
    along = float(np.median(d_along))
    across = float(np.median(np.linalg.norm(d - d_along[:, None] * normal, axis=1)))
    angle = float(np.degrees(np.arctan2(across, abs(along))))
    reading = ("band" if angle <= DECIDED_DEG else "core" if angle >= 90.0 - DECIDED_DEG
               else "undecided")
    offset = float(np.median(np.linalg.norm(d, axis=1)))
    record = {"reading": reading, "offset_mm": round(offset, 3),
              "along_normal_mm": round(along, 3), "across_mm": round(across, 3),
              "angle_deg": round(angle, 1)}
    return (bands, record, band) if reading == "band" else (views, record, core)
