"""The parse tree of routines turned into Python closures.

An expression becomes ``fn(frame) ->
value``, a statement ``fn(frame) -> None``. Every name is resolved here, when the module is
linked, as RAPID does at load time: an unknown name is a :class:`RapidLoadError` naming file and
line, so a module that references an instruction, signal or error number the controller lacks
does not load. AND/OR evaluate both sides (RAPID does not short-circuit); every ``num`` result is
rounded to single precision; a string result over 80 characters stops the program.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol

from drivers.rapid_vm.errors import RapidError, RapidLoadError, RapidStop
from drivers.rapid_vm.frames import (
    MAX_RETRIES,
    Frame,
    Param,
    ProgramExit,
    Propagate,
    RetrySig,
    ReturnSig,
    Routine,
    Stmt,
    TryNextSig,
    invoke,
    run_block,
)
from drivers.rapid_vm.operators import BINOPS, as_bool, as_num
from drivers.rapid_vm.values import RECORDS, component_type, convert, copy, f32


class Program(Protocol):
    """What compiled code reads of a :class:`drivers.rapid_vm.program.Program` (the loaded task).

    A protocol rather than an import: the program compiles its routines with this module.
    """

    builtins: dict[str, Any]
    constants: dict[str, float]
    globals: dict[str, Any]
    global_types: dict[str, tuple[str, int, str]]
    routines: dict[str, Any]
    pending: list[Any]
    in_trap: bool
    probes: dict[str, Callable[[str, Any], None]]
    killed: Callable[[], None]

    def connect(self, trap: Any) -> float:
        """CONNECT an interrupt to a trap routine."""

    def run_traps(self) -> None:
        """Run the traps whose interrupts are pending."""

Expr = Callable[[Frame], Any]
Node = tuple[Any, ...]
class Ref:
    """An INOUT argument of a built-in: read with :meth:`get`, written with :meth:`set`."""

    __slots__ = ("fr", "getter", "setter")

    def __init__(self, fr: Frame, getter: Expr, setter: Callable[[Frame, Any], None]) -> None:
        self.fr, self.getter, self.setter = fr, getter, setter

    def get(self) -> Any:
        """The variable's value."""
        return self.getter(self.fr)

    def set(self, value: Any) -> None:
        """Assign the variable."""
        self.setter(self.fr, value)


