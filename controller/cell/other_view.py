"""A view whose search was refused, resolved by the other view's seam: the line whose ends meet it.

Of two views, one finds the seam and the other refuses: an end of the joint's line read as fading
out inside a sheet (a sheet as bright as the table beside a rounded corner), two lines of similar
strength, an end read as unsure. The refused view's search still measured its lines
(:func:`controller.vision.seam_lines.measured_lines`). Two views of one seam agree where the seam
ends: each of them is triangulated with the seam found in the other view
(:func:`controller.stereo.locate.locate_seam`, every limit of the job), and a line is taken only
when

1. every end the finding view reads as the joint's end (``joint_end``) is where the 3D seam ends
   (seen by that view, its end ray within :data:`END_RAY_GAP_MM`), and at least one such end
   exists: a pen line, a scratch or a plate's outer edge beside the joint ends elsewhere;
2. the refused view's own ends count only where it read a sure sheet border (also within
   :data:`END_RAY_GAP_MM` of the 3D end); an end it read as fading out, covered or unsure is one
   it does not see (``image_border`` to :func:`locate_seam`, which then clips or refuses an end
   no view sees, as the job says);
3. no end of the 3D seam that no view sees lies where the refused view's line stops inside its
   image (read as fading out, covered or unsure): the found view sees the seam go on there, and
   a seam cut where one view stopped seeing it would be welded short;
4. exactly one line passes: two lines that both fit are a choice this does not make.

Measured on the benchmark's extended tuning part (README, *Twenty-seventh session*). Pixels are
(u, v) in each view's distorted image; 3D in the base frame (mm).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from controller.errors import SeamguideError
from controller.stereo.locate import Seam3D, ViewObservation
from controller.stereo.seam_ends import END_MATCH_PX, IMAGE_BORDER, JOINT_END
from controller.vision.seam_lines import IMAGE_END, SURE_END, MeasuredLine

#: An end the finding view sees must lie this close (mm) to its end ray: half the locate limit,
#: ``max_endpoint_gap_mm`` (of the lines a scratch probe on the extended tuning part took at that
#: limit, those at 0.5-1.0 mm were partial or wrong: pen hard 50041 0.82 mm, another line; wide
#: hard 10171 0.53-0.57 mm, the found view wrong; medium 10260 0.62 mm, a valley path).
END_RAY_GAP_MM = 0.5


@dataclass(frozen=True)
class OtherViewSeam:
    """The seam located with a line of the refused view: which line, its observation, the seam."""

    line: MeasuredLine
    observation: ViewObservation
    seam: Seam3D
    tried: int  # lines triangulated
    along: str  # the found view's name

    def marked(self, outcomes: list[Any]) -> list[Any]:
        """``outcomes`` (every view's detection or error), the refused view's error marked.

        Its details now carry the line taken (``taken_px``, ``taken_along``): its picture draws
        it (:func:`controller.vision.seam_overlay.refused_lines`).
        """
        for d in outcomes:
            if isinstance(d, SeamguideError):
                d.details.update(taken_px=self.line.points_px, taken_along=self.along)
        return outcomes

    def note(self, outcomes: Sequence[Any]) -> dict[str, Any]:
        """The record's ``other_view`` note: the refused view, why, and the line taken there.

        ``outcomes``: every view's detection or error, in view order (one error: the refused
        view's).
        """
        err = next(d for d in outcomes if isinstance(d, SeamguideError))
        pts = self.line.points_px
        return {"view": self.observation.name, "refused": type(err).__name__,
                "reason": str(err), "lines_looked_at": self.tried,
                "line_ends_px": [[round(float(v), 1) for v in pts[i]] for i in (0, -1)],
                "line_end_readings": list(self.line.end_readings),
                "line_refused_alone": self.line.why_refused}


def observation_of(line: MeasuredLine, like: ViewObservation) -> ViewObservation:
    """``line`` as an observation of the view ``like`` describes (camera, pose, name).

    A sure sheet border is the joint's end (``joint_end``); any other end is one the view does not
    see (``image_border``: :func:`controller.stereo.seam_ends.view_end_cut`).
    """
    kinds = tuple(JOINT_END if k == SURE_END else IMAGE_BORDER for k in line.end_readings)
    return ViewObservation(like.camera, like.T_base_cam, line.points_px, like.name,
                           (kinds[0], kinds[1]), line.width_px if line.width_px > 0 else None)


def _cut_where_it_fades(seam: Seam3D, obs: ViewObservation, line: MeasuredLine) -> bool:
    """Whether an end of ``seam`` no view sees lies where ``line`` stops inside its image.

    An end of the refused view's line read as fading out (or covered, or unsure) is where that
    view stopped seeing the gap, not where the seam ends: the found view sees it go on. Cut there
    (the stereo overlap ends with the line), the seam would be welded short of the joint's end
    (the T-corner tuning pair 60027: 34 % of the joint). Such a seam is not taken; an unseen end
    where the line leaves its image, or beyond the line's end, is an unseen end like any other.
    """
    ends = line.points_px[[0, -1]]
    for e, end3d in zip(seam.quality.get("ends", []), seam.dense_points_mm[[0, -1]], strict=False):
        if e["status"] == "seen":
            continue
        uv = obs.camera.project(end3d[None], obs.T_base_cam)[0]
        d = np.linalg.norm(ends - uv, axis=1)
        i = int(np.argmin(d))
        if d[i] <= END_MATCH_PX and line.end_readings[i] != IMAGE_END:
            return True
    return False


def seam_from_other_view(lines: Sequence[MeasuredLine], refused: ViewObservation,
                         found: ViewObservation, refused_first: bool,
                         locate: Callable[[list[ViewObservation]], Seam3D]
                         ) -> OtherViewSeam | None:
    """The one line of ``lines`` whose seam with ``found`` meets its ends (module doc), or None.

    ``refused``: the refused view (camera, pose, name; its points are not used); ``found``: the
    other view's observation, with its end kinds; ``refused_first``: the refused view is the
    first (reference) view; ``locate``: the cycle's :func:`locate_seam` with the job's limits,
    region and clipping.
    """
    if found.end_kinds is None or JOINT_END not in found.end_kinds:
        return None
    n_joint = sum(k == JOINT_END for k in found.end_kinds)
    passing: list[OtherViewSeam] = []
    for line in lines:
        obs = observation_of(line, refused)
        views = [obs, found] if refused_first else [found, obs]
        try:
            seam = locate(views)
        except SeamguideError:
            continue
        ends = seam.quality.get("ends", [])
        seen = [e for e in ends if e["status"] == "seen"]
        if any(e["ray_gap_mm"] > END_RAY_GAP_MM for e in seen):
            continue
        if sum(found.name in e["seen_by"] for e in seen) < n_joint:
            continue
        if _cut_where_it_fades(seam, obs, line):
            continue
        passing.append(OtherViewSeam(line, obs, seam, len(lines), found.name))
    return passing[0] if len(passing) == 1 else None
