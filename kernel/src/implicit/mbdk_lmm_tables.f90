!> Coefficients of the implicit linear multistep methods, as data, in one normalised form:
!>
!>   sum_{j=0..k} alpha_j y_{n+1-j} = h (beta_0 F_{n+1} + beta_1 F_n),    alpha_0 = 1
!>
!>   implicit_euler  k=1  order 1   (4.19)-(4.22)            A-stable, L-stable
!>   trapezoidal     k=1  order 2   (3.12), Adams-Moulton 2  A-stable
!>   bdf1 .. bdf6    k    order k   Gear (1971); bdf4 is the book's (4.80)
!>                                  bdf1, bdf2 A-stable; bdf3-6 A(alpha)-stable
!>
!> References: Fekete (2023) 3.2.1, 4.1.2, 4.4.2; Hairer & Wanner, Solving ODE II, III.1 and V.1.
!> The order conditions of these coefficients are checked in tests/test_method_data.py.
module mbdk_lmm_tables
  use mbdk_kinds, only: dp
  use mbdk_methods, only: MBDK_IMPLICIT_EULER, MBDK_TRAPEZOIDAL, MBDK_BDF1, MBDK_BDF6
  implicit none
  private

  integer, parameter, public :: MBDK_MAX_LMM_STEPS = 6

  type, public :: mbdk_lmm_t
    integer :: k = 0          !< number of previous values used
    integer :: order = 0
    real(dp) :: alpha(0:MBDK_MAX_LMM_STEPS) = 0.0_dp
    real(dp) :: beta0 = 0.0_dp
    real(dp) :: beta1 = 0.0_dp
  end type mbdk_lmm_t

  public :: mbdk_lmm_table

contains

  pure subroutine mbdk_lmm_table(id, tab, ok)
    integer, intent(in) :: id
    type(mbdk_lmm_t), intent(out) :: tab
    logical, intent(out) :: ok
    ok = .true.
    select case (id)
    case (MBDK_IMPLICIT_EULER)
      tab = make(1, 1, [1.0_dp, -1.0_dp], 1.0_dp, 0.0_dp)
    case (MBDK_TRAPEZOIDAL)
      tab = make(1, 2, [1.0_dp, -1.0_dp], 0.5_dp, 0.5_dp)
    case (MBDK_BDF1)
      tab = make(1, 1, [1.0_dp, -1.0_dp], 1.0_dp, 0.0_dp)
    case (MBDK_BDF1 + 1)
      tab = make(2, 2, [3.0_dp, -4.0_dp, 1.0_dp] / 3.0_dp, 2.0_dp / 3.0_dp, 0.0_dp)
    case (MBDK_BDF1 + 2)
      tab = make(3, 3, [11.0_dp, -18.0_dp, 9.0_dp, -2.0_dp] / 11.0_dp, 6.0_dp / 11.0_dp, 0.0_dp)
    case (MBDK_BDF1 + 3)
      tab = make(4, 4, [25.0_dp, -48.0_dp, 36.0_dp, -16.0_dp, 3.0_dp] / 25.0_dp, &
               12.0_dp / 25.0_dp, 0.0_dp)
    case (MBDK_BDF1 + 4)
      tab = make(5, 5, [137.0_dp, -300.0_dp, 300.0_dp, -200.0_dp, 75.0_dp, -12.0_dp] / 137.0_dp, &
               60.0_dp / 137.0_dp, 0.0_dp)
    case (MBDK_BDF6)
      tab = make(6, 6, [147.0_dp, -360.0_dp, 450.0_dp, -400.0_dp, 225.0_dp, -72.0_dp, 10.0_dp] &
               / 147.0_dp, 60.0_dp / 147.0_dp, 0.0_dp)
    case default
      ok = .false.
    end select

  contains

    pure function make(k, order, alpha, beta0, beta1) result(m)
      integer, intent(in) :: k, order
      real(dp), intent(in) :: alpha(0:), beta0, beta1
      type(mbdk_lmm_t) :: m
      m%k = k
      m%order = order
      m%alpha(0:k) = alpha
      m%beta0 = beta0
      m%beta1 = beta1
    end function make

  end subroutine mbdk_lmm_table

end module mbdk_lmm_tables