class Compiler:
    """Compiles one routine's statements in the scope of its locals and the program's globals."""

    def __init__(self, prog: Program, routine: Routine, locals_: dict[str, tuple[str, int]],
                 filename: str) -> None:
        self.prog, self.routine, self.locals, self.filename = prog, routine, locals_, filename
        self.line = routine.line

    def _err(self, msg: str) -> RapidLoadError:
        return RapidLoadError(f"{self.filename}:{self.line}: {msg}")

    # ---- names and targets -----------------------------------------------------------------

    def _var_type(self, name: str) -> tuple[str, int, str]:
        """(type, dims, where) of a variable: ``local``, ``global`` or ``const``."""
        if name in self.locals:
            return (*self.locals[name], "local")
        g = self.prog.global_types.get(name)
        if g is not None:
            return g
        raise self._err(f"reference error: unknown data {name!r}")

    def _target(self, node: Node) -> tuple[Expr, Callable[[Frame, Any], None], str]:
        """A variable, element or component: (getter, setter, its type)."""
        if node[0] == "var":
            name = node[1]
            t, dims, where = self._var_type(name)
            typ = t if not dims else f"{t}{{}}"
            if where == "local":
                return (lambda fr: fr.v[name]), (lambda fr, x: fr.v.__setitem__(name, x)), typ
            g = self.prog.globals
            if where == "const":
                def no_set(fr: Frame, x: Any) -> None:
                    raise RapidStop(f"{name} is a CONST")
                return (lambda fr: g[name]), no_set, typ
            return (lambda fr: g[name]), (lambda fr, x: g.__setitem__(name, x)), typ
        if node[0] == "idx":
            get_base, _, btype = self._target(node[1])
            if not btype.endswith("{}"):
                raise self._err(f"{btype} is not an array")
            (ie,) = [self.expr(i) for i in node[2]]

            def index(fr: Frame) -> tuple[list[Any], int]:
                arr, k = get_base(fr), ie(fr)
                if not (isinstance(k, float | int) and k == int(k) and 1 <= k <= len(arr)):
                    raise RapidStop(f"array index {k} outside 1..{len(arr)}")
                return arr, int(k) - 1

            def get_el(fr: Frame) -> Any:
                arr, k = index(fr)
                return arr[k]

            def set_el(fr: Frame, x: Any) -> None:
                arr, k = index(fr)
                arr[k] = x

            return get_el, set_el, btype[:-2]
        if node[0] == "comp":
            get_base, _, btype = self._target(node[1])
            name = node[2]
            ctype = component_type(btype, name, f"{self.filename}:{self.line}")
            return ((lambda fr: get_base(fr).f[name]),
                    (lambda fr, x: get_base(fr).f.__setitem__(name, x)), ctype)
        raise self._err("not a variable")

    # ---- expressions -----------------------------------------------------------------------

    def expr(self, node: Node) -> Expr:
        """The closure of an expression: ``fn(frame) -> value``."""
        tag = node[0]
        if tag == "num":
            v = f32(node[1])
            return lambda fr: v
        if tag in ("str", "bool"):
            c = node[1]
            return lambda fr: c
        if tag == "agg":
            items = [self.expr(e) for e in node[1]]
            return lambda fr: [f(fr) for f in items]
        if tag == "un":
            e = self.expr(node[2])
            if node[1] == "NOT":
                return lambda fr: not as_bool(e(fr))
            if node[1] == "-":
                return lambda fr: f32(-as_num(e(fr)))
            return lambda fr: as_num(e(fr))
        if tag == "bin":
            op, a, b = BINOPS[node[1]], self.expr(node[2]), self.expr(node[3])
            return lambda fr: op(a(fr), b(fr))
        if tag == "call":
            self.line = node[3]
            return self._call(node[1], node[2], want_value=True)
        if tag == "var":
            name = node[1]
            if name == "errno":
                return lambda fr: fr.errno
            if name in self.prog.constants and name not in self.locals:
                c = self.prog.constants[name]
                return lambda fr: c
        return self._target(node)[0]

    # ---- calls -----------------------------------------------------------------------------

    def _call(self, name: str, args: list[Node], want_value: bool) -> Expr:
        """A call of a user routine or a built-in; returns a closure giving its value."""
        r = self.prog.routines.get(name)
        if r is not None:
            if (r.kind == "FUNC") != want_value or r.kind == "TRAP":
                raise self._err(f"{name} is a {r.kind}, not a {'FUNC' if want_value else 'PROC'}")
            return self._user_call(r, args)
        b = self.prog.builtins.get(name)
        if b is None:
            raise self._err(f"reference error: unknown {'function' if want_value else 'routine'} "
                           f"{name!r}")
        fn, outs, is_func = b
        if is_func != want_value:
            raise self._err(f"{name} is {'a function' if is_func else 'an instruction'}")
        pos: list[Callable[[Frame], Any]] = []
        opts: list[tuple[str, Callable[[Frame], Any]]] = []
        for aname, e, optional in args:
            if optional:
                f = self.expr(e) if e is not None else (lambda fr: True)
                opts.append((aname, f))
            elif len(pos) in outs:
                getter, setter, _ = self._target(e)
                pos.append(lambda fr, g=getter, s=setter: Ref(fr, g, s))  # type: ignore[misc]
            else:
                pos.append(self.expr(e))
        where = f"{self.filename}:{self.line}"

        def run(fr: Frame) -> Any:
            return fn(where, [p(fr) for p in pos], {k: f(fr) for k, f in opts})
        return run

    def _user_call(self, r: Routine, args: list[Node]) -> Expr:
        req = [p for p in r.params if not p.optional]
        given = [a for a in args if not a[2]]
        if len(given) != len(req):
            raise self._err(f"{r.name} takes {len(req)} arguments, got {len(given)}")
        binds: list[tuple[Param, Expr, Callable[[Frame, Any], None] | None]] = []
        for p, (_, e, _) in zip(req, given, strict=True):
            if p.mode == "IN":
                binds.append((p, self.expr(e), None))
            else:
                getter, setter, _ = self._target(e)
                binds.append((p, getter, setter))
        opt_names = {p.name: p for p in r.params if p.optional}
        for aname, e, optional in args:
            if optional:
                op = opt_names.get(aname)
                if op is None:
                    raise self._err(f"{r.name} has no optional argument \\{aname}")
                binds.append((op, self.expr(e) if e is not None else (lambda fr: True), None))
        outs = [(p.name, s) for p, _, s in binds if s is not None]
        probe = self.prog.probes.get(r.name)

        def run(fr: Frame) -> Any:
            new = Frame(r)
            for p, get, s in binds:
                v = get(fr)
                new.v[p.name] = v if s is not None else (v if p.dims else convert(v, p.type))
            if probe is not None:
                probe("enter", None)
            result = invoke(r, new)
            if probe is not None:
                probe("exit", result)
            for pname, s in outs:
                s(fr, new.v[pname])
            return result
        return run

    # ---- statements ------------------------------------------------------------------------

    def block(self, nodes: list[Node]) -> list[Stmt]:
        """The closures of a statement list."""
        return [self._stmt(n) for n in nodes]

    def _guard(self, inner: Stmt) -> Stmt:
        prog = self.prog

        def run(fr: Frame) -> None:
            tries = 0
            while True:
                if prog.pending and not prog.in_trap:
                    prog.run_traps()
                if prog.pending:  # the kill sentinel while inside a trap
                    prog.killed()
                try:
                    inner(fr)
                    return
                except RapidError as e:
                    if tries >= MAX_RETRIES:
                        raise Propagate(e) from None
                    if not fr.handle(e):
                        return
                    tries += 1
        return run

    def _stmt(self, node: Node) -> Stmt:
        tag = node[0]
        self.line = node[-1]
        inner: Stmt
        if tag == "assign":
            getter, setter, t = self._target(node[1])
            e = self.expr(node[2])
            if t.endswith("{}"):
                raise self._err("whole-array assignment is not in this interpreter")
            inner = lambda fr: setter(fr, convert(e(fr), t))  # noqa: E731
        elif tag == "pcall":
            inner = self._call(node[1], node[2], want_value=False)
        elif tag == "late":
            inner = self._late(node[1], node[2])
        elif tag == "if":
            arms = [(self.expr(c), self.block(b)) for c, b in node[1]]
            other = self.block(node[2])

            def inner(fr: Frame) -> None:
                for cond, body in arms:
                    if as_bool(cond(fr)):
                        run_block(body, fr)
                        return
                run_block(other, fr)
        elif tag == "while":
            cond, body = self.expr(node[1]), self.block(node[2])

            def inner(fr: Frame) -> None:
                while as_bool(cond(fr)):
                    run_block(body, fr)
        elif tag == "for":
            inner = self._for_loop(node)
        elif tag == "test":
            inner = self._test(node)
        elif tag == "return":
            rt = self.routine.rtype
            if (node[1] is None) != (rt is None):
                raise self._err("RETURN needs a value in a FUNC and none elsewhere")
            e = self.expr(node[1]) if node[1] is not None else (lambda fr: None)

            def inner(fr: Frame) -> None:
                raise ReturnSig(convert(e(fr), rt) if rt else None)
        elif tag == "raise":
            inner = self._raise_(node[1])
        elif tag in ("retry", "trynext", "exit"):
            sig = {"retry": RetrySig, "trynext": TryNextSig, "exit": ProgramExit}[tag]

            def inner(fr: Frame) -> None:
                raise sig()
        elif tag == "connect":
            _, setter, _ = self._target(node[1])
            trap = self.prog.routines.get(node[2])
            if trap is None or trap.kind != "TRAP":
                raise self._err(f"reference error: {node[2]!r} is not a TRAP")
            inner = lambda fr: setter(fr, self.prog.connect(trap))  # noqa: E731
        else:
            raise self._err(f"statement {tag} is not in this interpreter")
        return self._guard(inner)

    def _late(self, name_e: Node, args: list[Node]) -> Stmt:
        e = self.expr(name_e)
        vals = [self.expr(a[1]) for a in args]
        prog = self.prog

        def run(fr: Frame) -> None:
            name = e(fr)
            r = prog.routines.get(str(name).lower())
            if r is None or r.kind != "PROC" or len(r.params) != len(vals):
                raise RapidError(int(prog.constants["err_refunkprc"]),
                                 f"late binding: no procedure {name!r} with {len(vals)} args")
            new = Frame(r)
            for p, v in zip(r.params, vals, strict=True):
                new.v[p.name] = convert(v(fr), p.type)
            invoke(r, new)
        return run

    def _raise_(self, e_node: Node | None) -> Stmt:
        if e_node is None:
            def reraise(fr: Frame) -> None:
                if not fr.in_handler or fr.err is None:
                    raise RapidStop(f"{self.routine.where()}: RAISE without an error")
                raise Propagate(fr.err)
            return reraise
        e = self.expr(e_node)

        def raise_new(fr: Frame) -> None:
            err = RapidError(int(as_num(e(fr))), "raised by the program")
            if fr.in_handler:
                raise Propagate(err)
            raise err
        return raise_new

    def _for_loop(self, node: Node) -> Stmt:
        _, var, ef, et, es, body_n, _ = node
        self.locals = {**self.locals, var: ("num", 0)}
        e_from, e_to = self.expr(ef), self.expr(et)
        e_step = self.expr(es) if es is not None else None
        body = self.block(body_n)

        def run(fr: Frame) -> None:
            i, to = as_num(e_from(fr)), as_num(e_to(fr))
            step = as_num(e_step(fr)) if e_step else (1.0 if i <= to else -1.0)
            while (i <= to) if step > 0 else (i >= to):
                fr.v[var] = f32(i)
                run_block(body, fr)
                i = f32(i + step)
        return run

    def _test(self, node: Node) -> Stmt:
        e = self.expr(node[1])
        cases = [([self.expr(v) for v in vals], self.block(b)) for vals, b in node[2]]
        default = self.block(node[3])

        def run(fr: Frame) -> None:
            x = e(fr)
            for vals, body in cases:
                if any(x == v(fr) for v in vals):
                    run_block(body, fr)
                    return
            run_block(default, fr)
        return run


__all__ = ["Compiler", "Ref", "RECORDS", "copy"]
