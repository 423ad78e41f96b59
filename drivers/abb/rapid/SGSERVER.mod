%%%
  VERSION:1
  LANGUAGE:ENGLISH
%%%

MODULE SGSERVER
  !
  ! seamguide robot link server for the ABB S4 controller, protocol SGRS/1.
  ! The protocol is docs/protocol.md of the seamguide repository; the mock controller
  ! (drivers/mock_controller.py) speaks it byte for byte like this module.
  !
  ! Line format:  kind seq SP body "*" chk LF   (at most 80 characters before LF)
  ! Checksum: Fletcher-16 modulo 255 over everything before "*", as 4 hex digits
  ! (s2 then s1), computed with DIV and MOD only.
  !
  ! Requires: a serial channel "sio1:" (8N1, 9600 or 19200 baud, no handshake,
  ! configured in the system parameters), digital output doWeld (arc on) and digital
  ! input diCycleReq (operator asks for a cycle; job name in sg_job).
  ! See docs/rapid-install.md. NOT yet run on a controller: check it on yours first.
  !
  CONST num CAPACITY := 250;
  ! printable ASCII 32..79 and 80..126, for the character codes (no Ord() on S4)
  CONST string PRINT1 := " !""#$%&'()*+,-./0123456789:;<=>?@ABCDEFGHIJKLMNO";
  CONST string PRINT2 := "PQRSTUVWXYZ[\\]^_`abcdefghijklmnopqrstuvwxyz{|}~";
  CONST string HEX := "0123456789ABCDEF";
  CONST string DIGITS := "0123456789";
  ! set FALSE on BaseWare without CalcJointT: unreachable targets then stop the program
  CONST bool PRECHECK := TRUE;

  PERS num sg_boot := 0;
  PERS string sg_job := "job1";
  PERS tooldata sgtool := [TRUE,[[0,0,0],[1,0,0,0]],[5,[0,0,100],[1,0,0,0],0,0,0]];

  VAR iodev ch;
  VAR intnum int_cyc;
  VAR bool cyc_flag := FALSE;
  VAR string cyc := "-";

  VAR num session := 0;
  VAR num last_seq := -1;
  VAR string last_reply := "";
  VAR num ev_seq := 0;

  VAR string f{10};
  VAR num nf := 0;
  VAR num rseq := 0;

  VAR speeddata sgspeed := [100,500,5000,1000];
  VAR zonedata sgzone := fine;
  VAR robtarget slots{251};
  VAR bool havepos{251};
  VAR bool haverot{251};
  VAR num path_n := 0;
  VAR robtarget snap;
  VAR jointtarget jt;

  ! motion state
  VAR num mid := 0;
  VAR num last_mid := 0;
  VAR string mstate := "I";
  VAR string mkind := "";
  VAR num pidx := 0;
  VAR num err := 0;
  VAR num arc := 0;

  PROC main()
    sg_boot := sg_boot + 1;
    SetDO doWeld, 0;
    ConfL \Off;
    ConfJ \Off;
    IDelete int_cyc;
    CONNECT int_cyc WITH t_cycle;
    ISignalDI diCycleReq, 1, int_cyc;
    Close ch;
    Open "sio1:", ch \Bin;
    WHILE TRUE DO
      ServeOnce 0.2;
      IF mstate = "R" RunMotion;
    ENDWHILE
  ERROR
    IF ERRNO = ERR_FILEACC THEN
      ! Close of a channel that was not open
      TRYNEXT;
    ENDIF
  ENDPROC

  TRAP t_cycle
    cyc := sg_job;
    cyc_flag := TRUE;
  ENDTRAP

  ! ---- characters, checksum, framing ---------------------------------------------

  FUNC num CharCode(string c)
    VAR num p;
    p := StrMatch(PRINT1, 1, c);
    IF p <= StrLen(PRINT1) RETURN 31 + p;
    p := StrMatch(PRINT2, 1, c);
    IF p <= StrLen(PRINT2) RETURN 79 + p;
    RETURN -1;
  ENDFUNC

  FUNC string Hex2(num n)
    RETURN StrPart(HEX, (n DIV 16) + 1, 1) + StrPart(HEX, (n MOD 16) + 1, 1);
  ENDFUNC

  ! Fletcher-16 (mod 255) as 4 hex digits; "" when a character is not printable
  FUNC string Checksum(string s)
    VAR num s1 := 0;
    VAR num s2 := 0;
    VAR num c;
    FOR i FROM 1 TO StrLen(s) DO
      c := CharCode(StrPart(s, i, 1));
      IF c < 0 RETURN "";
      s1 := (s1 + c) MOD 255;
      s2 := (s2 + s1) MOD 255;
    ENDFOR
    RETURN Hex2(s2) + Hex2(s1);
  ENDFUNC

  FUNC string Two(num n)
    IF n < 10 RETURN "0" + NumToStr(n, 0);
    RETURN NumToStr(n, 0);
  ENDFUNC

  PROC SendLine(string kind, num seq, string body)
    VAR string head;
    head := kind + Two(seq) + " " + body;
    WriteStrBin ch, head + "*" + Checksum(head) + "\0A";
  ENDPROC

  PROC Reply(num seq, string body)
    IF seq > 0 AND session > 0 THEN
      last_seq := seq;
      last_reply := body;
    ENDIF
    SendLine "A", seq, body;
  ENDPROC

  PROC Event(string body)
    ev_seq := (ev_seq + 1) MOD 100;
    SendLine "E", ev_seq, body;
  ENDPROC

  ! Reads one line (without LF) into ln; FALSE when nothing came within t seconds.
  ! A line longer than 80 characters is read to its LF and returned as "" (a bad line).
  FUNC bool ReadLine(INOUT string ln, num t)
    VAR string c;
    VAR bool over := FALSE;
    ln := "";
    c := ReadStrBin(ch, 1 \Time:=t);
    WHILE c <> "\0A" DO
      IF c <> "\0D" THEN
        IF StrLen(ln) >= 80 THEN
          over := TRUE;
        ELSE
          ln := ln + c;
        ENDIF
      ENDIF
      c := ReadStrBin(ch, 1 \Time:=1);
    ENDWHILE
    IF over ln := "";
    RETURN TRUE;
  ERROR
    IF ERRNO = ERR_DEV_MAXTIME THEN
      ! nothing (more) arrived: a partial line is a bad line
      IF StrLen(ln) > 0 THEN
        ln := "";
        RETURN TRUE;
      ENDIF
      RETURN FALSE;
    ENDIF
  ENDFUNC

  FUNC bool IsInt(string s)
    IF StrLen(s) < 1 OR StrLen(s) > 4 RETURN FALSE;
    RETURN StrMemb(s, 1, DIGITS) AND StrFind(s, 1, DIGITS \NotInSet) > StrLen(s);
  ENDFUNC

  ! Decodes a request line into rseq and the fields f{1..nf}; FALSE when it is bad.
  FUNC bool Decode(string ln)
    VAR num n;
    VAR num p;
    VAR num q;
    VAR string head;
    VAR string body;
    n := StrLen(ln);
    IF n < 10 RETURN FALSE;
    IF StrPart(ln, n - 4, 1) <> "*" RETURN FALSE;
    head := StrPart(ln, 1, n - 5);
    IF StrFind(head, 1, "*") <= StrLen(head) RETURN FALSE;
    IF Checksum(head) <> StrPart(ln, n - 3, 4) RETURN FALSE;
    IF StrPart(head, 1, 1) <> "Q" OR StrPart(head, 4, 1) <> " " RETURN FALSE;
    IF NOT IsInt(StrPart(head, 2, 2)) RETURN FALSE;
    IF NOT StrToVal(StrPart(head, 2, 2), rseq) RETURN FALSE;
    IF rseq = 0 RETURN FALSE;
    body := StrPart(head, 5, StrLen(head) - 4);
    nf := 0;
    p := 1;
    WHILE p <= StrLen(body) DO
      q := StrFind(body, p, " ");
      IF q = p OR nf >= 10 RETURN FALSE;
      nf := nf + 1;
      f{nf} := StrPart(body, p, q - p);
      p := q + 1;
      IF q = StrLen(body) RETURN FALSE;
    ENDWHILE
    RETURN nf > 0;
  ENDFUNC

  ! ---- requests --------------------------------------------------------------------

  PROC ServeOnce(num t)
    VAR string ln;
    VAR string body;
    IF cyc_flag THEN
      cyc_flag := FALSE;
      Event "CY " + cyc;
    ENDIF
    IF NOT ReadLine(ln, t) RETURN;
    IF NOT Decode(ln) THEN
      SendLine "A", 0, "ER 10 bad line";
      RETURN;
    ENDIF
    IF session > 0 AND rseq = last_seq THEN
      ! duplicate: the remembered reply, never a second execution
      SendLine "A", rseq, last_reply;
      RETURN;
    ENDIF
    body := Execute();
    Reply rseq, body;
  ENDPROC

  FUNC bool Num(num i, INOUT num v)
    IF i > nf RETURN FALSE;
    RETURN StrToVal(f{i}, v);
  ENDFUNC

  FUNC bool Slot(num i, INOUT num k)
    IF NOT IsInt(f{i}) RETURN FALSE;
    RETURN StrToVal(f{i}, k);
  ENDFUNC

  FUNC string Execute()
    VAR string c;
    VAR num a;
    VAR num b;
    VAR num x;
    VAR num y;
    VAR num z;
    VAR num w;
    c := f{1};
    IF c = "HI" THEN
      IF nf <> 2 OR NOT Slot(2, a) RETURN "ER 12 bad arguments to HI";
      IF a < 1 OR a > 999 RETURN "ER 12 bad arguments to HI";
      IF a <> session THEN
        session := a;
        last_seq := -1;
        last_mid := 0;
      ENDIF
      RETURN "OK " + NumToStr(sg_boot, 0) + " " + NumToStr(mid, 0) + " " + mstate;
    ENDIF
    IF c = "ID" RETURN "OK SGRS 1 IRB2400 " + NumToStr(CAPACITY, 0);
    IF c = "ST" THEN
      RETURN "OK " + Bool01(mstate = "R") + " " + NumToStr(arc, 0) + " " + NumToStr(mid, 0)
        + " " + mstate + " " + NumToStr(pidx, 0) + " " + NumToStr(err, 0) + " " + cyc;
    ENDIF
    IF session = 0 RETURN "ER 13 no session";
    IF c = "RJ" THEN
      jt := CJointT();
      RETURN "OK " + NumToStr(jt.robax.rax_1, 4) + " " + NumToStr(jt.robax.rax_2, 4) + " "
        + NumToStr(jt.robax.rax_3, 4) + " " + NumToStr(jt.robax.rax_4, 4) + " "
        + NumToStr(jt.robax.rax_5, 4) + " " + NumToStr(jt.robax.rax_6, 4);
    ENDIF
    IF c = "RP" THEN
      snap := CRobT(\Tool:=tool0 \WObj:=wobj0);
      RETURN "OK " + NumToStr(snap.trans.x, 3) + " " + NumToStr(snap.trans.y, 3) + " "
        + NumToStr(snap.trans.z, 3);
    ENDIF
    IF c = "RQ" THEN
      RETURN "OK " + NumToStr(snap.rot.q1, 6) + " " + NumToStr(snap.rot.q2, 6) + " "
        + NumToStr(snap.rot.q3, 6) + " " + NumToStr(snap.rot.q4, 6);
    ENDIF
    IF c = "TP" THEN
      IF nf <> 4 OR NOT (Num(2, x) AND Num(3, y) AND Num(4, z)) RETURN "ER 12 bad arguments to TP";
      sgtool.tframe.trans := [x, y, z];
      RETURN "OK";
    ENDIF
    IF c = "TO" THEN
      IF nf <> 5 OR NOT (Num(2, w) AND Num(3, x) AND Num(4, y) AND Num(5, z)) RETURN "ER 12 bad arguments to TO";
      sgtool.tframe.rot := [w, x, y, z];
      RETURN "OK";
    ENDIF
    IF c = "SV" THEN
      IF nf <> 3 OR NOT (Num(2, a) AND Num(3, b)) RETURN "ER 12 bad arguments to SV";
      IF a <= 0 OR a > 1000 OR b < 0 OR b > 200 RETURN "ER 50 speed or zone out of range";
      sgspeed.v_tcp := a;
      IF b = 0 THEN
        sgzone := fine;
      ELSE
        sgzone := [FALSE, b, 1.5 * b, 1.5 * b, 0.15 * b, 1.5 * b, 0.15 * b];
      ENDIF
      RETURN "OK";
    ENDIF
    IF c = "XP" OR c = "XO" THEN
      IF NOT Slot(2, a) RETURN "ER 12 bad arguments to " + c;
      IF a > CAPACITY RETURN "ER 24 slot out of range";
      IF c = "XP" THEN
        IF nf <> 5 OR NOT (Num(3, x) AND Num(4, y) AND Num(5, z)) RETURN "ER 12 bad arguments to XP";
        slots{a + 1}.trans := [x, y, z];
        slots{a + 1}.robconf := [0, 0, 0, 0];
        slots{a + 1}.extax := [9E9, 9E9, 9E9, 9E9, 9E9, 9E9];
        havepos{a + 1} := TRUE;
      ELSE
        IF nf <> 6 OR NOT (Num(3, w) AND Num(4, x) AND Num(5, y) AND Num(6, z)) RETURN "ER 12 bad arguments to XO";
        IF Abs(Sqrt(w * w + x * x + y * y + z * z) - 1) > 0.001 RETURN "ER 12 bad arguments to XO";
        slots{a + 1}.rot := [w, x, y, z];
        haverot{a + 1} := TRUE;
      ENDIF
      RETURN "OK";
    ENDIF
    IF c = "XR" THEN
      ! orientation of slot k = that of slot k - 1 (path points only)
      IF nf <> 2 OR NOT Slot(2, a) RETURN "ER 12 bad arguments to XR";
      IF a > CAPACITY RETURN "ER 24 slot out of range";
      IF a < 2 RETURN "ER 21 no orientation to repeat";
      IF NOT haverot{a} RETURN "ER 21 no orientation to repeat";
      slots{a + 1}.rot := slots{a}.rot;
      haverot{a + 1} := TRUE;
      RETURN "OK";
    ENDIF
    IF c = "PN" THEN
      IF nf <> 2 OR NOT Slot(2, a) OR a < 1 RETURN "ER 12 bad arguments to PN";
      IF a > CAPACITY RETURN "ER 23 path of " + NumToStr(a, 0) + " exceeds buffer " + NumToStr(CAPACITY, 0);
      FOR i FROM 2 TO CAPACITY + 1 DO
        havepos{i} := FALSE;
        haverot{i} := FALSE;
      ENDFOR
      path_n := a;
      RETURN "OK " + NumToStr(a, 0);
    ENDIF
    IF c = "CK" THEN
      cyc := "-";
      RETURN "OK";
    ENDIF
    IF c = "AB" THEN
      Abort;
      RETURN "OK";
    ENDIF
    IF c = "MJ" OR c = "ML" OR c = "RW" RETURN Motion(c);
    RETURN "ER 11 unknown request " + c;
  ENDFUNC

  FUNC string Bool01(bool b)
    IF b RETURN "1";
    RETURN "0";
  ENDFUNC

  ! Checks and accepts a motion; RunMotion (from main) executes it.
  FUNC string Motion(string c)
    VAR num m;
    VAR num a;
    VAR num v{6};
    IF NOT Slot(2, m) OR m < 1 RETURN "ER 12 bad arguments to " + c;
    IF mstate = "R" RETURN "ER 20 busy: a motion is running";
    IF m = last_mid RETURN "ER 25 motion " + NumToStr(m, 0) + " already executed";
    IF c = "MJ" THEN
      IF nf <> 8 RETURN "ER 12 bad arguments to MJ";
      FOR i FROM 1 TO 6 DO
        IF NOT Num(i + 2, a) RETURN "ER 12 bad arguments to MJ";
        v{i} := a;
      ENDFOR
      ! IRB 2400 axis limits (product specification)
      IF Abs(v{1}) > 180 OR v{2} < -100 OR v{2} > 110 OR v{3} < -60 OR v{3} > 65
        OR Abs(v{4}) > 200 OR Abs(v{5}) > 120 OR Abs(v{6}) > 400 RETURN "ER 31 joints outside limits";
      jt.robax := [v{1}, v{2}, v{3}, v{4}, v{5}, v{6}];
      jt.extax := [9E9, 9E9, 9E9, 9E9, 9E9, 9E9];
    ELSEIF c = "ML" THEN
      IF nf <> 2 RETURN "ER 12 bad arguments to ML";
      IF NOT (havepos{1} AND haverot{1}) RETURN "ER 21 target slot 0 incomplete";
      IF NOT Reachable(slots{1}) RETURN "ER 30 target unreachable";
      havepos{1} := FALSE;
      haverot{1} := FALSE;
    ELSE
      IF nf <> 3 OR NOT Slot(3, a) OR a > 1 RETURN "ER 12 bad arguments to RW";
      IF path_n = 0 RETURN "ER 22 path incomplete";
      FOR i FROM 2 TO path_n + 1 DO
        IF NOT (havepos{i} AND haverot{i}) RETURN "ER 22 path incomplete";
      ENDFOR
      FOR i FROM 2 TO path_n + 1 DO
        IF NOT Reachable(slots{i}) RETURN "ER 30 path point " + NumToStr(i - 1, 0) + " unreachable";
      ENDFOR
      arc := a;
    ENDIF
    mid := m;
    last_mid := m;
    mkind := c;
    mstate := "R";
    pidx := 0;
    err := 0;
    RETURN "OK " + NumToStr(m, 0);
  ENDFUNC

  FUNC bool Reachable(robtarget t)
    VAR jointtarget j;
    IF NOT PRECHECK RETURN TRUE;
    j := CalcJointT(t, sgtool \WObj:=wobj0);
    RETURN TRUE;
  ERROR
    IF ERRNO = ERR_ROBLIMIT RETURN FALSE;
  ENDFUNC

  ! ---- motion --------------------------------------------------------------------------

  PROC Abort()
    ! arc output off FIRST, then stop the robot and throw the rest of the path away
    SetDO doWeld, 0;
    arc := 0;
    IF mstate = "R" THEN
      StopMove;
      ClearPath;
      StartMove;
      mstate := "A";
      err := 41;
      Event "FL " + NumToStr(mid, 0) + " 41 " + NumToStr(pidx + 1, 0);
    ENDIF
  ENDPROC

  FUNC bool JointsAt(jointtarget t)
    VAR jointtarget c;
    c := CJointT();
    RETURN Abs(c.robax.rax_1 - t.robax.rax_1) < 0.01 AND Abs(c.robax.rax_2 - t.robax.rax_2) < 0.01
      AND Abs(c.robax.rax_3 - t.robax.rax_3) < 0.01 AND Abs(c.robax.rax_4 - t.robax.rax_4) < 0.01
      AND Abs(c.robax.rax_5 - t.robax.rax_5) < 0.01 AND Abs(c.robax.rax_6 - t.robax.rax_6) < 0.01;
  ENDFUNC

  FUNC bool PoseAt(robtarget t)
    VAR robtarget c;
    c := CRobT(\Tool:=sgtool \WObj:=wobj0);
    RETURN Distance(c.trans, t.trans) < 0.05;
  ENDFUNC

  PROC RunMotion()
    VAR num i;
    VAR robtarget target;
    IF mkind = "MJ" THEN
      MoveAbsJ \Conc, jt, sgspeed, fine, tool0;
      WHILE mstate = "R" AND NOT JointsAt(jt) DO
        ServeOnce 0.05;
      ENDWHILE
      IF mstate = "R" THEN
        mstate := "D";
        Event "IP " + NumToStr(mid, 0);
      ENDIF
    ELSEIF mkind = "ML" THEN
      target := slots{1};
      MoveL \Conc, target, sgspeed, fine, sgtool \WObj:=wobj0;
      WHILE mstate = "R" AND NOT PoseAt(target) DO
        ServeOnce 0.05;
      ENDWHILE
      IF mstate = "R" THEN
        mstate := "D";
        Event "IP " + NumToStr(mid, 0);
      ENDIF
    ELSE
      ! the weld: a MoveL per point; the program runs about one point ahead of the robot,
      ! so point i - 1 is reached when MoveL to point i returns. Requests are served
      ! between points, so AB stops the weld within one segment.
      IF arc = 1 SetDO doWeld, 1;
      i := 1;
      WHILE i <= path_n AND mstate = "R" DO
        IF i = path_n THEN
          MoveL slots{i + 1}, sgspeed, fine, sgtool \WObj:=wobj0;
        ELSE
          MoveL slots{i + 1}, sgspeed, sgzone, sgtool \WObj:=wobj0;
        ENDIF
        IF mstate = "R" AND i > 1 THEN
          pidx := i - 1;
          Event "PG " + NumToStr(mid, 0) + " " + NumToStr(pidx, 0);
        ENDIF
        ServeOnce 0.01;
        i := i + 1;
      ENDWHILE
      IF mstate = "R" THEN
        pidx := path_n;
        Event "PG " + NumToStr(mid, 0) + " " + NumToStr(pidx, 0);
        SetDO doWeld, 0;
        arc := 0;
        mstate := "D";
        Event "DN " + NumToStr(mid, 0);
      ENDIF
    ENDIF
  ERROR
    ! a recoverable motion error: arc off first, then stop, report the point
    SetDO doWeld, 0;
    arc := 0;
    StopMove;
    ClearPath;
    StartMove;
    mstate := "F";
    err := 40;
    Event "FL " + NumToStr(mid, 0) + " 40 " + NumToStr(pidx + 1, 0);
    RETURN;
  ENDPROC
ENDMODULE
