"""The RAPID interpreter (drivers/rapid_vm) on small programs: the kernel rules it enforces and the
ones the server relies on (each test can fail: it names the behaviour a wrong interpreter has)."""

from __future__ import annotations

import pytest

from drivers.rapid_vm.builtins_core import CORE_FUNCTIONS
from drivers.rapid_vm.errors import RapidLoadError, RapidStop
from drivers.rapid_vm.machine import ERRORS_S4
from drivers.rapid_vm.program import Program
from drivers.rapid_vm.values import f32


def run(src: str, entry: str = "main") -> Program:
    p = Program(dict(CORE_FUNCTIONS), ERRORS_S4, {"doweld": "signaldo"})
    p.load(f"MODULE T\n{src}\nENDMODULE\n", "T.mod")
    p.link()
    p.run(entry)
    return p


def test_num_is_single_precision():
    p = run("VAR num a := 16777216;\nVAR num b;\nVAR num c;\n"
            "PROC main()\n b := a + 1;\n c := 0.1 + 0.2;\nENDPROC")
    assert p.globals["b"] == 16777216.0  # 2^24 + 1 is not a single-precision number
    assert p.globals["c"] == f32(f32(0.1) + f32(0.2)) != 0.1 + 0.2


def test_a_string_over_80_characters_stops_the_program():
    src = ('VAR string s := "{}";\nPROC main()\n s := s + "x";\nERROR\n RETURN;\nENDPROC')
    run(src.format("a" * 79))  # 80 characters: fine
    with pytest.raises(RapidStop, match="81 characters"):  # no handler can catch it
        run(src.format("a" * 80))
    with pytest.raises(RapidLoadError, match="81 characters"):
        run(f'CONST string s := "{"b" * 81}";\nPROC main()\nENDPROC')


def test_not_is_only_at_the_start_of_an_expression():
    with pytest.raises(RapidLoadError, match="T.mod:4: expected an expression, found 'NOT'"):
        run("VAR bool a;\nPROC main()\n IF a OR NOT a a := TRUE;\nENDPROC")
    p = run("VAR bool a;\nVAR bool b;\nPROC main()\n b := a OR (NOT a);\nENDPROC")
    assert p.globals["b"] is True


def test_names_are_case_insensitive_and_a_routine_named_like_a_type_does_not_load():
    with pytest.raises(RapidLoadError, match="name clash.*'num'"):
        run("FUNC bool Num(num i)\n RETURN TRUE;\nENDFUNC\nPROC main()\nENDPROC")
    p = run("VAR NUM Count := 1;\nPROC main()\n COUNT := count + 1;\nENDPROC")
    assert p.globals["count"] == 2.0


def test_unknown_names_are_load_errors():
    with pytest.raises(RapidLoadError, match="T.mod:4: reference error: unknown function "
                                             "'calcjointt'"):
        run("VAR num x;\nPROC main()\n x := CalcJointT(1);\nENDPROC")
    with pytest.raises(RapidLoadError, match="unknown data 'err_roblimit'"):
        run("VAR num x;\nPROC main()\n x := ERR_ROBLIMIT;\nENDPROC")


def test_and_or_evaluate_both_sides():
    src = ("VAR num a{2};\nVAR bool b;\nVAR num i := 3;\n"
           "PROC main()\n b := i > 2 OR a{i} > 0;\nENDPROC")
    with pytest.raises(RapidStop, match="index 3.0 outside 1..2"):
        run(src)


def test_error_handler_retry_trynext_and_raise_to_the_caller():
    p = run("""VAR num tries := 0;
VAR num d := 0;
VAR num after := 0;
VAR num outer := 0;
PROC inner()
  after := after / 0;
ENDPROC
PROC main()
  after := 10 / d;
  inner;
  outer := outer + 1;
ERROR
  IF ERRNO = ERR_DIVZERO AND tries < 2 THEN
    tries := tries + 1;
    d := 5;
    RETRY;
  ENDIF
  outer := outer + 100;
  TRYNEXT;
ENDPROC""")
    # 10 / 0 fails, the handler fixes d and RETRY runs the statement again (2); inner has no
    # handler, so its error comes to main's at the call: one more RETRY of the call, then TRYNEXT
    # goes on after it
    assert (p.globals["tries"], p.globals["after"], p.globals["outer"]) == (2.0, 2.0, 101.0)


