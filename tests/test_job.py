from pathlib import Path

import numpy as np
import pytest

from controller.cell.job import load_job, teach_view
from controller.errors import ConfigError

EXAMPLE = Path(__file__).parent.parent / "examples" / "demo-job.toml"


def test_example_job_loads():
    job = load_job(EXAMPLE)
    assert job.name == "demo" and len(job.views) == 2
    job.require_taught()
    assert job.weld_params().tool_offset_mm == 3.0
    assert np.allclose(job.weld_params().T_flange_tcp[:3, 3], [0, 0, 350])


def _write(tmp_path, text):
    p = tmp_path / "job.toml"
    p.write_text(text)
    return p


@pytest.mark.parametrize("edit,key", [
    (lambda t: t.replace("speed_mm_s = 8.0", "sped_mm_s = 8.0"), "weld.sped_mm_s"),
    (lambda t: t.replace("tool_offset_mm = 3.0", "tool_offset_mm = \"3\""), "tool_offset_mm"),
    (lambda t: t.replace("nominal_centre_mm = [1000.0, 5.0, 296.0]", "nominal_centre_mm = [1, 2]"),
     "seam.nominal_centre_mm"),
    (lambda t: t.replace("[-10.9433, 11.3498, 36.8942,", "[-10.9433, 11.3498, 86.8942,"),
     "axis 3"),
    (lambda t: t.replace("speed_mm_s = 200.0", "speed_mm_s = 900.0", 1), "max_speed_mm_s"),
    (lambda t: t.replace("name = \"demo\"", ""), "name"),
    (lambda t: t + "\nbogus = 1\n", "bogus"),
    (lambda t: t.replace("[seam]", "[seam\n"), "not valid TOML"),
])
def test_bad_job_files_name_file_and_key(tmp_path, edit, key):
    p = _write(tmp_path, edit(EXAMPLE.read_text()))
    with pytest.raises(ConfigError) as info:
        load_job(p)
    assert key in str(info.value) and str(p) in str(info.value)


def test_untaught_view_is_refused_at_cycle_time(tmp_path):
    text = EXAMPLE.read_text().replace(
        "joints_deg = [2.5267, 29.5969, 30.0126, -11.0934, 75.1567, -85.9897]\n", "")
    job = load_job(_write(tmp_path, text))
    with pytest.raises(ConfigError, match="view2 has not been taught"):
        job.require_taught()


def test_teach_view_replaces_and_appends(tmp_path):
    p = _write(tmp_path, EXAMPLE.read_text())
    job = teach_view(p, "view2", np.array([1.0, 21, 11, 2, 61, 31]))
    assert job.views[1].joints_deg == (1.0, 21.0, 11.0, 2.0, 61.0, 31.0)
    job = teach_view(p, "view3", np.array([-5.0, 20, 10, 0, 60, -30]))
    assert [v.name for v in load_job(p).views] == ["view1", "view2", "view3"]
    with pytest.raises(ConfigError):
        teach_view(p, "view4", np.array([0.0, 0, 99, 0, 0, 0]))
    assert len(load_job(p).views) == 3  # nothing written on a refused teach


def test_teach_view_cli_reads_the_robot(tmp_path, capsys):
    from controller.cli import main

    p = _write(tmp_path, EXAMPLE.read_text())
    assert main(["teach-view", str(p), "view3", "--port", "mock://?seed=2"]) == 0
    job = load_job(p)
    assert job.views[-1].name == "view3"
    assert job.views[-1].joints_deg == (0.0, 0.0, 0.0, 0.0, 30.0, 0.0)  # the mock's home
    assert "view3" in capsys.readouterr().err


def test_path_tolerance_is_a_job_setting():
    from controller.cell.job import job_from_dict

    base = {"name": "j", "views": [], "seam": {"nominal_centre_mm": [1000.0, 0.0, 300.0]}}
    tol = job_from_dict(base).path_tolerance()
    assert (tol.position_mm, tol.orientation_deg, tol.spin_deg) == (0.05, 0.2, 2.0)
    tight = job_from_dict({**base, "path": {"tolerance_mm": 0.02, "spin_deg": 0.2}})
    assert tight.path_tolerance().position_mm == 0.02
    assert tight.path_tolerance().spin_deg == 0.2
    with pytest.raises(ConfigError, match="tolerance_mm"):
        job_from_dict({**base, "path": {"tolerance_mm": 0.0}})
    with pytest.raises(ConfigError, match="tolerance_sm"):
        job_from_dict({**base, "path": {"tolerance_sm": 0.1}})
