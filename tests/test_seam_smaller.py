"""The look at the image shrunk (controller.vision.seam_smaller): a close-up's wide, soft gap."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest
from drawn_plates import S, render
from rendered_cases import rendered_view

from bench.detect_score import score_view
from controller.cli import main
from controller.errors import AmbiguousSeam, SeamNotFound
from controller.vision import seam_detect, seam_smaller
from controller.vision.seam_detect import DetectParams, SeamDetection, detect_seam
from controller.vision.seam_smaller import moved, one_of, same_seam, smaller_look

GAP = (590.0, 610.0)  # rows of the gap's edges: 20 px wide, wider than the 16 px searched
ENDS = ((300.0, 600.0), (1300.0, 600.0))  # where the two plates stop facing each other


def _plates(blur_px: float, seed: int = 3) -> np.ndarray:
    """Two plates on a dark table meeting at a 20 px gap, both ending inside the image, the
    whole drawing blurred by ``blur_px`` (sigma, px) on top of the drawing's own 1 px."""

    def fill(m: np.ndarray) -> None:
        m[:] = 40.0  # the table
        x0, x1 = ENDS[0][0] * S, ENDS[1][0] * S
        m[int(250 * S):int(GAP[0] * S), int(x0):int(x1)] = 170.0
        m[int(GAP[1] * S):int(950 * S), int(x0):int(x1)] = 150.0
        m[int(GAP[0] * S):int(GAP[1] * S), int(x0):int(x1)] = 22.0  # the gap's floor
        if blur_px > 0:
            cv2.GaussianBlur(m, (0, 0), blur_px * S, dst=m)

    return render(fill, seed)


def _look_shrunk(img: np.ndarray) -> SeamDetection | None:
    p = DetectParams()
    return smaller_look(img, None, p, seam_detect.search, None)


def test_a_wide_defocused_gap_is_found_on_the_image_shrunk() -> None:
    det = _look_shrunk(_plates(blur_px=2.8))
    assert det is not None
    assert det.end_kinds == ("joint_end", "joint_end")
    assert np.max(np.abs(det.points_px[:, 1] - 600.0)) < 1.5  # measured again at full size
    for got, want in zip(det.endpoints_px, ENDS, strict=True):
        assert np.linalg.norm(got - want) < 6.0
    assert 16.0 < det.gap_width_px < 24.0
    assert det.stats["scale"] == 2.0 and det.stats["edge_blur_px"] >= seam_smaller.MIN_BLUR_PX
    assert any("shrunk by 2" in r for r in det.reasons)


def test_a_sharp_wide_band_is_not_looked_for_shrunk(monkeypatch: pytest.MonkeyPatch) -> None:
    # Sharp, the full-size image holds detail the shrunk one loses (a hairline gap beside a
    # shadow or a cut face reads, shrunk, as one wide band): the full-size verdict stands.
    img = _plates(blur_px=0.0)
    assert _look_shrunk(img) is None
    # The blur is what refuses it: without that condition the shrunk look returns it.
    monkeypatch.setattr(seam_smaller, "MIN_BLUR_PX", 0.0)
    assert _look_shrunk(img) is not None


def test_detect_seam_looks_shrunk_only_where_the_full_size_search_refuses(
        monkeypatch: pytest.MonkeyPatch) -> None:
    img = _plates(blur_px=2.8)
    assert "scale" not in detect_seam(img).stats  # found at full size: no second look
    full_size = seam_detect._detect_in

    def refusing(sub, hint, p, straighten, trace, box):  # type: ignore[no-untyped-def]
        if box is not None:  # the full-size search (the shrunk ones pass no box)
            raise SeamNotFound("no weld seam found in the image (test)")
        return full_size(sub, hint, p, straighten, trace, box)

    monkeypatch.setattr(seam_detect, "_detect_in", refusing)
    with pytest.raises(SeamNotFound, match="test"):
        detect_seam(img, params=DetectParams(smaller=False))
    # Searched in a region of interest, the shrunk look's seam comes back in image px.
    det = detect_seam(img, roi=(200, 150, 1450, 1050))
    assert det.stats["scale"] == 2.0
    for got, want in zip(det.endpoints_px, ENDS, strict=True):
        assert np.linalg.norm(got - want) < 6.0


