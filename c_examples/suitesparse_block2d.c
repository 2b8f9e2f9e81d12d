/*
 * suitesparse_block2d.c -- the plane-strain block of block2d.c assembled the way a
 * SuiteSparse user assembles it, with the matrices handed to dualsplit as they are.
 *
 *   - K (free DOFs, top edge eliminated) is assembled as a CHOLMOD triplet matrix
 *     holding the upper triangle (stype = 1, how CHOLMOD stores a symmetric matrix)
 *     with SuiteSparse_long indices, and compressed by cholmod_l_triplet_to_sparse
 *     (duplicates summed): a packed cholmod_sparse;
 *   - N is a CSparse (CXSparse cs_di, int indices) triplet matrix compressed by
 *     cs_di_compress; T stays a cs_di triplet matrix;
 *   - each goes to the library through ds_matrix_from_cholmod / ds_matrix_from_cs
 *     below: the DsMatrix points at the cholmod_sparse / cs arrays p, i, x -- no copy,
 *     no conversion, no index shift. K is CSC, DS_INDEX_TYPE_I64, DS_STORAGE_UPPER;
 *     N is CSC, DS_INDEX_TYPE_I32; T is COO (a cs triplet: p = columns, i = rows).
 *
 * Part 1, history: Coulomb friction (mu, default 0.3), ds_step over a press (5 steps
 * to uy) and shear (5 steps to ux) of the top edge, as in block2d.c.
 *
 * Part 2, reference: the frictionless problem (Tresca with p = 0) of the full press
 * is solved by ds_solve (K factored by the library, faer; tol 1e-12), then re-solved
 * independently with CHOLMOD on the final active set a = {i : lambda_N,i > 0}:
 *     K z = f,  K X = N_a^T,  S = N_a X,  S lambda_a = N_a z - g_a,  u = z - X lambda_a
 * (the equality-constrained system [K N_a^T; N_a 0] [u; lambda_a] = [f; g_a] by its
 * Schur complement). The program prints the relative differences of u and lambda_N,
 * checks that the reference is feasible (lambda_a >= 0, N u <= g on the inactive set)
 * and fails when u differs by more than --check-tol (default 1e-10).
 *
 * Options: --nx N --ny N (default 40 x 20), --mu mu (0.3), --uy v (-0.05),
 * --ux v (0.05), --tol t (library tolerance of part 1), --check-tol t, --quiet.
 *
 * Build (see the Makefile, `make suitesparse-demo`; Debian/Ubuntu: apt-get install
 * libsuitesparse-dev):
 *   cc -O2 -std=c99 -Iinclude -I/usr/include/suitesparse c_examples/suitesparse_block2d.c \
 *      target/release/libdualsplit.a -lcholmod -lcxsparse -lsuitesparseconfig \
 *      -lm -lpthread -ldl -o suitesparse_block2d
 *
 * Output: a table per step, a line "REFERENCE active=.. u_rel_diff=.. lambda_rel_diff=..
 * feasible=.." and a line "SUMMARY ...". Exit status: 0 on success, 1 if a step did
 * not converge or the reference check failed, 2 on a library or SuiteSparse error,
 * 3 on bad options.
 */

#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cholmod.h>
#include <cs.h>

#include "dualsplit.h"
/* The Q4 element, xcalloc (the plain demo's, shared with block2d.c). */
#include "block2d_scene.h"

/* cholmod_l and cs_dl use SuiteSparse_long, cs_di and cholmod (int) use int. */
typedef char assert_suitesparse_long_is_64_bit[sizeof(SuiteSparse_long) == sizeof(int64_t) ? 1 : -1];
typedef char assert_int_is_32_bit[sizeof(int) == sizeof(int32_t) ? 1 : -1];

/* ------------------------------------------------------------------------- */
/* SuiteSparse matrices as borrowed DsMatrix views                            */
/* ------------------------------------------------------------------------- */

/* A packed cholmod_sparse, field by field: CSC, base 0, stype -> storage. */
static DsMatrix ds_matrix_from_cholmod(const cholmod_sparse *a)
{
    DsMatrix m;
    m.format = DS_FORMAT_CSC;
    m.index_type = a->itype == CHOLMOD_LONG ? DS_INDEX_TYPE_I64 : DS_INDEX_TYPE_I32;
    m.base = 0;
    m.storage = a->stype > 0 ? DS_STORAGE_UPPER : a->stype < 0 ? DS_STORAGE_LOWER : DS_STORAGE_FULL;
    m.nrows = (int64_t)a->nrow;
    m.ncols = (int64_t)a->ncol;
    m.nnz = 0;
    m.p = a->p;
    m.i = a->i;
    m.x = (const double *)a->x;
    return m;
}

