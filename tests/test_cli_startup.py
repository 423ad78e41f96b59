"""The command line imports only what the command run needs (bench_cli_startup.py times it)."""

from __future__ import annotations

import json
import subprocess
import sys

import cv2
import numpy as np

from controller.cli.main import COMMANDS, build_parser

HEAVY = ("numpy", "cv2", "pinocchio", "scipy", "matplotlib")


def loaded_after(code: str) -> list[str]:
    """Which heavy packages a fresh interpreter has imported after running ``code``."""
    probe = (f"import sys\n{code}\n"
             f"print(__import__('json').dumps([m for m in {HEAVY!r} if m in sys.modules]))")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                         check=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def test_the_registry_names_every_command_its_module_registers():
    sub = build_parser()._subparsers._group_actions[0]  # argparse has no public API for it
    assert set(sub.choices) == set(COMMANDS)
    for command, module in COMMANDS.items():
        only = build_parser(command)._subparsers._group_actions[0].choices
        assert command in only and all(COMMANDS[c] == module for c in only)


def test_help_imports_none_of_the_heavy_packages():
    assert loaded_after("from controller.cli.main import build_parser; build_parser()") == []


def test_fk_imports_numpy_and_pinocchio_only():
    code = ("from controller.cli.main import main; import contextlib, io\n"
            "with contextlib.redirect_stdout(io.StringIO()): main(['fk', '0', '0', '0', '0', "
            "'0', '0'])")
    assert loaded_after(code) == ["numpy", "pinocchio"]


def test_detect_imports_numpy_and_cv2_only(tmp_path):
    img = np.full((240, 320), 150, np.uint8)
    img[:, 158:161] = 20  # a dark gap: a seam
    path = tmp_path / "seam.png"
    cv2.imwrite(str(path), img)
    code = ("from controller.cli.main import main; import contextlib, io\n"
            "with contextlib.redirect_stdout(io.StringIO()): "
            f"main(['detect', {str(path)!r}])")
    assert loaded_after(code) == ["numpy", "cv2"]
