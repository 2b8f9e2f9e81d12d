/*
 * mumps_schur.c -- keep your own direct solver: K factored by MUMPS, the contact
 * problem solved by dualsplit on the Schur complement of K onto the contact DOFs.
 *
 * The scene is the demo's 2D block (block2d.c, assembled in block2d_scene.h):
 * plane-strain Q4 block pressed onto a curved rigid foundation and sheared, the
 * top edge prescribed, Coulomb friction on every bottom node, the demo's load
 * history of 15 steps (ds_step: the library keeps the history).
 *
 * The workflow of a code that already factors K with MUMPS:
 *   1. MUMPS analyses and factors K_ff (SYM = 1, one triangle) with the contact
 *      DOFs C as its Schur list (ICNTL(19) = 1, LISTVAR_SCHUR): S = K_CC -
 *      K_CI K_II^-1 K_IC comes back dense on the host, its lower triangle by rows,
 *      which is its upper triangle column-major;
 *   2. the library gets (S as DS_FORMAT_DENSE with DS_STORAGE_UPPER, N_C, T_C):
 *      N and T restricted to the columns C;
 *   3. per step, MUMPS reduces the load onto C (ICNTL(26) = 1, JOB = 3: REDRHS =
 *      f_C - K_CI K_II^-1 f_I), ds_step solves the interface problem with that
 *      reduced load, and MUMPS expands the interface displacement u_C to the whole
 *      u (ICNTL(26) = 2, JOB = 3, REDRHS = u_C; RHS untouched since the
 *      reduction): contact forces act on C only, so u_I = K_II^-1 (f_I - K_IC u_C).
 *
 * As a check the program solves every step a second time with the library's own
 * path (K_ff sparse, ds_problem_new on the whole problem) and prints the largest
 * deviation of u, and of lambda_N and lambda_T, relative to the largest |u| and
 * |lambda| of the history so far; it exits 1 when a step does not converge, an
 * err exceeds 1e-10 or a deviation exceeds 1e-10.
 *
 * Built with MUMPS_SCHUR_MPI defined (mumps_mpi_schur.c), it runs the parallel
 * MUMPS over MPI ranks: K distributed (ICNTL(18) = 3, each rank passes the entries
 * of its own elements), the Schur complement and the right-hand side centralised
 * on the host, dualsplit called on rank 0 only, its multipliers broadcast, and the
 * expansion run by all ranks, u broadcast.
 *
 * Build and run (Debian: apt-get install libmumps-seq-dev; see the Makefile):
 *   make mumps-demo [DEMO_ARGS="--nx 40 --ny 20"]
 *   make mumps-mpi-demo           (libmumps-dev openmpi-bin; mpirun -np 2)
 *
 * Options: --nx N --ny N (elements, default 40 x 20), --tol t (default 1e-12),
 * --quiet (only the timing and SUMMARY lines).
 * Exit status: 0 on success, 1 failed check, 2 MUMPS or library error, 3 usage.
 */

#define _POSIX_C_SOURCE 199309L /* clock_gettime */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#ifdef MUMPS_SCHUR_MPI
#include <mpi.h>
#define EXAMPLE "mumps_mpi_schur"
#else
#define EXAMPLE "mumps_schur"
#endif

#include "dmumps_c.h"
#include "dualsplit.h"
#include "block2d_scene.h"

/* MUMPS's 1-based control and information arrays, as in its manual. */
#define ICNTL(i) icntl[(i) - 1]
#define INFOG(i) infog[(i) - 1]
#define INFO(i) info[(i) - 1]
/* The communicator value of the sequential MUMPS. */
#define USE_COMM_WORLD -987654

static double now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static int rank = 0, nprocs = 1;

/* Ends the program on every rank from wherever it stands (an error, or bad
   options): with MPI a nonzero code aborts the other ranks too. */
static void finish(int code)
{
#ifdef MUMPS_SCHUR_MPI
    if (code != 0) MPI_Abort(MPI_COMM_WORLD, code);
    MPI_Finalize();
#endif
    exit(code);
}

