!------------------------------------------------------------------------------
!   pendulum : the emulated pendulum-oscillator, Eq. (11) of Gonzalez-Buelga,
!              Wagg & Neild (2007), with smooth damping (b1 = b3 = 0), made
!              autonomous with the standard appended harmonic oscillator.
!
!   State (SI units)
!     U(1) = y        oscillator displacement [m]
!     U(2) = y'       [m/s]
!     U(3) = theta    pendulum angle [rad]
!     U(4) = theta'   [rad/s]
!     U(5) = xs       appended oscillator, xs = sin(w t) on its limit cycle
!     U(6) = ys       appended oscillator, ys = cos(w t)
!   Parameters
!     PAR(1) = alpha  forcing amplitude [N], F_e = alpha sin(w t) = alpha xs
!     PAR(2) = fe     forcing frequency [Hz], w = 2 pi fe
!     PAR(3) = m, PAR(4) = l, PAR(5) = b2, PAR(6) = g,
!     PAR(7) = M, PAR(8) = C, PAR(9) = K (pendsweep's ModelParams names)
!     PAR(11) = period [s], kept equal to 1/fe by the appended oscillator
!
!   The right-hand side is that of pendsweep's eq11_rhs (kernels/_rhs.py)
!   with f_d = b2 theta' and k3 = 0. FUNC also supplies the analytic
!   Jacobian (JAC = 1), which the period-doubling extended system uses.
!------------------------------------------------------------------------------

      SUBROUTINE FUNC(NDIM,U,ICP,PAR,IJAC,F,DFDU,DFDP)
!     ---------- ----

      IMPLICIT NONE
      INTEGER, INTENT(IN) :: NDIM, ICP(*), IJAC
      DOUBLE PRECISION, INTENT(IN) :: U(NDIM), PAR(*)
      DOUBLE PRECISION, INTENT(OUT) :: F(NDIM)
      DOUBLE PRECISION, INTENT(INOUT) :: DFDU(NDIM,NDIM), DFDP(NDIM,*)

      DOUBLE PRECISION ALPHA, FE, PM, PL, B2, G, BM, BC, BK, TPI, W
      DOUBLE PRECISION Y, V, TH, OM, XS, YS, S, C, FD, COM, DEN, N1, N2, R2
      DOUBLE PRECISION DCTH, DCOM, DDTH, YDD, THDD

      ALPHA = PAR(1)
      FE    = PAR(2)
      PM    = PAR(3)
      PL    = PAR(4)
      B2    = PAR(5)
      G     = PAR(6)
      BM    = PAR(7)
      BC    = PAR(8)
      BK    = PAR(9)
      TPI   = 8.0D0*ATAN(1.0D0)
      W     = TPI*FE

      Y  = U(1)
      V  = U(2)
      TH = U(3)
      OM = U(4)
      XS = U(5)
      YS = U(6)

      S   = SIN(TH)
      C   = COS(TH)
      FD  = B2*OM
      COM = ALPHA*XS - BC*V - BK*Y - PM*PL*OM*OM*C + S*FD/PL
      DEN = BM + PM*C*C
      N1  = COM + PM*G*S*S
      N2  = COM + (BM + PM)*G
      YDD = N1/DEN
      THDD = -(S/PL)*N2/DEN - FD/(PM*PL*PL)
      R2  = XS*XS + YS*YS

      F(1) = V
      F(2) = YDD
      F(3) = OM
      F(4) = THDD
      F(5) = XS + W*YS - XS*R2
      F(6) = -W*XS + YS - YS*R2

      IF(IJAC.EQ.0)RETURN

      DFDU(:,:) = 0.0D0
!     d COM / d theta and d DEN / d theta
      DCTH = PM*PL*OM*OM*S + C*FD/PL
      DDTH = -2.0D0*PM*C*S

      DFDU(1,2) = 1.0D0
      DFDU(3,4) = 1.0D0

!     y'' = N1/DEN, N1 = COM + m g s^2
      DFDU(2,1) = -BK/DEN
      DFDU(2,2) = -BC/DEN
      DFDU(2,3) = (DCTH + 2.0D0*PM*G*S*C - YDD*DDTH)/DEN
      DCOM = -2.0D0*PM*PL*OM*C + S*B2/PL
      DFDU(2,4) = DCOM/DEN
      DFDU(2,5) = ALPHA/DEN

!     theta'' = -(s/l) N2/DEN - b2 theta'/(m l^2), N2 = COM + (M + m) g
      DFDU(4,1) = -(S/PL)*(-BK)/DEN
      DFDU(4,2) = -(S/PL)*(-BC)/DEN
      DFDU(4,3) = -(C/PL)*N2/DEN - (S/PL)*(DCTH/DEN - N2*DDTH/(DEN*DEN))
      DFDU(4,4) = -(S/PL)*DCOM/DEN - B2/(PM*PL*PL)
      DFDU(4,5) = -(S/PL)*ALPHA/DEN

      DFDU(5,5) = 1.0D0 - R2 - 2.0D0*XS*XS
      DFDU(5,6) = W - 2.0D0*XS*YS
      DFDU(6,5) = -W - 2.0D0*XS*YS
      DFDU(6,6) = 1.0D0 - R2 - 2.0D0*YS*YS

      IF(IJAC.EQ.1)RETURN

!     Parameter derivatives: alpha and fe (the only ones ever free here)
      DFDP(:,1) = 0.0D0
      DFDP(:,2) = 0.0D0
      DFDP(2,1) = XS/DEN
      DFDP(4,1) = -(S/PL)*XS/DEN
      DFDP(5,2) = TPI*YS
      DFDP(6,2) = -TPI*XS

      END SUBROUTINE FUNC

      SUBROUTINE STPNT(NDIM,U,PAR,T)
!     ---------- -----
!     The semi-trivial orbit (theta = 0) at the Table IV defaults with
!     b1 = b3 = 0, alpha = 10 N, fe = 2.5 Hz: the oscillator's linear steady
!     response y = Im(Y exp(i w t)), Y = alpha / (K - (M + m) w^2 + i C w),
!     at scaled time T in [0, 1] (w t = 2 pi T). The driver overrides the
!     parameters with the same values (PAR in its constants), read from
!     pendsweep's TABLE_IV.

      IMPLICIT NONE
      INTEGER, INTENT(IN) :: NDIM
      DOUBLE PRECISION, INTENT(INOUT) :: U(NDIM),PAR(*)
      DOUBLE PRECISION, INTENT(IN) :: T

      DOUBLE PRECISION TPI, W, ALPHA, FE, PM, BM, BC, BK, AR, AI, DEN2
      DOUBLE PRECISION YRE, YIM, PH

      TPI = 8.0D0*ATAN(1.0D0)
      PAR(1) = 10.0D0
      PAR(2) = 2.5D0
      PAR(3) = 0.27D0
      PAR(4) = 0.1955D0
      PAR(5) = 4.5067D-5
      PAR(6) = 9.81D0
      PAR(7) = 10.9D0
      PAR(8) = 20.0D0
      PAR(9) = 1910.0D0
      PAR(11) = 1.0D0/PAR(2)

      ALPHA = PAR(1)
      FE    = PAR(2)
      PM    = PAR(3)
      BM    = PAR(7)
      BC    = PAR(8)
      BK    = PAR(9)
      W     = TPI*FE
!     Y = alpha / (AR + i AI)
      AR   = BK - (BM + PM)*W*W
      AI   = BC*W
      DEN2 = AR*AR + AI*AI
      YRE  =  ALPHA*AR/DEN2
      YIM  = -ALPHA*AI/DEN2
      PH   = TPI*T

!     y = Re(Y) sin(w t) + Im(Y) cos(w t)
      U(1) = YRE*SIN(PH) + YIM*COS(PH)
      U(2) = W*(YRE*COS(PH) - YIM*SIN(PH))
      U(3) = 0.0D0
      U(4) = 0.0D0
      U(5) = SIN(PH)
      U(6) = COS(PH)

      END SUBROUTINE STPNT

      SUBROUTINE BCND
      END SUBROUTINE BCND

      SUBROUTINE ICND
      END SUBROUTINE ICND

      SUBROUTINE FOPT
      END SUBROUTINE FOPT

      SUBROUTINE PVLS
      END SUBROUTINE PVLS
