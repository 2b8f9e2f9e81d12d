!> dualsplit -- Fortran 2003 interface (ISO_C_BINDING) to the C API of include/dualsplit.h.
!>
!> Frictional contact of an elastic body on a rigid foundation, one load increment at a
!> time, by N. Pop's dual splitting on the condensed dual problem. Every C function,
!> enum and struct of dualsplit.h has its Fortran counterpart here; tests/fortran.rs
!> fails when this file and the header drift apart.
!>
!> Sign conventions (as in the header):
!>   K u = f - N^T lambda_N - T^T lambda_T     (equilibrium)
!>   N u <= g,  lambda_N >= 0,  lambda_N,i (g_i - (N u)_i) = 0
!>   |lambda_T,i| <= p_i (Tresca)  or  <= mu_i lambda_N,i (Coulomb)
!>
!> Usage from Fortran 90 style code (1-based CSR of default INTEGER, REAL(8) vectors):
!>
!>     use dualsplit
!>     type(DsMatrix)  :: k, n, t
!>     type(DsOptions) :: opts
!>     type(DsReport)  :: rep
!>     type(c_ptr)     :: pb = c_null_ptr     ! the handle (DsProblem *)
!>     integer         :: st
!>     k = ds_matrix_csr(neq, neq, ia, ja, a, storage=DS_STORAGE_UPPER)   ! base 1
!>     n = ds_matrix_csr(m, neq, ian, jan, an)
!>     t = ds_matrix_csr(m, neq, iat, jat, at)
!>     st = ds_problem_new(2, k, n, t, pb)
!>     if (st /= DS_STATUS_OK) print *, ds_status_string(st), ': ', ds_last_error_message()
!>     call ds_options_default(opts)
!>     st = ds_step(pb, opts, DS_FRICTION_COULOMB, f, g0, mu, u, lam_n, lam_t, rep)
!>     call ds_problem_free(pb)                ! pb is c_null_ptr afterwards
!>
!> A DsMatrix only borrows the caller's arrays (the library reads them during the
!> ds_problem_new / ds_problem_refactor / ds_problem_set_contacts call and keeps
!> nothing): give them the TARGET attribute (or make them ALLOCATABLE, TARGET) and
!> pass whole contiguous arrays, so that the addresses ds_matrix_csr / _csc / _coo
!> store stay valid until that call. Index arrays may be default INTEGER (int32,
!> DS_INDEX_TYPE_I32) or INTEGER(8) (DS_INDEX_TYPE_I64); the helpers pick the type.
!>
!> Callbacks (ds_problem_set_monitor, ds_problem_set_log) are BIND(C) procedures of a
!> module with the interfaces ds_monitor_fn and ds_log_fn; a log callback converts its
!> message with ds_string_from_c.
!>
!> Every function returning a status returns one of the DS_STATUS_* values; on error
!> the outputs are untouched (DS_STATUS_NOT_CONVERGED writes the report only,
!> DS_STATUS_STOPPED the last iterate and the report, DS_STATUS_STALLED and
!> DS_STATUS_TIME_LIMIT the iterate with the lowest err and the report) and the
!> handle stays usable. Compile this file with the program (gfortran -c dualsplit.f90) and link with libdualsplit (see README.md).
module dualsplit
   use, intrinsic :: iso_c_binding, only: c_int, c_int32_t, c_int64_t, c_double, c_float, &
      c_ptr, c_null_ptr, c_char, c_size_t, c_associated, c_f_pointer, c_loc, c_funptr, &
      c_null_funptr, c_funloc, c_null_char
   implicit none
   private

   ! The handle is a TYPE(C_PTR); re-exported so that `use dualsplit` is enough.
   public :: c_ptr, c_null_ptr, c_associated

   ! ---------------------------------------------------------------------------------
   ! Enums (C enum values; the C API passes them as int32_t)
   ! ---------------------------------------------------------------------------------

   !> DsStatus: result of a call. DS_STATUS_OK is 0, every other value an error.
   integer(c_int32_t), parameter, public :: DS_STATUS_OK = 0
   integer(c_int32_t), parameter, public :: DS_STATUS_NULL_POINTER = 1
   integer(c_int32_t), parameter, public :: DS_STATUS_BAD_SIZE = 2
   integer(c_int32_t), parameter, public :: DS_STATUS_BAD_INDEX = 3
   integer(c_int32_t), parameter, public :: DS_STATUS_NOT_FINITE = 4
   integer(c_int32_t), parameter, public :: DS_STATUS_NOT_SYMMETRIC = 5
   integer(c_int32_t), parameter, public :: DS_STATUS_NOT_POSITIVE_DEFINITE = 6
   integer(c_int32_t), parameter, public :: DS_STATUS_NEGATIVE_FRICTION = 7
   integer(c_int32_t), parameter, public :: DS_STATUS_NOT_CONVERGED = 8
   integer(c_int32_t), parameter, public :: DS_STATUS_OUT_OF_MEMORY = 9
   integer(c_int32_t), parameter, public :: DS_STATUS_BAD_ARGUMENT = 10
   integer(c_int32_t), parameter, public :: DS_STATUS_IO_ERROR = 11
   integer(c_int32_t), parameter, public :: DS_STATUS_PANIC = 12
   integer(c_int32_t), parameter, public :: DS_STATUS_STOPPED = 13
   integer(c_int32_t), parameter, public :: DS_STATUS_STALLED = 14
   integer(c_int32_t), parameter, public :: DS_STATUS_TIME_LIMIT = 15
   integer(c_int32_t), parameter, public :: DS_STATUS_HOST_SOLVE_FAILED = 16
   integer(c_int32_t), parameter, public :: DS_STATUS_BUSY = 17

   !> DsFormat: layout of a DsMatrix (CSparse naming).
   integer(c_int32_t), parameter, public :: DS_FORMAT_CSR = 0
   integer(c_int32_t), parameter, public :: DS_FORMAT_CSC = 1
   integer(c_int32_t), parameter, public :: DS_FORMAT_COO = 2
   !> Dense column-major (a Schur complement from MUMPS, PARDISO or PETSc): the
   !> DsMatrix's nnz holds the leading dimension, p and i are not read (0.7).
   integer(c_int32_t), parameter, public :: DS_FORMAT_DENSE = 3

   !> DsIndexType: integer width of a DsMatrix's p and i arrays.
   integer(c_int32_t), parameter, public :: DS_INDEX_TYPE_I32 = 0
   integer(c_int32_t), parameter, public :: DS_INDEX_TYPE_I64 = 1

   !> DsStorage: which part of a symmetric K is stored (N and T must be FULL).
   integer(c_int32_t), parameter, public :: DS_STORAGE_FULL = 0
   integer(c_int32_t), parameter, public :: DS_STORAGE_UPPER = 1
   integer(c_int32_t), parameter, public :: DS_STORAGE_LOWER = 2

   !> DsMethod: the iterative method on the condensed dual (DsOptions%method).
   integer(c_int32_t), parameter, public :: DS_METHOD_SPLIT = 0
   integer(c_int32_t), parameter, public :: DS_METHOD_BLOCK_GS = 1
   integer(c_int32_t), parameter, public :: DS_METHOD_PGS = 2
   integer(c_int32_t), parameter, public :: DS_METHOD_NEWTON = 3
   integer(c_int32_t), parameter, public :: DS_METHOD_SPLIT_MPRGP = 4
   integer(c_int32_t), parameter, public :: DS_METHOD_MPRGP = 5
   integer(c_int32_t), parameter, public :: DS_METHOD_AUTO = 6

   !> DsDualForm: dense or matrix-free products with A (DsOptions%dual_form).
   integer(c_int32_t), parameter, public :: DS_DUAL_FORM_AUTO = 0
   integer(c_int32_t), parameter, public :: DS_DUAL_FORM_DENSE = 1
   integer(c_int32_t), parameter, public :: DS_DUAL_FORM_MATRIX_FREE = 2

   !> DsOrdering: the fill-reducing ordering of K (DsOptions%ordering).
   integer(c_int32_t), parameter, public :: DS_ORDERING_AUTO = 0
   integer(c_int32_t), parameter, public :: DS_ORDERING_AMD = 1
   integer(c_int32_t), parameter, public :: DS_ORDERING_METIS = 2
   !> Reported only: K given dense, factored by dense Cholesky (0.7).
   integer(c_int32_t), parameter, public :: DS_ORDERING_DENSE = 3

   !> DsFriction: what the `bound` array of ds_solve / ds_step holds.
   integer(c_int32_t), parameter, public :: DS_FRICTION_TRESCA = 0
   integer(c_int32_t), parameter, public :: DS_FRICTION_COULOMB = 1

   ! ---------------------------------------------------------------------------------
   ! Structs: component order and types exactly as in dualsplit.h
   ! ---------------------------------------------------------------------------------

   !> Options of ds_solve / ds_step. Fill with ds_options_default (which passes
   !> c_sizeof of this type to ds_options_init), then change fields.
   type, bind(C), public :: DsOptions
      integer(c_int32_t) :: struct_size   !< uint32_t in C: sizeof(DsOptions), set by ds_options_init
      integer(c_int32_t) :: method        !< a DS_METHOD_* value (default DS_METHOD_AUTO from 0.6)
      real(c_double)     :: tol           !< stop when err <= tol (default 1e-10)
      integer(c_int64_t) :: max_outer     !< outer iterations, >= 0 (default 10000)
      integer(c_int64_t) :: max_inner     !< Gauss-Seidel sweeps per sub-problem, >= 1 (default 1000)
      integer(c_int32_t) :: dual_form     !< a DS_DUAL_FORM_* value (default DS_DUAL_FORM_AUTO)
      real(c_double)     :: max_seconds   !< wall-clock budget of a solve in seconds, 0 = none (default 0)
      integer(c_int64_t) :: stall_window  !< stagnation test window in outer iterations, 0 = off (default 100)
      real(c_double)     :: stall_factor  !< progress: the best err drops by this factor per window (default 0.9)
      integer(c_int32_t) :: threads       !< the handle's threads, 0 = all cores, 1 = the calling thread (default 0)
      integer(c_int32_t) :: ordering      !< a DS_ORDERING_* value (default DS_ORDERING_AUTO)
      integer(c_int64_t) :: max_memory    !< uint64_t in C: bytes the large allocations may take, 0 = the machine's limit (0.5)
      integer(c_int32_t) :: host_loop     !< 1: the handle serves a host's Newton loop (0.10)
   end type DsOptions

   !> sizeof(DsOptions) in C: what ds_options_init is told (tests/fortran.rs checks
   !> it against the C compiler's sizeof).
   integer(c_size_t), parameter, public :: DS_OPTIONS_SIZE = 88

   !> A sparse matrix borrowed from the caller (CSparse naming); see ds_matrix_csr.
   type, bind(C), public :: DsMatrix
      integer(c_int32_t) :: format        !< DS_FORMAT_CSR, DS_FORMAT_CSC or DS_FORMAT_COO
      integer(c_int32_t) :: index_type    !< DS_INDEX_TYPE_I32 or DS_INDEX_TYPE_I64
      integer(c_int32_t) :: base          !< 0 (C) or 1 (Fortran)
      integer(c_int32_t) :: storage       !< DS_STORAGE_FULL, _UPPER or _LOWER (K only)
      integer(c_int64_t) :: nrows
      integer(c_int64_t) :: ncols
      integer(c_int64_t) :: nnz           !< COO: number of triplets; CSR/CSC: ignored
      type(c_ptr)        :: p             !< CSR row / CSC column pointers; COO column indices
      type(c_ptr)        :: i             !< CSR column / CSC row indices; COO row indices
      type(c_ptr)        :: x             !< values (const double *)
   end type DsMatrix

   !> What a solve reports besides u and the multipliers (the 0.4 and 0.5 fields are
   !> written because this module passes DsOptions of version 0.5).
   type, bind(C), public :: DsReport
      integer(c_int32_t) :: status        !< DS_STATUS_OK or DS_STATUS_NOT_CONVERGED
      integer(c_int32_t) :: method        !< the DS_METHOD_* that ran
      real(c_double)     :: err           !< relative KKT error (dimensionless)
      real(c_double)     :: equilibrium_residual
      integer(c_int64_t) :: outer_iterations
      integer(c_int64_t) :: inner_iterations
      integer(c_int64_t) :: n_open        !< contacts with lambda_N = 0
      integer(c_int64_t) :: n_stick       !< closed, |lambda_T| < p
      integer(c_int64_t) :: n_slip        !< closed, |lambda_T| = p (frictionless closed too)
      real(c_double)     :: factor_seconds
      real(c_double)     :: condense_seconds
      real(c_double)     :: solve_seconds
      integer(c_int32_t) :: ordering      !< DS_ORDERING_AMD, _METIS or _DENSE (0.7): K's factor (0.4)
      integer(c_int32_t) :: threads       !< threads of the handle's pool (0.4)
      integer(c_int64_t) :: factor_nnz    !< nonzeros of K's Cholesky factor (0.4)
      real(c_double)     :: factor_flops  !< flops of one factorisation of K (0.4)
      real(c_double)     :: analyse_seconds !< seconds of K's ordering and symbolic analysis (0.4)
      integer(c_int64_t) :: memory_predicted !< uint64_t in C: predicted peak bytes of this solve (0.5)
      integer(c_int64_t) :: memory_peak   !< uint64_t in C: counted peak bytes of this solve (0.5)
   end type DsReport

   !> What the analysis tells before any numeric work (ds_analyse, ds_problem_info).
   !> ds_info_init sets struct_size; the uint64_t fields of C are integer(c_int64_t).
   type, bind(C), public :: DsInfo
      integer(c_int32_t) :: struct_size   !< uint32_t in C: sizeof(DsInfo), set by ds_info_init
      integer(c_int32_t) :: d
      integer(c_int64_t) :: n             !< DOFs
      integer(c_int64_t) :: m             !< contacts
      integer(c_int64_t) :: c             !< dual unknowns d m
      integer(c_int64_t) :: nnz_k         !< stored entries of K, both triangles
      integer(c_int64_t) :: factor_nnz    !< entries of K's Cholesky factor
      real(c_double)     :: factor_flops  !< flops of one factorisation of K
      integer(c_int32_t) :: ordering      !< DS_ORDERING_AMD or DS_ORDERING_METIS
      integer(c_int32_t) :: setup_form    !< DS_DUAL_FORM_DENSE or DS_DUAL_FORM_MATRIX_FREE
      integer(c_int32_t) :: method        !< the DS_METHOD_* of the options
      integer(c_int32_t) :: solve_form    !< the DS_DUAL_FORM_* a solve with it uses
      integer(c_int64_t) :: setup_bytes   !< predicted peak bytes of ds_problem_new
      integer(c_int64_t) :: resident_bytes !< predicted bytes a handle holds
      integer(c_int64_t) :: solve_bytes   !< predicted peak bytes of one solve
      integer(c_int64_t) :: refactor_bytes !< predicted peak bytes of ds_problem_refactor
      integer(c_int64_t) :: memory_limit  !< the limit checked against, bytes (0: unknown)
      real(c_double)     :: analyse_seconds
      integer(c_int64_t) :: compliant_contacts !< contacts with finite c_N or k_T (0.8)
      integer(c_int64_t) :: power_law_contacts !< of those, m_N /= 1 (0.8)
      integer(c_int64_t) :: blocks_age    !< refactors since the contact blocks were computed (0.10)
      real(c_double)     :: err_factor    !< err's factor for kept blocks, 1 to 3 (0.10)
   end type DsInfo

   !> sizeof(DsInfo) in C (tests/fortran.rs checks it).
   integer(c_size_t), parameter, public :: DS_INFO_SIZE = 152

   !> What the last ds_solve or ds_step on a handle cost (ds_problem_last_cost):
   !> where its seconds went and the host's solves. ds_cost_init sets struct_size.
   type, bind(C), public :: DsCost
      integer(c_int32_t) :: struct_size   !< uint32_t in C: sizeof(DsCost), set by ds_cost_init
      integer(c_int32_t) :: solved        !< 1 once a solve returned a report, else 0 (all fields 0)
      real(c_double)     :: solve_seconds !< DsReport%solve_seconds of that call
      real(c_double)     :: rhs_seconds   !< the right-hand side
      real(c_double)     :: iterate_seconds !< the method's iterations
      real(c_double)     :: recover_seconds !< the recovery of u and err
      integer(c_int64_t) :: host_solves   !< right-hand sides the host's solve took (0: own factor)
      real(c_double)     :: host_seconds  !< seconds inside the host's solve
      real(c_double)     :: library_seconds !< solve_seconds - host_seconds
   end type DsCost

   !> sizeof(DsCost) in C (tests/fortran.rs checks it).
   integer(c_size_t), parameter, public :: DS_COST_SIZE = 64

   !> What the monitor callback receives after every outer iteration.
   type, bind(C), public :: DsProgress
      integer(c_int64_t) :: iteration     !< outer iterations done so far (1 after the first)
      real(c_double)     :: err           !< the current err (dimensionless)
      integer(c_int64_t) :: n_open
      integer(c_int64_t) :: n_stick
      integer(c_int64_t) :: n_slip
      real(c_double)     :: elapsed_seconds
   end type DsProgress

   !> The host's own solver of K for ds_problem_new_host (0.9): set struct_size
   !> to DS_HOST_SOLVER_SIZE, n, solve = c_funloc(a BIND(C) function with the
   !> interface ds_host_solve_fn), context (c_null_ptr, or c_loc of the
   !> host's data, valid until the handle is freed) and inverse_entries
   !> (c_null_funptr, or a function with the interface ds_host_inverse_fn);
   !> solve_single (0.10, optional: c_null_funptr by default, or a function
   !> with the interface ds_host_solve_single_fn for the loose products in
   !> single precision); solve_rows (0.10, optional: c_null_funptr by default,
   !> or a function with the interface ds_host_solve_rows_fn for the products
   !> on the contact DOFs alone); blocks (0.10: DS_HOST_BLOCKS_AUTO by
   !> default, DS_HOST_BLOCKS_SOLVES or DS_HOST_BLOCKS_FACTOR). context and
   !> inverse_entries default to c_null_ptr and c_null_funptr.
   type, bind(C), public :: DsHostSolver
      integer(c_int32_t) :: struct_size   !< uint32_t in C: sizeof(DsHostSolver)
      integer(c_int64_t) :: n             !< DOFs of K, >= 1
      type(c_funptr)     :: solve         !< DsHostSolveFn: x := K^-1 x (required)
      type(c_ptr)        :: context = c_null_ptr !< passed back to solve unchanged
      type(c_funptr)     :: inverse_entries = c_null_funptr !< DsHostInverseFn (optional)
      type(c_funptr)     :: solve_single = c_null_funptr !< DsHostSolveSingleFn (optional, 0.10)
      type(c_funptr)     :: solve_rows = c_null_funptr !< DsHostSolveRowsFn (optional, 0.10)
      integer(c_int32_t) :: blocks = 0    !< DS_HOST_BLOCKS_*: the contact blocks (0.10)
   end type DsHostSolver

   !> sizeof(DsHostSolver) in C (tests/fortran.rs checks it).
   integer(c_int32_t), parameter, public :: DS_HOST_SOLVER_SIZE = 64

   !> DsHostBlocks: how the contacts' blocks are obtained (DsHostSolver%blocks):
   !> the host's inverse_entries where given, else the cheaper of the library's
   !> own factor of K (handed over) and the host's solves (AUTO, the default);
   !> by the host's solves; by the library's own factor of K.
   integer(c_int32_t), parameter, public :: DS_HOST_BLOCKS_AUTO = 0
   integer(c_int32_t), parameter, public :: DS_HOST_BLOCKS_SOLVES = 1
   integer(c_int32_t), parameter, public :: DS_HOST_BLOCKS_FACTOR = 2

   ! ---------------------------------------------------------------------------------
   ! Callbacks (DsMonitorFn, DsLogFn): write them as BIND(C) procedures of a module
   ! with these interfaces, e.g.
   !
   !     integer(c_int32_t) function my_monitor(progress, user_data) bind(C)
   !        type(DsProgress), intent(in) :: progress
   !        type(c_ptr), value :: user_data
   !        my_monitor = 0                  ! nonzero stops the solve (DS_STATUS_STOPPED)
   !     end function
   !     st = ds_problem_set_monitor(pb, my_monitor)
   !
   ! They must not call the library on the same handle, nor STOP the program.
   ! ---------------------------------------------------------------------------------

   abstract interface
      !> typedef int32_t (*DsMonitorFn)(const struct DsProgress *progress, void *user_data);
      function ds_monitor_fn(progress, user_data) result(stop_solve) bind(C)
         import :: c_int32_t, c_ptr, DsProgress
         type(DsProgress), intent(in) :: progress
         type(c_ptr), value :: user_data
         integer(c_int32_t) :: stop_solve
      end function ds_monitor_fn

      !> typedef void (*DsLogFn)(int32_t level, const char *message, void *user_data);
      !> message: convert with ds_string_from_c(message).
      subroutine ds_log_fn(level, message, user_data) bind(C)
         import :: c_int32_t, c_ptr
         integer(c_int32_t), value :: level
         type(c_ptr), value :: message
         type(c_ptr), value :: user_data
      end subroutine ds_log_fn

      !> typedef int32_t (*DsHostSolveFn)(void *context, int64_t n, int64_t ncols,
      !>     double *x, int64_t ld);
      !> x(ld, ncols) := K^-1 x; return 0, or an error code of the host's
      !> (ds_solve / ds_step then return DS_STATUS_HOST_SOLVE_FAILED).
      function ds_host_solve_fn(context, n, ncols, x, ld) result(code) bind(C)
         import :: c_int32_t, c_int64_t, c_double, c_ptr
         type(c_ptr), value :: context
         integer(c_int64_t), value :: n, ncols, ld
         real(c_double), intent(inout) :: x(ld, *)
         integer(c_int32_t) :: code
      end function ds_host_solve_fn

      !> typedef int32_t (*DsHostSolveSingleFn)(void *context, int64_t n,
      !>     int64_t ncols, float *x, int64_t ld);
      !> As ds_host_solve_fn in single precision (optional, version 0.10).
      function ds_host_solve_single_fn(context, n, ncols, x, ld) result(code) bind(C)
         import :: c_int32_t, c_int64_t, c_float, c_ptr
         type(c_ptr), value :: context
         integer(c_int64_t), value :: n, ncols, ld
         real(c_float), intent(inout) :: x(ld, *)
         integer(c_int32_t) :: code
      end function ds_host_solve_single_fn

      !> typedef int32_t (*DsHostSolveRowsFn)(void *context, int64_t nrows,
      !>     const int64_t *rows, int64_t ncols, double *x, int64_t ld,
      !>     int32_t approximate);
      !> x(ld, ncols) holds the right-hand sides at the 0-based DOFs rows(1:nrows)
      !> (zero elsewhere); overwrite it with K^-1 of them at the same DOFs
      !> (optional, version 0.10; approximate = 1: a single-precision answer serves).
      function ds_host_solve_rows_fn(context, nrows, rows, ncols, x, ld, approximate) &
            result(code) bind(C)
         import :: c_int32_t, c_int64_t, c_double, c_ptr
         type(c_ptr), value :: context
         integer(c_int64_t), value :: nrows, ncols, ld
         integer(c_int64_t), intent(in) :: rows(*)
         real(c_double), intent(inout) :: x(ld, *)
         integer(c_int32_t), value :: approximate
         integer(c_int32_t) :: code
      end function ds_host_solve_rows_fn

      !> typedef int32_t (*DsHostInverseFn)(void *context, int64_t count,
      !>     const int64_t *rows, const int64_t *cols, double *values);
      !> values(k) := (K^-1)(rows(k) + 1, cols(k) + 1): 0-based DOFs.
      function ds_host_inverse_fn(context, count, rows, cols, values) result(code) bind(C)
         import :: c_int32_t, c_int64_t, c_double, c_ptr
         type(c_ptr), value :: context
         integer(c_int64_t), value :: count
         integer(c_int64_t), intent(in) :: rows(*), cols(*)
         real(c_double), intent(out) :: values(*)
         integer(c_int32_t) :: code
      end function ds_host_inverse_fn
   end interface
   public :: ds_monitor_fn, ds_log_fn

   ! ---------------------------------------------------------------------------------
   ! Public Fortran procedures (thin wrappers of the C functions, same names)
   ! ---------------------------------------------------------------------------------

   public :: ds_last_error_message, ds_status_string, ds_options_default, ds_options_init
   public :: ds_version
   public :: ds_problem_new_host
   public :: ds_problem_new, ds_problem_new_opts, ds_problem_free, ds_problem_refactor, ds_problem_set_contacts
   public :: ds_problem_sizes, ds_solve, ds_step, ds_history_reset, ds_problem_set_compliance
   public :: ds_solve_iteration
   public :: ds_analyse, ds_problem_info, ds_info_init, ds_problem_last_cost, ds_cost_init
   public :: ds_problem_set_monitor, ds_problem_set_log, ds_problem_dump, ds_string_from_c
   public :: ds_matrix_csr, ds_matrix_csc, ds_matrix_coo, ds_matrix_dense

   !> ds_problem_sizes(problem, n_dofs, n_contacts, d): n_dofs and n_contacts default
   !> INTEGER or INTEGER(8).
   interface ds_problem_sizes
      module procedure ds_problem_sizes_i32, ds_problem_sizes_i64
   end interface ds_problem_sizes

   !> mat = ds_matrix_csr(nrows, ncols, ia, ja, a [, storage] [, base]): a CSR DsMatrix
   !> over ia (nrows+1 row pointers), ja (column indices), a (values); index arrays
   !> INTEGER (int32) or INTEGER(8); base 1 unless given.
   interface ds_matrix_csr
      module procedure ds_matrix_csr_i32, ds_matrix_csr_i64
   end interface ds_matrix_csr

   !> mat = ds_matrix_csc(nrows, ncols, colptr, rowind, a [, storage] [, base]).
   interface ds_matrix_csc
      module procedure ds_matrix_csc_i32, ds_matrix_csc_i64
   end interface ds_matrix_csc

   !> mat = ds_matrix_coo(nrows, ncols, nnz, irow, jcol, a [, storage] [, base]):
   !> triplets, duplicates summed.
   interface ds_matrix_coo
      module procedure ds_matrix_coo_i32, ds_matrix_coo_i64
   end interface ds_matrix_coo

   !> mat = ds_matrix_dense(nrows, ncols, a, lda [, storage]): a dense column-major
   !> DsMatrix over a(lda, ncols) (or a rank-1 array of lda*ncols), lda >= nrows (a
   !> Schur complement from MUMPS, PARDISO or PETSc as K: storage DS_STORAGE_UPPER /
   !> LOWER reads one triangle).
   interface ds_matrix_dense
      module procedure ds_matrix_dense_i32, ds_matrix_dense_i64, ds_matrix_dense_i32_r2, &
         ds_matrix_dense_i64_r2
   end interface ds_matrix_dense

   ! ---------------------------------------------------------------------------------
   ! The C functions (private; called through the wrappers below)
   ! ---------------------------------------------------------------------------------

   interface
      ! const char *ds_last_error_message(void);
      function c_ds_last_error_message() result(msg) bind(C, name="ds_last_error_message")
         import :: c_ptr
         type(c_ptr) :: msg
      end function c_ds_last_error_message

      ! void ds_options_default(struct DsOptions *opts);  (programs of older headers)
      subroutine c_ds_options_default(opts) bind(C, name="ds_options_default")
         import :: DsOptions
         type(DsOptions), intent(inout) :: opts
      end subroutine c_ds_options_default

      ! enum DsStatus ds_options_init(struct DsOptions *opts, size_t size);
      function c_ds_options_init(opts, size) result(status) bind(C, name="ds_options_init")
         import :: c_int, c_size_t, DsOptions
         type(DsOptions), intent(inout) :: opts
         integer(c_size_t), value :: size
         integer(c_int) :: status
      end function c_ds_options_init

      ! enum DsStatus ds_problem_new(int32_t d, const struct DsMatrix *k,
      !     const struct DsMatrix *n, const struct DsMatrix *t, struct DsProblem **out);
      function c_ds_problem_new(d, k, n, t, out) result(status) bind(C, name="ds_problem_new")
         import :: c_int, c_int32_t, c_ptr, DsMatrix
         integer(c_int32_t), value :: d
         type(DsMatrix), intent(in) :: k, n, t
         type(c_ptr), intent(inout) :: out
         integer(c_int) :: status
      end function c_ds_problem_new

      ! enum DsStatus ds_problem_new_opts(int32_t d, const struct DsMatrix *k,
      !     const struct DsMatrix *n, const struct DsMatrix *t,
      !     const struct DsOptions *opts, struct DsProblem **out);
      function c_ds_problem_new_opts(d, k, n, t, opts, out) result(status) &
            bind(C, name="ds_problem_new_opts")
         import :: c_int, c_int32_t, c_ptr, DsMatrix, DsOptions
         integer(c_int32_t), value :: d
         type(DsMatrix), intent(in) :: k, n, t
         type(DsOptions), intent(in) :: opts
         type(c_ptr), intent(inout) :: out
         integer(c_int) :: status
      end function c_ds_problem_new_opts

      ! enum DsStatus ds_problem_new_host(int32_t d, const struct DsHostSolver *solver,
      !     const struct DsMatrix *k, const struct DsMatrix *n,
      !     const struct DsMatrix *t, const struct DsOptions *opts,
      !     struct DsProblem **out);
      function c_ds_problem_new_host(d, solver, k, n, t, opts, out) result(status) &
            bind(C, name="ds_problem_new_host")
         import :: c_int, c_int32_t, c_ptr, DsMatrix, DsOptions, DsHostSolver
         integer(c_int32_t), value :: d
         type(DsHostSolver), intent(in) :: solver
         type(c_ptr), value :: k
         type(DsMatrix), intent(in) :: n, t
         type(DsOptions), intent(in) :: opts
         type(c_ptr), intent(inout) :: out
         integer(c_int) :: status
      end function c_ds_problem_new_host

      ! enum DsStatus ds_analyse(int32_t d, const struct DsMatrix *k,
      !     const struct DsMatrix *n, const struct DsMatrix *t,
      !     const struct DsOptions *opts, struct DsInfo *info);
      function c_ds_analyse(d, k, n, t, opts, info) result(status) bind(C, name="ds_analyse")
         import :: c_int, c_int32_t, DsMatrix, DsOptions, DsInfo
         integer(c_int32_t), value :: d
         type(DsMatrix), intent(in) :: k, n, t
         type(DsOptions), intent(in) :: opts
         type(DsInfo), intent(inout) :: info
         integer(c_int) :: status
      end function c_ds_analyse

      ! enum DsStatus ds_problem_last_cost(const struct DsProblem *problem,
      !     struct DsCost *cost);
      function c_ds_problem_last_cost(problem, cost) result(status) &
            bind(C, name="ds_problem_last_cost")
         import :: c_int, c_ptr, DsCost
         type(c_ptr), value :: problem
         type(DsCost), intent(inout) :: cost
         integer(c_int) :: status
      end function c_ds_problem_last_cost

      ! enum DsStatus ds_problem_info(const struct DsProblem *problem,
      !     const struct DsOptions *opts, struct DsInfo *info);
      function c_ds_problem_info(problem, opts, info) result(status) &
            bind(C, name="ds_problem_info")
         import :: c_int, c_ptr, DsOptions, DsInfo
         type(c_ptr), value :: problem
         type(DsOptions), intent(in) :: opts
         type(DsInfo), intent(inout) :: info
         integer(c_int) :: status
      end function c_ds_problem_info

      ! void ds_problem_free(struct DsProblem *problem);
      subroutine c_ds_problem_free(problem) bind(C, name="ds_problem_free")
         import :: c_ptr
         type(c_ptr), value :: problem
      end subroutine c_ds_problem_free

      ! enum DsStatus ds_problem_refactor(struct DsProblem *problem, const struct DsMatrix *k);
      function c_ds_problem_refactor(problem, k) result(status) &
         bind(C, name="ds_problem_refactor")
         import :: c_int, c_ptr, DsMatrix
         type(c_ptr), value :: problem
         type(DsMatrix), intent(in) :: k
         integer(c_int) :: status
      end function c_ds_problem_refactor

      ! enum DsStatus ds_problem_set_contacts(struct DsProblem *problem,
      !     const struct DsMatrix *n, const struct DsMatrix *t);
      function c_ds_problem_set_contacts(problem, n, t) result(status) &
         bind(C, name="ds_problem_set_contacts")
         import :: c_int, c_ptr, DsMatrix
         type(c_ptr), value :: problem
         type(DsMatrix), intent(in) :: n, t
         integer(c_int) :: status
      end function c_ds_problem_set_contacts

      ! enum DsStatus ds_problem_dump(const struct DsProblem *problem, const char *dir,
      !     int32_t friction, const double *f, const double *g, const double *bound);
      function c_ds_problem_dump(problem, dir, friction, f, g, bound) result(status) &
         bind(C, name="ds_problem_dump")
         import :: c_int, c_int32_t, c_double, c_ptr, c_char
         type(c_ptr), value :: problem
         character(kind=c_char), intent(in) :: dir(*)
         integer(c_int32_t), value :: friction
         real(c_double), intent(in) :: f(*), g(*), bound(*)
         integer(c_int) :: status
      end function c_ds_problem_dump

      ! enum DsStatus ds_problem_sizes(const struct DsProblem *problem, int64_t *n_dofs,
      !     int64_t *n_contacts, int32_t *d);
      function c_ds_problem_sizes(problem, n_dofs, n_contacts, d) result(status) &
         bind(C, name="ds_problem_sizes")
         import :: c_int, c_int32_t, c_int64_t, c_ptr
         type(c_ptr), value :: problem
         integer(c_int64_t), intent(inout) :: n_dofs, n_contacts
         integer(c_int32_t), intent(inout) :: d
         integer(c_int) :: status
      end function c_ds_problem_sizes

      ! enum DsStatus ds_solve(struct DsProblem *problem, const struct DsOptions *opts,
      !     int32_t friction, const double *f, const double *g, const double *bound,
      !     double *u, double *lambda_n, double *lambda_t, struct DsReport *report);
      function c_ds_solve(problem, opts, friction, f, g, bound, u, lambda_n, lambda_t, &
                          report) result(status) bind(C, name="ds_solve")
         import :: c_int, c_int32_t, c_double, c_ptr
         type(c_ptr), value :: problem
         type(c_ptr), value :: opts
         integer(c_int32_t), value :: friction
         real(c_double), intent(in) :: f(*), g(*), bound(*)
         real(c_double), intent(inout) :: u(*), lambda_n(*), lambda_t(*)
         type(c_ptr), value :: report
         integer(c_int) :: status
      end function c_ds_solve

      ! enum DsStatus ds_step(... the arguments of ds_solve ...);
      function c_ds_step(problem, opts, friction, f_total, g0, bound, u, lambda_n, lambda_t, &
                         report) result(status) bind(C, name="ds_step")
         import :: c_int, c_int32_t, c_double, c_ptr
         type(c_ptr), value :: problem
         type(c_ptr), value :: opts
         integer(c_int32_t), value :: friction
         real(c_double), intent(in) :: f_total(*), g0(*), bound(*)
         real(c_double), intent(inout) :: u(*), lambda_n(*), lambda_t(*)
         type(c_ptr), value :: report
         integer(c_int) :: status
      end function c_ds_step

      ! enum DsStatus ds_solve_iteration(struct DsProblem *problem,
      !     const struct DsOptions *opts, int32_t friction, const double *r,
      !     const double *g, const double *bound, const double *slip,
      !     const double *lambda_t_start, double *du, double *lambda_n,
      !     double *lambda_t, struct DsReport *report);
      function c_ds_solve_iteration(problem, opts, friction, r, g, bound, slip, &
                                    lambda_t_start, du, lambda_n, lambda_t, report) &
         result(status) bind(C, name="ds_solve_iteration")
         import :: c_int, c_int32_t, c_double, c_ptr
         type(c_ptr), value :: problem
         type(c_ptr), value :: opts
         integer(c_int32_t), value :: friction
         real(c_double), intent(in) :: r(*), g(*), bound(*)
         type(c_ptr), value :: slip, lambda_t_start
         real(c_double), intent(inout) :: du(*), lambda_n(*), lambda_t(*)
         type(c_ptr), value :: report
         integer(c_int) :: status
      end function c_ds_solve_iteration

      ! enum DsStatus ds_problem_set_compliance(struct DsProblem *problem,
      !     const double *c_n, const double *m_n, const double *k_t);
      function c_ds_problem_set_compliance(problem, c_n, m_n, k_t) result(status) &
         bind(C, name="ds_problem_set_compliance")
         import :: c_int, c_ptr
         type(c_ptr), value :: problem, c_n, m_n, k_t
         integer(c_int) :: status
      end function c_ds_problem_set_compliance

      ! enum DsStatus ds_history_reset(struct DsProblem *problem);
      function c_ds_history_reset(problem) result(status) bind(C, name="ds_history_reset")
         import :: c_int, c_ptr
         type(c_ptr), value :: problem
         integer(c_int) :: status
      end function c_ds_history_reset

      ! enum DsStatus ds_problem_set_monitor(struct DsProblem *problem,
      !     DsMonitorFn monitor, void *user_data);
      function c_ds_problem_set_monitor(problem, monitor, user_data) result(status) &
         bind(C, name="ds_problem_set_monitor")
         import :: c_int, c_ptr, c_funptr
         type(c_ptr), value :: problem
         type(c_funptr), value :: monitor
         type(c_ptr), value :: user_data
         integer(c_int) :: status
      end function c_ds_problem_set_monitor

      ! enum DsStatus ds_problem_set_log(struct DsProblem *problem, int32_t level,
      !     DsLogFn log, void *user_data);
      function c_ds_problem_set_log(problem, level, log, user_data) result(status) &
         bind(C, name="ds_problem_set_log")
         import :: c_int, c_int32_t, c_ptr, c_funptr
         type(c_ptr), value :: problem
         integer(c_int32_t), value :: level
         type(c_funptr), value :: log
         type(c_ptr), value :: user_data
         integer(c_int) :: status
      end function c_ds_problem_set_log

      ! const char *ds_status_string(int32_t status);
      function c_ds_status_string(status) result(str) bind(C, name="ds_status_string")
         import :: c_int32_t, c_ptr
         integer(c_int32_t), value :: status
         type(c_ptr) :: str
      end function c_ds_status_string

      ! const char *ds_version(void);
      function c_ds_version() result(str) bind(C, name="ds_version")
         import :: c_ptr
         type(c_ptr) :: str
      end function c_ds_version

      ! size_t strlen(const char *s);  (C library, to convert the messages)
      function c_strlen(s) result(n) bind(C, name="strlen")
         import :: c_ptr, c_size_t
         type(c_ptr), value :: s
         integer(c_size_t) :: n
      end function c_strlen
   end interface

contains

   ! ---------------------------------------------------------------------------------
   ! Messages as Fortran strings
   ! ---------------------------------------------------------------------------------

   !> A copy of a NUL-terminated C string ('' for a NULL pointer).
   function c_to_fortran_string(cstr) result(str)
      type(c_ptr), intent(in) :: cstr
      character(len=:), allocatable :: str
      character(kind=c_char), pointer :: chars(:)
      integer :: n, j

      if (.not. c_associated(cstr)) then
         str = ''
         return
      end if
      n = int(c_strlen(cstr))
      allocate (character(len=n) :: str)
      if (n == 0) return
      call c_f_pointer(cstr, chars, [n])
      do j = 1, n
         str(j:j) = chars(j)
      end do
   end function c_to_fortran_string

   !> A copy of a NUL-terminated C string as a Fortran string, e.g. the message a log
   !> callback receives ('' for a null pointer).
   function ds_string_from_c(cstr) result(str)
      type(c_ptr), intent(in) :: cstr
      character(len=:), allocatable :: str
      str = c_to_fortran_string(cstr)
   end function ds_string_from_c

   !> The message of the last error on the calling thread ('' after a successful call),
   !> e.g. "ds_solve: argument f is NULL but must point to 12 values".
   function ds_last_error_message() result(msg)
      character(len=:), allocatable :: msg
      msg = c_to_fortran_string(c_ds_last_error_message())
   end function ds_last_error_message

   !> A description of a status value, e.g. "K is not symmetric".
   function ds_status_string(status) result(str)
      integer(c_int32_t), intent(in) :: status
      character(len=:), allocatable :: str
      str = c_to_fortran_string(c_ds_status_string(status))
   end function ds_status_string

   !> The version of the library the program runs against, "MAJOR.MINOR.PATCH".
   function ds_version() result(str)
      character(len=:), allocatable :: str
      str = c_to_fortran_string(c_ds_version())
   end function ds_version

   ! ---------------------------------------------------------------------------------
   ! Options, handle
   ! ---------------------------------------------------------------------------------

   !> Fills opts with the defaults: struct_size = the size of this module's
   !> DsOptions, DS_METHOD_SPLIT, tol 1e-10, max_outer 10000, max_inner 1000,
   !> DS_DUAL_FORM_AUTO, max_seconds 0, stall_window 100, stall_factor 0.9, threads 0,
   !> DS_ORDERING_AUTO.
   subroutine ds_options_default(opts)
      type(DsOptions), intent(out) :: opts
      integer :: status
      status = ds_options_init(opts)
   end subroutine ds_options_default

   !> status = ds_options_init(opts): as ds_options_default, with the status of the
   !> C function (DS_STATUS_OK). The size passed is that of this module's DsOptions,
   !> 80 bytes (the storage size of its components: c_sizeof is Fortran 2008).
   function ds_options_init(opts) result(status)
      type(DsOptions), intent(out) :: opts
      integer :: status
      status = int(c_ds_options_init(opts, DS_OPTIONS_SIZE))
   end function ds_options_init

   !> Validates K, N, T, factors K and forms the condensed dual; problem receives the
   !> new handle on success (untouched on error). d is 2 or 3.
   function ds_problem_new(d, k, n, t, problem) result(status)
      integer(c_int32_t), intent(in) :: d
      type(DsMatrix), intent(in) :: k, n, t
      type(c_ptr), intent(inout) :: problem
      integer(c_int32_t) :: status
      status = int(c_ds_problem_new(d, k, n, t, problem), c_int32_t)
   end function ds_problem_new

   !> As ds_problem_new, with opts%threads (the handle's own thread pool) and
   !> opts%ordering (the fill-reducing ordering of K).
   function ds_problem_new_opts(d, k, n, t, opts, problem) result(status)
      integer(c_int32_t), intent(in) :: d
      type(DsMatrix), intent(in) :: k, n, t
      type(DsOptions), intent(in) :: opts
      type(c_ptr), intent(inout) :: problem
      integer(c_int32_t) :: status
      status = int(c_ds_problem_new_opts(d, k, n, t, opts, problem), c_int32_t)
   end function ds_problem_new_opts

   !> A problem on the host's own solver of K (see ds_problem_new_host in
   !> dualsplit.h): solver as DsHostSolver says; k optional (the lumped
   !> preconditioner, K u_k in a history and the equilibrium residual).
   function ds_problem_new_host(d, solver, n, t, opts, problem, k) result(status)
      integer(c_int32_t), intent(in) :: d
      type(DsHostSolver), intent(in) :: solver
      type(DsMatrix), intent(in) :: n, t
      type(DsOptions), intent(in) :: opts
      type(c_ptr), intent(inout) :: problem
      type(DsMatrix), intent(in), optional, target :: k
      integer(c_int32_t) :: status
      type(c_ptr) :: kp
      kp = c_null_ptr
      if (present(k)) kp = c_loc(k)
      status = int(c_ds_problem_new_host(d, solver, kp, n, t, opts, problem), c_int32_t)
   end function ds_problem_new_host

   !> Sets info%struct_size to DS_INFO_SIZE (and the other fields to 0): call before
   !> ds_analyse or ds_problem_info.
   subroutine ds_info_init(info)
      type(DsInfo), intent(out) :: info
      info = DsInfo(int(DS_INFO_SIZE, c_int32_t), 0, 0_c_int64_t, 0_c_int64_t, 0_c_int64_t, &
         0_c_int64_t, 0_c_int64_t, 0.0_c_double, 0, 0, 0, 0, 0_c_int64_t, 0_c_int64_t, &
         0_c_int64_t, 0_c_int64_t, 0_c_int64_t, 0.0_c_double, 0_c_int64_t, 0_c_int64_t, &
         0_c_int64_t, 0.0_c_double)
   end subroutine ds_info_init

   !> The analysis alone (no handle, nothing factored): sizes, the factor's size
   !> and flops, the route opts lead to and its predicted memory. Call
   !> ds_info_init(info) first.
   function ds_analyse(d, k, n, t, opts, info) result(status)
      integer(c_int32_t), intent(in) :: d
      type(DsMatrix), intent(in) :: k, n, t
      type(DsOptions), intent(in) :: opts
      type(DsInfo), intent(inout) :: info
      integer(c_int32_t) :: status
      status = int(c_ds_analyse(d, k, n, t, opts, info), c_int32_t)
   end function ds_analyse

   !> The analysis of a handle as it is now, the solve memory predicted for
   !> opts%method. Call ds_info_init(info) first.
   function ds_problem_info(problem, opts, info) result(status)
      type(c_ptr), intent(in) :: problem
      type(DsOptions), intent(in) :: opts
      type(DsInfo), intent(inout) :: info
      integer(c_int32_t) :: status
      status = int(c_ds_problem_info(problem, opts, info), c_int32_t)
   end function ds_problem_info

   !> Sets cost%struct_size = DS_COST_SIZE and every other field to 0.
   subroutine ds_cost_init(cost)
      type(DsCost), intent(out) :: cost
      cost = DsCost(int(DS_COST_SIZE, c_int32_t), 0, 0.0_c_double, 0.0_c_double, &
         0.0_c_double, 0.0_c_double, 0_c_int64_t, 0.0_c_double, 0.0_c_double)
   end subroutine ds_cost_init

   !> What the last ds_solve or ds_step on the handle cost (see DsCost in
   !> dualsplit.h). Call ds_cost_init(cost) first.
   function ds_problem_last_cost(problem, cost) result(status)
      type(c_ptr), intent(in) :: problem
      type(DsCost), intent(inout) :: cost
      integer(c_int32_t) :: status
      status = int(c_ds_problem_last_cost(problem, cost), c_int32_t)
   end function ds_problem_last_cost

   !> Frees a handle (a null handle is fine) and sets it to c_null_ptr.
   subroutine ds_problem_free(problem)
      type(c_ptr), intent(inout) :: problem
      call c_ds_problem_free(problem)
      problem = c_null_ptr
   end subroutine ds_problem_free

   !> Refactors K with new values and the same pattern and storage.
   function ds_problem_refactor(problem, k) result(status)
      type(c_ptr), intent(in) :: problem
      type(DsMatrix), intent(in) :: k
      integer(c_int32_t) :: status
      status = int(c_ds_problem_refactor(problem, k), c_int32_t)
   end function ds_problem_refactor

   !> Replaces N and T (m may change) without refactoring K.
   function ds_problem_set_contacts(problem, n, t) result(status)
      type(c_ptr), intent(in) :: problem
      type(DsMatrix), intent(in) :: n, t
      integer(c_int32_t) :: status
      status = int(c_ds_problem_set_contacts(problem, n, t), c_int32_t)
   end function ds_problem_set_contacts

   !> Writes the handle's problem with one increment's f, g and bound to the folder
   !> dir (Matrix Market and text files) for replay with `dualsplit solve DIR`.
   function ds_problem_dump(problem, dir, friction, f, g, bound) result(status)
      type(c_ptr), intent(in) :: problem
      character(len=*), intent(in) :: dir
      integer(c_int32_t), intent(in) :: friction
      real(c_double), intent(in) :: f(*), g(*), bound(*)
      integer(c_int32_t) :: status
      status = int(c_ds_problem_dump(problem, trim(dir)//c_null_char, friction, f, g, &
                                     bound), c_int32_t)
   end function ds_problem_dump

   !> The sizes of a problem (INTEGER(c_int32_t), i.e. default INTEGER, outputs): n DOFs, m contacts, d.
   function ds_problem_sizes_i32(problem, n_dofs, n_contacts, d) result(status)
      type(c_ptr), intent(in) :: problem
      integer(c_int32_t), intent(inout) :: n_dofs, n_contacts
      integer(c_int32_t), intent(inout) :: d
      integer(c_int32_t) :: status
      integer(c_int64_t) :: n64, m64
      integer(c_int32_t) :: d32
      n64 = 0
      m64 = 0
      d32 = 0
      status = int(c_ds_problem_sizes(problem, n64, m64, d32), c_int32_t)
      if (status == DS_STATUS_OK) then
         n_dofs = int(n64, c_int32_t)
         n_contacts = int(m64, c_int32_t)
         d = d32
      end if
   end function ds_problem_sizes_i32

   !> The sizes of a problem (INTEGER(8) outputs): n DOFs, m contacts, d.
   function ds_problem_sizes_i64(problem, n_dofs, n_contacts, d) result(status)
      type(c_ptr), intent(in) :: problem
      integer(c_int64_t), intent(inout) :: n_dofs, n_contacts
      integer(c_int32_t), intent(inout) :: d
      integer(c_int32_t) :: status
      integer(c_int32_t) :: d32
      d32 = 0
      status = int(c_ds_problem_sizes(problem, n_dofs, n_contacts, d32), c_int32_t)
      if (status == DS_STATUS_OK) d = d32
   end function ds_problem_sizes_i64

   ! ---------------------------------------------------------------------------------
   ! Solves
   ! ---------------------------------------------------------------------------------

   !> Solves one increment exactly as given. opts and report are optional (the
   !> library's defaults; no report). f: n values; g, bound, lambda_n: m values;
   !> lambda_t: (d-1) m values. friction: DS_FRICTION_TRESCA (bound = p) or
   !> DS_FRICTION_COULOMB (bound = mu). On error u, lambda_n, lambda_t are untouched;
   !> on DS_STATUS_NOT_CONVERGED only the report is written; on DS_STATUS_STOPPED (the
   !> monitor asked to stop) the last iterate and the report.
   function ds_solve(problem, opts, friction, f, g, bound, u, lambda_n, lambda_t, report) &
      result(status)
      type(c_ptr), intent(in) :: problem
      type(DsOptions), intent(in), optional, target :: opts
      integer(c_int32_t), intent(in) :: friction
      real(c_double), intent(in) :: f(*), g(*), bound(*)
      real(c_double), intent(inout) :: u(*), lambda_n(*), lambda_t(*)
      type(DsReport), intent(inout), optional, target :: report
      integer(c_int32_t) :: status
      type(c_ptr) :: popts, prep
      popts = c_null_ptr
      prep = c_null_ptr
      if (present(opts)) popts = c_loc(opts)
      if (present(report)) prep = c_loc(report)
      status = int(c_ds_solve(problem, popts, friction, f, g, bound, u, &
                              lambda_n, lambda_t, prep), c_int32_t)
   end function ds_solve

   !> One step of a quasistatic history: pass the TOTAL load f_total and the INITIAL
   !> gaps g0; u receives the total displacement, lambda_n and lambda_t the total
   !> contact forces. Arguments and statuses as ds_solve.
   function ds_step(problem, opts, friction, f_total, g0, bound, u, lambda_n, lambda_t, &
                    report) result(status)
      type(c_ptr), intent(in) :: problem
      type(DsOptions), intent(in), optional, target :: opts
      integer(c_int32_t), intent(in) :: friction
      real(c_double), intent(in) :: f_total(*), g0(*), bound(*)
      real(c_double), intent(inout) :: u(*), lambda_n(*), lambda_t(*)
      type(DsReport), intent(inout), optional, target :: report
      integer(c_int32_t) :: status
      type(c_ptr) :: popts, prep
      popts = c_null_ptr
      prep = c_null_ptr
      if (present(opts)) popts = c_loc(opts)
      if (present(report)) prep = c_loc(report)
      status = int(c_ds_step(problem, popts, friction, f_total, g0, bound, &
                             u, lambda_n, lambda_t, prep), c_int32_t)
   end function ds_step

   !> One iteration of the host's own Newton loop (see ds_solve_iteration in
   !> dualsplit.h for the loop step by step): r is the host's residual
   !> f_ext - f_int(u_j) without contact forces (n values), g the gaps at u_j
   !> (m values), slip the slip already taken in the increment T (u_j - u_n)
   !> ((d-1) m values, optional: absent at the first iteration of an
   !> increment only), lambda_t_start the tangential
   !> forces at the start of the increment (optional; read only at contacts with
   !> a finite k_t). Returns the correction du and the TOTAL contact forces;
   !> starts from the last converged iteration's multipliers (the first
   !> iteration of an increment, slip absent, from their extrapolation along
   !> the last two increments where they lie on a line; from the third
   !> iteration on, from the line of the last two iterations where it lowers
   !> the residual). opts and report
   !> optional; outputs written as ds_solve. The optional slip and
   !> lambda_t_start come last here (in C they come before du): pass them by
   !> keyword.
   function ds_solve_iteration(problem, opts, friction, r, g, bound, du, lambda_n, &
                               lambda_t, report, slip, lambda_t_start) result(status)
      type(c_ptr), intent(in) :: problem
      type(DsOptions), intent(in), optional, target :: opts
      integer(c_int32_t), intent(in) :: friction
      real(c_double), intent(in) :: r(*), g(*), bound(*)
      real(c_double), intent(inout) :: du(*), lambda_n(*), lambda_t(*)
      type(DsReport), intent(inout), optional, target :: report
      real(c_double), intent(in), optional, target :: slip(*), lambda_t_start(*)
      integer(c_int32_t) :: status
      type(c_ptr) :: popts, prep, pslip, plt
      popts = c_null_ptr
      prep = c_null_ptr
      pslip = c_null_ptr
      plt = c_null_ptr
      if (present(opts)) popts = c_loc(opts)
      if (present(report)) prep = c_loc(report)
      if (present(slip)) pslip = c_loc(slip(1))
      if (present(lambda_t_start)) plt = c_loc(lambda_t_start(1))
      status = int(c_ds_solve_iteration(problem, popts, friction, r, g, bound, pslip, plt, &
                                        du, lambda_n, lambda_t, prep), c_int32_t)
   end function ds_solve_iteration

   !> Sets the interface law of every contact (see ds_problem_set_compliance in
   !> dualsplit.h): c_n (normal compliance, > 0, IEEE infinity rigid), m_n (its
   !> exponent, in [1, 10]), k_t (elastic slip stiffness, > 0,
   !> infinity rigid stick), each m values (m >= 1), optional (absent: the
   !> default).
   function ds_problem_set_compliance(problem, c_n, m_n, k_t) result(status)
      type(c_ptr), intent(in) :: problem
      real(c_double), intent(in), optional, target :: c_n(*), m_n(*), k_t(*)
      integer(c_int32_t) :: status
      type(c_ptr) :: pc, pm, pk
      pc = c_null_ptr
      pm = c_null_ptr
      pk = c_null_ptr
      if (present(c_n)) pc = c_loc(c_n(1))
      if (present(m_n)) pm = c_loc(m_n(1))
      if (present(k_t)) pk = c_loc(k_t(1))
      status = int(c_ds_problem_set_compliance(problem, pc, pm, pk), c_int32_t)
   end function ds_problem_set_compliance

   !> Forgets the history of ds_step (u_0 = 0, no warm start).
   function ds_history_reset(problem) result(status)
      type(c_ptr), intent(in) :: problem
      integer(c_int32_t) :: status
      status = int(c_ds_history_reset(problem), c_int32_t)
   end function ds_history_reset

   !> Sets the monitor callback (see ds_monitor_fn), called after every outer
   !> iteration of ds_solve / ds_step with a DsProgress and user_data (optional, default
   !> c_null_ptr); a nonzero result stops the solve (DS_STATUS_STOPPED, last iterate
   !> written). Without monitor, clears it.
   function ds_problem_set_monitor(problem, monitor, user_data) result(status)
      type(c_ptr), intent(in) :: problem
      procedure(ds_monitor_fn), optional :: monitor
      type(c_ptr), intent(in), optional :: user_data
      integer(c_int32_t) :: status
      type(c_funptr) :: fn
      type(c_ptr) :: data
      fn = c_null_funptr
      data = c_null_ptr
      if (present(monitor)) fn = c_funloc(monitor)
      if (present(user_data)) data = user_data
      status = int(c_ds_problem_set_monitor(problem, fn, data), c_int32_t)
   end function ds_problem_set_monitor

   !> Sets the log level (0 silent, the default; 1 a summary line per solve; 2 also a
   !> line per outer iteration) and the sink (see ds_log_fn; optional: stderr when
   !> absent), which receives user_data (optional, default c_null_ptr).
   function ds_problem_set_log(problem, level, log, user_data) result(status)
      type(c_ptr), intent(in) :: problem
      integer(c_int32_t), intent(in) :: level
      procedure(ds_log_fn), optional :: log
      type(c_ptr), intent(in), optional :: user_data
      integer(c_int32_t) :: status
      type(c_funptr) :: fn
      type(c_ptr) :: data
      fn = c_null_funptr
      data = c_null_ptr
      if (present(log)) fn = c_funloc(log)
      if (present(user_data)) data = user_data
      status = int(c_ds_problem_set_log(problem, level, fn, data), c_int32_t)
   end function ds_problem_set_log

   ! ---------------------------------------------------------------------------------
   ! DsMatrix over Fortran arrays
   ! ---------------------------------------------------------------------------------

   !> The fields common to every DsMatrix; base 1 and FULL storage unless given.
   function matrix_head(format, index_type, nrows, ncols, nnz, storage, base) result(mat)
      integer(c_int32_t), intent(in) :: format, index_type
      integer(c_int64_t), intent(in) :: nrows, ncols, nnz
      integer(c_int32_t), intent(in), optional :: storage, base
      type(DsMatrix) :: mat
      mat%format = format
      mat%index_type = index_type
      mat%base = 1
      if (present(base)) mat%base = base
      mat%storage = DS_STORAGE_FULL
      if (present(storage)) mat%storage = storage
      mat%nrows = nrows
      mat%ncols = ncols
      mat%nnz = nnz
      mat%p = c_null_ptr
      mat%i = c_null_ptr
      mat%x = c_null_ptr
   end function matrix_head

   function ds_matrix_csr_i32(nrows, ncols, ia, ja, a, storage, base) result(mat)
      integer(c_int32_t), intent(in) :: nrows, ncols
      integer(c_int32_t), intent(in), target :: ia(*), ja(*)
      real(c_double), intent(in), target :: a(*)
      integer(c_int32_t), intent(in), optional :: storage, base
      type(DsMatrix) :: mat
      integer(c_int64_t) :: nnz
      mat = matrix_head(DS_FORMAT_CSR, DS_INDEX_TYPE_I32, int(nrows, c_int64_t), &
                        int(ncols, c_int64_t), 0_c_int64_t, storage, base)
      mat%p = c_loc(ia(1))
      nnz = int(ia(nrows + 1), c_int64_t) - mat%base
      if (nnz > 0) then
         mat%i = c_loc(ja(1))
         mat%x = c_loc(a(1))
      end if
   end function ds_matrix_csr_i32

   function ds_matrix_csr_i64(nrows, ncols, ia, ja, a, storage, base) result(mat)
      integer(c_int64_t), intent(in) :: nrows, ncols
      integer(c_int64_t), intent(in), target :: ia(*), ja(*)
      real(c_double), intent(in), target :: a(*)
      integer(c_int32_t), intent(in), optional :: storage, base
      type(DsMatrix) :: mat
      integer(c_int64_t) :: nnz
      mat = matrix_head(DS_FORMAT_CSR, DS_INDEX_TYPE_I64, nrows, ncols, 0_c_int64_t, &
                        storage, base)
      mat%p = c_loc(ia(1))
      nnz = ia(nrows + 1) - mat%base
      if (nnz > 0) then
         mat%i = c_loc(ja(1))
         mat%x = c_loc(a(1))
      end if
   end function ds_matrix_csr_i64

   function ds_matrix_csc_i32(nrows, ncols, colptr, rowind, a, storage, base) result(mat)
      integer(c_int32_t), intent(in) :: nrows, ncols
      integer(c_int32_t), intent(in), target :: colptr(*), rowind(*)
      real(c_double), intent(in), target :: a(*)
      integer(c_int32_t), intent(in), optional :: storage, base
      type(DsMatrix) :: mat
      integer(c_int64_t) :: nnz
      mat = matrix_head(DS_FORMAT_CSC, DS_INDEX_TYPE_I32, int(nrows, c_int64_t), &
                        int(ncols, c_int64_t), 0_c_int64_t, storage, base)
      mat%p = c_loc(colptr(1))
      nnz = int(colptr(ncols + 1), c_int64_t) - mat%base
      if (nnz > 0) then
         mat%i = c_loc(rowind(1))
         mat%x = c_loc(a(1))
      end if
   end function ds_matrix_csc_i32

   function ds_matrix_csc_i64(nrows, ncols, colptr, rowind, a, storage, base) result(mat)
      integer(c_int64_t), intent(in) :: nrows, ncols
      integer(c_int64_t), intent(in), target :: colptr(*), rowind(*)
      real(c_double), intent(in), target :: a(*)
      integer(c_int32_t), intent(in), optional :: storage, base
      type(DsMatrix) :: mat
      integer(c_int64_t) :: nnz
      mat = matrix_head(DS_FORMAT_CSC, DS_INDEX_TYPE_I64, nrows, ncols, 0_c_int64_t, &
                        storage, base)
      mat%p = c_loc(colptr(1))
      nnz = colptr(ncols + 1) - mat%base
      if (nnz > 0) then
         mat%i = c_loc(rowind(1))
         mat%x = c_loc(a(1))
      end if
   end function ds_matrix_csc_i64

   function ds_matrix_coo_i32(nrows, ncols, nnz, irow, jcol, a, storage, base) result(mat)
      integer(c_int32_t), intent(in) :: nrows, ncols, nnz
      integer(c_int32_t), intent(in), target :: irow(*), jcol(*)
      real(c_double), intent(in), target :: a(*)
      integer(c_int32_t), intent(in), optional :: storage, base
      type(DsMatrix) :: mat
      mat = matrix_head(DS_FORMAT_COO, DS_INDEX_TYPE_I32, int(nrows, c_int64_t), &
                        int(ncols, c_int64_t), int(nnz, c_int64_t), storage, base)
      if (nnz > 0) then
         mat%p = c_loc(jcol(1))
         mat%i = c_loc(irow(1))
         mat%x = c_loc(a(1))
      end if
   end function ds_matrix_coo_i32

   function ds_matrix_coo_i64(nrows, ncols, nnz, irow, jcol, a, storage, base) result(mat)
      integer(c_int64_t), intent(in) :: nrows, ncols, nnz
      integer(c_int64_t), intent(in), target :: irow(*), jcol(*)
      real(c_double), intent(in), target :: a(*)
      integer(c_int32_t), intent(in), optional :: storage, base
      type(DsMatrix) :: mat
      mat = matrix_head(DS_FORMAT_COO, DS_INDEX_TYPE_I64, nrows, ncols, nnz, storage, base)
      if (nnz > 0) then
         mat%p = c_loc(jcol(1))
         mat%i = c_loc(irow(1))
         mat%x = c_loc(a(1))
      end if
   end function ds_matrix_coo_i64

   function ds_matrix_dense_i32(nrows, ncols, a, lda, storage) result(mat)
      integer(c_int32_t), intent(in) :: nrows, ncols, lda
      real(c_double), intent(in), target :: a(*)
      integer(c_int32_t), intent(in), optional :: storage
      type(DsMatrix) :: mat
      mat = ds_matrix_dense_i64(int(nrows, c_int64_t), int(ncols, c_int64_t), a, &
                                int(lda, c_int64_t), storage)
   end function ds_matrix_dense_i32

   function ds_matrix_dense_i64(nrows, ncols, a, lda, storage) result(mat)
      integer(c_int64_t), intent(in) :: nrows, ncols, lda
      real(c_double), intent(in), target :: a(*)
      integer(c_int32_t), intent(in), optional :: storage
      type(DsMatrix) :: mat
      ! nnz carries the leading dimension; p and i are not read.
      mat = matrix_head(DS_FORMAT_DENSE, DS_INDEX_TYPE_I32, nrows, ncols, lda, storage, 1_c_int32_t)
      if (nrows > 0 .and. ncols > 0) mat%x = c_loc(a(1))
   end function ds_matrix_dense_i64

   function ds_matrix_dense_i32_r2(nrows, ncols, a, lda, storage) result(mat)
      integer(c_int32_t), intent(in) :: nrows, ncols, lda
      real(c_double), intent(in), target :: a(lda, *)
      integer(c_int32_t), intent(in), optional :: storage
      type(DsMatrix) :: mat
      mat = ds_matrix_dense_i64_r2(int(nrows, c_int64_t), int(ncols, c_int64_t), a, &
                                   int(lda, c_int64_t), storage)
   end function ds_matrix_dense_i32_r2

   function ds_matrix_dense_i64_r2(nrows, ncols, a, lda, storage) result(mat)
      integer(c_int64_t), intent(in) :: nrows, ncols, lda
      real(c_double), intent(in), target :: a(lda, *)
      integer(c_int32_t), intent(in), optional :: storage
      type(DsMatrix) :: mat
      mat = matrix_head(DS_FORMAT_DENSE, DS_INDEX_TYPE_I32, nrows, ncols, lda, storage, 1_c_int32_t)
      if (nrows > 0 .and. ncols > 0) mat%x = c_loc(a(1, 1))
   end function ds_matrix_dense_i64_r2

end module dualsplit
