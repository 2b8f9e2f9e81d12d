!> minimal.f90 -- the minimal example of README.md in Fortran: one node pressed onto
!> the foundation with Tresca friction, plus what an error looks like.
!>
!> Build (or `make fortran-minimal`):
!>   gfortran -c include/dualsplit.f90
!>   gfortran c_examples/minimal.f90 dualsplit.o target/release/libdualsplit.a \
!>      -lm -lpthread -ldl -o minimal_f
!>
!> Prints lambda_N = 8, lambda_T = 0.4 (slip), u = (0.3, -0.5), the log lines and
!> monitor calls of the solve, the same node on a compliant interface, and the
!> message of a rejected matrix; exit status 0 when all are as expected.

!> The callbacks: BIND(C) procedures of a module.
module minimal_callbacks
   use dualsplit
   use, intrinsic :: iso_c_binding, only: c_int32_t, c_f_pointer
   implicit none
contains

   !> Monitor: user_data points to two integers, the number of calls so far and the
   !> iteration after which to stop (0: never).
   function count_iterations(progress, user_data) result(stop_solve) bind(C)
      type(DsProgress), intent(in) :: progress
      type(c_ptr), value :: user_data
      integer(c_int32_t) :: stop_solve
      integer(c_int32_t), pointer :: counter(:)
      call c_f_pointer(user_data, counter, [2])
      counter(1) = counter(1) + 1
      stop_solve = 0
      if (counter(2) > 0 .and. progress%iteration >= counter(2)) stop_solve = 1
   end function count_iterations

   !> Log sink: prints each line with its level.
   subroutine print_log(level, message, user_data) bind(C)
      integer(c_int32_t), value :: level
      type(c_ptr), value :: message
      type(c_ptr), value :: user_data
      if (c_associated(user_data)) continue
      print '(a,i0,2a)', 'LOG ', level, ' ', ds_string_from_c(message)
   end subroutine print_log
end module minimal_callbacks

