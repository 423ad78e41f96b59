"""Every RAPID file the package ships parses with an independent RAPID grammar.

The parser is ``../shared/tools/rapid-parser/rapidparse`` (the LALRPOP grammar of the open-source
pevers/rapid linter, built in the shared tools folder; see its README). It lives beside the shared
data: ``$SEAMGUIDE_SHARED_DATA/../tools`` when that variable is set, else ``../shared/tools``. The
test skips, saying where it looked, when the tool is not there (a clone elsewhere).
"""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest
from shared_data import shared_data_dir

RAPID_DIR = Path(__file__).resolve().parents[1] / "drivers" / "abb" / "rapid"
PARSER = shared_data_dir().parent / "tools" / "rapid-parser" / "rapidparse"
RAPID_FILES = sorted(p for ext in ("mod", "sys", "prg") for p in RAPID_DIR.glob(f"*.{ext}"))

needs_parser = pytest.mark.skipif(
    not PARSER.exists(), reason=f"independent RAPID parser {PARSER} not present; set "
    "SEAMGUIDE_SHARED_DATA to the shared data folder (the tool is in its ../tools)")


def _parse(path: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([str(PARSER), str(path)], capture_output=True, text=True, timeout=60)


def test_the_package_has_rapid_files():
    names = {p.name for p in RAPID_FILES}
    assert {"SGSERVER.mod", "SGREACH.mod"} <= names


@needs_parser
@pytest.mark.parametrize("path", RAPID_FILES, ids=lambda p: p.name)
def test_rapid_file_parses(path: Path):
    out = _parse(path)
    assert out.returncode == 0 and out.stdout.startswith("OK"), out.stdout + out.stderr


@needs_parser
def test_parser_catches_a_broken_copy_at_the_right_line(tmp_path: Path):
    # the check can fail: NOT after OR (which the kernel syntax rejects) on a known line
    src = (RAPID_DIR / "SGSERVER.mod").read_text().splitlines()
    line = next(i for i, s in enumerate(src) if "IF nf <> 2 OR (NOT IntArg(2, a))" in s)
    src[line] = src[line].replace("(NOT IntArg(2, a))", "NOT IntArg(2, a)")
    bad = tmp_path / "BROKEN.mod"
    bad.write_text("\n".join(src) + "\n")
    out = _parse(bad)
    assert out.returncode == 1 and out.stdout.startswith("FAIL")
    assert f"{line + 1}:" in out.stdout
