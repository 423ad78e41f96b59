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
    def _tok(self) -> Token:
        return self.toks[self.i]

    def _fail(self, what: str) -> RapidLoadError:
        t = self._tok
        return RapidLoadError(f"{self.filename}:{t.line}: expected {what}, found {t.text!r}")

    def _at(self, kind: str, value: object = None) -> bool:
        t = self._tok
        return t.kind == kind and (value is None or t.value == value)

    def _at_kw(self, *words: str) -> bool:
        return self._tok.kind == "kw" and self._tok.value in words

    def _accept(self, kind: str, value: object = None) -> Token | None:
        if self._at(kind, value):
            self.i += 1
            return self.toks[self.i - 1]
        return None

    def _expect(self, kind: str, value: object = None) -> Token:
        t = self._accept(kind, value)
        if t is None:
            raise self._fail(repr(value) if value is not None else kind)
        return t

    def _name(self) -> str:
        return str(self._expect("name").value)

    # ---- module and declarations -----------------------------------------------------------

    def module(self) -> Node:
        """``MODULE name [(attributes)] {declaration | routine} ENDMODULE``."""
        self._expect("kw", "MODULE")
        name = self._name()
        if self._accept("op", "("):
            while not self._accept("op", ")"):
                self.i += 1
        decls: list[Node] = []
        routines: list[Node] = []
        while not self._accept("kw", "ENDMODULE"):
            self._accept("kw", "LOCAL") or self._accept("kw", "TASK")
            if self._at_kw("VAR", "PERS", "CONST"):
                decls.append(self._data_decl())
            elif self._at_kw("PROC", "FUNC", "TRAP"):
                routines.append(self._routine())
            else:
                raise self._fail("a data declaration, PROC, FUNC, TRAP or ENDMODULE")
        self._expect("end")
        return (name, decls, routines)

    def _data_decl(self) -> Node:
        ln = self._tok.line
        kind = str(self._expect("kw").value)
        typ = self._name()
        name = self._name()
        dims: list[Node] = []
        if self._accept("op", "{"):
            dims.append(self._expr())
            while self._accept("op", ","):
                dims.append(self._expr())
            self._expect("op", "}")
        init = self._expr() if self._accept("op", ":=") else None
        self._expect("op", ";")
        if kind == "CONST" and init is None:
            raise RapidLoadError(f"{self.filename}:{ln}: CONST {name} needs a value")
        return ("data", kind, typ, name, dims, init, ln)

    def _routine(self) -> Node:
        ln = self._tok.line
        kind = str(self._expect("kw").value)
        rtype = self._name() if kind == "FUNC" else None
        name = self._name()
        params: list[Node] = []
        if kind != "TRAP":
            self._expect("op", "(")
            if not self._at("op", ")"):
                params.append(self._param())
                while self._accept("op", ","):
                    params.append(self._param())
            self._expect("op", ")")
        decls: list[Node] = []
        while self._at_kw("VAR", "PERS", "CONST"):
            decls.append(self._data_decl())
        end = {"PROC": "ENDPROC", "FUNC": "ENDFUNC", "TRAP": "ENDTRAP"}[kind]
        body = self._block(("ERROR", "UNDO", "BACKWARD", end))
        handler = self._block(("UNDO", end)) if self._accept("kw", "ERROR") else None
        if self._at_kw("UNDO", "BACKWARD"):
            raise self._fail(f"{end} (UNDO and BACKWARD are not in this interpreter)")
        self._expect("kw", end)
        return ("routine", kind, name, rtype, params, decls, body, handler, ln)

    def _param(self) -> Node:
        optional = self._accept("op", "\\") is not None
        mode = "IN"
        for m in ("INOUT", "VAR", "PERS"):
            if self._accept("kw", m):
                mode = m
        typ = self._name()
        name = self._name()
        dims = 0
        if self._accept("op", "{"):
            dims = 1
            while not self._accept("op", "}"):
                self.i += 1
        return (mode, typ, name, optional, dims)

    # ---- statements ------------------------------------------------------------------------

    def _block(self, ends: tuple[str, ...]) -> list[Node]:
        out: list[Node] = []
        while not self._at_kw(*ends):
            if self._at("end"):
                raise self._fail(" or ".join(ends))
            out.append(self._statement())
        return out

    def _statement(self) -> Node:
        t = self._tok
        ln = t.line
        if t.kind == "kw":
            word = str(t.value)
            if word == "IF":
                return self._if_stmt()
            if word in ("WHILE", "FOR", "TEST"):
                return getattr(self, f"_{word.lower()}_stmt")()
            if word in ("RETURN", "RAISE"):
                self.i += 1
                e = None if self._at("op", ";") else self._expr()
                self._expect("op", ";")
                return (word.lower(), e, ln)
            if word in ("RETRY", "TRYNEXT", "EXIT"):
                self.i += 1
                self._expect("op", ";")
                return (word.lower(), ln)
            if word == "CONNECT":
                self.i += 1
                lhs = self._target()
                self._expect("kw", "WITH")
                trap = self._name()
                self._expect("op", ";")
                return ("connect", lhs, trap, ln)
            raise self._fail("a statement")
        if self._accept("op", "%"):
            e = self._expr()
            self._expect("op", "%")
            args = self._args(";")
            self._expect("op", ";")
            return ("late", e, args, ln)
        if t.kind != "name":
            raise self._fail("a statement")
        nxt = self.toks[self.i + 1]
        if nxt.kind == "op" and nxt.value in (":=", "{", "."):
            lhs = self._target()
            self._expect("op", ":=")
            e = self._expr()
            self._expect("op", ";")
            return ("assign", lhs, e, ln)
        name = self._name()
        args = self._args(";")
        self._expect("op", ";")
        return ("pcall", name, args, ln)

    def _if_stmt(self) -> Node:
        ln = self._expect("kw", "IF").line
        cond = self._expr()
        if not self._accept("kw", "THEN"):  # compact IF: one simple statement
            st = self._statement()
            if st[0] in ("if", "while", "for", "test"):
                raise RapidLoadError(f"{self.filename}:{ln}: compact IF takes a simple statement")
            return ("if", [(cond, [st])], [], ln)
        arms = [(cond, self._block(("ELSEIF", "ELSE", "ENDIF")))]
        other: list[Node] = []
        while True:
            if self._accept("kw", "ELSEIF"):
                c = self._expr()
                self._expect("kw", "THEN")
                arms.append((c, self._block(("ELSEIF", "ELSE", "ENDIF"))))
            elif self._accept("kw", "ELSE"):
                other = self._block(("ENDIF",))
            else:
                self._expect("kw", "ENDIF")
                return ("if", arms, other, ln)

    def _while_stmt(self) -> Node:
        ln = self._expect("kw", "WHILE").line
        cond = self._expr()
        self._expect("kw", "DO")
        body = self._block(("ENDWHILE",))
        self._expect("kw", "ENDWHILE")
        return ("while", cond, body, ln)

    def _for_stmt(self) -> Node:
        ln = self._expect("kw", "FOR").line
        var = self._name()
        self._expect("kw", "FROM")
        e_from = self._expr()
        self._expect("kw", "TO")
        e_to = self._expr()
        e_step = self._expr() if self._accept("kw", "STEP") else None
        self._expect("kw", "DO")
        body = self._block(("ENDFOR",))
        self._expect("kw", "ENDFOR")
        return ("for", var, e_from, e_to, e_step, body, ln)

    def _test_stmt(self) -> Node:
        ln = self._expect("kw", "TEST").line
        e = self._expr()
        cases: list[tuple[list[Node], list[Node]]] = []
        default: list[Node] = []
        while self._accept("kw", "CASE"):
            values = [self._expr()]
            while self._accept("op", ","):
                values.append(self._expr())
            self._expect("op", ":")
            cases.append((values, self._block(("CASE", "DEFAULT", "ENDTEST"))))
        if self._accept("kw", "DEFAULT"):
            self._expect("op", ":")
            default = self._block(("ENDTEST",))
        self._expect("kw", "ENDTEST")
        return ("test", e, cases, default, ln)

    def _args(self, end: str) -> list[Node]:
        r"""Arguments up to ``end``: ``a, b \Opt:=e \Switch, name:=e``."""
        out: list[Node] = []
        while not self._at("op", end):
            if self._accept("op", "\\"):
                name = self._name()
                e = self._expr() if self._accept("op", ":=") else None
                out.append((name, e, True))
            else:
                name = None
                if self._at("name") and self.toks[self.i + 1].value == ":=":
                    name = self._name()
                    self.i += 1
                out.append((name, self._expr(), False))
            if not self._accept("op", ",") and not self._at("op", "\\"):
                break
        return out

    def _target(self) -> Node:
        e = self._postfix(("var", self._name()))
        return e

    # ---- expressions -----------------------------------------------------------------------

    def _expr(self) -> Node:
        if self._accept("kw", "NOT"):
            e: Node = ("un", "NOT", self._and_term())
        else:
            e = self._and_term()
        while self._at_kw("OR", "XOR"):
            op = str(self._expect("kw").value)
            e = ("bin", op, e, self._and_term())
        return e

    def _and_term(self) -> Node:
        e = self._relation()
        while self._accept("kw", "AND"):
            e = ("bin", "AND", e, self._relation())
        return e

    def _relation(self) -> Node:
        e = self._simple()
        if self._tok.kind == "op" and self._tok.value in _RELOPS:
            op = str(self._expect("op").value)
            e = ("bin", op, e, self._simple())
        return e

    def _simple(self) -> Node:
        if self._tok.kind == "op" and self._tok.value in ("+", "-"):
            op = str(self._expect("op").value)
            e: Node = ("un", op, self._product())
        else:
            e = self._product()
        while self._tok.kind == "op" and self._tok.value in ("+", "-"):
            op = str(self._expect("op").value)
            e = ("bin", op, e, self._product())
        return e

    def _product(self) -> Node:
        e = self._primary()
        while (self._tok.kind == "op" and self._tok.value in ("*", "/")) \
                or self._at_kw("DIV", "MOD"):
            op = str(self.toks[self.i].value)
            self.i += 1
            e = ("bin", op, e, self._primary())
        return e

    def _primary(self) -> Node:
        t = self._tok
        if t.kind == "num":
            self.i += 1
            return ("num", t.value)
        if t.kind == "str":
            self.i += 1
            return ("str", t.value)
        if self._accept("kw", "TRUE"):
            return ("bool", True)
        if self._accept("kw", "FALSE"):
            return ("bool", False)
        if self._accept("op", "("):
            e = self._expr()
            self._expect("op", ")")
            return e
        if self._accept("op", "["):
            items = [self._expr()]
            while self._accept("op", ","):
                items.append(self._expr())
            self._expect("op", "]")
            return ("agg", items)
        if t.kind == "name":
            name = self._name()
            if self._accept("op", "("):
                args = self._args(")")
                self._expect("op", ")")
                return ("call", name, args, t.line)
            return self._postfix(("var", name))
        raise self._fail("an expression")

    def _postfix(self, e: Node) -> Node:
        while True:
            if self._accept("op", "{"):
                idx = [self._expr()]
                while self._accept("op", ","):
                    idx.append(self._expr())
                self._expect("op", "}")
                e = ("idx", e, idx)
            elif self._accept("op", "."):
                e = ("comp", e, self._name())
            else:
                return e


def parse_module(text: str, filename: str = "<rapid>") -> Node:
    """The tree of one RAPID module; :class:`RapidLoadError` with file and line when bad."""
    return Parser(text, filename).module()
