/*
 * cholmod_operator.c -- the demo's block (block2d.c's scene) with K factored by
 * CHOLMOD (supernodal), and the library on CHOLMOD's solves: a host code that
 * already holds a factor of K hands the library its solve instead of K
 * (ds_problem_new_host), so K is factored once, by the host.
 *
 * Two handles step the same history (press, shear, unload, lift-off;
 * Coulomb friction): one on the library's own factor of K (ds_problem_new_opts),
 * one on CHOLMOD's solves. The program prints per step the largest deviation
 * between the two, of u and of the multipliers (lambda_N and lambda_T
 * together), each relative to its largest entry over the history so far (the
 * force scale of the history: near lift-off one barely closed contact carries
 * a force many orders below it), and the host's calls, and fails when a
 * deviation exceeds --check-tol (default 1e-10).
 *
 * The failure path: with --fail-at N the callback returns the code 77 on its
 * N-th call (counted from the handle's creation, whose contact blocks take the
 * first calls); the step in which that
 * happens must return DS_STATUS_HOST_SOLVE_FAILED with the code in the message,
 * leave its outputs untouched, and the step redone must give the own path's
 * answer again (a line "FAILURE step=.. call=.. named=0|1 untouched=0|1
 * message=\"..\""; the redone step's deviation counts in the SUMMARY check).
 *
 * Options: --nx N --ny N (default 40 x 20), --no-k (do not hand K over: Jacobi
 * instead of the lumped preconditioner, K u_k from the last equilibrium),
 * --tol t (library tolerance, default 1e-12), --check-tol t, --fail-at N,
 * --quiet.
 *
 * Build (see the Makefile, `make cholmod-operator-demo`; Debian/Ubuntu:
 * apt-get install libsuitesparse-dev):
 *   cc -O2 -std=c99 -Iinclude -I/usr/include/suitesparse c_examples/cholmod_operator.c \
 *      target/release/libdualsplit.a -lcholmod -lsuitesparseconfig -lm -lpthread -ldl \
 *      -o cholmod_operator
 *
 * Output: a table per step (unless --quiet) and a line "SUMMARY steps=..
 * contacts=.. dofs=.. max_dev=.. host_calls=.. with_k=0|1 check=ok|FAILED"
 * (host_calls: every call of the callback, those for the contact blocks at
 * creation included). Exit status: 0 on success, 1 if a step did not converge
 * or a check failed, 2 on a library or CHOLMOD error, 3 on bad options.
 */

#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cholmod.h>

#include "dualsplit.h"
/* The demo's scene: triplets, Q4 element, mesh, loads (shared with block2d.c). */
#include "block2d_scene.h"

/* What the callback needs: CHOLMOD's factor and workspace, and a call counter
   for --fail-at. */
typedef struct {
    cholmod_factor *lf;
    cholmod_common *cc;
    long calls, fail_at;
} Host;

/* DsHostSolveFn: x (n x ncols, leading dimension ld) := K^-1 x by CHOLMOD. */
static int32_t cholmod_solve_cb(void *context, int64_t n, int64_t ncols, double *x, int64_t ld)
{
    Host *h = (Host *)context;
    cholmod_dense b, *y;
    int64_t j;
    h->calls++;
    if (h->fail_at > 0 && h->calls == h->fail_at) return 77;
    /* A cholmod_dense header over the library's block: no copy in. */
    memset(&b, 0, sizeof b);
    b.nrow = (size_t)n;
    b.ncol = (size_t)ncols;
    b.nzmax = (size_t)(ld * ncols);
    b.d = (size_t)ld;
    b.x = x;
    b.xtype = CHOLMOD_REAL;
    b.dtype = CHOLMOD_DOUBLE;
    y = cholmod_l_solve(CHOLMOD_A, h->lf, &b, h->cc);
    if (y == NULL || h->cc->status != CHOLMOD_OK) {
        if (y != NULL) cholmod_l_free_dense(&y, h->cc);
        return h->cc->status != CHOLMOD_OK ? (int32_t)h->cc->status : -1;
    }
    for (j = 0; j < ncols; j++)
        memcpy(x + j * ld, (double *)y->x + j * (int64_t)y->d, (size_t)n * sizeof(double));
    cholmod_l_free_dense(&y, h->cc);
    return 0;
}

static int parse_double(const char *s, double *v)
{
    char *end;
    errno = 0;
    *v = strtod(s, &end);
    return errno == 0 && end != s && *end == '\0' && isfinite(*v);
}

static int parse_long(const char *s, long *v)
{
    char *end;
    errno = 0;
    *v = strtol(s, &end, 10);
    return errno == 0 && end != s && *end == '\0';
}

static void library_error(const char *what, DsStatus st)
{
    fprintf(stderr, "cholmod_operator: %s failed: %s (%d): %s\n", what,
            ds_status_string((int32_t)st), (int)st, ds_last_error_message());
}