@pytest.fixture(scope="module")
def close_up(tmp_path_factory: pytest.TempPathFactory) -> tuple[np.ndarray, dict]:
    """A close-up of the simulator (dark, noisy, defocused, a 21 px gap band between two rounded
    plate corners), rendered here: (image, truth)."""
    case = ("wide", "medium", "tuning", 10073)
    return rendered_view(tmp_path_factory.mktemp("cache"), case, 1)


def test_a_simulated_close_up_is_found_on_the_image_shrunk(close_up: tuple[np.ndarray, dict]
                                                           ) -> None:
    img, truth = close_up
    assert truth["family"] == "closeup" and truth["gap_px"] > 20.0
    # The full-size search refuses it; the shrunk look finds it.
    with pytest.raises(SeamNotFound):
        detect_seam(img, params=DetectParams(smaller=False))
    det = detect_seam(img)
    assert det.stats["scale"] == 2.0
    assert score_view(det.points_px, truth, list(det.end_kinds))["result"] == "found"


def test_seamguide_detect_says_the_seam_was_found_shrunk(
        close_up: tuple[np.ndarray, dict], tmp_path: Path) -> None:
    img, truth = close_up
    png, out = tmp_path / "close_up.png", tmp_path / "seam.json"
    cv2.imwrite(str(png), img)
    assert main(["detect", str(png), "--output", str(out)]) == 0
    doc = json.loads(out.read_text())
    assert doc["stats"]["scale"] == 2.0 and doc["stats"]["edge_blur_px"] >= 2.0
    assert doc["stats"]["way"] == "profiles, image shrunk by 2"
    # Said first: the search's own reasons that follow count px of the image shrunk by 2.
    assert "shrunk by 2 and again by 3" in doc["reasons"][0]
    assert "px of the image shrunk by 2" in doc["reasons"][0]
    assert sorted(e["kind"] for e in doc["ends"]) == sorted(truth["end_kinds"])


def _ambiguous_at_full_size(monkeypatch: pytest.MonkeyPatch, rows: tuple[float, float]) -> None:
    """The full-size search refuses as ambiguous between two lines along ``rows`` (y, px)."""
    full_size = seam_detect._detect_in

    def ambiguous(sub, hint, p, straighten, trace, box):  # type: ignore[no-untyped-def]
        if box is not None:  # the full-size search (the shrunk ones pass no box)
            lines = [[[x, y] for x in (300.0, 800.0, 1300.0)] for y in rows]
            raise AmbiguousSeam("two seam candidates of similar strength (test)",
                                best_px=lines[0], second_px=lines[1])
        return full_size(sub, hint, p, straighten, trace, box)

    monkeypatch.setattr(seam_detect, "_detect_in", ambiguous)


def test_the_shrunk_look_chooses_only_between_the_two_lines_full_size_could_not(
        monkeypatch: pytest.MonkeyPatch) -> None:
    img = _plates(blur_px=2.8)
    # The shrunk look finds the gap (row 600); it is one of the two lines: returned, and why.
    _ambiguous_at_full_size(monkeypatch, (450.0, 601.0))
    det = detect_seam(img)
    assert det.stats["scale"] == 2.0
    assert det.reasons[0].startswith("at full size: two seam candidates of similar strength "
                                     "(test); the search on the image shrunk took this one")
    assert np.max(np.abs(det.points_px[:, 1] - 600.0)) < 1.5
    # Neither line is the one it finds: the full-size refusal stands.
    _ambiguous_at_full_size(monkeypatch, (450.0, 750.0))
    with pytest.raises(AmbiguousSeam, match="test"):
        detect_seam(img)
    # Nor is it looked for shrunk when the detector is told not to.
    _ambiguous_at_full_size(monkeypatch, (450.0, 601.0))
    with pytest.raises(AmbiguousSeam, match="test"):
        detect_seam(img, params=DetectParams(smaller=False))


