%%%
  VERSION:1
  LANGUAGE:ENGLISH
%%%

MODULE SGREACH
  !
  ! Optional reachability pre-check for the seamguide RAPID server (SGSERVER.mod).
  ! Load it ONLY on a controller whose system software has CalcJointT and the error
  ! number ERR_ROBLIMIT (they are not in the S4 BaseWare RAPID reference this project
  ! checked; RobotWare documents both). SGSERVER calls SgReachCheck by late binding
  ! (%"SgReachCheck"%): without this module its targets are not pre-checked and an
  ! unreachable one is found by the motion itself (FL mid 40). With it, a motion to an
  ! unreachable target is refused before it starts (ER 30).
  !
  ! In: sg_target (the robtarget to check), sgtool. Out: sg_reach.
  !
  PROC SgReachCheck()
    VAR jointtarget j;
    j := CalcJointT(sg_target, sgtool \WObj:=wobj0);
    sg_reach := TRUE;
  ERROR
    IF ERRNO = ERR_ROBLIMIT THEN
      sg_reach := FALSE;
      RETURN;
    ENDIF
    RAISE;
  ENDPROC
ENDMODULE