/* Adds max_k |a_k - b_k| to *d and max_k |a_k| to *s (as maxima). */
static void dev_and_scale(const double *a, const double *b, long n, double *d, double *s)
{
    long k;
    for (k = 0; k < n; k++) {
        if (fabs(a[k] - b[k]) > *d) *d = fabs(a[k] - b[k]);
        if (fabs(a[k]) > *s) *s = fabs(a[k]);
    }
}

/* d / s, or d where s vanishes. */
static double ratio(double d, double s)
{
    return s > 0.0 ? d / s : d;
}

int main(int argc, char **argv)
{
    long nx = 40, ny = 20, fail_at = 0, k, i;
    double tol = 1e-12, check_tol = 1e-10, max_dev = 0.0, su = 0.0, sl = 0.0;
    int quiet = 0, with_k = 1, exit_code = 0, failure_seen = 0;
    long host_solves = 0, steps_done = 0;
    Scene s;
    cholmod_common cc;
    cholmod_triplet *kt;
    cholmod_sparse *ks;
    Host host;
    DsHostSolver solver;
    DsMatrix kc, nm, tm;
    DsProblem *own = NULL, *onh = NULL;
    DsOptions opts;
    DsReport ra, rb;
    DsStatus st;
    double *f, *ua, *ub, *lna, *lnb, *lta, *ltb;

    for (k = 1; k < argc; k++) {
        const char *opt = argv[k], *v = k + 1 < argc ? argv[k + 1] : NULL;
        int ok = 1;
        if (strcmp(opt, "--quiet") == 0) { quiet = 1; continue; }
        if (strcmp(opt, "--no-k") == 0) { with_k = 0; continue; }
        if (v == NULL) {
            fprintf(stderr, "cholmod_operator: option %s needs a value\n", opt);
            return 3;
        }
        if (strcmp(opt, "--nx") == 0) ok = parse_long(v, &nx) && nx >= 1 && nx <= 10000;
        else if (strcmp(opt, "--ny") == 0) ok = parse_long(v, &ny) && ny >= 1 && ny <= 10000;
        else if (strcmp(opt, "--tol") == 0) ok = parse_double(v, &tol) && tol > 0.0;
        else if (strcmp(opt, "--check-tol") == 0) ok = parse_double(v, &check_tol) && check_tol > 0.0;
        else if (strcmp(opt, "--fail-at") == 0) ok = parse_long(v, &fail_at) && fail_at >= 1;
        else {
            fprintf(stderr, "cholmod_operator: unknown option %s\n", opt);
            return 3;
        }
        if (!ok) {
            fprintf(stderr, "cholmod_operator: bad value '%s' for %s\n", v, opt);
            return 3;
        }
        k++;
    }

    /* ---- the demo's scene ---------------------------------------------------- */
    if (scene_build(&s, nx, ny, 1e4, 0.3, 2.0, 1.0, 0.05, 0.3, -0.05, 0.05) != 0) {
        fprintf(stderr, "cholmod_operator: bad element\n");
        return 2;
    }

    /* ---- the host's factor: K (upper triangle) in CHOLMOD, supernodal -------- */
    cholmod_l_start(&cc);
    cc.supernodal = CHOLMOD_SUPERNODAL;
    kt = cholmod_l_allocate_triplet((size_t)s.neq, (size_t)s.neq, (size_t)s.kff.n, 1,
                                    CHOLMOD_REAL, &cc);
    if (kt == NULL) return 2;
    for (i = 0; i < s.kff.n; i++)
        if (s.kff.row[i] <= s.kff.col[i]) {
            SuiteSparse_long t = (SuiteSparse_long)kt->nnz++;
            ((SuiteSparse_long *)kt->i)[t] = s.kff.row[i];
            ((SuiteSparse_long *)kt->j)[t] = s.kff.col[i];
            ((double *)kt->x)[t] = s.kff.val[i];
        }
    ks = cholmod_l_triplet_to_sparse(kt, kt->nnz, &cc);
    if (ks == NULL) return 2;
    host.cc = &cc;
    host.calls = 0;
    host.fail_at = fail_at;
    host.lf = cholmod_l_analyze(ks, &cc);
    if (host.lf == NULL || !cholmod_l_factorize(ks, host.lf, &cc) || cc.status != CHOLMOD_OK) {
        fprintf(stderr, "cholmod_operator: CHOLMOD factorisation failed (status %d)\n", cc.status);
        return 2;
    }

    /* ---- two handles: the library's own factor, and CHOLMOD's solves --------- */
    kc = coo_matrix(&s.kff, s.neq, s.neq);
    nm = coo_matrix(&s.nmat, s.m, s.neq);
    tm = coo_matrix(&s.tmat, s.m, s.neq);
    ds_options_default(&opts);
    opts.tol = tol;
    opts.dual_form = DS_DUAL_FORM_MATRIX_FREE;
    opts.method = DS_METHOD_AUTO;
    st = ds_problem_new_opts(2, &kc, &nm, &tm, &opts, &own);
    if (st != DS_STATUS_OK) {
        library_error("ds_problem_new_opts", st);
        return 2;
    }
    memset(&solver, 0, sizeof solver);
    solver.struct_size = (uint32_t)sizeof solver;
    solver.n = s.neq;
    solver.solve = cholmod_solve_cb;
    solver.context = &host;
    /* K is factored once, by the host: the contact blocks by its solves too
       (the default, DS_HOST_BLOCKS_AUTO, may factor the K handed over). */
    solver.blocks = DS_HOST_BLOCKS_SOLVES;
    st = ds_problem_new_host(2, &solver, with_k ? &kc : NULL, &nm, &tm, &opts, &onh);
    if (st != DS_STATUS_OK) {
        library_error("ds_problem_new_host", st);
        return 2;
    }

    f = (double *)xcalloc((size_t)s.neq, sizeof(double));
    ua = (double *)xcalloc((size_t)s.neq, sizeof(double));
    ub = (double *)xcalloc((size_t)s.neq, sizeof(double));
    lna = (double *)xcalloc((size_t)s.m, sizeof(double));
    lnb = (double *)xcalloc((size_t)s.m, sizeof(double));
    lta = (double *)xcalloc((size_t)s.m, sizeof(double));
    ltb = (double *)xcalloc((size_t)s.m, sizeof(double));

    if (!quiet) {
        printf("cholmod_operator: %ld x %ld Q4 elements, %ld free DOFs, %ld contacts, "
               "K %s, CHOLMOD %s\n",
               nx, ny, s.neq, s.m, with_k ? "handed over" : "not handed over",
               host.lf->is_super ? "supernodal" : "simplicial");
        printf("%4s %5s %5s %5s %10s %10s %9s %6s %10s\n", "step", "open", "stick", "slip",
               "dev_u", "dev_lambda", "err", "outer", "host_calls");
    }

    /* ---- the history on both handles ----------------------------------------- */
    for (k = 0; k < N_STEPS; k++) {
        double du = 0.0, dl = 0.0;
        scene_load(&s, k, f);
        st = ds_step(own, &opts, DS_FRICTION_COULOMB, f, s.g0, s.mu, ua, lna, lta, &ra);
        if (st != DS_STATUS_OK) {
            library_error("ds_step (own factor)", st);
            return st == DS_STATUS_NOT_CONVERGED ? 1 : 2;
        }
        for (i = 0; i < s.neq; i++) ub[i] = -7.0; /* sentinels: untouched on error */
        st = ds_step(onh, &opts, DS_FRICTION_COULOMB, f, s.g0, s.mu, ub, lnb, ltb, &rb);
        if (st == DS_STATUS_HOST_SOLVE_FAILED && fail_at > 0 && !failure_seen) {
            int untouched = 1, named = strstr(ds_last_error_message(), "code 77") != NULL;
            for (i = 0; i < s.neq; i++)
                if (ub[i] != -7.0) untouched = 0;
            printf("FAILURE step=%ld call=%ld named=%d untouched=%d message=\"%s\"\n", k + 1,
                   host.calls, named, untouched, ds_last_error_message());
            failure_seen = 1;
            if (!named || !untouched) exit_code = 1;
            /* The step again: the handle is usable, its history where it was. */
            st = ds_step(onh, &opts, DS_FRICTION_COULOMB, f, s.g0, s.mu, ub, lnb, ltb, &rb);
        }
        if (st != DS_STATUS_OK) {
            library_error("ds_step (CHOLMOD's solves)", st);
            return st == DS_STATUS_NOT_CONVERGED ? 1 : 2;
        }
        dev_and_scale(ua, ub, s.neq, &du, &su);
        dev_and_scale(lna, lnb, s.m, &dl, &sl);
        dev_and_scale(lta, ltb, s.m, &dl, &sl);
        du = ratio(du, su);
        dl = ratio(dl, sl);
        if (du > max_dev) max_dev = du;
        if (dl > max_dev) max_dev = dl;
        steps_done++;
        if (!quiet)
            printf("%4ld %5lld %5lld %5lld %10.2e %10.2e %9.2e %6lld %10ld\n", k + 1,
                   (long long)rb.n_open, (long long)rb.n_stick, (long long)rb.n_slip, du, dl,
                   rb.err, (long long)rb.outer_iterations, host.calls - host_solves);
        host_solves = host.calls;
    }
    if (fail_at > 0 && !failure_seen) {
        fprintf(stderr, "cholmod_operator: --fail-at %ld: no step failed (%ld calls)\n", fail_at,
                host.calls);
        exit_code = 1;
    }
    if (max_dev > check_tol) exit_code = 1;
    printf("SUMMARY steps=%ld contacts=%ld dofs=%ld max_dev=%.3e host_calls=%ld with_k=%d "
           "check=%s\n",
           steps_done, s.m, s.neq, max_dev, host.calls, with_k,
           max_dev <= check_tol ? "ok" : "FAILED");

    ds_problem_free(own);
    ds_problem_free(onh);
    cholmod_l_free_factor(&host.lf, &cc);
    cholmod_l_free_sparse(&ks, &cc);
    cholmod_l_free_triplet(&kt, &cc);
    cholmod_l_finish(&cc);
    scene_free(&s);
    free(f); free(ua); free(ub); free(lna); free(lnb); free(lta); free(ltb);
    return exit_code;
}
