/*
 * block2d.c -- an elastic block pressed onto a rigid foundation and sheared,
 * written the way a legacy finite element code is written (C99, plain arrays),
 * with the frictional contact solved by dualsplit through its C API.
 *
 *   - 2D plane strain, bilinear quadrilaterals (Q4), 2x2 Gauss integration;
 *   - a W x H block meshed with nx x ny elements, thickness 1;
 *   - the top edge is clamped to a prescribed displacement (ux_top, uy_top): those
 *     DOFs are eliminated from K and their effect moved to the right-hand side,
 *     f = -K_free,top * u_top, the classical way (an "ID array" numbers the free
 *     equations; prescribed DOFs get negative numbers);
 *   - every bottom node is a contact with the rigid foundation: the N row is the
 *     outward normal (0,-1) on its y DOF, so N u <= g reads u_y >= -g; the T row is
 *     (1,0) on its x DOF.  The foundation is curved: g_i = c (x_i - W/2)^2;
 *   - Coulomb friction, history mode (ds_step): the library keeps u and the
 *     multipliers between the steps of the load history, and the program passes
 *     the total load of each step.
 *
 * Load history (prescribed displacement of the top edge):
 *   press  : uy_top from 0 to uy (default -0.05) in 5 steps, ux_top = 0;
 *   shear  : ux_top from 0 to ux (default 0.05) in 5 steps, uy_top = uy;
 *   unload : uy_top back to 0 in 4 steps, ux_top = ux;
 *   lift   : one last step lifts the top edge to +0.2 |uy| (every contact opens).
 *
 * Check of the resultants.  With the library's convention
 *     K u = f - N^T lambda_N - T^T lambda_T,
 * the free rows of the full stiffness give (K_full u_full)_free = -N^T lambda_N
 * - T^T lambda_T, and a rigid translation is in the null space of K_full, so the
 * sum of all x (resp. y) components of K_full u_full vanishes.  The reaction of the
 * top support on the body, R_top = (K_full u_full)_top, therefore satisfies
 *     R_x,top = + sum_i (T^T lambda_T)_x = + sum lambda_T      (T row (1,0))
 *     R_y,top = + sum_i (N^T lambda_N)_y = - sum lambda_N      (N row (0,-1))
 * i.e. the foundation pushes the body up by sum lambda_N and the support pushes it
 * down by the same amount; friction acts on the body with -sum lambda_T in x and
 * the support balances it with +sum lambda_T.
 *
 * Build (see the Makefile):
 *   cc -O2 -std=c99 -Wall -Wextra -Iinclude c_examples/block2d.c \
 *      target/release/libdualsplit.a -lm -lpthread -ldl -o block2d
 *
 * Exit status: 0 on success, 1 if a step did not converge or the resultant check
 * failed, 2 on any other library error, 3 on bad command-line options.
 */

#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "dualsplit.h"
/* Triplets, the Q4 element and coo_matrix (shared with the MUMPS examples). */
#include "block2d_scene.h"

/* ------------------------------------------------------------------------- */
/* command line                                                                */
/* ------------------------------------------------------------------------- */

typedef struct {
    double e, nu, w, h, mu, curved, tol, uy, ux;
    long nx, ny, max_outer, max_inner;
    int method;
    int quiet;
} Params;