/* A CSparse cs_di: compressed column (nz = -1) or triplet (nz >= 0). */
static DsMatrix ds_matrix_from_cs(const cs_di *a)
{
    DsMatrix m;
    m.format = a->nz >= 0 ? DS_FORMAT_COO : DS_FORMAT_CSC;
    m.index_type = DS_INDEX_TYPE_I32;
    m.base = 0;
    m.storage = DS_STORAGE_FULL;
    m.nrows = a->m;
    m.ncols = a->n;
    m.nnz = a->nz >= 0 ? a->nz : 0;
    m.p = a->p;
    m.i = a->i;
    m.x = a->x;
    return m;
}

/* ------------------------------------------------------------------------- */
/* small helpers                                                               */
/* ------------------------------------------------------------------------- */

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
    fprintf(stderr, "suitesparse_block2d: %s failed: %s (%d): %s\n", what,
            ds_status_string((int32_t)st), (int)st, ds_last_error_message());
}

static double max_abs(const double *x, long n)
{
    double m = 0.0;
    long k;
    for (k = 0; k < n; k++)
        if (fabs(x[k]) > m) m = fabs(x[k]);
    return m;
}

/* In-place dense Cholesky S = L L^T (column-major, n x n) and solve; -1 if not SPD. */
static int dense_cholesky_solve(double *s, long n, double *rhs)
{
    long i, j, k;
    for (j = 0; j < n; j++) {
        double djj = s[j + j * n];
        for (k = 0; k < j; k++) djj -= s[j + k * n] * s[j + k * n];
        if (!(djj > 0.0)) return -1;
        djj = sqrt(djj);
        s[j + j * n] = djj;
        for (i = j + 1; i < n; i++) {
            double v = s[i + j * n];
            for (k = 0; k < j; k++) v -= s[i + k * n] * s[j + k * n];
            s[i + j * n] = v / djj;
        }
    }
    for (i = 0; i < n; i++) { /* L y = rhs */
        double v = rhs[i];
        for (k = 0; k < i; k++) v -= s[i + k * n] * rhs[k];
        rhs[i] = v / s[i + i * n];
    }
    for (i = n - 1; i >= 0; i--) { /* L^T x = y */
        double v = rhs[i];
        for (k = i + 1; k < n; k++) v -= s[k + i * n] * rhs[k];
        rhs[i] = v / s[i + i * n];
    }
    return 0;
}

/* ------------------------------------------------------------------------- */
/* main                                                                        */
/* ------------------------------------------------------------------------- */

/* N_PRESS = N_SHEAR = 5 (block2d_scene.h): the demo's press and shear only. */
#define N_HISTORY (N_PRESS + N_SHEAR)

