"""A recursive-descent parser for the subset of RAPID the seamguide server uses, into tuples.

Written from the RAPID kernel syntax (module, data and routine declarations, statements, and
the expression grammar: ``[NOT] term {OR|XOR term}``, ``term := relation {AND relation}``,
``relation := simple [relop simple]``, ``simple := [+|-] product {+|- product}``, ``product :=
primary {* / DIV MOD primary}``), so ``a OR NOT b`` is refused as the kernel syntax and the
independent parser refuse it. Names are case-insensitive (kept lower-case).

The tree (tuples, tag first; ``ln`` is the source line):

* expressions: ``("num", v)`` ``("str", s)`` ``("bool", b)`` ``("agg", [e])`` ``("var", name)``
  ``("idx", e, [e])`` ``("comp", e, name)`` ``("call", name, args, ln)`` ``("un", op, e)``
  ``("bin", op, l, r)``; an argument is ``(name | None, e | None, optional)``;
* statements: ``("assign", lhs, e, ln)`` ``("pcall", name, args, ln)`` ``("late", e, args, ln)``
  ``("if", [(cond, body)], else_body, ln)`` ``("while", cond, body, ln)``
  ``("for", var, e_from, e_to, e_step, body, ln)`` ``("test", e, [([e], body)], default, ln)``
  ``("return", e, ln)`` ``("raise", e, ln)`` ``("retry", ln)`` ``("trynext", ln)``
  ``("exit", ln)`` ``("connect", lhs, trap, ln)``;
* declarations: ``("data", kind, type, name, [dim e], init e | None, ln)`` and routines
  ``("routine", kind, name, type | None, params, decls, body, handler | None, ln)`` with a
  parameter ``(mode, type, name, optional, dims)``; a module is ``(name, decls, routines)``.
"""

from __future__ import annotations

from typing import Any

from drivers.rapid_vm.errors import RapidLoadError
from drivers.rapid_vm.lexer import Token, tokenize

Node = tuple[Any, ...]
_RELOPS = ("<", "<=", "=", ">", ">=", "<>")