def test_one_of_wants_most_of_the_seam_along_a_line() -> None:
    det = _det([(x, 500.0) for x in np.arange(100.0, 901.0, 4.0)], width=4.0)
    along = np.array([[100.0, 504.0], [900.0, 504.0]])  # 4 px off: within 6 px
    beside = np.array([[100.0, 510.0], [900.0, 510.0]])  # 10 px off
    half = np.array([[100.0, 500.0], [450.0, 500.0]])  # a piece of it: under 80 % of the seam
    assert one_of(det, [beside, along])
    assert not one_of(det, [beside])
    assert not one_of(det, [half])
    assert not one_of(det, [])
    # A gap 24 px wide: within half its width (12 px) is along.
    assert one_of(replace(det, width_px=np.full(len(det.points_px), 24.0)), [beside])


@pytest.fixture(scope="module")
def tee_close_up(tmp_path_factory: pytest.TempPathFactory) -> tuple[np.ndarray, dict]:
    """A dark close-up of the simulator's T-corner set (tuning part, a 24 px gap band leaving
    the image at one end and ending at a T-corner at the other), rendered here."""
    return rendered_view(tmp_path_factory.mktemp("cache"), ("tee", "medium", "tuning", 60041), 1)


def test_a_close_up_ambiguous_at_full_size_is_found_on_the_image_shrunk(
        tee_close_up: tuple[np.ndarray, dict]) -> None:
    img, truth = tee_close_up
    assert truth["gap_px"] > 20.0
    # At full size the wide gap is measured in pieces: a valley path joining the seam to the
    # crossbar is as strong as the seam's own, and the view was refused as ambiguous.
    with pytest.raises(AmbiguousSeam):
        detect_seam(img, params=DetectParams(smaller=False))
    det = detect_seam(img)
    assert det.stats["scale"] == 2.0 and det.reasons[0].startswith("at full size: ")
    assert score_view(det.points_px, truth, list(det.end_kinds))["result"] == "found"


def test_an_image_too_small_to_shrink_keeps_the_full_size_refusal() -> None:
    # 40x50 px shrunk by 2 is under the 32 px the search needs: its InputError is not the answer.
    with pytest.raises(SeamNotFound, match="no weld seam found"):
        detect_seam(np.full((40, 50), 128, np.uint8))


def _det(points: list[tuple[float, float]], kinds: tuple[str, str] = ("joint_end", "joint_end"),
         width: float = 20.0) -> SeamDetection:
    P = np.asarray(points, dtype=np.float64)
    return SeamDetection(points_px=P, confidence=0.9, reasons=[], endpoints_px=P[[0, -1]],
                         width_px=np.full(len(P), width), end_kinds=kinds,
                         stats={"length_px": 10.0})


def test_moved_maps_pixel_centres_and_scales_widths() -> None:
    d = _det([(0.0, 0.0), (10.0, 0.0)])
    m = moved(d, 2.0, (100.0, 50.0))
    # The shrunk pixel 0 covers pixels 0 and 1: its centre is 0.5.
    assert m.points_px.tolist() == [[100.5, 50.5], [120.5, 50.5]]
    assert m.endpoints_px.tolist() == m.points_px.tolist()
    assert m.gap_width_px == 40.0 and m.stats["length_px"] == 20.0
    assert moved(d, 1.0, (5.0, 0.0)).points_px.tolist() == [[5.0, 0.0], [15.0, 0.0]]


