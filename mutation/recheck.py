"""Re-run the tests on each mutant listed in a survivors file (``mutation/survivors.md``).

After tests were added, this says which earlier survivors are now killed without running the
whole mutation session again: each survivor's diff (one ``-`` line, one ``+`` line) is planted
alone in a copy of the working tree and its group's tests are run.

    .venv/bin/python mutation/recheck.py [mutation/survivors.md] [--out FILE]
"""

from __future__ import annotations

import argparse
import re
import sys
import tempfile
from pathlib import Path

from planted import ROOT, Bug, copy_tree, run_bug
from run import GROUPS


def survivors(text: str) -> list[tuple[str, str, str, str, str]]:
    """(group, path:line, operator, old line, new line) of every survivor in ``text``."""
    out = []
    group = ""
    for block in re.split(r"\n(?=## |- `)", text):
        if block.startswith("## "):
            group = block[3:].split("\n", 1)[0].strip()
            continue
        m = re.match(r"- `([^`]+)` (\S+)", block)
        if not m:
            continue
        minus = [ln[1:] for ln in block.splitlines() if ln.startswith("-") and not
                 ln.startswith(("---", "- `"))]
        plus = [ln[1:] for ln in block.splitlines() if ln.startswith("+")
                and not ln.startswith("+++")]
        if len(minus) == 1 and len(plus) == 1:
            out.append((group, m.group(1), m.group(2), minus[0], plus[0]))
    return out


def main() -> int:
    """Plant each survivor, run its group's tests; print and write killed / still surviving."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("survivors", nargs="?", default=str(ROOT / "mutation" / "survivors.md"))
    ap.add_argument("--out", default=None)
    a = ap.parse_args()
    groups = {g.name: g for g in GROUPS}
    rows = []
    with tempfile.TemporaryDirectory(prefix="seamguide-recheck-") as tmp:
        copy = Path(tmp)
        copy_tree(copy)
        for group, where, op, old, new in survivors(Path(a.survivors).read_text()):
            g = groups[group]
            bug = Bug(f"{where} {op}", g.module, old, new, g.tests)
            text = (copy / g.module).read_text()
            if text.count(old) != 1:
                rows.append(f"| {where} | {op} | line changed since; not rechecked |")
            else:
                caught, failed, _ = run_bug(copy, bug)
                now = f"killed by {failed}" if caught else "SURVIVES"
                rows.append(f"| {where} | {op} | {now} |")
            print(rows[-1], flush=True)
    if a.out:
        Path(a.out).write_text("| mutant | operator | now |\n|---|---|---|\n" + "\n".join(rows)
                               + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
