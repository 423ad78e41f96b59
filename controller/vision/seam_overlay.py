"""A picture of a seam detection for a person: the seam, its end points and the confidence."""

from __future__ import annotations

import textwrap
from collections.abc import Sequence
from typing import Any

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from controller.vision.seam_detect import SeamDetection
from controller.vision.seam_profiles import resample

_SHIFT = 4  # cv2 drawing with sub-pixel coordinates: 4 fractional bits


def _fixed(pts: NDArray[Any]) -> NDArray[np.int32]:
    # Pixel centres at integer coordinates, as cv2 drawing expects.
    return np.round(np.asarray(pts, dtype=np.float64) * (1 << _SHIFT)).astype(np.int32)


MAX_TEXT_LINES = 14


def text_lines(texts: list[str], width: int, max_lines: int = MAX_TEXT_LINES) -> list[str]:
    """``texts`` wrapped to ``width`` characters a line, at most ``max_lines`` lines.

    A refusal's reasons run to several hundred characters; cut at one line, the picture would
    lose the reason a person opened it for. Past the last line, "..." says there is more.
    """
    out = [w for t in texts for w in (textwrap.wrap(t, max(width, 20)) or [""])]
    if len(out) > max_lines:
        out = out[:max_lines - 1] + [out[max_lines - 1][: max(width, 20) - 4] + " ..."]
    return out


