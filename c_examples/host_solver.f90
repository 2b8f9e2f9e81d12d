!> host_solver.f90 -- the library on a Fortran host's own solve of K
!> (ds_problem_new_host): the node of minimal.f90 (K = diag(2, 4), pressed onto
!> the foundation with Tresca friction), with K^-1 applied by a BIND(C)
!> callback instead of K handed over, what the solve cost (ds_problem_last_cost:
!> the host's right-hand sides, checked against the callback's own count), then
!> a callback that fails, then the same solve with the host's solve on rows
!> (DsHostSolver%solve_rows) taking the products.
!>
!> Build (or `make fortran-host`):
!>   gfortran -c include/dualsplit.f90
!>   gfortran c_examples/host_solver.f90 dualsplit.o target/release/libdualsplit.a \
!>      -lm -lpthread -ldl -o host_solver_f
!>
!> Prints RESULT lambda_N lambda_T u_x u_y err (8, 0.4, 0.3, -0.5 by hand:
!> u_y = -g, 4 u_y = -10 + lambda_N, 2 u_x = 1 - lambda_T with |lambda_T| = p),
!> the host's calls, FAILED with the status and message of a failing callback,
!> AGAIN after it, and ROWS (the calls on rows, lambda_N, u_y) with the solve
!> on rows; exit status 0 when all are as expected.

!> The host: K = diag(kdiag), the solve divides by it. `context` points to
!> a host_data; fail_code /= 0 makes the solve fail with that code.
module host_callbacks
   use dualsplit
   use, intrinsic :: iso_c_binding, only: c_int32_t, c_int64_t, c_double, c_f_pointer
   implicit none

   type, bind(C) :: host_data
      real(c_double) :: kdiag(2)
      integer(c_int32_t) :: fail_code
      integer(c_int32_t) :: calls
      integer(c_int64_t) :: columns   ! right-hand sides solved, summed over the calls
      integer(c_int32_t) :: row_calls ! calls of rows_solve
   end type host_data
contains

   !> DsHostSolveFn: x(ld, ncols) := K^-1 x.
   function diagonal_solve(context, n, ncols, x, ld) result(code) bind(C)
      type(c_ptr), value :: context
      integer(c_int64_t), value :: n, ncols, ld
      real(c_double), intent(inout) :: x(ld, *)
      integer(c_int32_t) :: code
      type(host_data), pointer :: h
      integer(c_int64_t) :: i, j
      call c_f_pointer(context, h)
      h%calls = h%calls + 1
      code = h%fail_code
      if (code /= 0) return
      h%columns = h%columns + ncols
      do j = 1, ncols
         do i = 1, n
            x(i, j) = x(i, j) / h%kdiag(i)
         end do
      end do
   end function diagonal_solve

   !> DsHostSolveRowsFn: x(ld, ncols) holds the right-hand sides at the 0-based
   !> DOFs rows(1:nrows); K^-1 of them there (K diagonal: row by row).
   function rows_solve(context, nrows, rows, ncols, x, ld, approximate) result(code) bind(C)
      type(c_ptr), value :: context
      integer(c_int64_t), value :: nrows, ncols, ld
      integer(c_int64_t), intent(in) :: rows(*)
      real(c_double), intent(inout) :: x(ld, *)
      integer(c_int32_t), value :: approximate
      integer(c_int32_t) :: code
      type(host_data), pointer :: h
      integer(c_int64_t) :: i, j
      call c_f_pointer(context, h)
      h%row_calls = h%row_calls + 1
      h%columns = h%columns + ncols
      code = 0
      if (approximate /= 0 .and. approximate /= 1) code = 3
      do j = 1, ncols
         do i = 1, nrows
            x(i, j) = x(i, j) / h%kdiag(rows(i) + 1)
         end do
      end do
   end function rows_solve
end module host_callbacks