static void mumps_call(DMUMPS_STRUC_C *id, int job, const char *what)
{
    id->job = job;
    dmumps_c(id);
    if (id->INFOG(1) < 0) {
        if (rank == 0)
            fprintf(stderr, EXAMPLE ": MUMPS %s (JOB = %d) failed: INFOG(1) = %d, INFOG(2) = %d\n",
                    what, job, (int)id->INFOG(1), (int)id->INFOG(2));
        finish(2);
    }
}

static void library_error(const char *what, DsStatus st)
{
    fprintf(stderr, EXAMPLE ": %s failed: %s (%d): %s\n", what, ds_status_string((int32_t)st),
            (int)st, ds_last_error_message());
}

static double max_abs(const double *x, long n)
{
    double m = 0.0;
    long i;
    for (i = 0; i < n; i++) m = fmax(m, fabs(x[i]));
    return m;
}

static double max_diff(const double *x, const double *y, long n)
{
    double m = 0.0;
    long i;
    for (i = 0; i < n; i++) m = fmax(m, fabs(x[i] - y[i]));
    return m;
}

static void bcast(double *x, long n)
{
#ifdef MUMPS_SCHUR_MPI
    MPI_Bcast(x, (int)n, MPI_DOUBLE, 0, MPI_COMM_WORLD);
#else
    (void)x;
    (void)n;
#endif
}

int main(int argc, char **argv)
{
    long nx = 40, ny = 20, nc, i, k, a, el, steps_done = 0;
    double tol = 1e-12;
    int quiet = 0, all_converged = 1, exit_code = 0;
    Scene sc;
    long *cpos;
    MUMPS_INT *listvar, *irn, *jcn;
    double *kval, *schur = NULL, *f, *rhs, *red, *uc, *ln, *lt, *uref, *lnref, *ltref;
    long nnz;
    Triplets nc_mat, tc_mat;
    DMUMPS_STRUC_C id;
    DsProblem *prob = NULL, *ref = NULL;
    DsOptions opts;
    DsStatus st;
    double t0, t_factor, t_create = 0.0, t_reduce = 0.0, t_lib = 0.0, t_expand = 0.0;
    double t_ref_create = 0.0, t_ref = 0.0, max_err = 0.0, ref_max_err = 0.0;
    double max_dev_u = 0.0, max_dev_lam = 0.0, u_peak = 0.0, lam_peak = 0.0;

#ifdef MUMPS_SCHUR_MPI
    MPI_Init(&argc, &argv);
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &nprocs);
#endif
    for (i = 1; i < argc; i++) {
        if (strcmp(argv[i], "--nx") == 0 && i + 1 < argc) nx = strtol(argv[++i], NULL, 10);
        else if (strcmp(argv[i], "--ny") == 0 && i + 1 < argc) ny = strtol(argv[++i], NULL, 10);
        else if (strcmp(argv[i], "--tol") == 0 && i + 1 < argc) tol = strtod(argv[++i], NULL);
        else if (strcmp(argv[i], "--quiet") == 0) quiet = 1;
        else {
            if (rank == 0)
                fprintf(stderr, "usage: " EXAMPLE " [--nx N] [--ny N] [--tol t] [--quiet]\n");
            finish(3);
        }
    }
    if (nx < 1 || ny < 1 || !(tol > 0.0)) {
        if (rank == 0) fprintf(stderr, EXAMPLE ": --nx, --ny and --tol must be positive\n");
        finish(3);
    }
    /* Every rank assembles the mesh (cheap); with MPI each passes only its
       elements' entries to MUMPS. */
    if (scene_build(&sc, nx, ny, 1e4, 0.3, 2.0, 1.0, 0.05, 0.3, -0.05, 0.05) != 0) {
        if (rank == 0) fprintf(stderr, EXAMPLE ": an element has a non-positive Jacobian\n");
        finish(2);
    }

    /* ---- the contact DOFs C: the x and y equations of the bottom nodes ------ */
    nc = 2 * sc.m;
    cpos = (long *)xmalloc((size_t)sc.neq * sizeof(long));
    listvar = (MUMPS_INT *)xmalloc((size_t)nc * sizeof(MUMPS_INT));
    for (i = 0; i < sc.neq; i++) cpos[i] = -1;
    for (i = 0; i < sc.m; i++)
        for (a = 0; a < 2; a++) {
            long e = sc.eq[2 * i + a];
            cpos[e] = 2 * i + a;
            listvar[2 * i + a] = (MUMPS_INT)(e + 1);
        }
    /* N_C and T_C: N and T on the columns C, in C's numbering. */
    trip_init(&nc_mat, sc.nmat.n);
    trip_init(&tc_mat, sc.tmat.n);
    for (a = 0; a < sc.nmat.n; a++) trip_add(&nc_mat, sc.nmat.row[a], cpos[sc.nmat.col[a]], sc.nmat.val[a]);
    for (a = 0; a < sc.tmat.n; a++) trip_add(&tc_mat, sc.tmat.row[a], cpos[sc.tmat.col[a]], sc.tmat.val[a]);

    /* ---- MUMPS: K_ff's lower triangle, 1-based ------------------------------ */
    memset(&id, 0, sizeof id);
