!> block2d.f90 -- the scene of c_examples/block2d.c, written the way a Fortran finite
!> element code is written, with the frictional contact solved by dualsplit through
!> its Fortran module (include/dualsplit.f90).
!>
!>   - 2D plane strain, bilinear quadrilaterals (Q4), 2x2 Gauss integration;
!>   - a W x H block meshed with nx x ny elements, thickness 1;
!>   - the top edge is clamped to a prescribed displacement (ux_top, uy_top): an ID
!>     array numbers the free equations 1..neq and gives the prescribed DOFs negative
!>     numbers; their effect goes to the right-hand side, f = -K_fp u_p;
!>   - K is assembled directly into a 1-based compressed sparse row (CSR) structure of
!>     default INTEGER and REAL(8) arrays holding the upper triangle only
!>     (DS_STORAGE_UPPER; --storage full keeps both triangles): the sparsity pattern
!>     comes from the node connectivity, and each element matrix is added entry by
!>     entry (search in the row), the classical way;
!>   - every bottom node is a contact with the rigid foundation: the N row is the
!>     outward normal (0,-1) on its y DOF, the T row the tangent (1,0) on its x DOF;
!>     the foundation is curved, g_i = c (x_i - W/2)^2;
!>   - Coulomb friction, history mode (ds_step): the library keeps u and the
!>     multipliers between the steps; the program passes the total load of each step.
!>
!> Load history (prescribed displacement of the top edge), as in block2d.c:
!>   press 5 steps to uy, shear 5 steps to ux, unload 4 steps, lift to +0.2 |uy|.
!>
!> The command-line options are those of block2d.c (--nx, --ny, --method, --E, --nu,
!> --W, --H, --mu, --curved, --uy, --ux, --tol, --max-outer, --max-inner, --quiet),
!> with the same defaults, so both programs solve the same problems; the per-step
!> table and the SUMMARY line have the same columns and keys. Two more options:
!> --storage upper|full (how K is stored, default upper) and --dump FILE, which writes
!> u, lambda_N and lambda_T of every step with 17 significant digits
!> (tests/fortran.rs compares them with the C driver's).
!>
!> Build (see the Makefile, `make fortran-demo`):
!>   gfortran -O2 -ffp-contract=off -c include/dualsplit.f90
!>   gfortran -O2 -ffp-contract=off c_examples/block2d.f90 dualsplit.o \
!>      target/release/libdualsplit.a -lm -lpthread -ldl -o block2d_f
!>
!> Exit status: 0 on success, 1 if a step did not converge or the resultant check
!> failed, 2 on any other library error, 3 on bad command-line options.
program block2d_f
   use dualsplit
   use, intrinsic :: iso_c_binding, only: c_int32_t
   use, intrinsic :: iso_fortran_env, only: error_unit, output_unit
   implicit none

   integer, parameter :: dp = kind(1.0d0)
   integer, parameter :: npress = 5, nshear = 5, nunload = 4
   integer, parameter :: nsteps = npress + nshear + nunload + 1
   integer, parameter :: maxadj = 9          ! Q4: a node has at most 9 neighbours
   real(dp), parameter :: dev_tol = 1.0e-8_dp

   ! parameters (block2d.c's defaults)
   real(dp) :: e_mod, pois, wid, hei, fric, curved, tol, uy_fin, ux_fin
   integer :: nx, ny, max_outer, max_inner, method
   logical :: quiet, dump, upper
   character(len=1024) :: dump_file

   ! mesh, ID array, coupling triplets
   integer :: nnode, nelem, ndof, neq, npre, m, nzk, nfp, npr
   real(dp), allocatable :: xn(:), yn(:)
   integer, allocatable :: ien(:, :), id(:, :), pcomp(:), nadj(:), adj(:, :)
   integer, allocatable :: kfp_r(:), kfp_c(:), kpr_r(:), kpr_c(:)
   real(dp), allocatable :: kfp_v(:), kpr_v(:)

   ! K (upper triangle), N and T in 1-based CSR: what the library borrows
   integer, allocatable, target :: ia(:), ja(:), ian(:), jan(:), iat(:), jat(:)
   real(dp), allocatable, target :: ak(:), an(:), at(:)

   ! vectors
   real(dp), allocatable :: g0(:), fmu(:), up(:), f(:), u(:), lam_n(:), lam_t(:)
   real(dp), allocatable :: ufull(:), reac(:)
   real(dp) :: step_uy(nsteps), step_ux(nsteps)
   character(len=6) :: step_phase(nsteps)

   ! library objects
   type(DsMatrix) :: kmat, nmat, tmat
   type(DsOptions) :: opts
   type(DsReport) :: rep
   type(c_ptr) :: prob
   integer :: st

   ! bookkeeping
   real(dp) :: dmat(3, 3), ke(8, 8), xe(4), ye(4)
   real(dp) :: sum_n, sum_t, rx, ry, scale, dev, x, dxc
   real(dp) :: max_err, max_dev, force_peak, factor_s, total_solve_s
   integer :: total_outer, shear_max_slip, shear_max_stick, max_slip
   integer :: final_open, final_stick, final_slip, steps_done, exit_code
   logical :: all_converged, resultant_ok
   integer :: i, j, k, el, n0, a, b, c, nd, r, cb, ra, pos, ed(8), gd(8)

   prob = c_null_ptr
   call parse_args()

   ! ---- mesh: node (i,j) = j*(nx+1)+i+1, x = i W/nx, y = j H/ny --------------------
   nnode = (nx + 1)*(ny + 1)
   nelem = nx*ny
   ndof = 2*nnode
   allocate (xn(nnode), yn(nnode), ien(4, nelem))
   do j = 0, ny
      do i = 0, nx
         nd = j*(nx + 1) + i + 1
         xn(nd) = (wid*real(i, dp))/real(nx, dp)
         yn(nd) = (hei*real(j, dp))/real(ny, dp)
      end do
   end do
   do j = 0, ny - 1
      do i = 0, nx - 1
         el = j*nx + i + 1
         n0 = j*(nx + 1) + i + 1
         ien(1, el) = n0
         ien(2, el) = n0 + 1
         ien(3, el) = n0 + 1 + (nx + 1)
         ien(4, el) = n0 + (nx + 1)
      end do
   end do

   ! ---- ID array: id(c,node) > 0 free equation, < 0 prescribed DOF ------------------
   allocate (id(2, nnode), pcomp(ndof))
   neq = 0
   npre = 0
   do nd = 1, nnode
      do c = 1, 2
         if ((nd - 1)/(nx + 1) == ny) then
            npre = npre + 1
            pcomp(npre) = c
            id(c, nd) = -npre
         else
            neq = neq + 1
            id(c, nd) = neq
         end if
      end do
   end do

   ! ---- sparsity pattern of the upper triangle of K from the node connectivity ------
   allocate (nadj(nnode), adj(maxadj, nnode))
   nadj = 0
   do el = 1, nelem
      do a = 1, 4
         do b = 1, 4
            call add_neighbour(ien(a, el), ien(b, el))
         end do
      end do
   end do
   allocate (ia(neq + 1))
   ia = 0
   do nd = 1, nnode                     ! count the entries of each row
      do c = 1, 2
         r = id(c, nd)
         if (r <= 0) cycle
         do k = 1, nadj(nd)
            do b = 1, 2
               cb = id(b, adj(k, nd))
               if (cb > 0 .and. (cb >= r .or. .not. upper)) ia(r + 1) = ia(r + 1) + 1
            end do
         end do
      end do
   end do
   ia(1) = 1
   do r = 1, neq
      ia(r + 1) = ia(r + 1) + ia(r)
   end do
   nzk = ia(neq + 1) - 1
   allocate (ja(nzk), ak(nzk))
   do nd = 1, nnode                     ! fill, then sort each row
      do c = 1, 2
         r = id(c, nd)
         if (r <= 0) cycle
         pos = ia(r)
         do k = 1, nadj(nd)
            do b = 1, 2
               cb = id(b, adj(k, nd))
               if (cb > 0 .and. (cb >= r .or. .not. upper)) then
                  ja(pos) = cb
                  pos = pos + 1
               end if
            end do
         end do
         call sort_ints(ja(ia(r):ia(r + 1) - 1))
      end do
   end do
   ak = 0.0_dp

   ! ---- assembly: K_ff into the CSR, K_fp (load) and K_p* (reactions) as triplets ---
   call plane_strain_d(e_mod, pois, dmat)
   allocate (kfp_r(16*nx), kfp_c(16*nx), kfp_v(16*nx))
   allocate (kpr_r(32*nx), kpr_c(32*nx), kpr_v(32*nx))
   nfp = 0
   npr = 0
   do el = 1, nelem
      do a = 1, 4
         nd = ien(a, el)
         xe(a) = xn(nd)
         ye(a) = yn(nd)
         ed(2*a - 1) = id(1, nd)
         ed(2*a) = id(2, nd)
         gd(2*a - 1) = 2*nd - 1
         gd(2*a) = 2*nd
      end do
      call q4_stiffness(xe, ye, dmat, ke, st)
      if (st /= 0) then
         write (error_unit, '(a,i0,a)') 'block2d_f: element ', el, ' has a non-positive Jacobian'
         stop 2
      end if
      do a = 1, 8
         ra = ed(a)
         do b = 1, 8
            cb = ed(b)
            if (ra > 0 .and. cb > 0) then
               if (cb >= ra .or. .not. upper) call add_to_k(ra, cb, ke(a, b))
            else if (ra > 0) then
               nfp = nfp + 1
               kfp_r(nfp) = ra
               kfp_c(nfp) = -cb
               kfp_v(nfp) = ke(a, b)
            else
               npr = npr + 1
               kpr_r(npr) = -ra
               kpr_c(npr) = gd(b)
               kpr_v(npr) = ke(a, b)
            end if
         end do
      end do
   end do

   ! ---- contacts: one per bottom node (node i, i = 1..nx+1) ------------------------
   m = nx + 1
   allocate (ian(m + 1), jan(m), an(m), iat(m + 1), jat(m), at(m), g0(m), fmu(m))
   do i = 1, m
      nd = i
      x = xn(nd)
      dxc = x - 0.5_dp*wid
      ian(i) = i
      jan(i) = id(2, nd)
      an(i) = -1.0_dp               ! outward normal (0,-1)
      iat(i) = i
      jat(i) = id(1, nd)
      at(i) = 1.0_dp                ! tangent (1,0)
      g0(i) = (curved*dxc)*dxc
      fmu(i) = fric
   end do
   ian(m + 1) = m + 1
   iat(m + 1) = m + 1

   if (upper) then
      kmat = ds_matrix_csr(neq, neq, ia, ja, ak, storage=DS_STORAGE_UPPER)
   else
      kmat = ds_matrix_csr(neq, neq, ia, ja, ak, storage=DS_STORAGE_FULL)
   end if
   nmat = ds_matrix_csr(m, neq, ian, jan, an)
   tmat = ds_matrix_csr(m, neq, iat, jat, at)
   st = ds_problem_new(2, kmat, nmat, tmat, prob)
   if (st /= DS_STATUS_OK) then
      call library_error('ds_problem_new', st)
      stop 2
   end if

   call ds_options_default(opts)
   opts%method = method
   if (tol > 0.0_dp) opts%tol = tol
   if (max_outer > 0) opts%max_outer = max_outer
   if (max_inner > 0) opts%max_inner = max_inner

   ! ---- load history ------------------------------------------------------------------
   do k = 1, npress
      step_uy(k) = (uy_fin*real(k, dp))/real(npress, dp)
      step_ux(k) = 0.0_dp
      step_phase(k) = 'press'
   end do
   do k = 1, nshear
      step_uy(npress + k) = uy_fin
      step_ux(npress + k) = (ux_fin*real(k, dp))/real(nshear, dp)
      step_phase(npress + k) = 'shear'
   end do
   do k = 1, nunload
      ! + 0 turns the -0 of the last unloading step into +0
      step_uy(npress + nshear + k) = uy_fin*(1.0_dp - real(k, dp)/real(nunload, dp)) + 0.0_dp
      step_ux(npress + nshear + k) = ux_fin
      step_phase(npress + nshear + k) = 'unload'
   end do
   step_uy(nsteps) = -0.2_dp*uy_fin
   step_ux(nsteps) = ux_fin
   step_phase(nsteps) = 'lift'

   allocate (up(npre), f(neq), u(neq), lam_n(m), lam_t(m), ufull(ndof), reac(npre))
   u = 0.0_dp
   lam_n = 0.0_dp
   lam_t = 0.0_dp

   if (.not. quiet) then
      write (*, '(a)') 'block2d_f: plane-strain Q4 block '//gtoa(wid)//' x '//gtoa(hei)// &
         ', '//itoa(nx)//' x '//itoa(ny)//' elements, E = '//gtoa(e_mod)//', nu = '//gtoa(pois)
      write (*, '(9x,i0,a,i0,a,i0,a,i0,a)') neq, ' free DOFs, ', npre, &
         ' prescribed (top edge), ', m, ' contacts, K: ', nzk, ' entries (CSR, '// &
         storage_name(upper)//')'
      write (*, '(a)') '         Coulomb mu = '//gtoa(fric)//', gap g = '//gtoa(curved)// &
         ' (x - W/2)^2, method '//method_name(method)//', tol '//gtoa(opts%tol)
      write (*, '(a4,1x,a6,2(1x,a9),3(1x,a5),2(1x,a18),1x,a9,1x,a6,2(1x,a9))') 'step', &
         'phase ', 'uy_top', 'ux_top', 'open', 'stick', 'slip', 'sum_lamN', 'sum_lamT', &
         'err', 'outer', 'time[s]', 'res_dev'
   end if
   if (dump) open (unit=20, file=trim(dump_file), status='replace', action='write')

   max_err = 0.0_dp
   max_dev = 0.0_dp
   force_peak = 0.0_dp
   factor_s = 0.0_dp
   total_solve_s = 0.0_dp
   total_outer = 0
   shear_max_slip = 0
   shear_max_stick = 0
   max_slip = 0
   final_open = -1
   final_stick = -1
   final_slip = -1
   steps_done = 0
   all_converged = .true.
   resultant_ok = .true.
   exit_code = 0

   do k = 1, nsteps
      ! prescribed displacement of the top edge and the load f = -K_fp u_p
      do i = 1, npre
         if (pcomp(i) == 1) then
            up(i) = step_ux(k)
         else
            up(i) = step_uy(k)
         end if
      end do
      f = 0.0_dp
      do a = 1, nfp
         f(kfp_r(a)) = f(kfp_r(a)) - kfp_v(a)*up(kfp_c(a))
      end do

      st = ds_step(prob, opts, DS_FRICTION_COULOMB, f, g0, fmu, u, lam_n, lam_t, rep)
      if (dump) write (20, '(a,6(1x,i0))') 'step', k, st, rep%n_open, rep%n_stick, &
         rep%n_slip, rep%outer_iterations
      if (st == DS_STATUS_NOT_CONVERGED) then
         all_converged = .false.
         write (error_unit, '(a,i0,4a,es10.3,a,i0,2a)') 'block2d_f: step ', k, ' (', &
            trim(step_phase(k)), ') did not converge: ', 'err = ', rep%err, ' after ', &
            rep%outer_iterations, ' outer iterations: ', ds_last_error_message()
         if (rep%err > max_err) max_err = rep%err
         exit_code = 1
         exit
      else if (st /= DS_STATUS_OK) then
         call library_error('ds_step', st)
         call ds_problem_free(prob)
         stop 2
      end if
      if (rep%status /= DS_STATUS_OK) then
         write (error_unit, '(a,i0)') 'block2d_f: ds_step returned OK but report%status = ', rep%status
         all_converged = .false.
         exit_code = 1
      end if
      steps_done = steps_done + 1
      if (dump) then
         do i = 1, neq
            write (20, '(a,2(1x,i0),1x,es25.16e3)') 'u', k, i, u(i)
         end do
         do i = 1, m
            write (20, '(a,2(1x,i0),1x,es25.16e3)') 'ln', k, i, lam_n(i)
         end do
         do i = 1, m
            write (20, '(a,2(1x,i0),1x,es25.16e3)') 'lt', k, i, lam_t(i)
         end do
      end if

      ! resultants: contact forces and the reaction of the top support
      sum_n = 0.0_dp
      sum_t = 0.0_dp
      do c = 1, m
         sum_n = sum_n + lam_n(c)
         sum_t = sum_t + lam_t(c)
      end do
      do nd = 1, nnode
         do c = 1, 2
            r = id(c, nd)
            if (r > 0) then
               ufull(2*nd - 2 + c) = u(r)
            else
               ufull(2*nd - 2 + c) = up(-r)
            end if
         end do
      end do
      reac = 0.0_dp
      do a = 1, npr
         reac(kpr_r(a)) = reac(kpr_r(a)) + kpr_v(a)*ufull(kpr_c(a))
      end do
      rx = 0.0_dp
      ry = 0.0_dp
      do i = 1, npre
         if (pcomp(i) == 1) then
            rx = rx + reac(i)
         else
            ry = ry + reac(i)
         end if
      end do
      ! R_y,top = -sum lambda_N and R_x,top = +sum lambda_T (see block2d.c)
      scale = max(abs(rx), abs(ry), abs(sum_n), abs(sum_t))
      if (scale > force_peak) force_peak = scale
      scale = force_peak
      dev = 0.0_dp
      if (scale > 0.0_dp) dev = max(abs(ry + sum_n), abs(rx - sum_t))/scale
      if (.not. (dev <= dev_tol)) then
         resultant_ok = .false.
         write (error_unit, '(a,i0,a,4(a,es19.12))') 'block2d_f: step ', k, &
            ': resultants do not balance:', ' R_y,top = ', ry, ', -sum lambda_N = ', &
            -sum_n, ', R_x,top = ', rx, ', sum lambda_T = ', sum_t
      end if
      if (.not. (dev <= max_dev)) max_dev = dev

      if (.not. (rep%err <= max_err)) max_err = rep%err
      total_outer = total_outer + int(rep%outer_iterations)
      total_solve_s = total_solve_s + rep%solve_seconds
      if (k == 1) factor_s = rep%factor_seconds
      if (rep%n_slip > max_slip) max_slip = int(rep%n_slip)
      if (step_phase(k) == 'shear') then
         if (rep%n_slip > shear_max_slip) shear_max_slip = int(rep%n_slip)
         if (rep%n_stick > shear_max_stick) shear_max_stick = int(rep%n_stick)
      end if
      final_open = int(rep%n_open)
      final_stick = int(rep%n_stick)
      final_slip = int(rep%n_slip)

      if (.not. quiet) write (*, &
         '(i4,1x,a6,2(1x,f9.5),3(1x,i5),2(1x,es18.10e3),1x,es9.2e2,1x,i6,2(1x,es9.2e2))') &
         k, step_phase(k), step_uy(k), step_ux(k), rep%n_open, rep%n_stick, rep%n_slip, &
         sum_n, sum_t, rep%err, rep%outer_iterations, rep%solve_seconds, dev
   end do
   if (dump) close (20)

   if (.not. quiet) write (*, '(a,es10.3,a,es10.3,a)') 'factorisation of K: ', factor_s, &
      ' s, total solve time: ', total_solve_s, ' s'
   if (resultant_ok .and. steps_done == nsteps) then
      write (*, '(a,es9.2,a)') 'resultant check: ok (max relative deviation ', max_dev, ')'
   else if (.not. resultant_ok) then
      write (*, '(a,es9.2,a,es8.1,a)') 'resultant check: FAILED (max relative deviation ', &
         max_dev, ' > ', dev_tol, ')'
      exit_code = 1
   else
      write (*, '(a,i0,a,i0,a)') 'resultant check: incomplete (', steps_done, ' of ', &
         nsteps, ' steps)'
   end if

   write (*, '(a)') 'SUMMARY method='//method_name(method)//' steps='//itoa(steps_done)// &
      ' contacts='//itoa(m)//' dofs='//itoa(neq)//' max_err='//rtoa(max_err)// &
      ' all_converged='//ltoa(all_converged .and. steps_done == nsteps)// &
      ' resultant_ok='//ltoa(resultant_ok)//' max_res_dev='//rtoa(max_dev)// &
      ' total_outer='//itoa(total_outer)//' max_slip_count='//itoa(max_slip)// &
      ' shear_max_slip='//itoa(shear_max_slip)//' shear_max_stick='// &
      itoa(shear_max_stick)//' final_open='//itoa(final_open)//' final_stick='// &
      itoa(final_stick)//' final_slip='//itoa(final_slip)

   call ds_problem_free(prob)
   if (exit_code /= 0) stop 1

contains

   !> Adds node nb to the neighbour list of node na (once).
   subroutine add_neighbour(na, nb)
      integer, intent(in) :: na, nb
      integer :: q
      do q = 1, nadj(na)
         if (adj(q, na) == nb) return
      end do
      if (nadj(na) == maxadj) then
         write (error_unit, '(a,i0)') 'block2d_f: too many neighbours of node ', na
         stop 2
      end if
      nadj(na) = nadj(na) + 1
      adj(nadj(na), na) = nb
   end subroutine add_neighbour

   !> Insertion sort (the rows are short).
   subroutine sort_ints(v)
      integer, intent(inout) :: v(:)
      integer :: p, q, t
      do p = 2, size(v)
         t = v(p)
         q = p - 1
         do while (q >= 1)
            if (v(q) <= t) exit
            v(q + 1) = v(q)
            q = q - 1
         end do
         v(q + 1) = t
      end do
   end subroutine sort_ints

   !> K(row, col) += v, for an entry of the upper triangle's pattern.
   subroutine add_to_k(row, col, v)
      integer, intent(in) :: row, col
      real(dp), intent(in) :: v
      integer :: q
      do q = ia(row), ia(row + 1) - 1
         if (ja(q) == col) then
            ak(q) = ak(q) + v
            return
         end if
      end do
      write (error_unit, '(a,i0,a,i0,a)') 'block2d_f: (', row, ',', col, ') not in the pattern of K'
      stop 2
   end subroutine add_to_k

   !> Plane-strain elasticity matrix.
   subroutine plane_strain_d(e, nu, d)
      real(dp), intent(in) :: e, nu
      real(dp), intent(out) :: d(3, 3)
      real(dp) :: cc
      cc = e/((1.0_dp + nu)*(1.0_dp - 2.0_dp*nu))
      d = 0.0_dp
      d(1, 1) = cc*(1.0_dp - nu)
      d(1, 2) = cc*nu
      d(2, 1) = cc*nu
      d(2, 2) = cc*(1.0_dp - nu)
      d(3, 3) = (cc*(1.0_dp - 2.0_dp*nu))/2.0_dp
   end subroutine plane_strain_d

   !> Q4 stiffness, 2x2 Gauss, unit thickness; local nodes counter-clockwise, DOFs
   !> (u1x, u1y, u2x, u2y, ...). ierr = -1 on a non-positive Jacobian. The operations
   !> are those of block2d.c, in the same order.
   subroutine q4_stiffness(xe, ye, d, ke, ierr)
      real(dp), intent(in) :: xe(4), ye(4), d(3, 3)
      real(dp), intent(out) :: ke(8, 8)
      integer, intent(out) :: ierr
      real(dp), parameter :: xi_a(4) = [-1.0_dp, 1.0_dp, 1.0_dp, -1.0_dp]
      real(dp), parameter :: eta_a(4) = [-1.0_dp, -1.0_dp, 1.0_dp, 1.0_dp]
      real(dp) :: gp, xi, eta, w, dxi(4), deta(4), dx(4), dy(4)
      real(dp) :: j00, j01, j10, j11, det, bm(3, 8), db(3, 8), s
      integer :: ig, jg, p, q, kk, l

      ierr = 0
      gp = 1.0_dp/sqrt(3.0_dp)
      ke = 0.0_dp
      do ig = 0, 1
         do jg = 0, 1
            xi = -gp
            if (ig == 1) xi = gp
            eta = -gp
            if (jg == 1) eta = gp
            w = 1.0_dp
            j00 = 0.0_dp
            j01 = 0.0_dp
            j10 = 0.0_dp
            j11 = 0.0_dp
            do p = 1, 4
               dxi(p) = (0.25_dp*xi_a(p))*(1.0_dp + eta*eta_a(p))
               deta(p) = (0.25_dp*eta_a(p))*(1.0_dp + xi*xi_a(p))
               j00 = j00 + dxi(p)*xe(p)     ! dx/dxi
               j01 = j01 + dxi(p)*ye(p)     ! dy/dxi
               j10 = j10 + deta(p)*xe(p)    ! dx/deta
               j11 = j11 + deta(p)*ye(p)    ! dy/deta
            end do
            det = j00*j11 - j01*j10
            if (.not. (det > 0.0_dp)) then
               ierr = -1
               return
            end if
            do p = 1, 4
               dx(p) = (j11*dxi(p) - j01*deta(p))/det
               dy(p) = ((-j10)*dxi(p) + j00*deta(p))/det
            end do
            do p = 1, 4
               bm(1, 2*p - 1) = dx(p)
               bm(1, 2*p) = 0.0_dp
               bm(2, 2*p - 1) = 0.0_dp
               bm(2, 2*p) = dy(p)
               bm(3, 2*p - 1) = dy(p)
               bm(3, 2*p) = dx(p)
            end do
            do kk = 1, 3
               do q = 1, 8
                  s = 0.0_dp
                  do l = 1, 3
                     s = s + d(kk, l)*bm(l, q)
                  end do
                  db(kk, q) = s
               end do
            end do
            do p = 1, 8
               do q = 1, 8
                  s = 0.0_dp
                  do kk = 1, 3
                     s = s + bm(kk, p)*db(kk, q)
                  end do
                  ke(p, q) = ke(p, q) + (s*det)*w
               end do
            end do
         end do
      end do
   end subroutine q4_stiffness

   subroutine library_error(what, status)
      character(len=*), intent(in) :: what
      integer, intent(in) :: status
      write (error_unit, '(5a,i0,2a)') 'block2d_f: ', what, ' failed: ', &
         ds_status_string(int(status, c_int32_t)), ' (', status, '): ', ds_last_error_message()
   end subroutine library_error

   function method_name(meth) result(name)
      integer, intent(in) :: meth
      character(len=:), allocatable :: name
      select case (meth)
      case (DS_METHOD_SPLIT)
         name = 'split'
      case (DS_METHOD_BLOCK_GS)
         name = 'block-gs'
      case (DS_METHOD_PGS)
         name = 'pgs'
      case (DS_METHOD_NEWTON)
         name = 'newton'
      case default
         name = '?'
      end select
   end function method_name

   function storage_name(up_tri) result(name)
      logical, intent(in) :: up_tri
      character(len=:), allocatable :: name
      name = 'full'
      if (up_tri) name = 'upper triangle'
   end function storage_name

   function itoa(v) result(str)
      integer, intent(in) :: v
      character(len=:), allocatable :: str
      character(len=32) :: buf
      write (buf, '(i0)') v
      str = trim(buf)
   end function itoa

   function rtoa(v) result(str)
      real(dp), intent(in) :: v
      character(len=:), allocatable :: str
      character(len=32) :: buf
      write (buf, '(es10.3e3)') v
      str = trim(adjustl(buf))
   end function rtoa

   function gtoa(v) result(str)
      real(dp), intent(in) :: v
      character(len=:), allocatable :: str
      character(len=32) :: buf
      write (buf, '(1pg12.5)') v
      str = trim(adjustl(buf))
   end function gtoa

   function ltoa(v) result(str)
      logical, intent(in) :: v
      character(len=1) :: str
      str = '0'
      if (v) str = '1'
   end function ltoa

   subroutine usage(unit)
      integer, intent(in) :: unit
      write (unit, '(a)') 'usage: block2d_f [options]'
      write (unit, '(a)') '  --method split|block-gs|pgs|newton  dual method (default split)'
      write (unit, '(a)') '  --nx N, --ny N               elements along x and y (default 40 x 20)'
      write (unit, '(a)') "  --E e, --nu nu               Young's modulus, Poisson ratio (default 1e4, 0.3)"
      write (unit, '(a)') '  --W w, --H h                 block width and height (default 2, 1)'
      write (unit, '(a)') '  --mu mu                      Coulomb coefficient (default 0.3)'
      write (unit, '(a)') '  --curved c                   foundation gap g = c (x - W/2)^2 (default 0.05)'
      write (unit, '(a)') '  --uy v, --ux v               final press and shear displacement of the top'
      write (unit, '(a)') '                               edge (default -0.05, 0.05)'
      write (unit, '(a)') "  --tol t                      solver tolerance on err (default: library's)"
      write (unit, '(a)') "  --max-outer n, --max-inner n iteration limits (default: library's)"
      write (unit, '(a)') '  --quiet                      print only the checks and the SUMMARY line'
      write (unit, '(a)') '  --storage upper|full         K in CSR as its upper triangle (default) or whole'
      write (unit, '(a)') '  --dump FILE                  write u, lambda_N, lambda_T of every step'
   end subroutine usage

   !> The options of block2d.c, same defaults, same checks; exit status 3 on error.
   subroutine parse_args()
      integer :: nargs, q, ios
      character(len=1024) :: opt, val
      logical :: ok

      e_mod = 1.0e4_dp
      pois = 0.3_dp
      wid = 2.0_dp
      hei = 1.0_dp
      nx = 40
      ny = 20
      fric = 0.3_dp
      curved = 0.05_dp
      uy_fin = -0.05_dp
      ux_fin = 0.05_dp
      tol = -1.0_dp
      max_outer = -1
      max_inner = -1
      method = DS_METHOD_SPLIT
      quiet = .false.
      dump = .false.
      upper = .true.
      dump_file = ''

      nargs = command_argument_count()
      q = 1
      do while (q <= nargs)
         call get_command_argument(q, opt)
         if (opt == '--help' .or. opt == '-h') then
            call usage(output_unit)
            stop
         else if (opt == '--quiet') then
            quiet = .true.
            q = q + 1
            cycle
         end if
         if (q + 1 > nargs) then
            write (error_unit, '(3a)') 'block2d_f: option ', trim(opt), ' needs a value'
            call usage(error_unit)
            stop 3
         end if
         call get_command_argument(q + 1, val)
         ok = .true.
         ios = 0
         select case (trim(opt))
         case ('--method')
            select case (trim(val))
            case ('split')
               method = DS_METHOD_SPLIT
            case ('block-gs')
               method = DS_METHOD_BLOCK_GS
            case ('pgs')
               method = DS_METHOD_PGS
            case ('newton')
               method = DS_METHOD_NEWTON
            case default
               ok = .false.
            end select
         case ('--nx')
            read (val, *, iostat=ios) nx
            ok = ios == 0 .and. nx >= 1
         case ('--ny')
            read (val, *, iostat=ios) ny
            ok = ios == 0 .and. ny >= 1
         case ('--E')
            read (val, *, iostat=ios) e_mod
            ok = ios == 0 .and. e_mod > 0.0_dp
         case ('--nu')
            read (val, *, iostat=ios) pois
            ok = ios == 0 .and. pois > -1.0_dp .and. pois < 0.5_dp
         case ('--W')
            read (val, *, iostat=ios) wid
            ok = ios == 0 .and. wid > 0.0_dp
         case ('--H')
            read (val, *, iostat=ios) hei
            ok = ios == 0 .and. hei > 0.0_dp
         case ('--mu')
            read (val, *, iostat=ios) fric
            ok = ios == 0 .and. fric >= 0.0_dp
         case ('--curved')
            read (val, *, iostat=ios) curved
            ok = ios == 0
         case ('--uy')
            read (val, *, iostat=ios) uy_fin
            ok = ios == 0 .and. uy_fin < 0.0_dp
         case ('--ux')
            read (val, *, iostat=ios) ux_fin
            ok = ios == 0
         case ('--tol')
            read (val, *, iostat=ios) tol
            ok = ios == 0 .and. tol > 0.0_dp
         case ('--max-outer')
            read (val, *, iostat=ios) max_outer
            ok = ios == 0 .and. max_outer > 0
         case ('--max-inner')
            read (val, *, iostat=ios) max_inner
            ok = ios == 0 .and. max_inner > 0
         case ('--storage')
            upper = trim(val) == 'upper'
            ok = upper .or. trim(val) == 'full'
         case ('--dump')
            dump_file = val
            dump = .true.
         case default
            write (error_unit, '(2a)') 'block2d_f: unknown option ', trim(opt)
            call usage(error_unit)
            stop 3
         end select
         if (.not. ok) then
            write (error_unit, '(5a)') "block2d_f: bad value '", trim(val), "' for ", trim(opt)
            call usage(error_unit)
            stop 3
         end if
         q = q + 2
      end do
      ! the equation numbers are default INTEGERs
      if (real(nx + 1, dp)*real(ny + 1, dp)*2.0_dp > 2.0e9_dp) then
         write (error_unit, '(a)') 'block2d_f: mesh too large for 32-bit indices'
         stop 3
      end if
   end subroutine parse_args

end program block2d_f
