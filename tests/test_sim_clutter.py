"""Marks of the wide look (drivers/sim/sim_clutter.py): pens, tacks, spatter, dots, tables, pits."""

import numpy as np
from sim_looks import NEUTRAL

from drivers.sim.sim_clutter import PEN_KINDS
from drivers.sim.sim_scene import make_scene


def _scene(seed=4, **look):
    return make_scene("arc", seed, "medium", variety="wide", look={**NEUTRAL, **look})


def test_parallel_pen_lines_stay_on_one_sheet_and_end_inside_it():
    for seed in range(6):
        sc = _scene(seed, pens=3)
        pens = [d for d in sc.decals if d.kind == "pen_parallel"]
        assert len(pens) == 3
        half = sc.chord_mm / 2
        for d in pens:
            P = np.asarray(d.points)
            off = P[:, 1] - sc.seam_b(P[:, 0])
            assert np.all(np.sign(off) == np.sign(off[0]))  # one sheet
            assert np.all(np.abs(off) >= sc.gap_mm / 2 + 3.0 - 0.31)  # 3-20 mm beside the gap
            assert np.all(np.abs(off) <= sc.gap_mm / 2 + 20.0 + 0.31)  # (0.3 mm hand wobble)
            assert P[0, 0] > -half + 5 and P[-1, 0] < half - 5  # ends inside the sheet
            assert 0.3 <= d.width_mm <= 2.5
        assert len(sc.pen_lines_mm()) == 3


def test_a_crossing_pen_line_crosses_the_joint():
    sc = _scene(pens=1, pen_cross=True)
    cross = [d for d in sc.decals if d.kind == "pen_cross"]
    assert len(cross) == 1 and "pen_cross" in PEN_KINDS
    P = np.asarray(cross[0].points)
    off = P[:, 1] - sc.seam_b(P[:, 0])
    assert off.min() < -sc.gap_mm and off.max() > sc.gap_mm
    assert len(sc.pen_lines_mm()) == 2


def test_a_crossing_pen_line_on_a_short_joint_stays_on_it():
    # Wide medium tuning 10255: a joint shorter than the crossing line drawn for it made the
    # scene generator fail (an empty range for the line's middle).
    from bench.detect_cases import make_case_scene

    sc = make_case_scene(("wide", "medium", "tuning", 10255))
    cross = [d for d in sc.decals if d.kind == "pen_cross"]
    assert len(cross) == 1
    P = np.asarray(cross[0].points)
    assert -sc.chord_mm / 2 < P[:, 0].min() and P[:, 0].max() < sc.chord_mm / 2


def test_tacks_and_spatter_on_the_joint_give_the_occluded_spans():
    sc = _scene(tacks=3, spatter=6)
    over = [d for d in sc.decals if d.layer == "over"]
    assert {d.kind for d in over} == {"tack", "spatter"}
    spans = sc.occluded_spans_mm
    assert len(spans) >= 3
    assert all(0 <= s0 < s1 <= sc.length_mm + 1e-6 for s0, s1 in spans)
    assert all(a[1] < b[0] for a, b in zip(spans, spans[1:], strict=False))  # merged, ordered
    a, s = sc.arc_table()
    for d in over:
        if d.kind == "tack" and d.shape == "ellipse" and d.value > 0.5:  # a bead, not a crater
            sc_ = float(np.interp(d.p0[0], a, s))
            assert any(s0 <= sc_ <= s1 for s0, s1 in spans)


def test_scanner_dots_and_pits():
    sc = _scene(scanner_dots=20, pits=2.0)
    scan = [d for d in sc.decals if d.kind == "scanner"]
    assert len(scan) == 40  # a black ring and its white centre each
    pits = [d for d in sc.decals if d.kind == "pit"]
    assert len(pits) > 200 and all(d.radius_mm < 0.4 for d in pits)
    for d in scan:
        off = d.p0[1] - float(sc.seam_b(np.array([d.p0[0]]))[0])
        assert abs(off) > d.radius_mm  # not on the joint


def test_tables():
    perforated = [d for d in _scene(table="perforated").decals if d.kind == "hole"]
    classic = [d for d in _scene(table="holes").decals if d.kind == "hole"]
    assert len(perforated) > 300 and len(perforated) > 3 * len(classic)
    assert [d for d in _scene(table="slotted").decals if d.kind == "slot"]
    assert [d for d in _scene(table="grid_lines").decals if d.kind == "grid"]
    dark = make_scene("arc", 4, "medium", variety="wide", look={**NEUTRAL, "table": "dark"})
    assert not [d for d in dark.decals if d.layer == "table" and d.kind != "plate"]


def test_slots_range_from_thin_lines_to_wide_slots():
    # 0.6-12 mm, log-uniform: some as thin as a gap (the tuning part's engraved-line analogue).
    widths = []
    for seed in range(30):
        slots = [d for d in _scene(seed=seed, table="slotted").decals if d.kind == "slot"]
        widths.append(slots[0].p1[0] - slots[0].p0[0])
    assert 0.6 <= min(widths) < 2.0 and 6.0 < max(widths) <= 12.0