int main(int argc, char **argv)
{
    const double E = 1e4, NU = 0.3, W = 2.0, H = 1.0, CURVED = 0.05;
    long nx = 40, ny = 20;
    double mu_c = 0.3, uy = -0.05, ux = 0.05, tol = -1.0, check_tol = 1e-10;
    int quiet = 0;
    long nnode, nelem, ndof, neq, npre, m, i, j, e, k, a, b, c;
    long *eq, *conn;
    int *pcomp;
    double *xy, dmat[3][3];
    cholmod_common cc;
    cholmod_triplet *kt;
    cholmod_sparse *ks;
    cs_di *kfp_t, *kfp, *n_t, *n_c, *t_t;
    DsMatrix km, nm, tm;
    DsProblem *prob = NULL;
    DsOptions opts;
    DsReport rep;
    DsStatus st;
    double *up, *f, *u, *lam_n, *lam_t, *g0, *bound;
    double max_err = 0.0;
    long total_outer = 0, steps_done = 0, shear_max_slip = 0, shear_max_stick = 0;
    int exit_code = 0, all_converged = 1;

    for (k = 1; k < argc; k++) {
        const char *opt = argv[k], *v = k + 1 < argc ? argv[k + 1] : NULL;
        int ok = 1;
        if (strcmp(opt, "--quiet") == 0) {
            quiet = 1;
            continue;
        }
        if (v == NULL) {
            fprintf(stderr, "suitesparse_block2d: option %s needs a value\n", opt);
            return 3;
        }
        if (strcmp(opt, "--nx") == 0) ok = parse_long(v, &nx) && nx >= 1 && nx <= 10000;
        else if (strcmp(opt, "--ny") == 0) ok = parse_long(v, &ny) && ny >= 1 && ny <= 10000;
        else if (strcmp(opt, "--mu") == 0) ok = parse_double(v, &mu_c) && mu_c >= 0.0;
        else if (strcmp(opt, "--uy") == 0) ok = parse_double(v, &uy) && uy < 0.0;
        else if (strcmp(opt, "--ux") == 0) ok = parse_double(v, &ux);
        else if (strcmp(opt, "--tol") == 0) ok = parse_double(v, &tol) && tol > 0.0;
        else if (strcmp(opt, "--check-tol") == 0) ok = parse_double(v, &check_tol) && check_tol > 0.0;
        else {
            fprintf(stderr, "suitesparse_block2d: unknown option %s\n", opt);
            return 3;
        }
        if (!ok) {
            fprintf(stderr, "suitesparse_block2d: bad value '%s' for %s\n", v, opt);
            return 3;
        }
        k++;
    }

    /* ---- mesh and ID array (as block2d.c) ----------------------------------- */
    nnode = (nx + 1) * (ny + 1);
    nelem = nx * ny;
    ndof = 2 * nnode;
    xy = (double *)xcalloc((size_t)ndof, sizeof(double));
    conn = (long *)xcalloc((size_t)(4 * nelem), sizeof(long));
    eq = (long *)xcalloc((size_t)ndof, sizeof(long));
    pcomp = (int *)xcalloc((size_t)ndof, sizeof(int));
    for (j = 0; j <= ny; j++)
        for (i = 0; i <= nx; i++) {
            long nd = j * (nx + 1) + i;
            xy[2 * nd] = W * (double)i / (double)nx;
            xy[2 * nd + 1] = H * (double)j / (double)ny;
        }
    for (j = 0; j < ny; j++)
        for (i = 0; i < nx; i++) {
            long el = j * nx + i, n0 = j * (nx + 1) + i;
            conn[4 * el + 0] = n0;
            conn[4 * el + 1] = n0 + 1;
            conn[4 * el + 2] = n0 + 1 + (nx + 1);
            conn[4 * el + 3] = n0 + (nx + 1);
        }
    neq = npre = 0;
    for (k = 0; k < nnode; k++)
        for (c = 0; c < 2; c++) {
            if (k / (nx + 1) == ny) {
                pcomp[npre] = (int)c;
                eq[2 * k + c] = -(1 + npre);
                npre++;
            } else
                eq[2 * k + c] = neq++;
        }

    /* ---- assembly: K upper triangle as a CHOLMOD triplet, -K_fp as a cs triplet */
    cholmod_l_start(&cc);
    kt = cholmod_l_allocate_triplet((size_t)neq, (size_t)neq, (size_t)(36 * nelem), 1,
                                    CHOLMOD_REAL, &cc);
    kfp_t = cs_di_spalloc((int)neq, (int)npre, (int)(16 * nx), 1, 1);
    if (kt == NULL || kfp_t == NULL) {
        fprintf(stderr, "suitesparse_block2d: cannot allocate the triplet matrices\n");
        return 2;
    }
    plane_strain_d(E, NU, dmat);
    for (e = 0; e < nelem; e++) {
        double xe[4], ye[4], ke[8][8];
        long ed[8];
        for (a = 0; a < 4; a++) {
            long nd = conn[4 * e + a];
            xe[a] = xy[2 * nd];
            ye[a] = xy[2 * nd + 1];
            ed[2 * a] = eq[2 * nd];
            ed[2 * a + 1] = eq[2 * nd + 1];
        }
        if (q4_stiffness(xe, ye, dmat, ke) != 0) {
            fprintf(stderr, "suitesparse_block2d: element %ld has a non-positive Jacobian\n", e);
            return 2;
        }
        for (a = 0; a < 8; a++)
            for (b = 0; b < 8; b++) {
                long ra = ed[a], cb = ed[b];
                if (ra >= 0 && cb >= ra) { /* upper triangle: row <= column */
                    SuiteSparse_long t = (SuiteSparse_long)kt->nnz;
                    ((SuiteSparse_long *)kt->i)[t] = ra;
                    ((SuiteSparse_long *)kt->j)[t] = cb;
                    ((double *)kt->x)[t] = ke[a][b];
                    kt->nnz++;
                } else if (ra >= 0 && cb < 0) {
                    if (!cs_di_entry(kfp_t, (int)ra, (int)(-1 - cb), -ke[a][b])) {
                        fprintf(stderr, "suitesparse_block2d: cs_di_entry failed\n");
                        return 2;
                    }
                }
            }
    }
    ks = cholmod_l_triplet_to_sparse(kt, kt->nnz, &cc); /* sums duplicates, stype 1 */
    kfp = cs_di_compress(kfp_t);
    if (ks == NULL || kfp == NULL || !cs_di_dupl(kfp)) {
        fprintf(stderr, "suitesparse_block2d: compressing the triplets failed\n");
        return 2;
    }

    /* ---- contacts: N compressed (cs_di), T as a cs_di triplet --------------- */
    m = nx + 1;
    n_t = cs_di_spalloc((int)m, (int)neq, (int)m, 1, 1);
    t_t = cs_di_spalloc((int)m, (int)neq, (int)m, 1, 1);
    g0 = (double *)xcalloc((size_t)m, sizeof(double));
    bound = (double *)xcalloc((size_t)m, sizeof(double));
    if (n_t == NULL || t_t == NULL) return 2;
    for (i = 0; i <= nx; i++) {
        double dxc = xy[2 * i] - 0.5 * W;
        cs_di_entry(n_t, (int)i, (int)eq[2 * i + 1], -1.0); /* outward normal (0,-1) */
        cs_di_entry(t_t, (int)i, (int)eq[2 * i], 1.0);      /* tangent (1,0) */
        g0[i] = CURVED * dxc * dxc;
    }
    n_c = cs_di_compress(n_t);
    if (n_c == NULL) return 2;

    /* ---- the library borrows the SuiteSparse arrays ------------------------- */
    km = ds_matrix_from_cholmod(ks); /* CSC, I64, UPPER */
    nm = ds_matrix_from_cs(n_c);     /* CSC, I32 */
    tm = ds_matrix_from_cs(t_t);     /* COO, I32 */
    st = ds_problem_new(2, &km, &nm, &tm, &prob);
    if (st != DS_STATUS_OK) {
        library_error("ds_problem_new", st);
        return 2;
    }
    ds_options_default(&opts);
    if (tol > 0.0) opts.tol = tol;

    up = (double *)xcalloc((size_t)npre, sizeof(double));
    f = (double *)xcalloc((size_t)neq, sizeof(double));
    u = (double *)xcalloc((size_t)neq, sizeof(double));
    lam_n = (double *)xcalloc((size_t)m, sizeof(double));
    lam_t = (double *)xcalloc((size_t)m, sizeof(double));

    if (!quiet) {
        printf("suitesparse_block2d: %ld x %ld Q4 elements, %ld free DOFs, %ld contacts\n", nx,
               ny, neq, m);
        printf("  K: cholmod_sparse %s, stype %d, %ld entries (upper triangle)\n",
               ks->itype == CHOLMOD_LONG ? "SuiteSparse_long" : "int", ks->stype,
               (long)((SuiteSparse_long *)ks->p)[neq]);
        printf("  N: cs_di compressed (%d entries), T: cs_di triplet (%d entries)\n",
               n_c->p[n_c->n], t_t->nz);
        printf("%4s %-6s %9s %9s %5s %5s %5s %18s %18s %9s %6s\n", "step", "phase", "uy_top",
               "ux_top", "open", "stick", "slip", "sum_lamN", "sum_lamT", "err", "outer");
    }

    /* ---- part 1: Coulomb history with ds_step ------------------------------- */
    for (i = 0; i < m; i++) bound[i] = mu_c;
    for (k = 0; k < N_HISTORY; k++) {
        double sy = k < N_PRESS ? uy * (double)(k + 1) / N_PRESS : uy;
        double sx = k < N_PRESS ? 0.0 : ux * (double)(k + 1 - N_PRESS) / N_SHEAR;
        double sum_n = 0.0, sum_t = 0.0;
        for (i = 0; i < npre; i++) up[i] = pcomp[i] == 0 ? sx : sy;
        for (i = 0; i < neq; i++) f[i] = 0.0;
        cs_di_gaxpy(kfp, up, f); /* f = -K_fp u_p */
        memset(&rep, 0, sizeof rep);
        st = ds_step(prob, &opts, DS_FRICTION_COULOMB, f, g0, bound, u, lam_n, lam_t, &rep);
        if (st == DS_STATUS_NOT_CONVERGED) {
            fprintf(stderr, "suitesparse_block2d: step %ld did not converge (err %.3e)\n", k + 1,
                    rep.err);
            all_converged = 0;
            exit_code = 1;
            break;
        } else if (st != DS_STATUS_OK) {
            library_error("ds_step", st);
            return 2;
        }
        steps_done++;
        for (i = 0; i < m; i++) {
            sum_n += lam_n[i];
            sum_t += lam_t[i];
        }
        if (rep.err > max_err) max_err = rep.err;
        total_outer += (long)rep.outer_iterations;
        if (k >= N_PRESS) {
            if (rep.n_slip > shear_max_slip) shear_max_slip = (long)rep.n_slip;
            if (rep.n_stick > shear_max_stick) shear_max_stick = (long)rep.n_stick;
        }
        if (!quiet)
            printf("%4ld %-6s %9.5f %9.5f %5lld %5lld %5lld %18.10e %18.10e %9.2e %6lld\n", k + 1,
                   k < N_PRESS ? "press" : "shear", sy, sx, (long long)rep.n_open,
                   (long long)rep.n_stick, (long long)rep.n_slip, sum_n, sum_t, rep.err,
                   (long long)rep.outer_iterations);
    }

    /* ---- part 2: frictionless press, library vs CHOLMOD on the active set ---- */
    {
        cholmod_factor *lf;
        cholmod_dense *fd, *zd = NULL, *bd = NULL, *xd = NULL;
        long *act, na = 0, r;
        double *s, *rhs, *uref, *nu_ref, u_diff, lam_diff, lam_max = 0.0, viol = 0.0;
        double min_lam = 0.0;
        int feasible, check_ok;

        for (i = 0; i < npre; i++) up[i] = pcomp[i] == 0 ? 0.0 : uy;
        for (i = 0; i < neq; i++) f[i] = 0.0;
        cs_di_gaxpy(kfp, up, f);
        for (i = 0; i < m; i++) bound[i] = 0.0; /* Tresca p = 0: no friction */
        ds_options_default(&opts);
        opts.tol = 1e-12;
        st = ds_solve(prob, &opts, DS_FRICTION_TRESCA, f, g0, bound, u, lam_n, lam_t, &rep);
        if (st != DS_STATUS_OK) {
            library_error("ds_solve (frictionless)", st);
            return st == DS_STATUS_NOT_CONVERGED ? 1 : 2;
        }

        /* active set a = {i : lambda_N,i > 0}, in the row order of N */
        act = (long *)xcalloc((size_t)m, sizeof(long));
        for (i = 0; i < m; i++)
            if (lam_n[i] > 0.0) act[na++] = i;

        /* CHOLMOD factorisation of the same cholmod_sparse K */
        lf = cholmod_l_analyze(ks, &cc);
        if (lf == NULL || !cholmod_l_factorize(ks, lf, &cc) || cc.status != CHOLMOD_OK) {
            fprintf(stderr, "suitesparse_block2d: CHOLMOD factorisation failed (status %d)\n",
                    cc.status);
            return 2;
        }
        /* z = K^-1 f */
        fd = cholmod_l_zeros((size_t)neq, 1, CHOLMOD_REAL, &cc);
        memcpy(fd->x, f, (size_t)neq * sizeof(double));
        zd = cholmod_l_solve(CHOLMOD_A, lf, fd, &cc);
        /* X = K^-1 N_a^T: column q of N_a^T is row act[q] of N, i.e. the entries of N
           (compressed column) whose row index is act[q] */
        bd = cholmod_l_zeros((size_t)neq, (size_t)(na > 0 ? na : 1), CHOLMOD_REAL, &cc);
        if (zd == NULL || bd == NULL) return 2;
        {
            long *pos = (long *)xcalloc((size_t)m, sizeof(long));
            for (i = 0; i < m; i++) pos[i] = -1;
            for (r = 0; r < na; r++) pos[act[r]] = r;
            for (c = 0; c < n_c->n; c++)
                for (k = n_c->p[c]; k < n_c->p[c + 1]; k++)
                    if (pos[n_c->i[k]] >= 0)
                        ((double *)bd->x)[c + pos[n_c->i[k]] * neq] += n_c->x[k];
            free(pos);
        }
        xd = cholmod_l_solve(CHOLMOD_A, lf, bd, &cc);
        if (xd == NULL) return 2;

        /* S = N_a X = X^T N_a^T (na x na), rhs = N_a z - g_a */
        s = (double *)xcalloc((size_t)(na * na + 1), sizeof(double));
        rhs = (double *)xcalloc((size_t)(na + 1), sizeof(double));
        for (r = 0; r < na; r++) {
            const double *bcol = (const double *)bd->x + r * neq;
            double v = 0.0;
            for (i = 0; i < neq; i++) v += bcol[i] * ((const double *)zd->x)[i];
            rhs[r] = v - g0[act[r]];
            for (c = 0; c < na; c++) {
                const double *xcol = (const double *)xd->x + c * neq;
                double w = 0.0;
                for (i = 0; i < neq; i++) w += bcol[i] * xcol[i];
                s[r + c * na] = w;
            }
        }
        if (na > 0 && dense_cholesky_solve(s, na, rhs) != 0) {
            fprintf(stderr, "suitesparse_block2d: the Schur complement is not SPD\n");
            return 2;
        }
        /* u_ref = z - X lambda_a */
        uref = (double *)xcalloc((size_t)neq, sizeof(double));
        for (i = 0; i < neq; i++) {
            double v = ((const double *)zd->x)[i];
            for (c = 0; c < na; c++) v -= ((const double *)xd->x)[i + c * neq] * rhs[c];
            uref[i] = v;
        }
        /* compare */
        u_diff = 0.0;
        for (i = 0; i < neq; i++)
            if (fabs(u[i] - uref[i]) > u_diff) u_diff = fabs(u[i] - uref[i]);
        u_diff /= max_abs(uref, neq);
        lam_diff = 0.0;
        for (r = 0, i = 0; i < m; i++) {
            double ref = (r < na && act[r] == i) ? rhs[r++] : 0.0;
            if (fabs(lam_n[i] - ref) > lam_diff) lam_diff = fabs(lam_n[i] - ref);
            if (fabs(ref) > lam_max) lam_max = fabs(ref);
        }
        lam_diff /= lam_max > 0.0 ? lam_max : 1.0;
        /* the reference must solve the inequality problem: lambda_a >= 0, N u <= g */
        nu_ref = (double *)xcalloc((size_t)m, sizeof(double));
        cs_di_gaxpy(n_c, uref, nu_ref);
        min_lam = na > 0 ? rhs[0] : 0.0;
        for (r = 1; r < na; r++)
            if (rhs[r] < min_lam) min_lam = rhs[r];
        for (i = 0; i < m; i++)
            if (nu_ref[i] - g0[i] > viol) viol = nu_ref[i] - g0[i];
        feasible = min_lam >= 0.0 && viol <= 1e-12 * max_abs(uref, neq);
        check_ok = feasible && u_diff <= check_tol && lam_diff <= check_tol;
        printf("REFERENCE active=%ld u_rel_diff=%.3e lambda_rel_diff=%.3e feasible=%d "
               "min_lambda=%.3e max_penetration=%.3e err=%.3e outer=%lld check=%s\n",
               na, u_diff, lam_diff, feasible, min_lam, viol, rep.err,
               (long long)rep.outer_iterations, check_ok ? "ok" : "FAILED");
        if (!check_ok) exit_code = 1;

        cholmod_l_free_factor(&lf, &cc);
        cholmod_l_free_dense(&fd, &cc);
        cholmod_l_free_dense(&zd, &cc);
        cholmod_l_free_dense(&bd, &cc);
        cholmod_l_free_dense(&xd, &cc);
        free(act); free(s); free(rhs); free(uref); free(nu_ref);
    }

    printf("SUMMARY steps=%ld contacts=%ld dofs=%ld max_err=%.3e all_converged=%d "
           "total_outer=%ld shear_max_slip=%ld shear_max_stick=%ld k_index=%s k_storage=%s\n",
           steps_done, m, neq, max_err, all_converged && steps_done == N_HISTORY, total_outer,
           shear_max_slip, shear_max_stick, km.index_type == DS_INDEX_TYPE_I64 ? "i64" : "i32",
           km.storage == DS_STORAGE_UPPER ? "upper" : "other");

    ds_problem_free(prob);
    cholmod_l_free_sparse(&ks, &cc);
    cholmod_l_free_triplet(&kt, &cc);
    cholmod_l_finish(&cc);
    cs_di_spfree(kfp_t); cs_di_spfree(kfp); cs_di_spfree(n_t); cs_di_spfree(n_c);
    cs_di_spfree(t_t);
    free(xy); free(conn); free(eq); free(pcomp); free(g0); free(bound);
    free(up); free(f); free(u); free(lam_n); free(lam_t);
    return exit_code;
}
