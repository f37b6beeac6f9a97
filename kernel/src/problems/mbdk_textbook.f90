!> The textbook ODEs of Fekete (2023), compiled, with their parameters (order of p(:) below).
!> Second-order problems use the layout y = [q; v] (nq > 0), so Euler-Cromer applies to them.
!>
!>  id name               n   p(:)                        equation
!>   1 linear_growth      1   a (2)                       y' = a t                      (4.8)
!>   2 decay              1   lambda (1)                  y' = -lambda y                (4.14)
!>   3 riccati            1   a (1), b (2)                x' = a t x^2 + b x            (4.25)
!>   4 beam_linear        1   F (5000 N), l (1000 mm),    phi' = -(F/EI)(l - x)         (4.42)
!>                            EI (4.2e10 N mm^2)
!>   5 beam_nonlinear     1   F, l, EI                    phi' = -(F/EI)(l - x)(1+phi^2)^1.5  (4.50)
!>   6 damped_oscillator  2   m (10), c (5), k (100)      m y'' + c y' + k y = 0        (4.53)
!>   7 pendulum           2   g (9.81), l (1)             phi'' = -(3g/2l) sin phi      (4.69)
!>   8 pendulum_linear    2   g, l                        phi'' = -(3g/2l) phi          (4.77)
!>   9 trolley_crane      4   m1 (10), m2 (1), l (1),     y = [x1, phi, x1', phi']      (4.78)
!>                            g (9.81), k (50), s (3000),
!>                            coupling (-1)
!>  10 double_pendulum    4   m1 (1), m2 (2), l1 (1),     y = [phi1, phi2, phi1', phi2'] (3.64)
!>                            l2 (2), g (9.81)
!>  11 linear_system      n   A (n x n, column-major)     y' = A y                      (4.58)
!>  12 four_bar_relative  6   a, b, c, d, m1, m2, m3, g,  four-bar in relative coordinates (1.29)
!>                            alpha, beta                 (mbdk_four_bar_forms)
!>  13 four_bar_natural   8   same as 12                  four-bar in natural coordinates (1.31)
!>  14 free_rigid_body    7   J1 (1), J2 (2), J3 (3)      y = [q (unit quaternion, scalar first),
!>                            principal inertias          Omega (body frame)]: Euler's equations
!>                                                        J Omega' = (J Omega) x Omega, (5.1)-(5.3)
!>                                                        with no torque, q' = q (0, Omega) / 2
!>  15 heavy_top          7   J1 (0.015), J2 (0.015),     the same with gravity's torque about the
!>                            J3 (0.01), m (1), g (9.81), fixed point, the centre at l on body
!>                            l (0.1)                     axis 3: M = s x R^T (0, 0, -m g)
!>  16 rigid_body_angles  6   J1, J2, J3, sequence (313)  free_rigid_body with angles: y = [a (3
!>                                                        angles of the sequence 313 or 123),
!>                                                        Omega], a' = G_b(a)^-1 Omega (5.43)
!>
!> trolley_crane: trolley m1 on a spring s and damper k, a uniform bar (m2, l) hinged to it.
!> coupling = -1 reproduces the book's (4.78) as printed; that equation is the reduction of
!> (3.52), whose constraint Jacobian row "1, 1, 0, sin/2" has a sign slip (the bar's centre then
!> moves opposite to the trolley). coupling = +1 is the consistent mechanism x2 = x1 + (l/2)cos phi.
!> Both conserve energy when k = 0. It is evaluated as the 2x2 mass-matrix solve
!> [m1+m2, -c a sin; -c a sin, m2 l^2/3] [x1''; phi''] = [c a cos phi'^2 - s x1 - k x1'; -a g cos]
!> with a = m2 l / 2, c = coupling.
!>
!> double_pendulum: two uniform bars; angles from the horizontal, gravity along -y (hanging
!> equilibrium at -90 deg). Evaluated as the 2x2 mass-matrix solve of the Lagrange equations,
!> which is algebraically identical to the book's closed form (3.64) (tests/test_problems.py
!> evaluates (3.64) as printed and compares).
!>
!> free_rigid_body: a torque-free body in its principal axes (mbdk_rotations' conventions).
!> |q| = 1 is not enforced: its drift is what a study of the integrators measures.
!> rigid_body_angles: at a gimbal lock of its sequence (3-1-3: theta = 0 or pi; 1-2-3: beta =
!> +-pi/2) the right-hand side returns MBDK_ERR_SINGULAR_MATRIX (the run stops there, named),
!> and near one the angle rates grow like 1 / sin(theta): what studies/rigid_body.py measures.
!> heavy_top: J about the fixed point, in the body's principal axes; gravity's direction in the
!> body frame is taken from q / |q|, so that a drift of |q| does not scale the torque.
!>
!> Analytic Jacobians for ids 1-8 and 11; finite differences for 9, 10 and 12-16.
module mbdk_textbook
  use mbdk_kinds, only: dp, i8
  use mbdk_status, only: MBDK_SUCCESS, MBDK_ERR_INVALID_INPUT, MBDK_ERR_UNKNOWN_PROBLEM
  use mbdk_memory, only: mbdk_alloc_status, MBDK_REAL_BYTES
  use mbdk_problem, only: mbdk_problem_t
  use mbdk_four_bar_forms, only: mbdk_four_bar_relative_rhs, mbdk_four_bar_natural_rhs, &
    mbdk_four_bar_params_ok
  use mbdk_rotations, only: mbdk_quat_rates, mbdk_angles_rates, MBDK_SEQ_EULER313, &
    MBDK_SEQ_CARDAN123
  implicit none
  private

  integer, parameter, public :: MBDK_PROBLEM_COUNT = 16
  integer, parameter, public :: MBDK_PROBLEM_NAME_LEN = 24
  integer, parameter :: LINEAR_GROWTH = 1, DECAY = 2, RICCATI = 3, BEAM_LINEAR = 4, &
    BEAM_NONLINEAR = 5, DAMPED_OSCILLATOR = 6, PENDULUM = 7, PENDULUM_LINEAR = 8, &
    TROLLEY_CRANE = 9, DOUBLE_PENDULUM = 10, LINEAR_SYSTEM = 11, &
    FOUR_BAR_RELATIVE = 12, FOUR_BAR_NATURAL = 13, FREE_RIGID_BODY = 14, &
    HEAVY_TOP = 15, RIGID_BODY_ANGLES = 16

  character(len=MBDK_PROBLEM_NAME_LEN), parameter :: names(MBDK_PROBLEM_COUNT) = [character( &
    len=MBDK_PROBLEM_NAME_LEN) :: 'linear_growth', 'decay', 'riccati', 'beam_linear', &
    'beam_nonlinear', 'damped_oscillator', 'pendulum', 'pendulum_linear', 'trolley_crane', &
    'double_pendulum', 'linear_system', 'four_bar_relative', 'four_bar_natural', &
    'free_rigid_body', 'heavy_top', 'rigid_body_angles']
  integer, parameter :: dims(MBDK_PROBLEM_COUNT) = [1, 1, 1, 1, 1, 2, 2, 2, 4, 4, 0, 6, 8, 7, 7, &
                                                    6]
  integer, parameter :: nparams(MBDK_PROBLEM_COUNT) = [1, 1, 2, 3, 3, 3, 2, 2, 7, 5, -1, 10, &
                                                       10, 3, 6, 4]

  type, extends(mbdk_problem_t), public :: mbdk_textbook_t
    integer :: id = 0
    real(dp), allocatable :: p(:)
    real(dp), allocatable :: a(:, :)   !< linear_system: A, built once at init
    !> products of parameters alone, formed once at init (double_pendulum: the constant
    !> mass-matrix entries and the coefficients of the coupling and gravity terms), so that an
    !> evaluation does only the arithmetic that depends on the state
    real(dp) :: c(5) = 0.0_dp
  contains
    procedure :: rhs => textbook_rhs
    procedure :: jac => textbook_jac
  end type mbdk_textbook_t

  public :: mbdk_textbook_init, mbdk_problem_id, mbdk_problem_info

contains

  pure integer function mbdk_problem_id(name)
    character(len=*), intent(in) :: name
    integer :: i
    mbdk_problem_id = 0
    do i = 1, MBDK_PROBLEM_COUNT
      if (trim(adjustl(name)) == trim(names(i))) then
        mbdk_problem_id = i
        return
      end if
    end do
  end function mbdk_problem_id

  !> Name, state dimension (0: given by y0) and parameter count (-1: n*n) of problem id.
  pure subroutine mbdk_problem_info(id, name, n, np)
    integer, intent(in) :: id
    character(len=*), intent(out) :: name
    integer, intent(out) :: n, np
    if (id < 1 .or. id > MBDK_PROBLEM_COUNT) then
      name = ''; n = -1; np = -1
      return
    end if
    name = names(id); n = dims(id); np = nparams(id)
  end subroutine mbdk_problem_info

  !> Builds problem id with state size n and parameters p; checks sizes and physical ranges.
  !> MBDK_ERR_NO_MEMORY where the copies of p (linear_system: n^2) cannot be had.
  subroutine mbdk_textbook_init(prob, id, n, p, stat)
    type(mbdk_textbook_t), intent(out) :: prob
    integer, intent(in) :: id, n
    real(dp), intent(in) :: p(:)
    integer, intent(out) :: stat
    integer :: astat, j
    stat = MBDK_ERR_UNKNOWN_PROBLEM
    if (id < 1 .or. id > MBDK_PROBLEM_COUNT) return
    stat = MBDK_ERR_INVALID_INPUT
    if (id == LINEAR_SYSTEM) then
      if (n < 1 .or. size(p, kind=i8) /= int(n, i8) * n) return   ! (n^2 in 64 bits)
    else
      if (n /= dims(id) .or. size(p) /= nparams(id)) return
    end if
    select case (id)
    case (BEAM_LINEAR, BEAM_NONLINEAR)
      if (p(3) == 0.0_dp) return
    case (DAMPED_OSCILLATOR)
      if (p(1) <= 0.0_dp) return
    case (PENDULUM, PENDULUM_LINEAR)
      if (p(2) <= 0.0_dp) return
    case (TROLLEY_CRANE)
      if (p(1) <= 0.0_dp .or. p(2) <= 0.0_dp .or. p(3) <= 0.0_dp) return
      if (abs(p(7)) /= 1.0_dp) return
    case (DOUBLE_PENDULUM)
      if (any(p(1:4) <= 0.0_dp)) return
    case (FOUR_BAR_RELATIVE, FOUR_BAR_NATURAL)
      if (.not. mbdk_four_bar_params_ok(p)) return
    case (FREE_RIGID_BODY, HEAVY_TOP, RIGID_BODY_ANGLES)
      ! principal inertias of a body: positive, and each at most the sum of the other two
      if (any(.not. (p(1:3) > 0.0_dp))) return
      if (p(1) > p(2) + p(3) .or. p(2) > p(1) + p(3) .or. p(3) > p(1) + p(2)) return
      if (id == HEAVY_TOP) then
        if (.not. (p(4) > 0.0_dp)) return
      end if
      if (id == RIGID_BODY_ANGLES) then
        if (p(4) /= 313.0_dp .and. p(4) /= 123.0_dp) return
      end if
    end select
    prob%id = id
    prob%n = n
    allocate (prob%p(size(p)), prob%a(merge(n, 0, id == LINEAR_SYSTEM), &
              merge(n, 0, id == LINEAR_SYSTEM)), stat=astat)
    call mbdk_alloc_status(astat, MBDK_REAL_BYTES * size(p, kind=i8) * merge(2, 1, &
                           id == LINEAR_SYSTEM), stat)
    if (stat /= MBDK_SUCCESS) return
    stat = MBDK_ERR_INVALID_INPUT
    prob%p = p
    if (id == LINEAR_SYSTEM) then
      do j = 1, n   ! column by column: no temporary of n^2
        prob%a(:, j) = p((j - 1) * int(n, i8) + 1:j * int(n, i8))
      end do
    end if
    if (id == DOUBLE_PENDULUM) prob%c = [(p(1) / 3.0_dp + p(2)) * p(3)**2, &
                                         p(2) * p(4)**2 / 3.0_dp, 0.5_dp * p(2) * p(3) * p(4), &
                                         (0.5_dp * p(1) + p(2)) * p(5) * p(3), &
                                         0.5_dp * p(2) * p(5) * p(4)]
    prob%nq = 0
    if ((id >= DAMPED_OSCILLATOR .and. id <= DOUBLE_PENDULUM) .or. &
        id == FOUR_BAR_RELATIVE .or. id == FOUR_BAR_NATURAL) prob%nq = n / 2
    prob%has_jac = .not. (id == TROLLEY_CRANE .or. id == DOUBLE_PENDULUM .or. &
                          id >= FOUR_BAR_RELATIVE)
    stat = MBDK_SUCCESS
  end subroutine mbdk_textbook_init

  subroutine textbook_rhs(self, t, y, f, stat)
    class(mbdk_textbook_t), intent(in) :: self
    real(dp), intent(in) :: t
    real(dp), intent(in), contiguous :: y(:)
    real(dp), intent(out), contiguous :: f(:)
    integer, intent(out) :: stat
    real(dp) :: w2, a, sn, cs, d, m11, m12, m22, r1, r2, det, sd, cd

    stat = MBDK_SUCCESS
    associate (p => self%p)
      select case (self%id)
      case (LINEAR_GROWTH)
        f(1) = p(1) * t
      case (DECAY)
        f(1) = -p(1) * y(1)
      case (RICCATI)
        f(1) = p(1) * t * y(1)**2 + p(2) * y(1)
      case (BEAM_LINEAR)
        f(1) = -(p(1) / p(3)) * (p(2) - t)
      case (BEAM_NONLINEAR)
        f(1) = -(p(1) / p(3)) * (p(2) - t) * (1.0_dp + y(1)**2)**1.5_dp
      case (DAMPED_OSCILLATOR)
        f(1) = y(2)
        f(2) = -(p(3) * y(1) + p(2) * y(2)) / p(1)
      case (PENDULUM)
        w2 = 1.5_dp * p(1) / p(2)
        f(1) = y(2)
        f(2) = -w2 * sin(y(1))
      case (PENDULUM_LINEAR)
        w2 = 1.5_dp * p(1) / p(2)
        f(1) = y(2)
        f(2) = -w2 * y(1)
      case (TROLLEY_CRANE)
        ! p = m1, m2, l, g, k, s, coupling
        a = 0.5_dp * p(2) * p(3)
        sn = sin(y(2)); cs = cos(y(2))
        m11 = p(1) + p(2)
        m12 = -p(7) * a * sn
        m22 = p(2) * p(3)**2 / 3.0_dp
        r1 = p(7) * a * cs * y(4)**2 - p(6) * y(1) - p(5) * y(3)
        r2 = -a * p(4) * cs
        det = m11 * m22 - m12 * m12
        f(1) = y(3)
        f(2) = y(4)
        f(3) = (m22 * r1 - m12 * r2) / det
        f(4) = (m11 * r2 - m12 * r1) / det
      case (DOUBLE_PENDULUM)
        ! p = m1, m2, l1, l2, g; c = m11, m22, m2 l1 l2 / 2, (m1/2 + m2) g l1, m2 g l2 / 2
        associate (c => self%c)
          d = y(1) - y(2)
          sd = sin(d); cd = cos(d)
          m12 = c(3) * cd
          r1 = -c(3) * sd * y(4)**2 - c(4) * cos(y(1))
          r2 = c(3) * sd * y(3)**2 - c(5) * cos(y(2))
          det = c(1) * c(2) - m12 * m12
          f(1) = y(3)
          f(2) = y(4)
          f(3) = (c(2) * r1 - m12 * r2) / det
          f(4) = (c(1) * r2 - m12 * r1) / det
        end associate
      case (LINEAR_SYSTEM)
        f = matmul(self%a, y)
      case (FOUR_BAR_RELATIVE)
        call mbdk_four_bar_relative_rhs(p, y, f, stat)
      case (FOUR_BAR_NATURAL)
        call mbdk_four_bar_natural_rhs(p, y, f, stat)
      case (FREE_RIGID_BODY, HEAVY_TOP)
        f(1:4) = mbdk_quat_rates(y(1:4), y(5:7), .true.)
        f(5) = (p(2) - p(3)) * y(6) * y(7) / p(1)
        f(6) = (p(3) - p(1)) * y(7) * y(5) / p(2)
        f(7) = (p(1) - p(2)) * y(5) * y(6) / p(3)
        if (self%id == HEAVY_TOP) then
          ! the vertical in body components, R^T e_z = the third row of R(q / |q|), and the
          ! torque (0, 0, l) x (-m g R^T e_z) = m g l (z2, -z1, 0)
          a = sum(y(1:4)**2)
          m11 = 2.0_dp * (y(2) * y(4) - y(1) * y(3)) / a      ! z1
          m12 = 2.0_dp * (y(3) * y(4) + y(1) * y(2)) / a      ! z2
          w2 = p(4) * p(5) * p(6)
          f(5) = f(5) + w2 * m12 / p(1)
          f(6) = f(6) - w2 * m11 / p(2)
        end if
      case (RIGID_BODY_ANGLES)
        if (p(4) == 313.0_dp) then
          call mbdk_angles_rates(MBDK_SEQ_EULER313, y(1:3), y(4:6), .true., f(1:3), stat)
        else
          call mbdk_angles_rates(MBDK_SEQ_CARDAN123, y(1:3), y(4:6), .true., f(1:3), stat)
        end if
        f(4) = (p(2) - p(3)) * y(5) * y(6) / p(1)
        f(5) = (p(3) - p(1)) * y(6) * y(4) / p(2)
        f(6) = (p(1) - p(2)) * y(4) * y(5) / p(3)
      end select
    end associate
  end subroutine textbook_rhs

  subroutine textbook_jac(self, t, y, jac, stat)
    class(mbdk_textbook_t), intent(in) :: self
    real(dp), intent(in) :: t, y(:)
    real(dp), intent(out) :: jac(:, :)
    integer, intent(out) :: stat
    real(dp) :: w2

    stat = MBDK_SUCCESS
    jac = 0.0_dp
    associate (p => self%p)
      select case (self%id)
      case (LINEAR_GROWTH, BEAM_LINEAR)
        continue
      case (DECAY)
        jac(1, 1) = -p(1)
      case (RICCATI)
        jac(1, 1) = 2.0_dp * p(1) * t * y(1) + p(2)
      case (BEAM_NONLINEAR)
        jac(1, 1) = -3.0_dp * (p(1) / p(3)) * (p(2) - t) * y(1) * sqrt(1.0_dp + y(1)**2)
      case (DAMPED_OSCILLATOR)
        jac(1, 2) = 1.0_dp
        jac(2, 1) = -p(3) / p(1)
        jac(2, 2) = -p(2) / p(1)
      case (PENDULUM)
        w2 = 1.5_dp * p(1) / p(2)
        jac(1, 2) = 1.0_dp
        jac(2, 1) = -w2 * cos(y(1))
      case (PENDULUM_LINEAR)
        w2 = 1.5_dp * p(1) / p(2)
        jac(1, 2) = 1.0_dp
        jac(2, 1) = -w2
      case (LINEAR_SYSTEM)
        jac = self%a
      case default
        stat = MBDK_ERR_INVALID_INPUT
      end select
    end associate
  end subroutine textbook_jac

end module mbdk_textbook
