"""The seam in several views at once: one thread per view, every view's outcome kept."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from numpy.typing import NDArray

from controller.errors import InputError, SeamguideError, named_error
from controller.geometry.camera_model import CameraModel
from controller.vision.seam_detect import DetectParams, SeamDetection, detect_seam


def detect_seams(images: list[NDArray[Any]], *,
                 camera: CameraModel | Sequence[CameraModel] | None = None,
                 rois: list[tuple[int, int, int, int] | None] | None = None,
                 detector: Any = None,
                 names: Sequence[str] | None = None,
                 params: Sequence[DetectParams | None] | None = None,
                 hints: Sequence[Any] | None = None,
                 outcomes: list[SeamDetection | SeamguideError] | None = None
                 ) -> list[SeamDetection]:
    """:func:`detect_seam` on several views at once, one thread per view (at most 2 at a time).

    NumPy and OpenCV release the GIL for most of the work: two views take 0.6-0.8 of the time
    of one after the other on two cores. Results in the order of ``images``; the first view's
    error (in that order) is raised. ``camera`` is one model for every view or one
    per view (cameras with different lenses). ``detector`` replaces :func:`detect_seam` (same
    keyword arguments ``camera`` and ``roi``), e.g. in tests. With ``names`` (one per view), a
    view's error is raised as the same error type whose message starts with ``NAME: `` and whose
    details hold ``view=NAME``. ``params``: one :class:`DetectParams` per view (None: the
    detector's defaults, and no ``params`` argument is passed to a replacement ``detector``);
    ``hints``: one nominal seam polyline (px) per view or None (passed as ``hint`` only where
    given).
    ``outcomes``: if given, every view's detection or error is appended to it, in view order,
    before an error is raised (a record's pictures of every view, the refused ones too).
    """
    from concurrent.futures import ThreadPoolExecutor

    fn = detect_seam if detector is None else detector
    rois = rois if rois is not None else [None] * len(images)
    cams = (list(camera) if isinstance(camera, Sequence) else [camera] * len(images))
    prms = list(params) if params is not None else [None] * len(images)
    hnts = list(hints) if hints is not None else [None] * len(images)
    if len(rois) != len(images) or len(cams) != len(images) or len(prms) != len(images) or \
            len(hnts) != len(images) or (names is not None and len(names) != len(images)):
        raise InputError(f"detect_seams: {len(images)} images but {len(rois)} regions of interest, "
                         f"{len(cams)} cameras, {len(prms)} parameter sets, {len(hnts)} nominal "
                         f"seams and {len(names or images)} names")

    def one(i: int) -> SeamDetection | SeamguideError:
        extra: dict[str, Any] = {} if prms[i] is None else {"params": prms[i]}
        if hnts[i] is not None:
            extra["hint"] = hnts[i]
        try:
            return fn(images[i], camera=cams[i], roi=rois[i], **extra)  # type: ignore[no-any-return]
        except SeamguideError as err:
            named = err if names is None else named_error(err, names[i])
            if named is not err:
                named.__cause__ = err  # as `raise named from err` would
            return named

    if len(images) < 2:
        results = [one(i) for i in range(len(images))]
    else:
        with ThreadPoolExecutor(max_workers=2) as ex:
            results = list(ex.map(one, range(len(images))))
    if outcomes is not None:
        outcomes.extend(results)
    for r in results:
        if isinstance(r, SeamguideError):
            raise r
    return results  # type: ignore[return-value]  # no error among them
