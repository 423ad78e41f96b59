"""A loaded RAPID program.

Its modules' data and routines, linked against a controller's system
(its instructions, functions, error numbers and I/O signals), run from ``main``.

Loading follows the controller: every module is parsed, its data declared (initial values
evaluated), and the whole program linked, every name resolved; a name the system lacks, or a
name used twice (RAPID names are case-insensitive: a routine ``Num`` clashes with the type
``num``), is a :class:`RapidLoadError` and nothing runs. ``PERS`` data keep their values across
program restarts (pass the old program's :meth:`Program.persistent`).

Interrupts: a TRAP connected with ``CONNECT`` runs between two statements of the program once
:meth:`Program.interrupt` was called (from any thread), never inside another trap.
"""

from __future__ import annotations

import itertools
import threading
from collections.abc import Callable
from typing import Any

from drivers.rapid_vm.compiler import Compiler
from drivers.rapid_vm.errors import RapidError, RapidLoadError, RapidStop
from drivers.rapid_vm.frames import Frame, Param, ProgramExit, Routine, invoke
from drivers.rapid_vm.parser import parse_module
from drivers.rapid_vm.values import PREDEFINED, convert, copy, default, known_type

#: A built-in: ``fn(where, positional values, optional values)``, the positions of its INOUT
#: arguments (given as :class:`~drivers.rapid_vm.compiler.Ref`), and whether it is a function.
Builtin = tuple[Callable[[str, list[Any], dict[str, Any]], Any], frozenset[int], bool]


def _local_init(t: str, n: int, e: Callable[[Frame], Any] | None) -> Callable[[Frame], Any]:
    """The initial value of a local variable: an array of ``n``, ``e``'s value, or the default."""
    def init(fr: Frame) -> Any:
        if n:
            return [default(t) for _ in range(n)]
        return convert(e(fr), t) if e is not None else default(t)
    return init


