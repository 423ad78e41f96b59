"""The simulator's T-corner close-ups (variety ``tee``): a third plate across one end of the joint
beyond a crossbar gap, and the scenes drawn before it unchanged."""

import numpy as np
import pytest
from rendered_cases import rendered_view

from drivers.sim.sim_look import FX_NOMINAL
from drivers.sim.sim_scene import make_scene


def test_tee_scenes_are_close_ups_with_a_crossbar_as_wide_as_the_gap() -> None:
    for seed in range(60000, 60012):
        sc = make_scene("arc", seed, ("medium", "hard", "easy")[seed % 3], variety="tee")
        look = sc.look
        assert look.family == "closeup" and 150.0 <= look.standoff_mm <= 220.0
        assert 14.0 <= sc.gap_mm * FX_NOMINAL / look.standoff_mm <= 28.0
        assert 0.7 * sc.gap_mm <= look.tee_mm <= 1.5 * sc.gap_mm
        assert look.tee_end in (-1, 1) and 40.0 <= look.tee_plate_mm <= 120.0
        assert look.corner_mm == 0.0 and look.tilt_a_rad == 0.0 == look.tilt_b_rad


def test_the_other_varieties_draw_what_they_drew_before() -> None:
    # The wide clutter's stream was keyed by the number of varieties (4): a fifth one must not
    # change a scene already rendered (the benchmark's cache, cache tag v4).
    sc = make_scene("straight", 10002, "easy", variety="wide")
    assert sc.look.tee_mm == 0.0 and sc.look.table == "perforated"
    assert len(sc.decals) == 857
    assert sc.decals[0].p0 == pytest.approx((-30.102680286843395, 14.36974949712355))


@pytest.fixture(scope="module")
def tee_view(tmp_path_factory: pytest.TempPathFactory) -> tuple[np.ndarray, dict]:
    """Tuning tee seed 60000, view 0 (both joint ends in view, the T-corner at one), rendered
    here: (grey image, truth)."""
    case = ("tee", "medium", "tuning", 60000)
    img, truth = rendered_view(tmp_path_factory.mktemp("cache"), case, 0)
    img = img if img.ndim == 2 else img.mean(axis=2)
    return np.asarray(img, np.float64), truth


def test_the_joint_ends_at_a_crossbar_with_the_third_plate_beyond(
        tee_view: tuple[np.ndarray, dict]) -> None:
    img, truth = tee_view
    assert list(truth["end_kinds"]) == ["joint_end", "joint_end"]
    T = np.asarray(truth["seam_px"], np.float64)
    w = truth["gap_px"]

    def beyond(end: np.ndarray, before: np.ndarray) -> np.ndarray:
        """Grey levels along the seam's direction from 2 px to 6 gap widths past ``end``."""
        u = (end - before) / np.linalg.norm(end - before)
        ks = np.arange(2.0, 6.0 * w)
        q = np.round(end + np.outer(ks, u)).astype(int)
        return img[q[:, 1], q[:, 0]]

    mid, tang = T[len(T) // 2], T[len(T) // 2 + 4] - T[len(T) // 2 - 4]
    nrm = np.array([-tang[1], tang[0]]) / np.linalg.norm(tang)
    q = np.round(mid + np.outer(np.arange(40.0, 60.0), nrm)).astype(int)
    sheets = np.median(img[q[:, 1], q[:, 0]])  # one sheet, 40-60 px beside the seam's middle
    runs = [beyond(T[0], T[8]), beyond(T[-1], T[-9])]
    # At the T-corner: the crossbar (dark), then the third plate (as bright as the sheets); at
    # the other end the dark table goes on.
    tee = [r for r in runs if np.median(r[-int(2 * w):]) > 0.6 * sheets]
    plain = [r for r in runs if np.median(r[-int(2 * w):]) < 0.4 * sheets]
    assert len(tee) == 1 and len(plain) == 1
    assert tee[0][: int(w)].min() < 0.4 * sheets
