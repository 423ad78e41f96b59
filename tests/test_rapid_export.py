"""The planned weld path as a RAPID module: the fitted MoveL / MoveC segments the cycle sends,
targets that round-trip, the arc switched around the weld only, and a module the independent
RAPID parser (``../shared/tools/rapid-parser``) accepts."""

import re
import subprocess
from pathlib import Path

import numpy as np
import pytest
from shared_data import shared_data_dir
from stereo_scenes import seam_curve

from controller.errors import ConfigError
from controller.geometry.kinematics import irb2400
from controller.geometry.poses import pose_error, pose_from_pos_quat
from controller.path.path_fit import PathTolerance, deviation, fit_segments
from controller.path.rapid_export import rapid_module
from controller.path.weld_path import WeldPath, plan_weld
from controller.stereo.seam_curve import resample_curve

PARSER = shared_data_dir().parent / "tools" / "rapid-parser" / "rapidparse"
TARGET = re.compile(r"CONST robtarget (sg_\w+) := \[\[([^\]]+)\],\[([^\]]+)\]")


@pytest.fixture(scope="module")
def dense():
    """The S-curve planned point by point (no segments): every target a MoveL."""
    pts = resample_curve(seam_curve("s_curve"), count=60)
    return plan_weld(irb2400(), pts, np.array([0, 0, 1.0]))


@pytest.fixture(scope="module")
def fitted(dense) -> WeldPath:
    """The same path with its weld fitted as MoveL / MoveC segments, as the cycle sends it."""
    segs = fit_segments([t.T_base_tcp for t in dense.weld_targets])
    assert len(segs) < len(dense.weld_targets) - 1 and any(g.via_mm is not None for g in segs)
    return WeldPath(dense.targets, dense.params, segs)


def targets(text: str) -> dict[str, np.ndarray]:
    return {n: pose_from_pos_quat([float(v) for v in p.split(",")],
                                  [float(v) for v in q.split(",")])
            for n, p, q in TARGET.findall(text)}


def proc(text: str) -> list[str]:
    body = text[text.index("PROC sg_weld"):text.index("  ERROR")]
    return [ln.strip() for ln in body.splitlines()[1:] if ln.strip()]


def test_the_weld_is_the_fitted_segments_with_the_arc_on_over_them_only(fitted):
    text = rapid_module(fitted, module="SgTest")
    assert text.startswith("MODULE SgTest") and text.rstrip().endswith("ENDMODULE")
    steps = proc(text)
    on, off = steps.index("SetDO do_arc_on, 1;"), steps.index("SetDO do_arc_on, 0;")
    assert steps[on - 1] == "MoveL sg_w0, v50, fine, sg_torch;"  # reached dry, a fine point
    weld = steps[on + 1:off]
    assert len(weld) == len(fitted.segments)
    for i, (step, g) in enumerate(zip(weld, fitted.segments, strict=True), start=1):
        zone = "fine" if i == len(weld) else "z1"
        if g.via_mm is None:
            assert step == f"MoveL sg_w{i}, sg_weld_speed, {zone}, sg_torch;"
        else:
            assert step == f"MoveC sg_c{i}, sg_w{i}, sg_weld_speed, {zone}, sg_torch;"
    assert steps[:on - 1] == ["ConfJ \\On;", "ConfL \\Off;", "MoveJ sg_a0, v200, fine, sg_torch;"]
    assert steps[off + 1:] == ["MoveL sg_d0, v100, fine, sg_torch;"]  # departs dry
    assert "ERROR\n    SetDO do_arc_on, 0;" in text


def test_the_written_moves_follow_the_planned_path_within_the_tolerance(fitted):
    T = targets(rapid_module(fitted))
    weld = fitted.weld_targets
    dense = np.array([t.T_base_tcp for t in weld])
    assert pose_error(T["sg_w0"], weld[0].T_base_tcp)[0] < 0.001
    assert pose_error(T["sg_a0"], fitted.targets[0].T_base_tcp)[0] < 0.001
    assert pose_error(T["sg_d0"], fitted.targets[-1].T_base_tcp)[0] < 0.001
    tol = PathTolerance()
    prev = T["sg_w0"]
    for i, g in enumerate(fitted.segments, start=1):
        end = T[f"sg_w{i}"]
        assert pose_error(end, g.T_end)[0] < 0.001 and pose_error(end, g.T_end)[1] < 1e-3
        via = T[f"sg_c{i}"][:3, 3] if g.via_mm is not None else None
        assert (via is None) == (f"sg_c{i}" not in T)
        # the motion the file commands, as written (rounded), against the dense planned path
        assert tol.admits(deviation(prev, end, via, dense[g.first:g.last + 1])), i
        prev = end


def test_without_segments_every_weld_target_is_a_movel(dense):
    steps = proc(rapid_module(dense))
    on, off = steps.index("SetDO do_arc_on, 1;"), steps.index("SetDO do_arc_on, 0;")
    assert len(steps[on + 1:off]) == len(dense.weld_targets) - 1
    assert all(s.startswith("MoveL sg_w") for s in steps[on + 1:off])
    T = targets(rapid_module(dense))
    for i, t in enumerate(dense.weld_targets):
        d_mm, _ = pose_error(T[f"sg_w{i}"], t.T_base_tcp)
        assert d_mm < 0.001
        # orientation written with 6 decimals: the torch tip (350 mm out) moves < 0.01 mm
        tip = T[f"sg_w{i}"][:3, :3] @ [0, 0, 350.0]
        assert np.linalg.norm(tip - t.T_base_tcp[:3, :3] @ [0, 0, 350.0]) < 0.01


@pytest.mark.skipif(not PARSER.exists(), reason=f"independent RAPID parser {PARSER} not "
                    "present; set SEAMGUIDE_SHARED_DATA to the shared data folder")
def test_the_module_parses_with_the_independent_rapid_parser(fitted, dense, tmp_path: Path):
    files = []
    for name, path in (("SgFitted", fitted), ("SgDense", dense)):
        f = tmp_path / f"{name}.mod"
        f.write_text(rapid_module(path, module=name, comment="job s_curve\nseed 1"))
        files.append(f)
    out = subprocess.run([str(PARSER), *map(str, files)], capture_output=True, text=True,
                         timeout=60)
    assert out.returncode == 0 and out.stdout.count("OK") == 2, out.stdout + out.stderr
    # and it can fail: a MoveC with its circle point missing
    bad = tmp_path / "SgBad.mod"
    bad.write_text(re.sub(r"MoveC sg_c\d+, ", "MoveC ", files[0].read_text(), count=1)
                   .replace("MoveC sg_w", "MoveC , sg_w", 1))
    out = subprocess.run([str(PARSER), str(bad)], capture_output=True, text=True, timeout=60)
    assert out.returncode == 1 and out.stdout.startswith("FAIL"), out.stdout


def test_bad_names_refused(dense):
    with pytest.raises(ConfigError, match="module name"):
        rapid_module(dense, module="1bad")
    with pytest.raises(ConfigError, match="signal"):
        rapid_module(dense, arc_output="do arc")