static void usage(FILE *out)
{
    fprintf(out,
            "usage: block2d [options]\n"
            "  --method split|block-gs|pgs|newton|split-mprgp|mprgp  dual method (default split)\n"
            "  --nx N, --ny N               elements along x and y (default 40 x 20)\n"
            "  --E e, --nu nu               Young's modulus, Poisson ratio (default 1e4, 0.3)\n"
            "  --W w, --H h                 block width and height (default 2, 1)\n"
            "  --mu mu                      Coulomb coefficient (default 0.3)\n"
            "  --curved c                   foundation gap g = c (x - W/2)^2 (default 0.05)\n"
            "  --uy v, --ux v               final press and shear displacement of the top\n"
            "                               edge (default -0.05, 0.05)\n"
            "  --tol t                      solver tolerance on err (default: library's)\n"
            "  --max-outer n, --max-inner n iteration limits (default: library's)\n"
            "  --quiet                      print only the checks and the SUMMARY line\n");
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

static const char *method_name(int m)
{
    switch (m) {
    case DS_METHOD_SPLIT: return "split";
    case DS_METHOD_BLOCK_GS: return "block-gs";
    case DS_METHOD_PGS: return "pgs";
    case DS_METHOD_NEWTON: return "newton";
    case DS_METHOD_SPLIT_MPRGP: return "split-mprgp";
    case DS_METHOD_MPRGP: return "mprgp";
    default: return "?";
    }
}

static int parse_args(int argc, char **argv, Params *p)
{
    int k;
    p->e = 1e4; p->nu = 0.3; p->w = 2.0; p->h = 1.0;
    p->nx = 40; p->ny = 20;
    p->mu = 0.3; p->curved = 0.05;
    p->uy = -0.05; p->ux = 0.05;
    p->tol = -1.0; p->max_outer = -1; p->max_inner = -1;
    p->method = DS_METHOD_SPLIT;
    p->quiet = 0;

    for (k = 1; k < argc; k++) {
        const char *a = argv[k];
        const char *v = (k + 1 < argc) ? argv[k + 1] : NULL;
        int ok = 1;
        if (strcmp(a, "--help") == 0 || strcmp(a, "-h") == 0) {
            usage(stdout);
            exit(0);
        } else if (strcmp(a, "--quiet") == 0) {
            p->quiet = 1;
            continue;
        }
        if (v == NULL) {
            fprintf(stderr, "block2d: option %s needs a value\n", a);
            return -1;
        }
        if (strcmp(a, "--method") == 0) {
            if (strcmp(v, "split") == 0) p->method = DS_METHOD_SPLIT;
            else if (strcmp(v, "block-gs") == 0) p->method = DS_METHOD_BLOCK_GS;
            else if (strcmp(v, "pgs") == 0) p->method = DS_METHOD_PGS;
            else if (strcmp(v, "newton") == 0) p->method = DS_METHOD_NEWTON;
            else if (strcmp(v, "split-mprgp") == 0) p->method = DS_METHOD_SPLIT_MPRGP;
            else if (strcmp(v, "mprgp") == 0) p->method = DS_METHOD_MPRGP;
            else ok = 0;
        } else if (strcmp(a, "--nx") == 0) ok = parse_long(v, &p->nx) && p->nx >= 1;
        else if (strcmp(a, "--ny") == 0) ok = parse_long(v, &p->ny) && p->ny >= 1;
        else if (strcmp(a, "--E") == 0) ok = parse_double(v, &p->e) && p->e > 0.0;
        else if (strcmp(a, "--nu") == 0) ok = parse_double(v, &p->nu) && p->nu > -1.0 && p->nu < 0.5;
        else if (strcmp(a, "--W") == 0) ok = parse_double(v, &p->w) && p->w > 0.0;
        else if (strcmp(a, "--H") == 0) ok = parse_double(v, &p->h) && p->h > 0.0;
        else if (strcmp(a, "--mu") == 0) ok = parse_double(v, &p->mu) && p->mu >= 0.0;
        else if (strcmp(a, "--curved") == 0) ok = parse_double(v, &p->curved);
        else if (strcmp(a, "--uy") == 0) ok = parse_double(v, &p->uy) && p->uy < 0.0;
        else if (strcmp(a, "--ux") == 0) ok = parse_double(v, &p->ux);
        else if (strcmp(a, "--tol") == 0) ok = parse_double(v, &p->tol) && p->tol > 0.0;
        else if (strcmp(a, "--max-outer") == 0) ok = parse_long(v, &p->max_outer) && p->max_outer > 0;
        else if (strcmp(a, "--max-inner") == 0) ok = parse_long(v, &p->max_inner) && p->max_inner > 0;
        else {
            fprintf(stderr, "block2d: unknown option %s\n", a);
            return -1;
        }
        if (!ok) {
            fprintf(stderr, "block2d: bad value '%s' for %s\n", v, a);
            return -1;
        }
        k++;
    }
    /* the equation numbers are passed as int32 */
    if ((double)(p->nx + 1) * (double)(p->ny + 1) * 2.0 > 2.0e9) {
        fprintf(stderr, "block2d: mesh too large for 32-bit indices\n");
        return -1;
    }
    return 0;
}

static void library_error(const char *what, DsStatus st)
{
    fprintf(stderr, "block2d: %s failed: %s (%d): %s\n", what, ds_status_string((int32_t)st),
            (int)st, ds_last_error_message());
}

/* ------------------------------------------------------------------------- */
/* main                                                                        */
/* ------------------------------------------------------------------------- */

/* N_PRESS, N_SHEAR, N_UNLOAD, N_STEPS: the load history, from block2d_scene.h. */

int main(int argc, char **argv)
{
    Params par;
    long nx, ny, nnode, nelem, ndof, neq, npre, m;
    long i, j, e, k, a, b, c;
    double *xy, *up, *f, *u, *lam_n, *lam_t, *g0, *mu, *ufull, *reac;
    long *eq, *conn;
    int *pcomp;
    double dmat[3][3];
    Triplets kff, kfp, kpr, nmat, tmat;
    DsMatrix km, nm, tm;
    DsProblem *prob = NULL;
    DsOptions opts;
    DsStatus st;
    double step_uy[N_STEPS], step_ux[N_STEPS];
    const char *step_phase[N_STEPS];
    double max_err = 0.0, max_dev = 0.0, force_peak = 0.0, factor_s = 0.0, total_solve_s = 0.0;
    long total_outer = 0, shear_max_slip = 0, shear_max_stick = 0, max_slip = 0;
    long final_open = -1, final_stick = -1, final_slip = -1, steps_done = 0;
    int all_converged = 1, resultant_ok = 1, exit_code = 0;
    const double dev_tol = 1e-8;

    if (parse_args(argc, argv, &par) != 0) {
        usage(stderr);
        return 3;
    }
    nx = par.nx;
    ny = par.ny;

    /* ---- mesh: node (i,j) = j*(nx+1)+i, x = i W/nx, y = j H/ny ------------ */
    nnode = (nx + 1) * (ny + 1);
    nelem = nx * ny;
    ndof = 2 * nnode;
    xy = (double *)xmalloc((size_t)ndof * sizeof(double));
    conn = (long *)xmalloc((size_t)(4 * nelem) * sizeof(long));
    for (j = 0; j <= ny; j++)
        for (i = 0; i <= nx; i++) {
            long nd = j * (nx + 1) + i;
            xy[2 * nd] = par.w * (double)i / (double)nx;
            xy[2 * nd + 1] = par.h * (double)j / (double)ny;
        }
    for (j = 0; j < ny; j++)
        for (i = 0; i < nx; i++) {
            long el = j * nx + i, n0 = j * (nx + 1) + i;
            conn[4 * el + 0] = n0;
            conn[4 * el + 1] = n0 + 1;
            conn[4 * el + 2] = n0 + 1 + (nx + 1);
            conn[4 * el + 3] = n0 + (nx + 1);
        }

    /* ---- ID array: eq[dof] >= 0 free equation, -(1+p) prescribed DOF p ------ */
    eq = (long *)xmalloc((size_t)ndof * sizeof(long));
    pcomp = (int *)xmalloc((size_t)ndof * sizeof(int));
    neq = 0;
    npre = 0;
    for (k = 0; k < nnode; k++) {
        int top = (k / (nx + 1)) == ny;
        for (c = 0; c < 2; c++) {
            if (top) {
                pcomp[npre] = (int)c;
                eq[2 * k + c] = -(1 + npre);
                npre++;
            } else {
                eq[2 * k + c] = neq++;
            }
        }
    }

    /* ---- assembly in triplets: K_ff (to the library), K_fp (load), K_p* (reactions) */
    plane_strain_d(par.e, par.nu, dmat);
    trip_init(&kff, 64 * nelem);
    trip_init(&kfp, 16 * nx);
    trip_init(&kpr, 32 * nx);
    for (e = 0; e < nelem; e++) {
        double xe[4], ye[4], ke[8][8];
        long ed[8];
        for (a = 0; a < 4; a++) {
            long nd = conn[4 * e + a];
            xe[a] = xy[2 * nd];
            ye[a] = xy[2 * nd + 1];
            ed[2 * a] = 2 * nd;
            ed[2 * a + 1] = 2 * nd + 1;
        }
        if (q4_stiffness(xe, ye, dmat, ke) != 0) {
            fprintf(stderr, "block2d: element %ld has a non-positive Jacobian\n", e);
            return 2;
        }
        for (a = 0; a < 8; a++) {
            long ra = eq[ed[a]];
            for (b = 0; b < 8; b++) {
                long cb = eq[ed[b]];
                if (ra >= 0 && cb >= 0) trip_add(&kff, ra, cb, ke[a][b]);
                else if (ra >= 0) trip_add(&kfp, ra, -1 - cb, ke[a][b]);
                else trip_add(&kpr, -1 - ra, ed[b], ke[a][b]);
            }
        }
    }

    /* ---- contacts: one per bottom node -------------------------------------- */
    m = nx + 1;
    trip_init(&nmat, m);
    trip_init(&tmat, m);
    g0 = (double *)xmalloc((size_t)m * sizeof(double));
    mu = (double *)xmalloc((size_t)m * sizeof(double));
    for (i = 0; i <= nx; i++) {
        long nd = i; /* bottom row j = 0 */
        double x = xy[2 * nd], dxc = x - 0.5 * par.w;
        trip_add(&nmat, i, eq[2 * nd + 1], -1.0); /* outward normal (0,-1) */
        trip_add(&tmat, i, eq[2 * nd], 1.0);      /* tangent (1,0)          */
        g0[i] = par.curved * dxc * dxc;
        mu[i] = par.mu;
    }

    km = coo_matrix(&kff, neq, neq);
    nm = coo_matrix(&nmat, m, neq);
    tm = coo_matrix(&tmat, m, neq);
    st = ds_problem_new(2, &km, &nm, &tm, &prob);
    if (st != DS_STATUS_OK) {
        library_error("ds_problem_new", st);
        return 2;
    }

    ds_options_default(&opts);
    opts.method = par.method;
    if (par.tol > 0.0) opts.tol = par.tol;
    if (par.max_outer > 0) opts.max_outer = par.max_outer;
    if (par.max_inner > 0) opts.max_inner = par.max_inner;

    /* ---- load history -------------------------------------------------------- */
    for (k = 0; k < N_PRESS; k++) {
        step_uy[k] = par.uy * (double)(k + 1) / N_PRESS;
        step_ux[k] = 0.0;
        step_phase[k] = "press";
    }
    for (k = 0; k < N_SHEAR; k++) {
        step_uy[N_PRESS + k] = par.uy;
        step_ux[N_PRESS + k] = par.ux * (double)(k + 1) / N_SHEAR;
        step_phase[N_PRESS + k] = "shear";
    }
    for (k = 0; k < N_UNLOAD; k++) {
        /* + 0.0 turns the -0.0 of the last unloading step into +0.0 */
        step_uy[N_PRESS + N_SHEAR + k] = par.uy * (1.0 - (double)(k + 1) / N_UNLOAD) + 0.0;
        step_ux[N_PRESS + N_SHEAR + k] = par.ux;
        step_phase[N_PRESS + N_SHEAR + k] = "unload";
    }
    step_uy[N_STEPS - 1] = -0.2 * par.uy;
    step_ux[N_STEPS - 1] = par.ux;
    step_phase[N_STEPS - 1] = "lift";

    up = (double *)xcalloc((size_t)npre, sizeof(double));
    f = (double *)xcalloc((size_t)neq, sizeof(double));
    u = (double *)xcalloc((size_t)neq, sizeof(double));
    lam_n = (double *)xcalloc((size_t)m, sizeof(double));
    lam_t = (double *)xcalloc((size_t)m, sizeof(double));
    ufull = (double *)xcalloc((size_t)ndof, sizeof(double));
    reac = (double *)xcalloc((size_t)npre, sizeof(double));

    if (!par.quiet) {
        printf("block2d: plane-strain Q4 block %g x %g, %ld x %ld elements, E = %g, nu = %g\n",
               par.w, par.h, nx, ny, par.e, par.nu);
        printf("         %ld free DOFs, %ld prescribed (top edge), %ld contacts, K: %ld triplets\n",
               neq, npre, m, kff.n);
        printf("         Coulomb mu = %g, gap g = %g (x - W/2)^2, method %s, tol %g\n", par.mu,
               par.curved, method_name(par.method), opts.tol);
        printf("%4s %-6s %9s %9s %5s %5s %5s %18s %18s %9s %6s %9s %9s\n", "step", "phase",
               "uy_top", "ux_top", "open", "stick", "slip", "sum_lamN", "sum_lamT", "err", "outer",
               "time[s]", "res_dev");
    }

    for (k = 0; k < N_STEPS; k++) {
        DsReport rep;
        double sum_n = 0.0, sum_t = 0.0, rx = 0.0, ry = 0.0, scale, dev;
        long p;

        /* prescribed displacement of the top edge and the load f = -K_fp u_p */
        for (p = 0; p < npre; p++) up[p] = pcomp[p] == 0 ? step_ux[k] : step_uy[k];
        for (i = 0; i < neq; i++) f[i] = 0.0;
        for (a = 0; a < kfp.n; a++) f[kfp.row[a]] -= kfp.val[a] * up[kfp.col[a]];

        memset(&rep, 0, sizeof rep);
        st = ds_step(prob, &opts, DS_FRICTION_COULOMB, f, g0, mu, u, lam_n, lam_t, &rep);
        if (st == DS_STATUS_NOT_CONVERGED) {
            all_converged = 0;
            fprintf(stderr,
                    "block2d: step %ld (%s, uy_top = %g, ux_top = %g) did not converge: "
                    "err = %.3e after %lld outer iterations: %s\n",
                    k + 1, step_phase[k], step_uy[k], step_ux[k], rep.err,
                    (long long)rep.outer_iterations, ds_last_error_message());
            if (rep.err > max_err) max_err = rep.err;
            exit_code = 1;
            break;
        } else if (st != DS_STATUS_OK) {
            library_error("ds_step", st);
            ds_problem_free(prob);
            return 2;
        }
        if (rep.status != DS_STATUS_OK) {
            fprintf(stderr, "block2d: ds_step returned OK but report.status = %d\n",
                    (int)rep.status);
            all_converged = 0;
            exit_code = 1;
        }
        steps_done++;

        /* resultants: contact forces and the reaction of the top support */
        for (c = 0; c < m; c++) {
            sum_n += lam_n[c];
            sum_t += lam_t[c];
        }
        for (a = 0; a < ndof; a++) ufull[a] = eq[a] >= 0 ? u[eq[a]] : up[-1 - eq[a]];
        for (p = 0; p < npre; p++) reac[p] = 0.0;
        for (a = 0; a < kpr.n; a++) reac[kpr.row[a]] += kpr.val[a] * ufull[kpr.col[a]];
        for (p = 0; p < npre; p++) {
            if (pcomp[p] == 0) rx += reac[p];
            else ry += reac[p];
        }
        /* R_y,top = -sum lambda_N and R_x,top = +sum lambda_T (see the header) */
        scale = fmax(fmax(fabs(rx), fabs(ry)), fmax(fabs(sum_n), fabs(sum_t)));
        if (scale > force_peak) force_peak = scale;
        scale = force_peak;
        dev = scale > 0.0 ? fmax(fabs(ry + sum_n), fabs(rx - sum_t)) / scale : 0.0;
        if (!(dev <= dev_tol)) {
            resultant_ok = 0;
            fprintf(stderr,
                    "block2d: step %ld: resultants do not balance: R_y,top = %.12e, "
                    "-sum lambda_N = %.12e, R_x,top = %.12e, sum lambda_T = %.12e\n",
                    k + 1, ry, -sum_n, rx, sum_t);
        }
        if (!(dev <= max_dev)) max_dev = dev;

        if (!(rep.err <= max_err)) max_err = rep.err;
        total_outer += (long)rep.outer_iterations;
        total_solve_s += rep.solve_seconds;
        if (k == 0) factor_s = rep.factor_seconds;
        if (rep.n_slip > max_slip) max_slip = (long)rep.n_slip;
        if (strcmp(step_phase[k], "shear") == 0) {
            if (rep.n_slip > shear_max_slip) shear_max_slip = (long)rep.n_slip;
            if (rep.n_stick > shear_max_stick) shear_max_stick = (long)rep.n_stick;
        }
        final_open = (long)rep.n_open;
        final_stick = (long)rep.n_stick;
        final_slip = (long)rep.n_slip;

        if (!par.quiet)
            printf("%4ld %-6s %9.5f %9.5f %5lld %5lld %5lld %18.10e %18.10e %9.2e %6lld %9.2e %9.2e\n",
                   k + 1, step_phase[k], step_uy[k], step_ux[k], (long long)rep.n_open,
                   (long long)rep.n_stick, (long long)rep.n_slip, sum_n, sum_t, rep.err,
                   (long long)rep.outer_iterations, rep.solve_seconds, dev);
    }

    if (!par.quiet)
        printf("factorisation of K: %.3e s, total solve time: %.3e s\n", factor_s, total_solve_s);
    if (resultant_ok && steps_done == N_STEPS)
        printf("resultant check: ok (max relative deviation %.2e)\n", max_dev);
    else if (!resultant_ok) {
        printf("resultant check: FAILED (max relative deviation %.2e > %.0e)\n", max_dev, dev_tol);
        exit_code = 1;
    } else
        printf("resultant check: incomplete (%ld of %d steps)\n", steps_done, N_STEPS);

    printf("SUMMARY method=%s steps=%ld contacts=%ld dofs=%ld max_err=%.3e all_converged=%d "
           "resultant_ok=%d max_res_dev=%.3e total_outer=%ld max_slip_count=%ld "
           "shear_max_slip=%ld shear_max_stick=%ld final_open=%ld final_stick=%ld "
           "final_slip=%ld\n",
           method_name(par.method), steps_done, m, neq, max_err, all_converged && steps_done == N_STEPS,
           resultant_ok, max_dev, total_outer, max_slip, shear_max_slip, shear_max_stick,
           final_open, final_stick, final_slip);

    ds_problem_free(prob);
    trip_free(&kff);
    trip_free(&kfp);
    trip_free(&kpr);
    trip_free(&nmat);
    trip_free(&tmat);
    free(xy); free(conn); free(eq); free(pcomp); free(g0); free(mu);
    free(up); free(f); free(u); free(lam_n); free(lam_t); free(ufull); free(reac);
    return exit_code;
}
