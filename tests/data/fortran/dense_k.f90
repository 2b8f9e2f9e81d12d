! tests/fortran.rs: a dense K through ds_matrix_dense (upper triangle of a padded
! lda = 3 array, -99 where nothing may be read) gives the answer of the same K as
! COO, and the report names the dense factorisation (DS_ORDERING_DENSE).
program dense_k
   use, intrinsic :: iso_c_binding
   use dualsplit
   implicit none
   real(c_double), target :: kd(3, 2), kv(3), nv(1), tv(1)
   integer(c_int32_t), target :: ki(3), kj(3), ni(1), nj(1), ti(1), tj(1)
   type(DsMatrix) :: k, kc, n, t
   type(DsReport) :: rep
   type(DsOptions) :: opts
   type(c_ptr) :: pa = c_null_ptr, pb = c_null_ptr
   real(c_double) :: f(2), g(1), p(1), u1(2), u2(2), ln1(1), ln2(1), lt1(1), lt2(1)
   integer(c_int32_t) :: st1, st2

   kd = reshape([4.0d0, -99.0d0, -99.0d0, 1.0d0, 3.0d0, -99.0d0], [3, 2])
   k = ds_matrix_dense(2_c_int32_t, 2_c_int32_t, kd, 3_c_int32_t, storage=DS_STORAGE_UPPER)
   kv = [4.0d0, 1.0d0, 3.0d0]
   ki = [1, 1, 2]
   kj = [1, 2, 2]
   kc = ds_matrix_coo(2_c_int32_t, 2_c_int32_t, 3_c_int32_t, ki, kj, kv, storage=DS_STORAGE_UPPER)
   nv = [-1.0d0]
   ni = [1]
   nj = [2]
   n = ds_matrix_coo(1_c_int32_t, 2_c_int32_t, 1_c_int32_t, ni, nj, nv)
   tv = [1.0d0]
   ti = [1]
   tj = [1]
   t = ds_matrix_coo(1_c_int32_t, 2_c_int32_t, 1_c_int32_t, ti, tj, tv)
   f = [0.5d0, -2.0d0]
   g = [0.0d0]
   p = [0.3d0]
   st1 = ds_problem_new(2, k, n, t, pa)
   st2 = ds_problem_new(2, kc, n, t, pb)
   if (st1 /= DS_STATUS_OK .or. st2 /= DS_STATUS_OK) then
      print *, 'ds_problem_new: ', ds_last_error_message()
      stop 1
   end if
   call ds_options_default(opts) ! the report's fields of this version are written
   st1 = ds_solve(pa, opts=opts, friction=DS_FRICTION_TRESCA, f=f, g=g, bound=p, u=u1, lambda_n=ln1, &
                  lambda_t=lt1, report=rep)
   st2 = ds_solve(pb, friction=DS_FRICTION_TRESCA, f=f, g=g, bound=p, u=u2, lambda_n=ln2, &
                  lambda_t=lt2)
   if (st1 /= DS_STATUS_OK .or. st2 /= DS_STATUS_OK) then
      print *, 'ds_solve: ', ds_last_error_message()
      stop 1
   end if
   print '(a, i0)', 'ORDERING ', rep%ordering
   print '(a, 3es24.16)', 'DIFF ', maxval(abs(u1 - u2)), abs(ln1(1) - ln2(1)), abs(lt1(1) - lt2(1))
   print '(a, 4es24.16)', 'DENSE ', u1, ln1(1), lt1(1)
   call ds_problem_free(pa)
   call ds_problem_free(pb)
end program dense_k
