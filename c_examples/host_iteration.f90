!> host_iteration.f90 -- the host's Newton loop through the Fortran module, on the
!> smallest case with an answer by hand: one node (DOFs u_x, u_y), K = diag(2, 4),
!> N = [0 -1], T = [1 0], Coulomb mu = 0.5, gap 0.
!>
!> Iteration 1 (r = (10, -8), no slip taken yet): lambda_N = 8, the stick force
!> 10 exceeds mu lambda_N = 4, so the node slips: lambda_T = 4, du_x = 3.
!> Iteration 2, after the host's tangent changed (K = diag(2.5, 4): refactored),
!> with the slip taken s = 3 and r = (-5, -8): sticking holds the total slip at
!> zero, du_x = -s = -3, so lambda_T = r_x - 2.5 du_x = 2.5, inside the cone.
!>
!> Build (or `make fortran-host-iteration`):
!>   gfortran -c include/dualsplit.f90
!>   gfortran c_examples/host_iteration.f90 dualsplit.o target/release/libdualsplit.a \
!>      -lm -lpthread -ldl -o host_iteration_f
!>
!> Prints ITERATION lines (du_x du_y lambda_N lambda_T open stick slip) and
!> "host_iteration_f: ok" when both match the closed form.
program host_iteration_f
   use dualsplit
   implicit none

   integer, target :: kia(3) = [1, 2, 3], kja(2) = [1, 2]
   real(8), target :: ka(2) = [2.0d0, 4.0d0], ka2(2) = [2.5d0, 4.0d0]
   integer, target :: nia(2) = [1, 2], nja(1) = [2]
   real(8), target :: na(1) = [-1.0d0]
   integer, target :: tia(2) = [1, 2], tja(1) = [1]
   real(8), target :: ta(1) = [1.0d0]
   type(DsMatrix) :: k, n, t
   type(DsReport) :: rep
   type(c_ptr) :: pb
   real(8) :: r1(2) = [10.0d0, -8.0d0], r2(2) = [-5.0d0, -8.0d0]
   real(8) :: g(1) = [0.0d0], mu(1) = [0.5d0], s(1)
   real(8) :: du(2), ln(1), lt(1)
   integer :: st
   logical :: ok

   pb = c_null_ptr
   k = ds_matrix_csr(2, 2, kia, kja, ka)
   n = ds_matrix_csr(1, 2, nia, nja, na)
   t = ds_matrix_csr(1, 2, tia, tja, ta)
   st = ds_problem_new(2, k, n, t, pb)
   if (st /= DS_STATUS_OK) stop 2
   ! Iteration 1: no slip taken (slip absent).
   st = ds_solve_iteration(pb, friction=DS_FRICTION_COULOMB, r=r1, g=g, bound=mu, du=du, &
                           lambda_n=ln, lambda_t=lt, report=rep)
   if (st /= DS_STATUS_OK) stop 2
   print '(a,4es24.16,3i3)', 'ITERATION', du, ln, lt, rep%n_open, rep%n_stick, rep%n_slip
   ok = abs(du(1) - 3.0d0) < 1d-9 .and. abs(ln(1) - 8.0d0) < 1d-9 .and. abs(lt(1) - 4.0d0) < 1d-9
   ! Iteration 2: a new tangent, the slip taken s = u_x - u_x,n = 3.
   k = ds_matrix_csr(2, 2, kia, kja, ka2)
   st = ds_problem_refactor(pb, k)
   if (st /= DS_STATUS_OK) stop 2
   s(1) = du(1)
   st = ds_solve_iteration(pb, friction=DS_FRICTION_COULOMB, r=r2, g=g, bound=mu, du=du, &
                           lambda_n=ln, lambda_t=lt, report=rep, slip=s)
   if (st /= DS_STATUS_OK) stop 2
   print '(a,4es24.16,3i3)', 'ITERATION', du, ln, lt, rep%n_open, rep%n_stick, rep%n_slip
   ok = ok .and. abs(du(1) + 3.0d0) < 1d-9 .and. abs(ln(1) - 8.0d0) < 1d-9 &
        .and. abs(lt(1) - 2.5d0) < 1d-9 .and. rep%n_stick == 1
   ! A slip of NaN is refused and nothing is written.
   s(1) = ieee_nan()
   du = 7.0d0
   st = ds_solve_iteration(pb, friction=DS_FRICTION_COULOMB, r=r2, g=g, bound=mu, du=du, &
                           lambda_n=ln, lambda_t=lt, slip=s)
   print '(a,i0)', 'NAN_SLIP ', st
   ok = ok .and. st == DS_STATUS_NOT_FINITE .and. all(du == 7.0d0)
   call ds_problem_free(pb)
   if (ok) print '(a)', 'host_iteration_f: ok'
   if (.not. ok) stop 1
contains
   function ieee_nan() result(x)
      use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
      real(8) :: x
      x = ieee_value(x, ieee_quiet_nan)
   end function ieee_nan
end program host_iteration_f
