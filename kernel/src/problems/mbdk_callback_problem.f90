!> Problems whose right-hand side belongs to the caller:
!>
!>   mbdk_c_problem_t     a C function  int f(int n, double t, const double *y, double *dydt,
!>                        void *user_data), 0 = success, non-zero = failure (mbdk.h), and
!>                        optionally its Jacobian  int jac(int n, double t, const double *y,
!>                        double *dfdy, void *user_data), dfdy column-major n x n (dfdy[i + j n]
!>                        = dF_i/dy_j), which the implicit methods' Newton then uses
!>   mbdk_proc_problem_t  a Fortran procedure  subroutine f(n, t, y, dydt, flag); flag(1) /= 0
!>                        signals failure. This is how a Python function reaches the kernel through
!>                        f2py: the slow, documented "Python callback" path (~1 us per call).
!>                        Optionally its Jacobian  subroutine jac(n, t, y, dfdy, flag), dfdy(n, n).
!>
!> A failure reported by the callback becomes MBDK_ERR_CALLBACK_FAILED.
module mbdk_callback_problem
  use, intrinsic :: iso_c_binding, only: c_int, c_double, c_ptr, c_funptr, c_f_procpointer, &
    c_associated
  use mbdk_kinds, only: dp
  use mbdk_status, only: MBDK_SUCCESS, MBDK_ERR_CALLBACK_FAILED
  use mbdk_problem, only: mbdk_problem_t
  implicit none
  private

  abstract interface
    integer(c_int) function mbdk_c_rhs(n, t, y, dydt, user_data) bind(C)
      import :: c_int, c_double, c_ptr
      integer(c_int), value :: n
      real(c_double), value :: t
      real(c_double), intent(in) :: y(n)
      real(c_double), intent(out) :: dydt(n)
      type(c_ptr), value :: user_data
    end function mbdk_c_rhs

    integer(c_int) function mbdk_c_jac(n, t, y, dfdy, user_data) bind(C)
      import :: c_int, c_double, c_ptr
      integer(c_int), value :: n
      real(c_double), value :: t
      real(c_double), intent(in) :: y(n)
      real(c_double), intent(out) :: dfdy(n, n)
      type(c_ptr), value :: user_data
    end function mbdk_c_jac

    subroutine mbdk_proc_rhs(n, t, y, dydt, flag)
      import :: dp
      integer, intent(in) :: n
      real(dp), intent(in) :: t
      real(dp), intent(in) :: y(n)
      real(dp), intent(inout) :: dydt(n)
      integer, intent(inout) :: flag(1)
    end subroutine mbdk_proc_rhs
    subroutine mbdk_proc_jac(n, t, y, dfdy, flag)
      import :: dp
      integer, intent(in) :: n
      real(dp), intent(in) :: t
      real(dp), intent(in) :: y(n)
      real(dp), intent(inout) :: dfdy(n, n)
      integer, intent(inout) :: flag(1)
    end subroutine mbdk_proc_jac
  end interface
  public :: mbdk_c_rhs, mbdk_c_jac, mbdk_proc_rhs, mbdk_proc_jac

  type, extends(mbdk_problem_t), public :: mbdk_c_problem_t
    procedure(mbdk_c_rhs), nopass, pointer :: f => null()
    procedure(mbdk_c_jac), nopass, pointer :: jacf => null()
    type(c_ptr) :: user_data
  contains
    procedure :: rhs => c_problem_rhs
    procedure :: jac => c_problem_jac
  end type mbdk_c_problem_t

  type, extends(mbdk_problem_t), public :: mbdk_proc_problem_t
    procedure(mbdk_proc_rhs), nopass, pointer :: f => null()
    procedure(mbdk_proc_jac), nopass, pointer :: jf => null()
  contains
    procedure :: rhs => proc_problem_rhs
    procedure :: jac => proc_problem_jac
  end type mbdk_proc_problem_t

  public :: mbdk_c_problem_init, mbdk_proc_problem_init

contains

  !> jac: a C Jacobian function, or c_null_funptr for none (finite differences)
  subroutine mbdk_c_problem_init(prob, f, user_data, n, nq, jac)
    type(mbdk_c_problem_t), intent(out) :: prob
    type(c_funptr), intent(in) :: f
    type(c_ptr), intent(in) :: user_data
    integer, intent(in) :: n, nq
    type(c_funptr), intent(in), optional :: jac
    call c_f_procpointer(f, prob%f)
    if (present(jac)) then
      if (c_associated(jac)) then
        call c_f_procpointer(jac, prob%jacf)
        prob%has_jac = .true.
      end if
    end if
    prob%user_data = user_data
    prob%n = n
    prob%nq = nq
  end subroutine mbdk_c_problem_init

  !> jac (optional): its Jacobian, which the implicit methods' Newton then uses
  subroutine mbdk_proc_problem_init(prob, f, n, nq, jac)
    type(mbdk_proc_problem_t), intent(out) :: prob
    procedure(mbdk_proc_rhs) :: f
    integer, intent(in) :: n, nq
    procedure(mbdk_proc_jac), optional :: jac
    prob%f => f
    if (present(jac)) then
      prob%jf => jac
      prob%has_jac = .true.
    end if
    prob%n = n
    prob%nq = nq
  end subroutine mbdk_proc_problem_init

  subroutine c_problem_rhs(self, t, y, f, stat)
    class(mbdk_c_problem_t), intent(in) :: self
    real(dp), intent(in) :: t
    real(dp), intent(in), contiguous :: y(:)
    real(dp), intent(out), contiguous :: f(:)
    integer, intent(out) :: stat
    stat = MBDK_SUCCESS
    if (self%f(int(self%n, c_int), t, y, f, self%user_data) /= 0) stat = MBDK_ERR_CALLBACK_FAILED
  end subroutine c_problem_rhs

  subroutine c_problem_jac(self, t, y, jac, stat)
    class(mbdk_c_problem_t), intent(in) :: self
    real(dp), intent(in) :: t, y(:)
    real(dp), intent(out) :: jac(:, :)
    integer, intent(out) :: stat
    stat = MBDK_SUCCESS
    if (self%jacf(int(self%n, c_int), t, y, jac, self%user_data) /= 0) &
      stat = MBDK_ERR_CALLBACK_FAILED
  end subroutine c_problem_jac

  subroutine proc_problem_rhs(self, t, y, f, stat)
    class(mbdk_proc_problem_t), intent(in) :: self
    real(dp), intent(in) :: t
    real(dp), intent(in), contiguous :: y(:)
    real(dp), intent(out), contiguous :: f(:)
    integer, intent(out) :: stat
    integer :: flag(1)
    flag = 0
    f = 0.0_dp
    call self%f(self%n, t, y, f, flag)
    stat = merge(MBDK_ERR_CALLBACK_FAILED, MBDK_SUCCESS, flag(1) /= 0)
  end subroutine proc_problem_rhs

  subroutine proc_problem_jac(self, t, y, jac, stat)
    class(mbdk_proc_problem_t), intent(in) :: self
    real(dp), intent(in) :: t, y(:)
    real(dp), intent(out) :: jac(:, :)
    integer, intent(out) :: stat
    integer :: flag(1)
    flag = 0
    jac = 0.0_dp
    call self%jf(self%n, t, y, jac, flag)
    stat = merge(MBDK_ERR_CALLBACK_FAILED, MBDK_SUCCESS, flag(1) /= 0)
  end subroutine proc_problem_jac

end module mbdk_callback_problem