class Parser:
    """Parses one module's tokens; :meth:`module` returns ``(name, decls, routines)``."""

    def __init__(self, text: str, filename: str = "<rapid>") -> None:
        self.toks = tokenize(text, filename)
        self.i = 0
        self.filename = filename

    # ---- token helpers ---------------------------------------------------------------------

    @property
    def tok(self) -> Token:
        return self.toks[self.i]

    def fail(self, what: str) -> RapidLoadError:
        t = self.tok
        return RapidLoadError(f"{self.filename}:{t.line}: expected {what}, found {t.text!r}")

    def at(self, kind: str, value: object = None) -> bool:
        t = self.tok
        return t.kind == kind and (value is None or t.value == value)

    def at_kw(self, *words: str) -> bool:
        return self.tok.kind == "kw" and self.tok.value in words

    def accept(self, kind: str, value: object = None) -> Token | None:
        if self.at(kind, value):
            self.i += 1
            return self.toks[self.i - 1]
        return None

    def expect(self, kind: str, value: object = None) -> Token:
        t = self.accept(kind, value)
        if t is None:
            raise self.fail(repr(value) if value is not None else kind)
        return t

    def name(self) -> str:
        return str(self.expect("name").value)

    # ---- module and declarations -----------------------------------------------------------

    def module(self) -> Node:
        """``MODULE name [(attributes)] {declaration | routine} ENDMODULE``."""
        self.expect("kw", "MODULE")
        name = self.name()
        if self.accept("op", "("):
            while not self.accept("op", ")"):
                self.i += 1
        decls: list[Node] = []
        routines: list[Node] = []
        while not self.accept("kw", "ENDMODULE"):
            self.accept("kw", "LOCAL") or self.accept("kw", "TASK")
            if self.at_kw("VAR", "PERS", "CONST"):
                decls.append(self.data_decl())
            elif self.at_kw("PROC", "FUNC", "TRAP"):
                routines.append(self.routine())
            else:
                raise self.fail("a data declaration, PROC, FUNC, TRAP or ENDMODULE")
        self.expect("end")
        return (name, decls, routines)

    def data_decl(self) -> Node:
        ln = self.tok.line
        kind = str(self.expect("kw").value)
        typ = self.name()
        name = self.name()
        dims: list[Node] = []
        if self.accept("op", "{"):
            dims.append(self.expr())
            while self.accept("op", ","):
                dims.append(self.expr())
            self.expect("op", "}")
        init = self.expr() if self.accept("op", ":=") else None
        self.expect("op", ";")
        if kind == "CONST" and init is None:
            raise RapidLoadError(f"{self.filename}:{ln}: CONST {name} needs a value")
        return ("data", kind, typ, name, dims, init, ln)

    def routine(self) -> Node:
        ln = self.tok.line
        kind = str(self.expect("kw").value)
        rtype = self.name() if kind == "FUNC" else None
        name = self.name()
        params: list[Node] = []
        if kind != "TRAP":
            self.expect("op", "(")
            if not self.at("op", ")"):
                params.append(self.param())
                while self.accept("op", ","):
                    params.append(self.param())
            self.expect("op", ")")
        decls: list[Node] = []
        while self.at_kw("VAR", "PERS", "CONST"):
            decls.append(self.data_decl())
        end = {"PROC": "ENDPROC", "FUNC": "ENDFUNC", "TRAP": "ENDTRAP"}[kind]
        body = self.block(("ERROR", "UNDO", "BACKWARD", end))
        handler = self.block(("UNDO", end)) if self.accept("kw", "ERROR") else None
        if self.at_kw("UNDO", "BACKWARD"):
            raise self.fail(f"{end} (UNDO and BACKWARD are not in this interpreter)")
        self.expect("kw", end)
        return ("routine", kind, name, rtype, params, decls, body, handler, ln)

    def param(self) -> Node:
        optional = self.accept("op", "\\") is not None
        mode = "IN"
        for m in ("INOUT", "VAR", "PERS"):
            if self.accept("kw", m):
                mode = m
        typ = self.name()
        name = self.name()
        dims = 0
        if self.accept("op", "{"):
            dims = 1
            while not self.accept("op", "}"):
                self.i += 1
        return (mode, typ, name, optional, dims)

    # ---- statements ------------------------------------------------------------------------

    def block(self, ends: tuple[str, ...]) -> list[Node]:
        out: list[Node] = []
        while not self.at_kw(*ends):
            if self.at("end"):
                raise self.fail(" or ".join(ends))
            out.append(self.statement())
        return out

    def statement(self) -> Node:
        t = self.tok
        ln = t.line
        if t.kind == "kw":
            word = str(t.value)
            if word == "IF":
                return self.if_stmt()
            if word in ("WHILE", "FOR", "TEST"):
                return getattr(self, f"{word.lower()}_stmt")()
            if word in ("RETURN", "RAISE"):
                self.i += 1
                e = None if self.at("op", ";") else self.expr()
                self.expect("op", ";")
                return (word.lower(), e, ln)
            if word in ("RETRY", "TRYNEXT", "EXIT"):
                self.i += 1
                self.expect("op", ";")
                return (word.lower(), ln)
            if word == "CONNECT":
                self.i += 1
                lhs = self.target()
                self.expect("kw", "WITH")
                trap = self.name()
                self.expect("op", ";")
                return ("connect", lhs, trap, ln)
            raise self.fail("a statement")
        if self.accept("op", "%"):
            e = self.expr()
            self.expect("op", "%")
            args = self.args(";")
            self.expect("op", ";")
            return ("late", e, args, ln)
        if t.kind != "name":
            raise self.fail("a statement")
        nxt = self.toks[self.i + 1]
        if nxt.kind == "op" and nxt.value in (":=", "{", "."):
            lhs = self.target()
            self.expect("op", ":=")
            e = self.expr()
            self.expect("op", ";")
            return ("assign", lhs, e, ln)
        name = self.name()
        args = self.args(";")
        self.expect("op", ";")
        return ("pcall", name, args, ln)

    def if_stmt(self) -> Node:
        ln = self.expect("kw", "IF").line
        cond = self.expr()
        if not self.accept("kw", "THEN"):  # compact IF: one simple statement
            st = self.statement()
            if st[0] in ("if", "while", "for", "test"):
                raise RapidLoadError(f"{self.filename}:{ln}: compact IF takes a simple statement")
            return ("if", [(cond, [st])], [], ln)
        arms = [(cond, self.block(("ELSEIF", "ELSE", "ENDIF")))]
        other: list[Node] = []
        while True:
            if self.accept("kw", "ELSEIF"):
                c = self.expr()
                self.expect("kw", "THEN")
                arms.append((c, self.block(("ELSEIF", "ELSE", "ENDIF"))))
            elif self.accept("kw", "ELSE"):
                other = self.block(("ENDIF",))
            else:
                self.expect("kw", "ENDIF")
                return ("if", arms, other, ln)

    def while_stmt(self) -> Node:
        ln = self.expect("kw", "WHILE").line
        cond = self.expr()
        self.expect("kw", "DO")
        body = self.block(("ENDWHILE",))
        self.expect("kw", "ENDWHILE")
        return ("while", cond, body, ln)

    def for_stmt(self) -> Node:
        ln = self.expect("kw", "FOR").line
        var = self.name()
        self.expect("kw", "FROM")
        e_from = self.expr()
        self.expect("kw", "TO")
        e_to = self.expr()
        e_step = self.expr() if self.accept("kw", "STEP") else None
        self.expect("kw", "DO")
        body = self.block(("ENDFOR",))
        self.expect("kw", "ENDFOR")
        return ("for", var, e_from, e_to, e_step, body, ln)

    def test_stmt(self) -> Node:
        ln = self.expect("kw", "TEST").line
        e = self.expr()
        cases: list[tuple[list[Node], list[Node]]] = []
        default: list[Node] = []
        while self.accept("kw", "CASE"):
            values = [self.expr()]
            while self.accept("op", ","):
                values.append(self.expr())
            self.expect("op", ":")
            cases.append((values, self.block(("CASE", "DEFAULT", "ENDTEST"))))
        if self.accept("kw", "DEFAULT"):
            self.expect("op", ":")
            default = self.block(("ENDTEST",))
        self.expect("kw", "ENDTEST")
        return ("test", e, cases, default, ln)

    def args(self, end: str) -> list[Node]:
        """Arguments up to ``end``: ``a, b \\Opt:=e \\Switch, name:=e``."""
        out: list[Node] = []
        while not self.at("op", end):
            if self.accept("op", "\\"):
                name = self.name()
                e = self.expr() if self.accept("op", ":=") else None
                out.append((name, e, True))
            else:
                name = None
                if self.at("name") and self.toks[self.i + 1].value == ":=":
                    name = self.name()
                    self.i += 1
                out.append((name, self.expr(), False))
            if not self.accept("op", ",") and not self.at("op", "\\"):
                break
        return out

    def target(self) -> Node:
        e = self.postfix(("var", self.name()))
        return e

    # ---- expressions -----------------------------------------------------------------------

    def expr(self) -> Node:
        if self.accept("kw", "NOT"):
            e: Node = ("un", "NOT", self.and_term())
        else:
            e = self.and_term()
        while self.at_kw("OR", "XOR"):
            op = str(self.expect("kw").value)
            e = ("bin", op, e, self.and_term())
        return e

    def and_term(self) -> Node:
        e = self.relation()
        while self.accept("kw", "AND"):
            e = ("bin", "AND", e, self.relation())
        return e

    def relation(self) -> Node:
        e = self.simple()
        if self.tok.kind == "op" and self.tok.value in _RELOPS:
            op = str(self.expect("op").value)
            e = ("bin", op, e, self.simple())
        return e

    def simple(self) -> Node:
        if self.tok.kind == "op" and self.tok.value in ("+", "-"):
            op = str(self.expect("op").value)
            e: Node = ("un", op, self.product())
        else:
            e = self.product()
        while self.tok.kind == "op" and self.tok.value in ("+", "-"):
            op = str(self.expect("op").value)
            e = ("bin", op, e, self.product())
        return e

    def product(self) -> Node:
        e = self.primary()
        while (self.tok.kind == "op" and self.tok.value in ("*", "/")) or self.at_kw("DIV", "MOD"):
            op = str(self.toks[self.i].value)
            self.i += 1
            e = ("bin", op, e, self.primary())
        return e

    def primary(self) -> Node:
        t = self.tok
        if t.kind == "num":
            self.i += 1
            return ("num", t.value)
        if t.kind == "str":
            self.i += 1
            return ("str", t.value)
        if self.accept("kw", "TRUE"):
            return ("bool", True)
        if self.accept("kw", "FALSE"):
            return ("bool", False)
        if self.accept("op", "("):
            e = self.expr()
            self.expect("op", ")")
            return e
        if self.accept("op", "["):
            items = [self.expr()]
            while self.accept("op", ","):
                items.append(self.expr())
            self.expect("op", "]")
            return ("agg", items)
        if t.kind == "name":
            name = self.name()
            if self.accept("op", "("):
                args = self.args(")")
                self.expect("op", ")")
                return ("call", name, args, t.line)
            return self.postfix(("var", name))
        raise self.fail("an expression")

    def postfix(self, e: Node) -> Node:
        while True:
            if self.accept("op", "{"):
                idx = [self.expr()]
                while self.accept("op", ","):
                    idx.append(self.expr())
                self.expect("op", "}")
                e = ("idx", e, idx)
            elif self.accept("op", "."):
                e = ("comp", e, self.name())
            else:
                return e


def parse_module(text: str, filename: str = "<rapid>") -> Node:
    """The tree of one RAPID module; :class:`RapidLoadError` with file and line when bad."""
    return Parser(text, filename).module()
