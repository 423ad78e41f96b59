"""``seamguide detect IMAGE``: the seam in one image, as JSON (and an overlay picture)."""

from __future__ import annotations

import argparse
import logging
from typing import Any

from controller.errors import AmbiguousSeam, InputError, SeamNotFound
from controller.jsonio import emit_json

log = logging.getLogger(__name__)


def register(sub: Any) -> None:
    """Add the ``detect`` subcommand to ``sub`` (an argparse subparsers object)."""
    p = sub.add_parser(
        "detect", help="find the seam in one image",
        description="Find the weld seam in one image. Prints JSON: seam_px (the sub-pixel "
        "centreline [[u, v], ...] in the distorted image, ordered end to end), ends (in the "
        "same order: [{\"px\": [u, v], \"kind\": \"joint_end\" | \"image_border\"}, ...]), "
        "occluded_spans_px (arc-length ranges bridged through tack welds or spatter), "
        "confidence (0..1) and reasons. Exit code 9 when no seam is found, 10 when two "
        "candidates are too alike to choose, or when a dark band with a darker core on one "
        "side may be the gap beside a shadow or a gap with a cut face inside it (give --gap-mm, "
        "or locate from two views). Contract: docs/seam-detect.md.")
    p.add_argument("image", help="image file (PNG, JPEG, ...; 8-bit greyscale or colour)")
    p.add_argument("--calibration", help="calibration file: checks that the image size matches")
    p.add_argument("--output", help="write the JSON here instead of stdout")
    p.add_argument("--overlay", help="write a PNG showing the seam, its ends and the confidence")
    p.add_argument("--roi", help="search only in this pixel box: x0,y0,x1,y1")
    p.add_argument("--hint", nargs="+", metavar="U,V",
                   help="the nominal seam: two or more of its points in px of the image, in "
                   "order along it (from the job's drawing, or a previous part); a line "
                   "--hint-tolerance px or more from it (mean distance) is never returned (a "
                   "safety check: such a line still makes the choice ambiguous)")
    p.add_argument("--hint-tolerance", type=float, default=60.0, metavar="PX",
                   help="with --hint: how far (px) the seam may lie from it (default 60)")
    p.add_argument("--gamma", type=float, default=2.2,
                   help="camera response to linearise grey levels (1 for a linear camera; "
                   "default 2.2)")
    p.add_argument("--distance-mm", type=float, metavar="Z",
                   help="working distance (mm, camera to the seam along the optical axis; needs "
                   "--calibration): sets the detector's pixel scales from fx / Z px per mm "
                   "(without it: the defaults, tuned for about 6-8 px per mm)")
    p.add_argument("--gap-mm", type=float, nargs=2, metavar=("LO", "HI"),
                   help="with --distance-mm: the narrowest and widest expected gap, mm; a "
                   "dark band wider than such a gap can be (a shadow beside it) is then refused "
                   "(default: the scales of 0.1 1.2 and no limit on the band)")
    p.set_defaults(func=run)


def _parse_roi(text: str | None) -> tuple[int, int, int, int] | None:
    if text is None:
        return None
    parts = text.split(",")
    try:
        vals = [int(float(v)) for v in parts]
    except ValueError as err:
        raise InputError(f"--roi {text!r}: give four integers x0,y0,x1,y1") from err
    if len(vals) != 4 or vals[2] <= vals[0] or vals[3] <= vals[1]:
        raise InputError(f"--roi {text!r}: give x0,y0,x1,y1 with x1 > x0 and y1 > y0")
    return vals[0], vals[1], vals[2], vals[3]


def _parse_hint(texts: list[str] | None) -> list[tuple[float, float]] | None:
    if texts is None:
        return None
    pts = []
    for t in texts:
        try:
            u, v = (float(x) for x in t.split(","))
        except ValueError as err:
            raise InputError(f"--hint {t!r}: give each point as U,V (px), e.g. --hint 100,20 "
                             "140,900") from err
        pts.append((u, v))
    if len(pts) < 2:
        raise InputError("--hint: give two or more points U,V along the nominal seam, e.g. "
                         "--hint 100,20 140,900")
    return pts


