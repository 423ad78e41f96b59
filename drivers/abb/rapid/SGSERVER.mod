%%%
  VERSION:1
  LANGUAGE:ENGLISH
%%%

MODULE SGSERVER
  !
  ! seamguide robot link server for the ABB S4 controller, protocol SGRS/1.
  ! The protocol is docs/protocol.md of the seamguide repository; the mock controller
  ! (drivers/mock/) speaks it like this module, and the tests run this module itself
  ! in a RAPID interpreter (drivers/rapid_vm/) through the client's contract tests.
  !
  ! Line format:  kind seq SP body "*" chk LF   (at most 80 characters before LF)
  ! Checksum: Fletcher-16 modulo 255 over everything before "*", as 4 hex digits
  ! (s2 then s1), computed with DIV and MOD only.
  !
  ! Only instructions of the S4 BaseWare RAPID reference are used; docs/rapid-install.md
  ! lists each one with where it is documented. Anything newer (CalcJointT, ERR_ROBLIMIT)
  ! is in the optional module SGREACH.mod, called by late binding (see Reachable), so
  ! this module loads without it.
  !
  ! Requires (load time): a serial channel "sio1:" (8N1, 9600 or 19200 baud, no
  ! handshake, configured in the system parameters), digital output doWeld (arc on) and
  ! digital input diCycleReq (operator asks for a cycle; job name in sg_job).
  ! See docs/rapid-install.md. NOT yet run on a controller: check it on yours first.
  !
  ! No string here can grow past the 80 characters of a RAPID string: every string that
  ! is built from received or operator data has its length checked before it is joined.
  !
  CONST num CAPACITY := 250;
  ! printable ASCII 32..79 and 80..126: character <-> code (no Ord()/Chr() on S4)
  CONST string PRINT1 := " !""#$%&'()*+,-./0123456789:;<=>?@ABCDEFGHIJKLMNO";
  CONST string PRINT2 := "PQRSTUVWXYZ[\\]^_`abcdefghijklmnopqrstuvwxyz{|}~";
  CONST string HEX := "0123456789ABCDEF";
  CONST string DIGITS := "0123456789";
  CONST string JOBCHARS := "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789_";
  ! the requests this server knows, each between spaces
  CONST string REQUESTS := " HI ID ST RJ RP RQ TP TO SV XP XO XR XT XC PN CK AB MJ ML MT RW ";
  ! longest body that fits a line: 80 - "A12 " - "*ABCD"
  CONST num MAXBODY := 71;

  PERS num sg_boot := 0;
  PERS string sg_job := "job1";
  PERS tooldata sgtool := [TRUE,[[0,0,0],[1,0,0,0]],[5,[0,0,100],[1,0,0,0],0,0,0]];

  ! shared with the optional module SGREACH (reachability pre-check)
  VAR robtarget sg_target;
  VAR bool sg_reach := TRUE;

  VAR iodev ch;
  VAR intnum int_cyc;
  VAR bool cyc_flag := FALSE;
  VAR string cyc := "-";

  VAR num session := 0;
  VAR num last_seq := -1;
  VAR string last_reply := "";
  VAR num ev_seq := 0;

  ! the line read: its character codes lc{1..nlc}; the fields of a request f{1..nf}
  ! (nf = 13: more than 12 fields)
  VAR num lc{80};
  VAR num nlc := 0;
  VAR num tx{86};
  VAR string f{12};
  VAR num nf := 0;
  VAR num rseq := 0;

  VAR speeddata sgspeed := [100,500,5000,1000];
  VAR zonedata sgzone := fine;
  VAR robtarget slots{251};
  VAR bool havepos{251};
  VAR bool haverot{251};
  ! the circle point of a path point reached by MoveC (XC); the robtarget circ is made from it
  ! and the point's orientation when the move is issued
  VAR pos circs{251};
  VAR bool havecirc{251};
  VAR num ncirc := 0;
  VAR robtarget circ;
  VAR num path_n := 0;
  VAR robtarget snap;
  VAR bool havesnap := FALSE;
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
    ! anything else stops the program with the error on the teach pendant
    RAISE;
  ENDPROC

  TRAP t_cycle
    ! the protocol's job name is 1..16 of [A-Za-z0-9_]; anything else is refused here,
    ! so the CY event and the ST reply stay within a line
    IF JobOk(sg_job) THEN
      cyc := sg_job;
      cyc_flag := TRUE;
    ELSE
      TPWrite "seamguide: sg_job must be 1-16 letters, digits or _";
    ENDIF
  ENDTRAP

  FUNC bool JobOk(string s)
    IF StrLen(s) < 1 OR StrLen(s) > 16 RETURN FALSE;
    RETURN StrFind(s, 1, JOBCHARS \NotInSet) > StrLen(s);
  ENDFUNC

  ! ---- characters, checksum, framing ---------------------------------------------

  ! code of a printable character, -1 for any other
  FUNC num CharCode(string c)
    VAR num p;
    p := StrMatch(PRINT1, 1, c);
    IF p <= StrLen(PRINT1) RETURN 31 + p;
    p := StrMatch(PRINT2, 1, c);
    IF p <= StrLen(PRINT2) RETURN 79 + p;
    RETURN -1;
  ENDFUNC

  ! the character of a printable code 32..126
  FUNC string CharOf(num c)
    IF c <= 79 RETURN StrPart(PRINT1, c - 31, 1);
    RETURN StrPart(PRINT2, c - 79, 1);
  ENDFUNC

  FUNC string Hex2(num n)
    RETURN StrPart(HEX, (n DIV 16) + 1, 1) + StrPart(HEX, (n MOD 16) + 1, 1);
  ENDFUNC

  FUNC string Two(num n)
    IF n < 10 RETURN "0" + NumToStr(n, 0);
    RETURN NumToStr(n, 0);
  ENDFUNC

  ! A body that could not go on a line (too long, or a character outside printable
  ! ASCII) is replaced by an error: the line stays readable and the program runs on.
  FUNC string Fit(string body)
    IF StrLen(body) > MAXBODY RETURN "ER 14 reply too long";
    IF StrFind(body, 1, "*") <= StrLen(body) RETURN "ER 14 reply not printable";
    RETURN body;
  ENDFUNC

  ! Writes kind seq SP body "*" chk LF as bytes (WriteBin); the checksum is computed
  ! from the codes written.
  PROC SendLine(string kind, num seq, string body)
    VAR string head;
    VAR num n;
    VAR num s1 := 0;
    VAR num s2 := 0;
    head := kind + Two(seq) + " " + Fit(body);
    n := StrLen(head);
    FOR i FROM 1 TO n DO
      tx{i} := CharCode(StrPart(head, i, 1));
      IF tx{i} < 0 THEN
        SendLine kind, seq, "ER 14 reply not printable";
        RETURN;
      ENDIF
      s1 := (s1 + tx{i}) MOD 255;
      s2 := (s2 + s1) MOD 255;
    ENDFOR
    tx{n + 1} := 42;
    tx{n + 2} := CharCode(StrPart(HEX, (s2 DIV 16) + 1, 1));
    tx{n + 3} := CharCode(StrPart(HEX, (s2 MOD 16) + 1, 1));
    tx{n + 4} := CharCode(StrPart(HEX, (s1 DIV 16) + 1, 1));
    tx{n + 5} := CharCode(StrPart(HEX, (s1 MOD 16) + 1, 1));
    tx{n + 6} := 10;
    WriteBin ch, tx, n + 6;
  ENDPROC

  PROC Reply(num seq, string body)
    VAR string b;
    b := Fit(body);
    IF seq > 0 AND session > 0 THEN
      last_seq := seq;
      last_reply := b;
    ENDIF
    SendLine "A", seq, b;
  ENDPROC

  PROC Event(string body)
    ev_seq := (ev_seq + 1) MOD 100;
    SendLine "E", ev_seq, body;
  ENDPROC

  ! Reads one line (without LF) into ln and its codes into lc{1..nlc}; FALSE when
  ! nothing came within t seconds. A line longer than 80 characters, with a byte
  ! outside printable ASCII, or cut short by a pause of 1 s, is returned as "" (a bad
  ! line); a CR is ignored only just before the LF.
  FUNC bool ReadLine(INOUT string ln, num t)
    VAR num c;
    VAR bool bad := FALSE;
    VAR bool cr := FALSE;
    ln := "";
    nlc := 0;
    c := ReadBin(ch \Time:=t);
    WHILE c <> 10 DO
      IF cr bad := TRUE;
      cr := FALSE;
      IF c = 13 THEN
        cr := TRUE;
      ELSEIF nlc >= 80 OR c < 32 OR c > 126 THEN
        bad := TRUE;
      ELSE
        nlc := nlc + 1;
        lc{nlc} := c;
        ln := ln + CharOf(c);
      ENDIF
      c := ReadBin(ch \Time:=1);
    ENDWHILE
    IF bad ln := "";
    RETURN TRUE;
  ERROR
    IF ERRNO = ERR_DEV_MAXTIME THEN
      ! nothing (more) arrived: a partial line is a bad line
      IF StrLen(ln) > 0 OR bad OR cr THEN
        ln := "";
        RETURN TRUE;
      ENDIF
      RETURN FALSE;
    ENDIF
    RAISE;
  ENDFUNC

  FUNC bool IsInt(string s)
    IF StrLen(s) < 1 OR StrLen(s) > 4 RETURN FALSE;
    RETURN StrFind(s, 1, DIGITS \NotInSet) > StrLen(s);
  ENDFUNC

  ! Decodes the line read (ln, lc) into rseq and the fields f{1..nf}; FALSE when bad.
  FUNC bool Decode(string ln)
    VAR num n;
    VAR num p;
    VAR num q;
    VAR num s1 := 0;
    VAR num s2 := 0;
    VAR string head;
    VAR string body;
    n := StrLen(ln);
    IF n < 10 OR n <> nlc RETURN FALSE;
    IF StrPart(ln, n - 4, 1) <> "*" RETURN FALSE;
    head := StrPart(ln, 1, n - 5);
    IF StrFind(head, 1, "*") <= StrLen(head) RETURN FALSE;
    FOR i FROM 1 TO n - 5 DO
      s1 := (s1 + lc{i}) MOD 255;
      s2 := (s2 + s1) MOD 255;
    ENDFOR
    IF Hex2(s2) + Hex2(s1) <> StrPart(ln, n - 3, 4) RETURN FALSE;
    IF StrPart(head, 1, 1) <> "Q" OR StrPart(head, 4, 1) <> " " RETURN FALSE;
    IF NOT IsInt(StrPart(head, 2, 2)) RETURN FALSE;
    IF NOT StrToVal(StrPart(head, 2, 2), rseq) RETURN FALSE;
    IF rseq = 0 RETURN FALSE;
    body := StrPart(head, 5, StrLen(head) - 4);
    nf := 0;
    p := 1;
    WHILE p <= StrLen(body) DO
      q := StrFind(body, p, " ");
      IF q = p RETURN FALSE;
      IF nf < 12 THEN
        nf := nf + 1;
        f{nf} := StrPart(body, p, q - p);
      ELSE
        nf := 13;
      ENDIF
      p := q + 1;
      IF q = StrLen(body) RETURN FALSE;
    ENDWHILE
    RETURN nf > 0;
  ENDFUNC

  ! ---- requests --------------------------------------------------------------------

  PROC ServeOnce(num t)
    VAR string ln;
    VAR string body;
    VAR num q := 0;
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
    q := rseq;
    body := Execute();
    Reply q, body;
  ERROR
    ! A recoverable error while serving (the serial channel, or a request that raised
    ! in a routine it calls): the request, if one was read, is answered with the error
    ! number, and the caller goes on (a running motion is not stopped by it).
    IF q > 0 Reply q, "ER 15 server error " + NumToStr(ERRNO, 0);
    RETURN;
  ENDPROC

  ! field i as a protocol number (-?d{1,5}(.d{1,6})?, what the client sends) into v
  FUNC bool NumArg(num i, INOUT num v)
    VAR string s;
    VAR num n;
    VAR num p;
    IF i > nf RETURN FALSE;
    s := f{i};
    IF StrPart(s, 1, 1) = "-" THEN
      IF StrLen(s) = 1 RETURN FALSE;
      s := StrPart(s, 2, StrLen(s) - 1);
    ENDIF
    n := StrLen(s);
    p := StrFind(s, 1, ".");
    IF p = 1 OR p > 6 RETURN FALSE;
    IF StrFind(StrPart(s, 1, p - 1), 1, DIGITS \NotInSet) < p RETURN FALSE;
    IF p <= n THEN
      IF n - p < 1 OR n - p > 6 RETURN FALSE;
      IF StrFind(s, p + 1, DIGITS \NotInSet) <= n RETURN FALSE;
    ENDIF
    RETURN StrToVal(f{i}, v);
  ENDFUNC

  ! field i as an unsigned integer of 1..4 digits into k
  FUNC bool IntArg(num i, INOUT num k)
    IF i > nf RETURN FALSE;
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
    IF StrLen(c) <> 2 OR StrMatch(REQUESTS, 1, " " + c + " ") > StrLen(REQUESTS) THEN
      IF StrLen(c) > 8 c := StrPart(c, 1, 8);
      RETURN "ER 11 unknown request " + c;
    ENDIF
    IF c = "HI" THEN
      IF nf <> 2 OR (NOT IntArg(2, a)) RETURN "ER 12 bad arguments to HI";
      IF a < 1 OR a > 999 RETURN "ER 12 bad arguments to HI";
      IF a <> session THEN
        session := a;
        last_seq := -1;
        last_mid := 0;
      ENDIF
      RETURN "OK " + NumToStr(sg_boot, 0) + " " + NumToStr(mid, 0) + " " + mstate;
    ENDIF
    IF c = "ID" THEN
      IF nf <> 1 RETURN "ER 12 bad arguments to ID";
      RETURN "OK SGRS 1 IRB2400 " + NumToStr(CAPACITY, 0);
    ENDIF
    IF c = "ST" THEN
      IF nf <> 1 RETURN "ER 12 bad arguments to ST";
      RETURN "OK " + Bool01(mstate = "R") + " " + NumToStr(arc, 0) + " " + NumToStr(mid, 0)
        + " " + mstate + " " + NumToStr(pidx, 0) + " " + NumToStr(err, 0) + " " + cyc;
    ENDIF
    IF session = 0 RETURN "ER 13 no session";
    IF c = "RJ" THEN
      IF nf <> 1 RETURN "ER 12 bad arguments to RJ";
      jt := CJointT();
      RETURN "OK " + NumToStr(jt.robax.rax_1, 4) + " " + NumToStr(jt.robax.rax_2, 4) + " "
        + NumToStr(jt.robax.rax_3, 4) + " " + NumToStr(jt.robax.rax_4, 4) + " "
        + NumToStr(jt.robax.rax_5, 4) + " " + NumToStr(jt.robax.rax_6, 4);
    ENDIF
    IF c = "RP" THEN
      IF nf <> 1 RETURN "ER 12 bad arguments to RP";
      snap := CRobT(\Tool:=tool0 \WObj:=wobj0);
      havesnap := TRUE;
      RETURN "OK " + NumToStr(snap.trans.x, 3) + " " + NumToStr(snap.trans.y, 3) + " "
        + NumToStr(snap.trans.z, 3);
    ENDIF
    IF c = "RQ" THEN
      IF nf <> 1 RETURN "ER 12 bad arguments to RQ";
      ! no RP before it: the orientation now (as the mock answers)
      IF NOT havesnap snap := CRobT(\Tool:=tool0 \WObj:=wobj0);
      RETURN "OK " + NumToStr(snap.rot.q1, 6) + " " + NumToStr(snap.rot.q2, 6) + " "
        + NumToStr(snap.rot.q3, 6) + " " + NumToStr(snap.rot.q4, 6);
    ENDIF
    IF c = "TP" THEN
      IF nf <> 4 OR (NOT (NumArg(2, x) AND NumArg(3, y) AND NumArg(4, z))) RETURN "ER 12 bad arguments to TP";
      sgtool.tframe.trans := [x, y, z];
      RETURN "OK";
    ENDIF
    IF c = "TO" THEN
      IF nf <> 5 OR (NOT (NumArg(2, w) AND NumArg(3, x) AND NumArg(4, y) AND NumArg(5, z))) RETURN "ER 12 bad arguments to TO";
      IF Abs(Sqrt(w * w + x * x + y * y + z * z) - 1) > 0.001 RETURN "ER 12 bad arguments to TO";
      sgtool.tframe.rot := [w, x, y, z];
      RETURN "OK";
    ENDIF
    IF c = "SV" THEN
      IF nf <> 3 OR (NOT (NumArg(2, a) AND NumArg(3, b))) RETURN "ER 12 bad arguments to SV";
      IF a <= 0 OR a > 1000 OR b < 0 OR b > 200 RETURN "ER 50 speed or zone out of range";
      sgspeed.v_tcp := a;
      IF b = 0 THEN
        sgzone := fine;
      ELSE
        sgzone := [FALSE, b, 1.5 * b, 1.5 * b, 0.15 * b, 1.5 * b, 0.15 * b];
      ENDIF
      RETURN "OK";
    ENDIF
    IF c = "XP" OR c = "XO" OR c = "XR" OR c = "XT" RETURN Target(c);
    IF c = "XC" RETURN Circle();
    IF c = "MT" RETURN MoveTo();
    IF c = "PN" THEN
      IF nf <> 2 OR (NOT IntArg(2, a)) RETURN "ER 12 bad arguments to PN";
      IF a < 1 RETURN "ER 12 bad arguments to PN";
      IF a > CAPACITY RETURN "ER 23 path of " + NumToStr(a, 0) + " exceeds buffer " + NumToStr(CAPACITY, 0);
      FOR i FROM 2 TO CAPACITY + 1 DO
        havepos{i} := FALSE;
        haverot{i} := FALSE;
        havecirc{i} := FALSE;
      ENDFOR
      ncirc := 0;
      path_n := a;
      RETURN "OK " + NumToStr(a, 0);
    ENDIF
    IF c = "CK" THEN
      IF nf <> 1 RETURN "ER 12 bad arguments to CK";
      cyc := "-";
      RETURN "OK";
    ENDIF
    IF c = "AB" THEN
      IF nf <> 1 RETURN "ER 12 bad arguments to AB";
      Abort;
      RETURN "OK";
    ENDIF
    RETURN Motion(c);
  ENDFUNC

  FUNC string Bool01(bool b)
    IF b RETURN "1";
    RETURN "0";
  ENDFUNC

  ! XP k x y z, XO k q1 q2 q3 q4, XR k, XT k x y z q1 q2 q3 q4: a target slot's position,
  ! orientation, or both
  FUNC string Target(string c)
    VAR num k;
    VAR num w;
    VAR num x;
    VAR num y;
    VAR num z;
    IF (c = "XP" AND nf <> 5) OR (c = "XO" AND nf <> 6) OR (c = "XR" AND nf <> 2) OR (c = "XT" AND nf <> 9) RETURN "ER 12 bad arguments to " + c;
    IF NOT IntArg(2, k) RETURN "ER 12 bad arguments to " + c;
    IF k > CAPACITY RETURN "ER 24 slot out of range";
    IF c = "XP" THEN
      IF NOT (NumArg(3, x) AND NumArg(4, y) AND NumArg(5, z)) RETURN "ER 12 bad arguments to XP";
      slots{k + 1}.trans := [x, y, z];
      slots{k + 1}.robconf := [0, 0, 0, 0];
      slots{k + 1}.extax := [9E9, 9E9, 9E9, 9E9, 9E9, 9E9];
      havepos{k + 1} := TRUE;
    ELSEIF c = "XO" THEN
      IF NOT (NumArg(3, w) AND NumArg(4, x) AND NumArg(5, y) AND NumArg(6, z)) RETURN "ER 12 bad arguments to XO";
      IF Abs(Sqrt(w * w + x * x + y * y + z * z) - 1) > 0.001 RETURN "ER 12 bad arguments to XO";
      slots{k + 1}.rot := [w, x, y, z];
      haverot{k + 1} := TRUE;
    ELSEIF c = "XT" THEN
      IF NOT PoseArgs(k) RETURN "ER 12 bad arguments to XT";
    ELSE
      ! orientation of slot k = that of slot k - 1 (path points only)
      IF k < 2 RETURN "ER 21 no orientation to repeat";
      IF NOT haverot{k} RETURN "ER 21 no orientation to repeat";
      slots{k + 1}.rot := slots{k}.rot;
      haverot{k + 1} := TRUE;
    ENDIF
    RETURN "OK";
  ENDFUNC

  ! fields 3..9 (x y z q1 q2 q3 q4, as XT and MT carry them) into slot k; FALSE when
  ! any is bad, and then the slot is left as it was (all seven checked before any is kept)
  FUNC bool PoseArgs(num k)
    VAR num px;
    VAR num py;
    VAR num pz;
    VAR num w;
    VAR num x;
    VAR num y;
    VAR num z;
    IF NOT (NumArg(3, px) AND NumArg(4, py) AND NumArg(5, pz)) RETURN FALSE;
    IF NOT (NumArg(6, w) AND NumArg(7, x) AND NumArg(8, y) AND NumArg(9, z)) RETURN FALSE;
    IF Abs(Sqrt(w * w + x * x + y * y + z * z) - 1) > 0.001 RETURN FALSE;
    slots{k + 1}.trans := [px, py, pz];
    slots{k + 1}.rot := [w, x, y, z];
    slots{k + 1}.robconf := [0, 0, 0, 0];
    slots{k + 1}.extax := [9E9, 9E9, 9E9, 9E9, 9E9, 9E9];
    havepos{k + 1} := TRUE;
    haverot{k + 1} := TRUE;
    RETURN TRUE;
  ENDFUNC

  ! MT mid x y z q1 q2 q3 q4: XT 0 and ML mid in one request. Slot 0 keeps the target
  ! only while the move is accepted: refused, it is emptied (no later ML moves to it)
  FUNC string MoveTo()
    VAR string r;
    IF nf <> 9 RETURN "ER 12 bad arguments to MT";
    IF NOT PoseArgs(0) RETURN "ER 12 bad arguments to MT";
    r := Motion("MT");
    IF StrPart(r, 1, 3) <> "OK " THEN
      havepos{1} := FALSE;
      haverot{1} := FALSE;
    ENDIF
    RETURN r;
  ENDFUNC

  ! XC k x y z: path point k is reached by a MoveC through this circle point (mm)
  FUNC string Circle()
    VAR num k;
    VAR num x;
    VAR num y;
    VAR num z;
    IF nf <> 5 RETURN "ER 12 bad arguments to XC";
    IF NOT IntArg(2, k) RETURN "ER 12 bad arguments to XC";
    IF k < 1 OR k > CAPACITY RETURN "ER 24 slot out of range";
    IF NOT (NumArg(3, x) AND NumArg(4, y) AND NumArg(5, z)) RETURN "ER 12 bad arguments to XC";
    circs{k + 1} := [x, y, z];
    IF NOT havecirc{k + 1} ncirc := ncirc + 1;
    havecirc{k + 1} := TRUE;
    RETURN "OK";
  ENDFUNC

  ! TRUE when c is at least 0.001 mm off the line from a to b: a, c, b make a circle
  FUNC bool MakesCircle(pos a, pos c, pos b)
    VAR num ux;
    VAR num uy;
    VAR num uz;
    VAR num vx;
    VAR num vy;
    VAR num vz;
    VAR num d;
    ux := c.x - a.x;
    uy := c.y - a.y;
    uz := c.z - a.z;
    vx := b.x - a.x;
    vy := b.y - a.y;
    vz := b.z - a.z;
    d := Sqrt(vx * vx + vy * vy + vz * vz);
    IF d < 0.001 RETURN FALSE;
    RETURN Sqrt((uy * vz - uz * vy) * (uy * vz - uz * vy) + (uz * vx - ux * vz) * (uz * vx - ux * vz)
      + (ux * vy - uy * vx) * (ux * vy - uy * vx)) / d >= 0.001;
  ENDFUNC

  ! Checks and accepts a motion (MJ, ML, RW); RunMotion (from main) executes it.
  FUNC string Motion(string c)
    VAR num m;
    VAR num a;
    VAR num v{6};
    VAR robtarget start;
    IF (c = "MJ" AND nf <> 8) OR (c = "ML" AND nf <> 2) OR (c = "MT" AND nf <> 9) OR (c = "RW" AND nf <> 3) RETURN "ER 12 bad arguments to " + c;
    IF NOT IntArg(2, m) RETURN "ER 12 bad arguments to " + c;
    IF m < 1 RETURN "ER 12 bad arguments to " + c;
    IF mstate = "R" RETURN "ER 20 busy: a motion is running";
    IF m = last_mid RETURN "ER 25 motion " + NumToStr(m, 0) + " already executed";
    IF c = "MJ" THEN
      FOR i FROM 1 TO 6 DO
        IF NOT NumArg(i + 2, a) RETURN "ER 12 bad arguments to MJ";
        v{i} := a;
      ENDFOR
      ! IRB 2400 axis limits (product specification)
      IF Abs(v{1}) > 180 OR v{2} < -100 OR v{2} > 110 OR v{3} < -60 OR v{3} > 65
        OR Abs(v{4}) > 200 OR Abs(v{5}) > 120 OR Abs(v{6}) > 400 RETURN "ER 31 joints outside limits";
      jt.robax := [v{1}, v{2}, v{3}, v{4}, v{5}, v{6}];
      jt.extax := [9E9, 9E9, 9E9, 9E9, 9E9, 9E9];
    ELSEIF c = "ML" OR c = "MT" THEN
      IF NOT (havepos{1} AND haverot{1}) RETURN "ER 21 target slot 0 incomplete";
      IF NOT Reachable(slots{1}) RETURN "ER 30 target unreachable";
      havepos{1} := FALSE;
      haverot{1} := FALSE;
    ELSE
      IF (NOT IntArg(3, a)) OR a > 1 RETURN "ER 12 bad arguments to RW";
      IF path_n = 0 RETURN "ER 22 path incomplete";
      FOR i FROM 2 TO path_n + 1 DO
        IF NOT (havepos{i} AND haverot{i}) RETURN "ER 22 path incomplete";
      ENDFOR
      FOR i FROM 2 TO path_n + 1 DO
        IF NOT Reachable(slots{i}) RETURN "ER 30 path point " + NumToStr(i - 1, 0) + " unreachable";
      ENDFOR
      ! a circle starts at the point before it (for point 1: where the robot is); the loop
      ! only when the path has circle points (a dense path's RW answers as quickly as before)
      IF ncirc > 0 THEN
        start := CRobT(\Tool:=sgtool \WObj:=wobj0);
        FOR i FROM 2 TO path_n + 1 DO
          IF havecirc{i} THEN
            IF NOT MakesCircle(start.trans, circs{i}, slots{i}.trans) RETURN "ER 12 circle point " + NumToStr(i - 1, 0) + " makes no circle";
          ENDIF
          start := slots{i};
        ENDFOR
      ENDIF
      arc := a;
    ENDIF
    mid := m;
    last_mid := m;
    mkind := c;
    IF c = "MT" mkind := "ML";
    mstate := "R";
    pidx := 0;
    err := 0;
    RETURN "OK " + NumToStr(m, 0);
  ENDFUNC

  ! TRUE when the robot can reach t with sgtool. The check is the optional module
  ! SGREACH (procedure SgReachCheck, CalcJointT), called by late binding: without that
  ! module every target counts as reachable here and an unreachable one is found by the
  ! motion itself (a fault, FL mid 40).
  FUNC bool Reachable(robtarget t)
    sg_target := t;
    sg_reach := TRUE;
    %"SgReachCheck"%;
    RETURN sg_reach;
  ERROR
    IF ERRNO = ERR_REFUNKPRC RETURN TRUE;
    RAISE;
  ENDFUNC

  ! ---- motion --------------------------------------------------------------------------

  ! the path point a fault or abort is reported at (0: not a path)
  FUNC num FaultPoint()
    IF mkind = "RW" RETURN pidx + 1;
    RETURN 0;
  ENDFUNC

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
      Event "FL " + NumToStr(mid, 0) + " 41 " + NumToStr(FaultPoint(), 0);
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
      WHILE mstate = "R" AND (NOT JointsAt(jt)) DO
        ServeOnce 0.05;
      ENDWHILE
      IF mstate = "R" THEN
        mstate := "D";
        Event "IP " + NumToStr(mid, 0);
      ENDIF
    ELSEIF mkind = "ML" THEN
      target := slots{1};
      MoveL \Conc, target, sgspeed, fine, sgtool \WObj:=wobj0;
      WHILE mstate = "R" AND (NOT PoseAt(target)) DO
        ServeOnce 0.05;
      ENDWHILE
      IF mstate = "R" THEN
        mstate := "D";
        Event "IP " + NumToStr(mid, 0);
      ENDIF
    ELSE
      ! the weld: a MoveL (or a MoveC where the point has a circle point) per point; the
      ! program runs about one point ahead of the robot, so point i - 1 is reached when
      ! the move to point i returns. Requests are served between points, so AB stops the
      ! weld within one segment.
      IF arc = 1 SetDO doWeld, 1;
      i := 1;
      WHILE i <= path_n AND mstate = "R" DO
        IF havecirc{i + 1} THEN
          ! the circle point's orientation is not used by the default circle reorientation
          circ := slots{i + 1};
          circ.trans := circs{i + 1};
        ENDIF
        IF i = path_n THEN
          IF havecirc{i + 1} THEN
            MoveC circ, slots{i + 1}, sgspeed, fine, sgtool \WObj:=wobj0;
          ELSE
            MoveL slots{i + 1}, sgspeed, fine, sgtool \WObj:=wobj0;
          ENDIF
        ELSEIF havecirc{i + 1} THEN
          MoveC circ, slots{i + 1}, sgspeed, sgzone, sgtool \WObj:=wobj0;
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
    ! A recoverable error of a motion instruction: arc off first, then stop, report the
    ! point. Errors while serving a request cannot reach here: ServeOnce never raises
    ! for what the client sends (every request is answered OK or ER).
    SetDO doWeld, 0;
    arc := 0;
    StopMove;
    ClearPath;
    StartMove;
    mstate := "F";
    err := 40;
    Event "FL " + NumToStr(mid, 0) + " 40 " + NumToStr(FaultPoint(), 0);
    RETURN;
  ENDPROC
ENDMODULE