#ifdef MUMPS_SCHUR_MPI
    id.comm_fortran = (MUMPS_INT)MPI_Comm_c2f(MPI_COMM_WORLD);
#else
    id.comm_fortran = USE_COMM_WORLD;
#endif
    id.par = 1; /* the host works too */
    id.sym = 1; /* symmetric positive definite */
    mumps_call(&id, -1, "initialisation");
    id.ICNTL(1) = -1; /* no messages */
    id.ICNTL(2) = -1;
    id.ICNTL(3) = -1;
    id.ICNTL(4) = 0;
    id.n = (MUMPS_INT)sc.neq;
    irn = (MUMPS_INT *)xmalloc((size_t)sc.kff.n * sizeof(MUMPS_INT));
    jcn = (MUMPS_INT *)xmalloc((size_t)sc.kff.n * sizeof(MUMPS_INT));
    kval = (double *)xmalloc((size_t)sc.kff.n * sizeof(double));
    nnz = 0;
#ifdef MUMPS_SCHUR_MPI
    /* Distributed entry (ICNTL(18) = 3): this rank's elements, e mod nprocs. */
    for (el = rank; el < nx * ny; el += nprocs)
        for (a = 0; a < 8; a++)
            for (long b = 0; b < 8; b++) {
                long r = sc.eq[sc.elem_dofs[8 * el + a]], c = sc.eq[sc.elem_dofs[8 * el + b]];
                if (r >= c && c >= 0) {
                    irn[nnz] = (MUMPS_INT)(r + 1);
                    jcn[nnz] = (MUMPS_INT)(c + 1);
                    kval[nnz++] = sc.ke[64 * el + 8 * a + b];
                }
            }
    id.ICNTL(18) = 3;
    id.nnz_loc = nnz;
    id.irn_loc = irn;
    id.jcn_loc = jcn;
    id.a_loc = kval;
#else
    (void)el;
    for (a = 0; a < sc.kff.n; a++)
        if (sc.kff.row[a] >= sc.kff.col[a]) {
            irn[nnz] = sc.kff.row[a] + 1;
            jcn[nnz] = sc.kff.col[a] + 1;
            kval[nnz++] = sc.kff.val[a];
        }
    id.nnz = nnz;
    id.irn = irn;
    id.jcn = jcn;
    id.a = kval;