def run(args: argparse.Namespace) -> int:
    """Run ``seamguide detect``; returns 0, or raises a SeamguideError (its exit code is used)."""
    from controller.vision.image_io import load_image
    from controller.vision.seam_detect import DetectParams, checked_roi, detect_seam
    from controller.vision.seam_edge_ends import one_image_answer
    from controller.vision.seam_overlay import draw_overlay, refused_lines

    camera = None
    if args.calibration:
        from calibration.calibration_file import load_calibration

        camera = load_calibration(args.calibration).camera
    roi = _parse_roi(args.roi)
    hint = _parse_hint(args.hint)
    if not args.hint_tolerance > 0 or args.hint_tolerance == float("inf"):
        raise InputError(f"--hint-tolerance {args.hint_tolerance}: give a positive number of px")
    image = load_image(args.image, camera=camera)
    if args.gamma <= 0:
        raise InputError(f"--gamma {args.gamma}: must be positive")
    params = _scaled(DetectParams(gamma=args.gamma, hint_tol_px=args.hint_tolerance), args,
                     camera)
    det = None
    try:
        det = detect_seam(image, camera=camera, roi=roi, hint=hint, params=params)
        # What one image cannot answer alone: a shadow split off without the job's gap (two
        # readings), an end called the image border left inside the image.
        one_image_answer(det, params, checked_roi(roi, image.shape[1], image.shape[0]))
    except (SeamNotFound, AmbiguousSeam) as err:
        if args.overlay:
            drawn, legend = refused_lines(err)
            _write_png(args.overlay, draw_overlay(image, det, f"NO SEAM: {err}",
                                                  rivals_px=drawn, legend=legend,
                                                  nominal_px=hint))
        raise
    if args.overlay:
        _write_png(args.overlay, draw_overlay(image, det, nominal_px=hint))
    doc = {"image": str(args.image), "image_size": [int(image.shape[1]), int(image.shape[0])],
           **det.to_dict()}
    emit_json(doc, args.output)
    log.info("seam: %d points, confidence %.2f", len(det.points_px), det.confidence)
    return 0


def _scaled(params: Any, args: argparse.Namespace, camera: Any) -> Any:
    """``params`` with the pixel scales of ``--distance-mm`` (and ``--gap-mm``), if given."""
    from controller.vision.seam_scale import DEFAULT_GAP_MM, check_gap_mm, params_for_scale

    if args.distance_mm is None:
        if args.gap_mm is not None:
            raise InputError("--gap-mm sets the scales with --distance-mm: give --distance-mm Z "
                             "(and --calibration) too, or leave --gap-mm out")
        return params
    if camera is None:
        raise InputError(f"--distance-mm {args.distance_mm:g}: give --calibration too (its fx "
                         "turns the distance into px per mm)")
    if not args.distance_mm > 0 or args.distance_mm == float("inf"):
        raise InputError(f"--distance-mm {args.distance_mm}: give the working distance in mm, a "
                         "positive number")
    gap = check_gap_mm(args.gap_mm if args.gap_mm is not None else DEFAULT_GAP_MM, "--gap-mm")
    px_per_mm = camera.fx / args.distance_mm
    log.info("scales for %.2f px/mm (fx %.1f px at %.1f mm), gap %g-%g mm", px_per_mm,
             camera.fx, args.distance_mm, *gap)
    return params_for_scale(px_per_mm, gap, base=params, limit_band=args.gap_mm is not None)


def _write_png(path: str, img: Any) -> None:
    import cv2

    ok = cv2.imwrite(path, img)
    if not ok:
        raise InputError(f"--overlay {path}: cannot write a PNG there; check the folder exists "
                         "and the name ends in .png")