class Program:
    """Modules loaded into one RAPID task, linked against ``builtins``, ``constants``, ``signals``.

    ``signals`` maps an I/O signal name to its type (``signaldo`` / ``signaldi``); a signal is
    passed to built-ins as its name.
    """

    def __init__(self, builtins: dict[str, Builtin], constants: dict[str, float],
                 signals: dict[str, str], persistent: dict[str, Any] | None = None) -> None:
        self.builtins = builtins
        self.constants = dict(constants)
        self.globals: dict[str, Any] = {}
        #: name -> (type, dims, "global" | "const")
        self.global_types: dict[str, tuple[str, int, str]] = {}
        self.routines: dict[str, Routine] = {}
        self._pers_names: list[str] = []
        self._old_pers = persistent or {}
        self._sources: list[tuple[str, tuple[Any, ...], dict[str, Any]]] = []
        self._traps: dict[float, Routine] = {}
        self._ids = itertools.count(1)
        self._lock = threading.Lock()
        self.pending: list[Routine] = []
        self.in_trap = False
        #: Called on entry (``"enter", None``) and normal exit (``"exit", value``) of the named
        #: routines (set before :meth:`link`): how a test harness watches the program.
        self.probes: dict[str, Callable[[str, Any], None]] = {}
        #: Checked between statements; raises to end the program from outside.
        self.killed: Callable[[], None] = lambda: None
        for name, (t, v) in PREDEFINED.items():
            self._declare(name, t, 0, "const", v, "<system>")
        for name, t in signals.items():
            self._declare(name, t, 0, "const", name, "<system>")

    # ---- loading ---------------------------------------------------------------------------

    def _declare(self, name: str, t: str, dims: int, where: str, value: Any, src: str) -> None:
        if name in self.global_types or name in self.routines or name in self.builtins \
                or name in self.constants or known_type(name):
            raise RapidLoadError(f"{src}: name clash: {name!r} is already a name of the program "
                                 "or the system (RAPID names are case-insensitive)")
        self.global_types[name] = (t, dims, where)
        self.globals[name] = value

    def load(self, text: str, filename: str) -> None:
        """Parse a module and declare its data and routines (link with :meth:`link`)."""
        mod_name, decls, routines = parse_module(text, filename)
        boot = Routine("PROC", f"<{mod_name} data>", None, [], filename, 0)
        comp = Compiler(self, boot, {}, filename)
        for _, kind, t, name, dim_nodes, init, ln in decls:
            comp.line = ln
            if not known_type(t):
                raise RapidLoadError(f"{filename}:{ln}: reference error: unknown data type {t!r}")
            dims = [int(comp.expr(d)(Frame(boot))) for d in dim_nodes]
            if len(dims) > 1:
                raise RapidLoadError(f"{filename}:{ln}: only one-dimensional arrays here")
            value: Any = ([default(t) for _ in range(dims[0])] if dims else default(t))
            if init is not None:
                v = comp.expr(init)(Frame(boot))
                value = [convert(x, t) for x in v] if dims else convert(v, t)
            if kind == "PERS":
                self._pers_names.append(name)
                if name in self._old_pers:
                    value = copy(self._old_pers[name])
            self._declare(name, t, len(dims), "const" if kind == "CONST" else "global", value,
                          f"{filename}:{ln}")
        for node in routines:
            _, kind, name, rtype, params, _, _, _, ln = node
            if name in self.routines or name in self.global_types or name in self.builtins \
                    or known_type(name) or name in self.constants:
                raise RapidLoadError(f"{filename}:{ln}: name clash: {kind} {name!r} has the name "
                                     "of a data type, data or routine (RAPID names are "
                                     "case-insensitive)")
            if rtype is not None and not known_type(rtype):
                raise RapidLoadError(f"{filename}:{ln}: unknown type {rtype!r}")
            ps = [Param(m, t, n, o, d) for m, t, n, o, d in params]
            self.routines[name] = Routine(kind, name, rtype, ps, filename, ln)
        self._sources.append((filename, tuple(routines), {}))

    def link(self) -> None:
        """Compile every routine; :class:`RapidLoadError` for a name nothing defines."""
        for filename, routines, _ in self._sources:
            for node in routines:
                _, kind, name, rtype, params, decls, body, handler, ln = node
                r = self.routines[name]
                locals_ = {p.name: (p.type, p.dims) for p in r.params}
                comp = Compiler(self, r, locals_, filename)
                for _, _, t, dname, dims, init, dln in decls:
                    comp.line = dln
                    n = int(comp.expr(dims[0])(Frame(r))) if dims else 0
                    e = comp.expr(init) if init is not None else None
                    r.decls.append((dname, _local_init(t, n, e)))
                    comp.locals[dname] = (t, 1 if dims else 0)
                r.body = comp.block(body)
                r.handler = comp.block(handler) if handler is not None else None
        self._sources = [(f, (), {}) for f, _, _ in self._sources]

    def persistent(self) -> dict[str, Any]:
        """The PERS data (copies), to give to the next program start."""
        return {n: copy(self.globals[n]) for n in self._pers_names}

    # ---- interrupts ------------------------------------------------------------------------

    def connect(self, trap: Routine) -> float:
        """CONNECT: a new interrupt number for ``trap``."""
        k = float(next(self._ids))
        self._traps[k] = trap
        return k

    def delete_interrupt(self, k: float) -> None:
        """IDelete."""
        self._traps.pop(k, None)

    def interrupt(self, k: float) -> None:
        """Order the TRAP connected to interrupt ``k`` (thread-safe; ignored if none)."""
        with self._lock:
            trap = self._traps.get(k)
            if trap is not None:
                self.pending.append(trap)

    def run_traps(self) -> None:
        """Run the ordered traps (called between statements)."""
        self.killed()
        while True:
            with self._lock:
                if not self.pending:
                    return
                trap = self.pending.pop(0)
            self.in_trap = True
            try:
                invoke(trap, Frame(trap))
            except RapidError as e:
                raise RapidStop(f"{trap.where()}: unhandled error {e}") from e
            finally:
                self.in_trap = False

    # ---- running ---------------------------------------------------------------------------

    def run(self, entry: str = "main") -> None:
        """Run ``entry`` to its end; :class:`RapidStop` when the program stops with an error."""
        r = self.routines.get(entry)
        if r is None or r.kind != "PROC":
            raise RapidLoadError(f"no PROC {entry} to start")
        try:
            invoke(r, Frame(r))
        except ProgramExit:
            return
        except RapidError as e:
            raise RapidStop(f"unhandled error in {entry}: {e}") from e
