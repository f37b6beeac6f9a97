!> Embedded explicit Runge-Kutta pairs as data: the tableau (a, b, c), the error weights e and
!> the dense-output polynomial p of each pair; mbdk_embedded_rk steps them all with one routine.
!>
!> Both pairs are FSAL ("first same as last"): the last stage is F at the new state, so an
!> accepted step costs s - 1 evaluations, and it enters the error estimate and the dense output.
!>   y_new   = y + h sum_i b_i K_i                    (the higher order: local extrapolation)
!>   err     = h sum_i e_i K_i                        (e = b - b_hat, over all stages)
!>   y(t + theta h) = y + h sum_i K_i sum_j p_ij theta^j,  0 <= theta <= 1
!>
!> dopri54: Dormand and Prince (1980), order 5 with an embedded order-4 estimate, 7 stages;
!>          its continuous extension of order 4 is Shampine's (1986) (the one in Hairer,
!>          Norsett and Wanner, Solving ODEs I, II.6, and in SciPy's RK45).
!> bs32:    Bogacki and Shampine (1989), order 3 with an embedded order-2 estimate, 4 stages;
!>          dense output: the cubic Hermite polynomial through y, y_new and F at both ends
!>          (order 3, free: F at both ends are stages 1 and 4).
!> tests/test_adaptive.py checks the orders of the steps, of the estimates and of the dense
!> output numerically, and the simplifying conditions sum_j a_ij = c_i.
module mbdk_embedded_pairs
  use mbdk_kinds, only: dp
  use mbdk_methods, only: MBDK_DOPRI54, MBDK_BS32
  implicit none
  private
  public :: mbdk_pair_table

  integer, parameter, public :: MBDK_PAIR_MAX_STAGES = 7
  integer, parameter, public :: MBDK_PAIR_MAX_DEGREE = 4

  type, public :: mbdk_pair_t
    integer :: s = 0                 !< stages, the FSAL stage included
    integer :: degree = 0            !< degree of the dense-output polynomial in theta
    integer :: order = 0             !< order of y_new
    integer :: est_order = 0         !< order of the embedded solution (error estimate O(h^(est+1)))
    real(dp) :: a(MBDK_PAIR_MAX_STAGES, MBDK_PAIR_MAX_STAGES) = 0.0_dp
    real(dp) :: b(MBDK_PAIR_MAX_STAGES) = 0.0_dp
    real(dp) :: c(MBDK_PAIR_MAX_STAGES) = 0.0_dp
    real(dp) :: e(MBDK_PAIR_MAX_STAGES) = 0.0_dp
    real(dp) :: p(MBDK_PAIR_MAX_STAGES, MBDK_PAIR_MAX_DEGREE) = 0.0_dp
  end type mbdk_pair_t

contains

  !> The pair of method id; found = .false. for a method that is not an embedded pair.
  subroutine mbdk_pair_table(id, pr, found)
    integer, intent(in) :: id
    type(mbdk_pair_t), intent(out) :: pr
    logical, intent(out) :: found
    found = .true.
    select case (id)
    case (MBDK_DOPRI54)
      pr%s = 7; pr%degree = 4; pr%order = 5; pr%est_order = 4
      pr%c(1:7) = [0.0_dp, 1.0_dp / 5, 3.0_dp / 10, 4.0_dp / 5, 8.0_dp / 9, 1.0_dp, 1.0_dp]
      pr%a(2, 1) = 1.0_dp / 5
      pr%a(3, 1:2) = [3.0_dp / 40, 9.0_dp / 40]
      pr%a(4, 1:3) = [44.0_dp / 45, -56.0_dp / 15, 32.0_dp / 9]
      pr%a(5, 1:4) = [19372.0_dp / 6561, -25360.0_dp / 2187, 64448.0_dp / 6561, -212.0_dp / 729]
      pr%a(6, 1:5) = [9017.0_dp / 3168, -355.0_dp / 33, 46732.0_dp / 5247, 49.0_dp / 176, &
                      -5103.0_dp / 18656.0_dp]
      pr%b(1:7) = [35.0_dp / 384, 0.0_dp, 500.0_dp / 1113, 125.0_dp / 192, -2187.0_dp / 6784, &
                   11.0_dp / 84.0_dp, 0.0_dp]
      pr%a(7, 1:6) = pr%b(1:6)
      ! b - b_hat, b_hat = (5179/57600, 0, 7571/16695, 393/640, -92097/339200, 187/2100, 1/40)
      pr%e(1:7) = [-71.0_dp / 57600, 0.0_dp, 71.0_dp / 16695, -71.0_dp / 1920, &
                   17253.0_dp / 339200.0_dp, -22.0_dp / 525.0_dp, 1.0_dp / 40.0_dp]
      pr%p(1, 1:4) = [1.0_dp, -8048581381.0_dp / 2820520608.0_dp, &
                      8663915743.0_dp / 2820520608.0_dp, -12715105075.0_dp / 11282082432.0_dp]
      pr%p(3, 1:4) = [0.0_dp, 131558114200.0_dp / 32700410799.0_dp, &
                      -68118460800.0_dp / 10900136933.0_dp, 87487479700.0_dp / 32700410799.0_dp]
      pr%p(4, 1:4) = [0.0_dp, -1754552775.0_dp / 470086768.0_dp, &
                      14199869525.0_dp / 1410260304.0_dp, -10690763975.0_dp / 1880347072.0_dp]
      pr%p(5, 1:4) = [0.0_dp, 127303824393.0_dp / 49829197408.0_dp, &
                      -318862633887.0_dp / 49829197408.0_dp, 701980252875.0_dp / 199316789632.0_dp]
      pr%p(6, 1:4) = [0.0_dp, -282668133.0_dp / 205662961.0_dp, 2019193451.0_dp / 616988883.0_dp, &
                      -1453857185.0_dp / 822651844.0_dp]
      pr%p(7, 1:4) = [0.0_dp, 40617522.0_dp / 29380423.0_dp, -110615467.0_dp / 29380423.0_dp, &
                      69997945.0_dp / 29380423.0_dp]
    case (MBDK_BS32)
      pr%s = 4; pr%degree = 3; pr%order = 3; pr%est_order = 2
      pr%c(1:4) = [0.0_dp, 0.5_dp, 0.75_dp, 1.0_dp]
      pr%a(2, 1) = 0.5_dp
      pr%a(3, 1:2) = [0.0_dp, 0.75_dp]
      pr%b(1:4) = [2.0_dp / 9, 1.0_dp / 3, 4.0_dp / 9, 0.0_dp]
      pr%a(4, 1:3) = pr%b(1:3)
      ! b - b_hat, b_hat = (7/24, 1/4, 1/3, 1/8)
      pr%e(1:4) = [-5.0_dp / 72, 1.0_dp / 12, 1.0_dp / 9, -1.0_dp / 8]
      ! cubic Hermite: y + h (theta K1 + theta^2 (...) + theta^3 (...)) with y_new - y = h b.K
      pr%p(1, 1:3) = [1.0_dp, -4.0_dp / 3.0_dp, 5.0_dp / 9.0_dp]
      pr%p(2, 1:3) = [0.0_dp, 1.0_dp, -2.0_dp / 3.0_dp]
      pr%p(3, 1:3) = [0.0_dp, 4.0_dp / 3.0_dp, -8.0_dp / 9.0_dp]
      pr%p(4, 1:3) = [0.0_dp, -1.0_dp, 1.0_dp]
    case default
      found = .false.
    end select
  end subroutine mbdk_pair_table

end module mbdk_embedded_pairs