program host_solver_f
   use dualsplit
   use host_callbacks
   use, intrinsic :: iso_c_binding, only: c_int32_t, c_int64_t, c_loc, c_funloc, c_null_funptr
   implicit none

   integer, target :: nia(2) = [1, 2], nja(1) = [2]   ! N = [0 -1], 1-based CSR
   real(8), target :: na(1) = [-1.0d0]
   integer, target :: tia(2) = [1, 2], tja(1) = [1]   ! T = [1  0]
   real(8), target :: ta(1) = [1.0d0]
   type(host_data), target :: host
   type(DsHostSolver) :: solver
   type(DsMatrix) :: n, t
   type(DsOptions) :: opts
   type(DsReport) :: rep
   type(DsCost) :: cost
   type(c_ptr) :: pb
   real(8) :: f(2) = [1.0d0, -10.0d0], g(1) = [0.5d0], p(1) = [0.4d0]
   real(8) :: u(2), ln(1), lt(1)
   integer :: st
   integer(c_int64_t) :: columns_before
   logical :: ok, ok_cost

   host%kdiag = [2.0d0, 4.0d0]
   host%fail_code = 0
   host%calls = 0
   host%columns = 0
   host%row_calls = 0
   solver%struct_size = DS_HOST_SOLVER_SIZE
   solver%n = 2
   solver%solve = c_funloc(diagonal_solve)
   solver%context = c_loc(host)
   solver%inverse_entries = c_null_funptr     ! the contact blocks by solves
   n = ds_matrix_csr(1, 2, nia, nja, na)
   t = ds_matrix_csr(1, 2, tia, tja, ta)
   call ds_options_default(opts)
   pb = c_null_ptr
   st = ds_problem_new_host(2, solver, n, t, opts, pb)
   if (st /= DS_STATUS_OK) then
      print '(a)', 'ds_problem_new_host: '//ds_status_string(st)//': '//ds_last_error_message()
      stop 2
   end if
   u = 0.0d0
   ln = 0.0d0
   lt = 0.0d0
   columns_before = host%columns
   st = ds_solve(pb, opts, DS_FRICTION_TRESCA, f, g, p, u, ln, lt, rep)
   if (st /= DS_STATUS_OK) then
      print '(a)', 'ds_solve: '//ds_status_string(st)//': '//ds_last_error_message()
      stop 2
   end if
   print '(a,5(1x,es23.15e3))', 'RESULT', ln(1), lt(1), u(1), u(2), rep%err
   print '(a,1x,i0)', 'CALLS', host%calls
   ! What the solve cost: the host's right-hand sides as this callback counted them.
   call ds_cost_init(cost)
   st = ds_problem_last_cost(pb, cost)
   print '(a,1x,i0,1x,i0,1x,i0,2(1x,es10.3))', 'COST', st, cost%host_solves, &
      host%columns - columns_before, cost%host_seconds, cost%library_seconds
   ok_cost = st == DS_STATUS_OK .and. cost%solved == 1 .and. &
      cost%host_solves == host%columns - columns_before .and. cost%host_solves > 0 .and. &
      cost%host_seconds <= cost%solve_seconds
   ok = abs(ln(1) - 8.0d0) <= 1.0d-9 .and. abs(lt(1) - 0.4d0) <= 1.0d-9 .and. &
        abs(u(1) - 0.3d0) <= 1.0d-9 .and. abs(u(2) + 0.5d0) <= 1.0d-9 .and. ok_cost

   ! The host fails with its code 5: DS_STATUS_HOST_SOLVE_FAILED, outputs untouched.
   host%fail_code = 5
   u = -7.0d0
   st = ds_solve(pb, opts, DS_FRICTION_TRESCA, f, g, p, u, ln, lt, rep)
   print '(a,1x,i0,2a)', 'FAILED', st, ' ', ds_last_error_message()
   ok = ok .and. st == DS_STATUS_HOST_SOLVE_FAILED .and. all(u == -7.0d0)
   ok = ok .and. index(ds_last_error_message(), 'code 5') > 0

   ! The handle is usable: the same solve again.
   host%fail_code = 0
   st = ds_solve(pb, opts, DS_FRICTION_TRESCA, f, g, p, u, ln, lt, rep)
   print '(a,1x,i0,2(1x,es23.15e3))', 'AGAIN', st, ln(1), u(2)
   ok = ok .and. st == DS_STATUS_OK .and. abs(ln(1) - 8.0d0) <= 1.0d-9

   call ds_problem_free(pb)

   ! The host's solve on rows: every product with A a call of rows_solve.
   solver%solve_rows = c_funloc(rows_solve)
   st = ds_problem_new_host(2, solver, n, t, opts, pb)
   if (st /= DS_STATUS_OK) then
      print '(a)', 'ds_problem_new_host (rows): '//ds_status_string(st)//': '//ds_last_error_message()
      stop 2
   end if
   st = ds_solve(pb, opts, DS_FRICTION_TRESCA, f, g, p, u, ln, lt, rep)
   print '(a,1x,i0,1x,i0,2(1x,es23.15e3))', 'ROWS', st, host%row_calls, ln(1), u(2)
   ok = ok .and. st == DS_STATUS_OK .and. host%row_calls > 0 .and. &
        abs(ln(1) - 8.0d0) <= 1.0d-9 .and. abs(u(2) + 0.5d0) <= 1.0d-9
   call ds_problem_free(pb)
   if (.not. ok) then
      print '(a)', 'host_solver_f: FAILED'
      stop 1
   end if
   print '(a)', 'host_solver_f: ok'
end program host_solver_f