def test_two_readings_are_the_same_seam_only_with_the_same_ends() -> None:
    line = [(float(x), 600.0) for x in range(300, 1301, 50)]
    a = _det(line)
    assert same_seam(a, _det(line[::-1]))  # the other order is the same seam
    assert same_seam(a, _det([(x + 3.0, y + 2.0) for x, y in line]))
    assert not same_seam(a, _det(line, kinds=("joint_end", "image_border")))
    assert not same_seam(a, _det(line[:-1]))  # an end 50 px short
    assert not same_seam(a, _det([(x, y + 6.0) for x, y in line]))  # beside it: 6 > 20 / 4


def test_the_ends_of_a_wide_gap_agree_within_half_its_width() -> None:
    # A 24 px gap leaving the image at the top at 45 deg, read at two scales 2 px apart, the
    # readings parting near the border: they cross it 10 px apart, more than the 8 px asked of
    # a narrow gap's ends (wide hard tuning 10112 view 1: 11.8 px, a 27 px gap).
    line = [(300.0 + t, t) for t in range(0, 801, 50)]
    beside = [(x + 2.0 * np.sqrt(2.0), y) for x, y in line]
    beside[0] = (line[0][0] + 10.0, 0.0)
    kinds = ("image_border", "joint_end")
    assert same_seam(_det(line, kinds, width=24.0), _det(beside, kinds, width=24.0))
    # The same two readings of a 10 px gap: the ends 8 px apart at most.
    assert not same_seam(_det(line, kinds, width=10.0), _det(beside, kinds, width=10.0))
    # Nor half a wide gap's width more than that: an end read elsewhere.
    beside[0] = (line[0][0] + 13.0, 0.0)
    assert not same_seam(_det(line, kinds, width=24.0), _det(beside, kinds, width=24.0))


def test_where_nothing_is_found_shrunk_by_3_two_other_scales_must_agree() -> None:
    # Wide medium tuning 10093 v0, 10219 v0, 10257 v1, hard 10051 v0 (close-ups): found shrunk
    # by 2, nothing found shrunk by 3 (the faint gap under the search's thresholds there), the
    # same seam shrunk by 1.5, 2.5 or 4: refused until 2026-12-06.
    from controller.vision.seam_smaller import _confirmed

    line = [(float(x), 600.0) for x in range(300, 1301, 50)]
    full, same, other = _det(line), _det([(x + 2.0, y) for x, y in line]), _det(line[:-1])

    def at(found: dict[float, SeamDetection | None]):  # type: ignore[no-untyped-def]
        asked: list[float] = []

        def found_at(f: float) -> SeamDetection | None:
            asked.append(f)
            return found.get(f)

        return found_at, asked

    found_at, asked = at({3: same})
    assert _confirmed(full, found_at) == [3.0] and asked == [3]  # found at 3: nothing else asked
    assert _confirmed(full, at({3: other, 1.5: same, 2.5: same})[0]) == []  # 3 differs: refused
    assert _confirmed(full, at({1.5: same, 2.5: same})[0]) == [1.5, 2.5]
    assert _confirmed(full, at({2.5: same, 4.0: same})[0]) == [2.5, 4.0]
    assert _confirmed(full, at({2.5: same})[0]) == []  # one scale is not enough
    assert _confirmed(full, at({1.5: same, 2.5: same, 4.0: other})[0]) == []  # one differs
    assert _confirmed(full, at({})[0]) == []


def test_a_faint_close_up_found_at_two_other_scales_is_returned(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    img, truth = rendered_view(tmp_path, ("wide", "medium", "tuning", 10219), 0)
    assert truth["family"] == "closeup"
    det = detect_seam(img)
    assert det.stats["scale"] == 2.0
    assert score_view(det.points_px, truth, list(det.end_kinds))["result"] == "found"
    assert "shrunk by 2 and again by 1.5 and 2.5" in det.reasons[0]
    # Shrunk by 3 nothing is found: without the other scales it is refused.
    monkeypatch.setattr(seam_smaller, "ALT_CONFIRM", ())
    with pytest.raises(SeamNotFound):
        detect_seam(img)