def test_retry_gives_up_after_four_tries():
    with pytest.raises(RapidStop, match="unhandled error"):
        run("VAR num n := 0;\nPROC main()\n n := 1 / 0;\nERROR\n n := n + 1;\n RETRY;\nENDPROC")


def test_a_function_handler_that_runs_off_its_end_stops_the_program():
    src = """VAR num r;
FUNC num F()
  RETURN 1 / 0;
ERROR
  IF ERRNO = {} RETURN -1;
ENDFUNC
PROC main()
  r := F();
ENDPROC"""
    assert run(src.format("ERR_DIVZERO")).globals["r"] == -1.0
    with pytest.raises(RapidStop, match="ended without RETURN or RAISE"):
        run(src.format("ERR_FILEACC"))


def test_late_binding_of_a_missing_procedure_is_a_recoverable_error():
    p = run("""VAR num r := 0;
PROC Present()
  r := r + 1;
ENDPROC
PROC main()
  %"Present"%;
  %"Absent"%;
  r := r + 10;
ERROR
  IF ERRNO = ERR_REFUNKPRC TRYNEXT;
  RAISE;
ENDPROC""")
    assert p.globals["r"] == 11.0


def test_for_while_test_and_records():
    p = run("""VAR pos p;
VAR robtarget t;
VAR string s := "";
PROC main()
  VAR num k := 0;
  FOR i FROM 1 TO 3 DO
    k := k + i;
  ENDFOR
  FOR i FROM 3 TO 1 DO
    s := s + NumToStr(i, 0);
  ENDFOR
  WHILE k < 100 DO
    k := k * 2;
  ENDWHILE
  TEST k
  CASE 1, 2:
    s := s + "small";
  DEFAULT:
    s := s + "big" + NumToStr(k, 0);
  ENDTEST
  t.trans := [1, 2, 3];
  p := t.trans;
  p.x := 9;
ENDPROC""")
    assert p.globals["s"] == "321big192"
    assert [p.globals["p"].f[c] for c in "xyz"] == [9.0, 2.0, 3.0]
    assert p.globals["t"].f["trans"].f["x"] == 1.0  # assignment copied the record


def test_string_functions_as_the_reference_describes():
    p = run("""VAR num a;
VAR num b;
VAR num c;
VAR bool ok;
VAR bool bad;
VAR num v;
VAR string s;
PROC main()
  a := StrFind("AB12", 1, "0123456789");
  b := StrFind("1234", 1, "0123456789" \\NotInSet);
  c := StrMatch("HI ID ST", 1, "ST");
  ok := StrToVal("-12.5", v);
  bad := StrToVal("12x", v);
  s := NumToStr(2.5, 0) + " " + NumToStr(-0.00001, 3) + " " + StrPart("ABCDE", 2, 3);
ENDPROC""")
    g = p.globals
    assert (g["a"], g["b"], g["c"]) == (3.0, 5.0, 7.0)
    assert g["ok"] and not g["bad"] and g["v"] == -12.5
    assert g["s"] == "3 0.000 BCD"
    with pytest.raises(RapidStop, match="StrPart"):
        run('VAR string s;\nPROC main()\n s := StrPart("ABC", 2, 3);\nENDPROC')


def test_trap_runs_between_statements_after_an_interrupt():
    p = Program(dict(CORE_FUNCTIONS), ERRORS_S4, {})
    p.load("""MODULE T
VAR intnum irq;
VAR num hits := 0;
VAR num loops := 0;
TRAP t_irq
  hits := hits + 1;
ENDTRAP
PROC main()
  CONNECT irq WITH t_irq;
  WHILE loops < 5 DO
    loops := loops + 1;
  ENDWHILE
ENDPROC
ENDMODULE""", "T.mod")
    p.link()
    p.probes = {}
    p.interrupt(1.0)  # not connected yet: ignored
    p.run()
    assert p.globals["hits"] == 0
    p.interrupt(p.globals["irq"])
    p.run()  # main again: a new CONNECT, and the interrupt ordered before is served
    assert p.globals["hits"] == 1
