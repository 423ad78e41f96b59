import json

import numpy as np

from controller.cli import main


def test_fk_prints_contract_json(capsys):
    assert main(["fk", "0", "0", "0", "0", "0", "0"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert np.allclose(out["position_mm"], [940, 0, 1455])
    assert np.allclose(out["quaternion_wxyz"], [0.7071068, 0, 0.7071068, 0], atol=1e-6)


def test_fk_out_of_limits_exit_code_and_message(capsys):
    code = main(["fk", "0", "0", "90", "0", "0", "0"])
    assert code == 13
    assert "axis 3" in capsys.readouterr().err


def test_ik_lists_solutions_that_include_fk_input(capsys, tmp_path):
    main(["fk", "20", "30", "10", "40", "50", "60", "--output", str(tmp_path / "p.json")])
    pose = json.loads((tmp_path / "p.json").read_text())
    args = [str(v) for v in pose["position_mm"] + pose["quaternion_wxyz"]]
    assert main(["ik", *args]) == 0
    sols = json.loads(capsys.readouterr().out)["solutions_deg"]
    assert any(np.allclose(s, [20, 30, 10, 40, 50, 60], atol=1e-4) for s in sols)


def test_ik_bad_quaternion(capsys):
    assert main(["ik", "900", "0", "900", "1", "1", "0", "0"]) == 3
    assert "quaternion" in capsys.readouterr().err