def overlay_text(texts: list[str], legend: Sequence[str], width: int) -> list[str]:
    """The picture's text: ``texts`` then ``legend``, wrapped (:func:`text_lines`).

    At most :data:`MAX_TEXT_LINES` lines; the legend names the lines drawn, so ``texts`` are
    cut short before it is (it keeps up to half the lines).
    """
    told = text_lines(list(legend), width, MAX_TEXT_LINES // 2) if legend else []
    return text_lines(texts, width, MAX_TEXT_LINES - len(told)) + told


#: BGR colours of the lines a refusal drew attention to, in order: cyan, magenta, light
#: orange; none is the seam's green.
RIVAL_COLOURS = ((255, 200, 0), (255, 0, 255), (80, 180, 255))
_NAMES = ("cyan", "magenta", "orange")


def refused_lines(err: Exception) -> tuple[list[ArrayLike], list[str]]:
    """The lines (image px, each (N, 2)) a refusal drew attention to, and what to write of them.

    A view refused alone whose line the cycle took by the other view's seam
    (:mod:`controller.cell.other_view`): that line (``taken_px``, ``taken_along``). An ambiguous
    refusal: the strongest line and the one it could not be told from (its details' ``best_px``,
    ``second_px``). A refused best candidate (too weak, fading out): that
    one (``best_px``). No candidate passing: the strongest lines looked at, each with why it was
    refused (``looked_at_px``, ``looked_at_why``). Other errors: none.
    """
    d = getattr(err, "details", {})
    if "taken_px" in d:  # the cycle took one of its lines by the other view's seam
        return [d["taken_px"]], [f"1 (cyan): the line taken, its ends meeting the seam found in "
                                 f"{d.get('taken_along', 'the other view')} (the record's "
                                 "other_view)"]
    roi = "Give a --roi around the joint, and check the seam found there"
    if "second_px" in d:
        return [d["best_px"], d["second_px"]], [
            f"1 (cyan): the strongest candidate; 2 (magenta): the line it could not be told "
            f"from. {roi}"]
    if "best_px" in d:
        return [d["best_px"]], [f"1 (cyan): the refused candidate. {roi}"]
    shown = list(zip(d.get("looked_at_px", []), d.get("looked_at_why", []), strict=False))
    if not shown:
        return [], []
    legend = [", ".join(f"{k + 1} ({_NAMES[k]})" for k in range(len(shown)))
              + ": the strongest lines looked at, each refused:"]
    legend += [f"{k + 1}: {why.split(' (')[0]}" for k, (_, why) in enumerate(shown)]
    return [px for px, _ in shown], legend


def draw_overlay(image: NDArray[np.uint8], detection: SeamDetection | None = None,
                 message: str | None = None, max_width: int = 1600,
                 rivals_px: Sequence[ArrayLike] = (), legend: Sequence[str] = (),
                 nominal_px: ArrayLike | None = None) -> NDArray[np.uint8]:
    """BGR uint8 picture: ``image`` dimmed, the seam in green, ends in orange, text on top.

    ``detection`` may be None (a failed detection), then ``message`` says why; with both, the
    detection was refused for a single-image answer (two readings, drawn). ``rivals_px``: the
    centrelines (each (N, 2) image px) a refusal drew attention to (:func:`refused_lines`),
    drawn in :data:`RIVAL_COLOURS` and numbered, so that a person sees which line to give a
    ``--roi`` around; ``legend``: what to write of them, after ``message``; ``nominal_px``:
    the nominal seam ((N, 2) image px: ``--hint``, the job's nominal line),
    drawn dashed in white. The picture is shrunk to at most ``max_width`` px wide (drawing is
    done at full resolution first).
    """
    img = image if image.ndim == 3 else cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    out = (img.astype(np.float32) * 0.75).astype(np.uint8)
    H, W = out.shape[:2]
    scale_line = max(1, int(round(W / 800)))
    lines: list[str] = []
    if detection is not None:
        if message:  # returned by the detector, refused for a single-image answer
            lines.append("green: the darker core's middle, the seam if the lighter part is a "
                         "shadow beside the gap")
        else:
            lines.append(f"seam found, confidence {detection.confidence:.2f}")
            lines += detection.reasons
        if detection.band_px is not None:
            lines.append("yellow: the whole dark band's middle, the seam if its lighter part is "
                         "a cut face inside the gap rather than a shadow beside it")
    if message:
        lines.append(message)
    if nominal_px is not None:
        lines.append("white dashes: the nominal seam (no line beyond its tolerance is returned)")
    y = 40 * scale_line
    colour = (40, 230, 40) if detection is not None and not message else (60, 60, 255)
    # Hershey simplex at 0.7 x scale_line: about 12 x scale_line px a character. The text goes
    # first and the lines over it: a long text covers a third of the picture, the seam with it.
    for text in overlay_text(lines, legend, (W - 40 * scale_line) // (12 * scale_line)):
        cv2.putText(out, text, (20 * scale_line, y), cv2.FONT_HERSHEY_SIMPLEX,
                    0.7 * scale_line, (0, 0, 0), 4 * scale_line, cv2.LINE_AA)
        cv2.putText(out, text, (20 * scale_line, y), cv2.FONT_HERSHEY_SIMPLEX,
                    0.7 * scale_line, colour, scale_line, cv2.LINE_AA)
        y += 32 * scale_line
    if nominal_px is not None:
        # Dashes of 16 px, 16 px apart (px of the image, before any shrinking).
        nom = _fixed(resample(np.asarray(nominal_px, dtype=np.float64).reshape(-1, 2), 2.0,
                              extend=0.0)[0]).reshape(-1, 1, 2)
        for i in range(0, len(nom) - 1, 16 * scale_line):
            cv2.polylines(out, [nom[i:i + 8 * scale_line + 1]], False, (255, 255, 255),
                          scale_line, cv2.LINE_AA, _SHIFT)
    for k, (line, rival_colour) in enumerate(zip(rivals_px, RIVAL_COLOURS, strict=False)):
        rival = np.asarray(line, dtype=np.float64).reshape(-1, 2)
        cv2.polylines(out, [_fixed(rival).reshape(-1, 1, 2)], False, rival_colour,
                      2 * scale_line, cv2.LINE_AA, _SHIFT)
        mid = rival[len(rival) // 2]
        cv2.putText(out, str(k + 1), (int(mid[0]) + 12 * scale_line, int(mid[1])),
                    cv2.FONT_HERSHEY_SIMPLEX, 1.2 * scale_line, rival_colour, 2 * scale_line,
                    cv2.LINE_AA)
    if detection is not None:
        pts = _fixed(detection.points_px)
        cv2.polylines(out, [pts.reshape(-1, 1, 2)], False, (40, 230, 40), scale_line,
                      cv2.LINE_AA, _SHIFT)
        for i, e in enumerate(detection.endpoints_px):
            c = tuple(int(v) for v in _fixed(e))
            cv2.circle(out, c, 12 * scale_line << _SHIFT, (0, 140, 255), scale_line,
                       cv2.LINE_AA, _SHIFT)
            cv2.putText(out, "start" if i == 0 else "end",
                        (int(e[0]) + 14 * scale_line, int(e[1]) - 14 * scale_line),
                        cv2.FONT_HERSHEY_SIMPLEX, 0.6 * scale_line, (0, 140, 255), scale_line,
                        cv2.LINE_AA)
        if detection.band_px is not None:
            cv2.polylines(out, [_fixed(detection.band_px).reshape(-1, 1, 2)], False,
                          (0, 220, 255), scale_line, cv2.LINE_AA, _SHIFT)
    if max_width < W:
        f = max_width / W
        out = np.asarray(cv2.resize(out, (max_width, int(round(H * f))),
                                    interpolation=cv2.INTER_AREA), np.uint8)
    return np.asarray(out, dtype=np.uint8)


def outcome_overlay(image: NDArray[np.uint8], outcome: SeamDetection | Exception,
                    nominal_px: ArrayLike | None = None) -> NDArray[np.uint8]:
    """The picture of one view's outcome in a cycle (BGR uint8, as :func:`draw_overlay`).

    ``outcome``: its detection, or the error it was refused with, written on the picture (an
    ambiguous refusal's lines drawn); ``nominal_px``: the job's nominal line in the view.
    """
    if isinstance(outcome, Exception):
        drawn, legend = refused_lines(outcome)
        return draw_overlay(image, None, f"NO SEAM: {outcome}", rivals_px=drawn, legend=legend,
                            nominal_px=nominal_px)
    return draw_overlay(image, outcome, nominal_px=nominal_px)
