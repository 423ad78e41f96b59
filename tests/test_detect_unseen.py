"""bench.detect_unseen tells why no candidate lay on the joint, along the true line itself."""

from __future__ import annotations

import numpy as np

from bench.detect_unseen import unseen_class, unseen_readings, unseen_table

H, W = 800, 1200
TRUTH = np.column_stack([np.linspace(0, W - 1, 300), np.full(300, 400.0)])


def _image(profile: np.ndarray, holes: tuple[tuple[int, int], ...] = (), seed: int = 0
           ) -> np.ndarray:
    """A sheet (linear radiance 0.5) with ``profile`` (added, linear, per row offset from the
    line at y = 400) across it, interrupted over ``holes`` (x ranges), gamma 2.2 and noise."""
    rng = np.random.default_rng(seed)
    lin = np.full((H, W), 0.5)
    rows = np.arange(H)[:, None] - 400.0
    add = np.interp(rows, np.arange(-len(profile) // 2, len(profile) // 2 + 1)[:len(profile)],
                    profile, left=0.0, right=0.0) * np.ones((1, W))
    for a, b in holes:
        add[:, a:b] = 0.0
    grey = 255.0 * np.clip(lin + add, 0.0, 1.0) ** (1 / 2.2) + rng.normal(0.0, 1.5, (H, W))
    return np.clip(np.round(grey), 0, 255).astype(np.uint8)


GAP = np.array([0, 0, -0.1, -0.4, -0.4, -0.4, -0.1, 0, 0], dtype=np.float64)  # 4 px, dark
# The same gap between two bright ridges (a ground strip's edges): sheet, ridge, floor, ridge.
RIDGED = np.array([0, 0, 0.3, 0.5, 0.5, 0.3, -0.1, -0.4, -0.4, -0.1, 0.3, 0.5, 0.5, 0.3, 0, 0],
                  dtype=np.float64)


def test_a_plain_gap_is_seen_whole_and_its_profiles_fit() -> None:
    r = unseen_readings(_image(GAP), TRUTH)
    assert r["mask_cover"] > 0.9 and r["piece_px"] >= 1000 and r["profile_share"] > 0.9
    assert unseen_class(r) == ("seen whole", "profiles fit")


def test_a_plain_sheet_is_not_seen_and_fits_no_profile() -> None:
    r = unseen_readings(_image(np.zeros(9)), TRUTH)
    assert r["mask_cover"] < 0.1 and r["profile_share"] < 0.1
    assert unseen_class(r) == ("coarse search does not see it", "profiles fail")


def test_a_gap_broken_every_200_px_is_seen_in_pieces() -> None:
    holes = tuple((x, x + 60) for x in range(200, W, 260))
    r = unseen_readings(_image(GAP, holes), TRUTH)
    assert r["mask_cover"] >= 0.5 and r["piece_px"] < 300
    assert unseen_class(r)[0] == "seen in pieces"


def test_a_gap_between_bright_ridges_fails_the_two_edge_profiles() -> None:
    # The shop look's hairline between two ground strips: the two-step model (sheet, floor,
    # sheet) does not fit a profile whose brightest points are beside the gap.
    r = unseen_readings(_image(RIDGED), TRUTH)
    assert r["profile_share"] < 0.3  # 0.18: most profiles fail
    assert unseen_readings(_image(GAP), TRUTH)["profile_share"] > 0.9  # the same gap, no ridges
    assert unseen_class(r)[1] == "profiles fail"


def test_the_table_counts_views_by_what_was_seen_per_look() -> None:
    rows = [{"family": "shop", "gap_px": 2.0, "unseen": {"mask_cover": 0.3, "piece_px": 40.0,
                                                          "profile_share": 0.1}},
            {"family": "shop", "gap_px": 4.0, "unseen": {"mask_cover": 0.9, "piece_px": 900.0,
                                                          "profile_share": 0.2}},
            {"family": "plain", "gap_px": 3.0, "unseen": {"mask_cover": 0.3, "piece_px": 40.0,
                                                           "profile_share": 0.1}},
            {"family": "plain", "gap_px": 3.0, "unseen": None}]
    md = unseen_table(rows)
    assert md.startswith("3 views with no candidate on the joint")
    assert "| coarse search does not see it | profiles fail | 1 | 1 | 2.5 |" in md
    assert "| seen whole | profiles fail | 0 | 1 | 4.0 |" in md
    assert unseen_table([{"family": "plain", "unseen": None}]) == ""


def test_the_photographs_readings_are_printed_per_label(tmp_path, capsys) -> None:
    import json

    import cv2

    from bench.detect_unseen import main

    (tmp_path / "images").mkdir()
    (tmp_path / "labels").mkdir()
    cv2.imwrite(str(tmp_path / "images" / "a.png"), _image(GAP))
    (tmp_path / "labels" / "a.json").write_text(json.dumps(
        {"image": "images/a.png", "polyline_px": TRUTH.tolist(), "seam_present": True}))
    assert main(["--photos", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "| a | 1.00 |" in out and "seen whole / profiles fit |" in out
    assert main(["--photos", str(tmp_path / "none")]) == 1
    assert "no labelled photographs in" in capsys.readouterr().err
