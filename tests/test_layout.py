"""The tree is the architecture: imports run one way, no cycles, no module over 400 lines.

The layers, bottom up (a module imports from its own group and from the groups it lists):

* ``controller.errors``, ``controller.jsonio``: nothing of ours.
* ``controller.geometry`` (poses, camera model, kinematics, view files): the bottom layer.
* ``controller.vision``, ``controller.stereo``, ``controller.path``: geometry; not each other.
* ``calibration``: geometry. It does not import drivers: the teach routine is given its robot
  and camera as objects (the command line opens them), so calibration runs on any backend.
* ``drivers`` (robot link, mock, RAPID interpreter, cameras, simulators): geometry, and inside
  drivers one way (no cycles). ``drivers.sim`` may import ``calibration``: the boards it
  simulates are calibration's ``BoardSpec``; no other driver does (``drivers.cameras`` reaches
  it only through the simulated camera it can open).
* ``controller.cell`` (cycle, guidance pipeline, daemon, records, job, configuration): all the
  above. It is where vision, stereo and path meet the devices.
* ``controller.station`` (the operator's web station): the cell and everything below.
* ``controller.cli``: everything; nothing imports it.

Imports are read with ``ast`` from the source, those inside functions (lazy imports) and under
``TYPE_CHECKING`` included.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("controller", "drivers", "calibration")
MAX_LINES = 400
#: Modules allowed over MAX_LINES, each with the reason (none).
OVER_LIMIT_ALLOWED: dict[str, str] = {}
#: Import cycles allowed, each with the reason (none; the two type-only ones are protocols now).
KNOWN_CYCLES: dict[tuple[str, ...], str] = {}

BOTTOM = {"controller.errors", "controller.jsonio"}
LOWER = {"bottom", "geometry"}
ALLOWED: dict[str, set[str]] = {
    "bottom": set(),
    "geometry": {"bottom"},
    "vision": LOWER,
    "stereo": LOWER,
    "path": LOWER,
    "calibration": LOWER,
    "drivers": LOWER | {"drivers.sim"},  # cameras.py opens the simulated camera (sim:)
    "drivers.sim": LOWER | {"drivers", "calibration"},
    "cell": LOWER | {"vision", "stereo", "path", "calibration", "drivers", "drivers.sim"},
    "station": LOWER | {"vision", "stereo", "path", "calibration", "drivers", "drivers.sim",
                        "cell"},
    "cli": LOWER | {"vision", "stereo", "path", "calibration", "drivers", "drivers.sim", "cell",
                    "station"},
}


def modules() -> dict[str, Path]:
    """Every module of the three packages by dotted name (a package by its own name)."""
    out = {}
    for pkg in PACKAGES:
        for f in sorted((ROOT / pkg).rglob("*.py")):
            parts = f.relative_to(ROOT).with_suffix("").parts
            name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
            out[name] = f
    return out


def layer(module: str) -> str:
    """The layer a module belongs to (see the module docstring)."""
    parts = module.split(".")
    if module in BOTTOM:
        return "bottom"
    if parts[0] == "controller":
        if len(parts) == 1:
            return "bottom"
        return parts[1]
    if parts[0] == "drivers":
        return "drivers.sim" if parts[1:2] == ["sim"] else "drivers"
    return "calibration"


def imports_of(path: Path, known: dict[str, Path]) -> set[str]:
    """The modules of ours that ``path`` imports, anywhere in it (``from a import b`` counts as
    ``a.b`` when that is a module, else ``a``)."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        targets: list[str] = []
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            targets = [f"{node.module}.{a.name}" if f"{node.module}.{a.name}" in known
                       else node.module for a in node.names]
        for t in targets:
            if t.split(".")[0] in PACKAGES:
                while t not in known and "." in t:
                    t = t.rsplit(".", 1)[0]
                out.add(t)
    return out


def graph() -> dict[str, set[str]]:
    known = modules()
    return {m: imports_of(p, known) - {m} for m, p in known.items()}


def test_every_module_is_in_a_known_layer():
    unknown = sorted(m for m in modules() if layer(m) not in ALLOWED)
    assert unknown == [], f"modules in no layer (add the layer to tests/test_layout.py): {unknown}"


def test_imports_run_one_way():
    wrong = []
    for m, deps in graph().items():
        for d in sorted(deps):
            a, b = layer(m), layer(d)
            if a != b and b not in ALLOWED[a]:
                wrong.append(f"{m} ({a}) imports {d} ({b})")
    assert wrong == [], "imports against the direction:\n" + "\n".join(wrong)


def find_cycles(g: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in g.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(g):
        if v not in index:
            visit(v)
    return out


def test_no_two_modules_import_each_other():
    cycles = {tuple(c) for c in find_cycles(graph())}
    assert sorted(cycles - set(KNOWN_CYCLES)) == [], "modules that import each other"
    assert sorted(set(KNOWN_CYCLES) - cycles) == [], "gone: remove from KNOWN_CYCLES"


def test_the_cycle_finder_finds_cycles():
    g = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}, "e": {"f"}, "f": {"e"}}
    assert sorted(find_cycles(g)) == [["a", "b", "c"], ["e", "f"]]
    assert find_cycles({"a": {"b"}, "b": set()}) == []


def test_the_layers_refuse_an_import_against_the_direction():
    assert "cell" not in ALLOWED["vision"] and "cli" not in ALLOWED["cell"]
    assert "drivers" not in ALLOWED["calibration"] and "calibration" not in ALLOWED["drivers"]
    assert layer("controller.geometry.poses") == "geometry" and layer("drivers.sim.x") \
        == "drivers.sim"


def test_no_module_is_over_400_lines():
    over = {}
    for m, p in modules().items():
        n = len(p.read_text(encoding="utf-8").splitlines())
        if n > MAX_LINES and m not in OVER_LIMIT_ALLOWED:
            over[m] = n
    assert over == {}, f"split by what the parts do: {over}"
    stale = [m for m in OVER_LIMIT_ALLOWED
             if len(modules()[m].read_text(encoding="utf-8").splitlines()) <= MAX_LINES]
    assert stale == [], f"no longer over {MAX_LINES} lines: remove from OVER_LIMIT_ALLOWED {stale}"