program minimal_f
   use dualsplit
   use minimal_callbacks
   use, intrinsic :: iso_c_binding, only: c_int32_t, c_loc
   implicit none

   ! 2 DOFs (u_x, u_y) of one node, K = diag(2, 4), 1-based CSR, default INTEGER
   integer, target :: kia(3) = [1, 2, 3], kja(2) = [1, 2]
   real(8), target :: ka(2) = [2.0d0, 4.0d0]
   integer, target :: nia(2) = [1, 2], nja(1) = [2]   ! N = [0 -1]
   real(8), target :: na(1) = [-1.0d0]
   integer, target :: tia(2) = [1, 2], tja(1) = [1]   ! T = [1  0]
   real(8), target :: ta(1) = [1.0d0]
   integer, target :: bad_ja(2) = [1, 3]              ! column 3 of a 2 x 2 matrix
   ! a compliant interface: c_N = 4, elastic slip k_T = 0.5; and a bad c_N
   real(8), target :: cn(1) = [4.0d0], kt(1) = [0.5d0], cn_bad(1) = [0.0d0]

   type(DsMatrix) :: k, n, t, kbad
   type(DsOptions) :: opts
   type(DsReport) :: rep
   type(DsInfo) :: info
   type(c_ptr) :: pb, pb2
   real(8) :: f(2) = [1.0d0, -10.0d0], g(1) = [0.5d0], p(1) = [0.4d0]
   real(8) :: u(2), ln(1), lt(1)
   integer :: st, ndofs, ncontacts, d
   integer(c_int32_t), target :: counter(2)
   logical :: ok

   pb = c_null_ptr
   pb2 = c_null_ptr
   k = ds_matrix_csr(2, 2, kia, kja, ka)
   n = ds_matrix_csr(1, 2, nia, nja, na)
   t = ds_matrix_csr(1, 2, tia, tja, ta)
   st = ds_problem_new(2, k, n, t, pb)
   if (st /= DS_STATUS_OK) then
      print '(a)', 'ds_problem_new: '//ds_status_string(st)//': '//ds_last_error_message()
      stop 2
   end if
   st = ds_problem_sizes(pb, ndofs, ncontacts, d)
   print '(a,3(1x,i0))', 'SIZES', ndofs, ncontacts, d

   ! a log sink and a monitor for the first solve
   counter = 0
   st = ds_problem_set_log(pb, 2, print_log)
   if (st == DS_STATUS_OK) st = ds_problem_set_monitor(pb, count_iterations, c_loc(counter))
   if (st /= DS_STATUS_OK) stop 2

   call ds_options_default(opts)
   ! Pop's splitting, whose every outer iteration reaches the monitor (the default,
   ! DS_METHOD_AUTO, solves this one-contact problem by Newton within its warm-up
   ! sweeps, before any outer iteration)
   opts%method = DS_METHOD_SPLIT
   ! the analysis alone, and the handle's: c = 2 dual unknowns, memory predicted
   call ds_info_init(info)
   st = ds_analyse(2, k, n, t, opts, info)
   if (st /= DS_STATUS_OK) stop 2
   print '(a,3(1x,i0))', 'INFO', info%n, info%c, merge(1, 0, info%setup_bytes > 0)
   call ds_info_init(info)
   st = ds_problem_info(pb, opts, info)
   if (st /= DS_STATUS_OK .or. info%c /= 2) stop 2
   u = 0.0d0
   ln = 0.0d0
   lt = 0.0d0
   st = ds_solve(pb, opts, DS_FRICTION_TRESCA, f, g, p, u, ln, lt, rep)
   if (st /= DS_STATUS_OK) then
      print '(a)', 'ds_solve: '//ds_status_string(st)//': '//ds_last_error_message()
      stop 2
   end if
   ! lambda_N = 8, lambda_T = 0.4 (slip), u = (0.3, -0.5)
   print '(a,5(1x,es23.15e3),3(1x,i0))', 'RESULT', ln(1), lt(1), u(1), u(2), rep%err, &
      rep%n_open, rep%n_stick, rep%n_slip
   print '(a,2(1x,i0))', 'MONITOR', counter(1), rep%outer_iterations
   print '(a,1x,i0)', 'MEMORY', merge(1, 0, rep%memory_peak > 0 .and. &
      rep%memory_peak <= rep%memory_predicted)
   ok = counter(1) == rep%outer_iterations
   ok = ok .and. abs(ln(1) - 8.0d0) <= 1.0d-9 .and. abs(lt(1) - 0.4d0) <= 1.0d-9 .and. &
        abs(u(1) - 0.3d0) <= 1.0d-9 .and. abs(u(2) + 0.5d0) <= 1.0d-9

   ! a monitor that asks to stop after the first iteration: DS_STATUS_STOPPED, with
   ! the last iterate written
   counter = [0, 1]
   st = ds_solve(pb, opts, DS_FRICTION_TRESCA, f, g, p, u, ln, lt, rep)
   print '(a,1x,i0,1x,a,1x,i0)', 'STOP', st, ds_status_string(st), counter(1)
   ok = ok .and. st == DS_STATUS_STOPPED .and. rep%status == DS_STATUS_STOPPED
   ok = ok .and. counter(1) == 1

   ! the same solve without options and report (both are optional), silent and
   ! unmonitored again
   st = ds_problem_set_log(pb, 0)
   if (st == DS_STATUS_OK) st = ds_problem_set_monitor(pb)
   u = 0.0d0
   st = ds_solve(pb, friction=DS_FRICTION_TRESCA, f=f, g=g, bound=p, u=u, lambda_n=ln, &
                 lambda_t=lt)
   ok = ok .and. st == DS_STATUS_OK .and. abs(u(1) - 0.3d0) <= 1.0d-9

   ! a compliant interface: lambda_N = c_N (-u_y - g)+ = 4, and the node sticks
   ! elastically, lambda_T = k_T u_x = 0.2 < p, u = (0.4, -1.5); a bad c_N is
   ! refused and the law kept; absent arrays make the contact rigid again
   st = ds_problem_set_compliance(pb, c_n=cn, k_t=kt)
   ok = ok .and. st == DS_STATUS_OK
   st = ds_problem_set_compliance(pb, c_n=cn_bad)
   print '(a,1x,i0,1x,a)', 'COMPLIANCE', st, ds_last_error_message()
   ok = ok .and. st == DS_STATUS_BAD_ARGUMENT
   st = ds_solve(pb, friction=DS_FRICTION_TRESCA, f=f, g=g, bound=p, u=u, lambda_n=ln, &
                 lambda_t=lt)
   print '(a,4(1x,es23.15e3))', 'COMPLIANT', ln(1), lt(1), u(1), u(2)
   ok = ok .and. st == DS_STATUS_OK .and. abs(ln(1) - 4.0d0) <= 1.0d-9 .and. &
        abs(lt(1) - 0.2d0) <= 1.0d-9 .and. abs(u(1) - 0.4d0) <= 1.0d-9 .and. &
        abs(u(2) + 1.5d0) <= 1.0d-9
   call ds_info_init(info)
   st = ds_problem_info(pb, opts, info)
   ok = ok .and. st == DS_STATUS_OK .and. info%compliant_contacts == 1 .and. &
        info%power_law_contacts == 0
   st = ds_problem_set_compliance(pb)
   if (st == DS_STATUS_OK) st = ds_solve(pb, friction=DS_FRICTION_TRESCA, f=f, g=g, &
                                         bound=p, u=u, lambda_n=ln, lambda_t=lt)
   ok = ok .and. st == DS_STATUS_OK .and. abs(ln(1) - 8.0d0) <= 1.0d-9

   ! an error: the status, its description and the message, as Fortran strings
   kbad = ds_matrix_csr(2, 2, kia, bad_ja, ka)
   st = ds_problem_new(2, kbad, n, t, pb2)
   print '(a,1x,i0,1x,a)', 'ERROR', st, ds_status_string(st)//' | '//ds_last_error_message()
   ok = ok .and. st == DS_STATUS_BAD_INDEX .and. .not. c_associated(pb2)
   ok = ok .and. len(ds_last_error_message()) > 0

   call ds_problem_free(pb)
   call ds_problem_free(pb2)   ! a null handle is fine
   ok = ok .and. .not. c_associated(pb)
   if (.not. ok) then
      print '(a)', 'minimal_f: unexpected result'
      stop 1
   end if
   print '(a)', 'minimal_f: ok'
end program minimal_f