#endif
    /* The Schur complement onto C, centralised on the host. */
    id.ICNTL(19) = 1;
    if (rank == 0) {
        schur = (double *)xcalloc((size_t)(nc * nc), sizeof(double));
        id.size_schur = (MUMPS_INT)nc;
        id.listvar_schur = listvar;
        id.schur = schur;
    }
    t0 = now();
    mumps_call(&id, 4, "analysis and factorisation with the Schur complement");
    t_factor = now() - t0;

    f = (double *)xcalloc((size_t)sc.neq, sizeof(double));
    rhs = (double *)xcalloc((size_t)sc.neq, sizeof(double));
    red = (double *)xcalloc((size_t)nc, sizeof(double));
    uc = (double *)xcalloc((size_t)nc, sizeof(double));
    ln = (double *)xcalloc((size_t)sc.m, sizeof(double));
    lt = (double *)xcalloc((size_t)sc.m, sizeof(double));
    uref = (double *)xcalloc((size_t)sc.neq, sizeof(double));
    lnref = (double *)xcalloc((size_t)sc.m, sizeof(double));
    ltref = (double *)xcalloc((size_t)sc.m, sizeof(double));

    /* ---- the library on rank 0: the interface problem and the reference ----- */
    ds_options_default(&opts);
    opts.tol = tol;
    if (rank == 0) {
        DsMatrix sm, nm, tm, km, nf, tf;
        sm.format = DS_FORMAT_DENSE;
        sm.index_type = DS_INDEX_TYPE_I32; /* not read for a dense matrix */
        sm.base = 0;
        sm.storage = DS_STORAGE_UPPER; /* MUMPS: lower triangle by rows */
        sm.nrows = nc;
        sm.ncols = nc;
        sm.nnz = nc; /* the leading dimension */
        sm.p = NULL;
        sm.i = NULL;
        sm.x = schur;
        nm = coo_matrix(&nc_mat, sc.m, nc);
        tm = coo_matrix(&tc_mat, sc.m, nc);
        t0 = now();
        st = ds_problem_new(2, &sm, &nm, &tm, &prob);
        t_create = now() - t0;
        if (st != DS_STATUS_OK) {
            library_error("ds_problem_new (interface)", st);
            finish(2);
        }
        km = coo_matrix(&sc.kff, sc.neq, sc.neq);
        nf = coo_matrix(&sc.nmat, sc.m, sc.neq);
        tf = coo_matrix(&sc.tmat, sc.m, sc.neq);
        t0 = now();
        st = ds_problem_new(2, &km, &nf, &tf, &ref);
        t_ref_create = now() - t0;
        if (st != DS_STATUS_OK) {
            library_error("ds_problem_new (reference)", st);
            finish(2);
        }
        if (!quiet) {
            printf(EXAMPLE ": %ld x %ld Q4 block, %ld free DOFs, %ld contacts, Schur complement "
                   "%ld x %ld, %d MPI rank(s)\n", nx, ny, sc.neq, sc.m, nc, nc, nprocs);
            printf("%4s %9s %9s %5s %5s %5s %9s %9s %9s %9s\n", "step", "uy_top", "ux_top", "open",
                   "stick", "slip", "err", "dev_u", "dev_lam", "ref_err");
        }
    }

    for (k = 0; k < N_STEPS; k++) {
        DsReport rep, rep_ref;
        double status[2] = {0.0, 0.0}; /* (converged, err) from rank 0 */

        /* reduction: REDRHS = f_C - K_CI K_II^-1 f_I (RHS centralised on the host) */
        scene_load(&sc, k, f);
        if (rank == 0) {
            memcpy(rhs, f, (size_t)sc.neq * sizeof(double));
            id.rhs = rhs;
            id.nrhs = 1;
            id.lrhs = (MUMPS_INT)sc.neq;
            id.redrhs = red;
            id.lredrhs = (MUMPS_INT)nc;
        }
        id.ICNTL(26) = 1;
        t0 = now();
        mumps_call(&id, 3, "reduction of the load");
        t_reduce += now() - t0;

        /* the interface problem, on rank 0 only */
        if (rank == 0) {
            memset(&rep, 0, sizeof rep);
            t0 = now();
            st = ds_step(prob, &opts, DS_FRICTION_COULOMB, red, sc.g0, sc.mu, uc, ln, lt, &rep);
            t_lib += now() - t0;
            if (st != DS_STATUS_OK && st != DS_STATUS_NOT_CONVERGED) {
                library_error("ds_step", st);
                finish(2);
            }
            status[0] = st == DS_STATUS_OK && rep.status == DS_STATUS_OK;
            status[1] = rep.err;
            memcpy(red, uc, (size_t)nc * sizeof(double));
        }
        bcast(status, 2);
        bcast(ln, sc.m);
        bcast(lt, sc.m);
        if (!(status[0] > 0.0)) {
            if (rank == 0)
                fprintf(stderr, EXAMPLE ": step %ld did not converge: err = %.3e\n", k + 1,
                        status[1]);
            all_converged = 0;
            exit_code = 1;
            break;
        }
        if (status[1] > max_err) max_err = status[1];

        /* expansion: u from u_C (REDRHS), all ranks; u lands in RHS on the host */
        id.ICNTL(26) = 2;
        t0 = now();
        mumps_call(&id, 3, "expansion of the interface displacement");
        t_expand += now() - t0;
        bcast(rhs, sc.neq);
        steps_done++;

        /* the check: the library's own path on the whole problem */
        if (rank == 0) {
            double du, dl;
            memset(&rep_ref, 0, sizeof rep_ref);
            t0 = now();
            st = ds_step(ref, &opts, DS_FRICTION_COULOMB, f, sc.g0, sc.mu, uref, lnref, ltref,
                         &rep_ref);
            t_ref += now() - t0;
            if (st != DS_STATUS_OK) {
                library_error("ds_step (reference)", st);
                finish(2);
            }
            if (rep_ref.err > ref_max_err) ref_max_err = rep_ref.err;
            /* relative to the largest |u| and |lambda| of the history so far: the
               contact forces of a step where almost everything opens are rounding */
            u_peak = fmax(u_peak, max_abs(uref, sc.neq));
            lam_peak = fmax(lam_peak, fmax(max_abs(lnref, sc.m), max_abs(ltref, sc.m)));
            du = max_diff(rhs, uref, sc.neq) / fmax(u_peak, 1e-300);
            dl = fmax(max_diff(ln, lnref, sc.m), max_diff(lt, ltref, sc.m)) / fmax(lam_peak, 1e-300);
            if (du > max_dev_u) max_dev_u = du;
            if (dl > max_dev_lam) max_dev_lam = dl;
            if (!quiet)
                printf("%4ld %9.5f %9.5f %5lld %5lld %5lld %9.2e %9.2e %9.2e %9.2e\n", k + 1,
                       sc.step_uy[k], sc.step_ux[k], (long long)rep.n_open,
                       (long long)rep.n_stick, (long long)rep.n_slip, rep.err, du, dl,
                       rep_ref.err);
        }
    }

    if (rank == 0) {
        int ok = all_converged && steps_done == N_STEPS && max_dev_u <= 1e-10 &&
                 max_dev_lam <= 1e-10 && max_err <= 1e-10;
        if (!ok) exit_code = 1;
        printf("time split: MUMPS analysis + factorisation + Schur %.3e s, library on S: "
               "creation %.3e s + %ld steps %.3e s, MUMPS reduction %.3e s, expansion %.3e s; "
               "library on the whole K: creation %.3e s + steps %.3e s\n",
               t_factor, t_create, steps_done, t_lib, t_reduce, t_expand, t_ref_create, t_ref);
        printf("SUMMARY example=" EXAMPLE " ranks=%d steps=%ld dofs=%ld schur=%ld max_err=%.3e "
               "ref_max_err=%.3e max_dev_u=%.3e max_dev_lambda=%.3e all_converged=%d ok=%d "
               "t_mumps_factor=%.3e t_library=%.3e t_reduce=%.3e t_expand=%.3e t_reference=%.3e\n",
               nprocs, steps_done, sc.neq, nc, max_err, ref_max_err, max_dev_u, max_dev_lam,
               all_converged && steps_done == N_STEPS, ok, t_factor, t_create + t_lib, t_reduce,
               t_expand, t_ref_create + t_ref);
        ds_problem_free(prob);
        ds_problem_free(ref);
    }
    mumps_call(&id, -2, "termination");
    scene_free(&sc);
    trip_free(&nc_mat);
    trip_free(&tc_mat);
    free(cpos); free(listvar); free(irn); free(jcn); free(kval); free(schur);
    free(f); free(rhs); free(red); free(uc); free(ln); free(lt);
    free(uref); free(lnref); free(ltref);
#ifdef MUMPS_SCHUR_MPI
    MPI_Finalize();
#endif
    return exit_code;
}
