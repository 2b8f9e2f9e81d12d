/*
 * hyperelastic_host.c -- a nonlinear host: a neo-Hookean block in plane strain,
 * pressed onto a curved rigid foundation and dragged over it with Coulomb
 * friction, under large deformation. The program runs its own Newton loop in
 * every load increment, refactors its tangent at every iteration and asks
 * dualsplit for the contact solve of each linearised problem
 * (ds_solve_iteration), the way a nonlinear finite element code would.
 *
 *   - Q4 elements, 2x2 Gauss, total Lagrangian; compressible neo-Hookean
 *     W = mu/2 (I1 - 3) - mu ln J + lambda/2 (ln J)^2 with the plane-strain
 *     I1 = C11 + C22 + 1; the second Piola-Kirchhoff stress
 *     S = mu (I - C^-1) + lambda ln J C^-1 and its tangent
 *     lambda C^-1 x C^-1 + (mu - lambda ln J) (C^-1 (x) C^-1 symmetrised);
 *   - a W x H block meshed with nx x ny elements; the top edge is moved by a
 *     prescribed displacement (press, then drag), its DOFs eliminated;
 *   - every bottom node is a contact with the foundation, whose gap below the
 *     node is g0 = c (x - W/2)^2: N row (0,-1) on the node's y DOF (N u <= g0
 *     reads u_y >= -g0), T row (1,0) on its x DOF; Coulomb friction mu_f.
 *
 * The host's loop, per load increment from the converged u_n (see
 * ds_solve_iteration in dualsplit.h):
 *
 *   1. move the top edge to the increment's prescribed displacement;
 *   2. assemble the tangent K_t(u_j) and the internal forces f_int(u_j); the
 *      residual without contact forces is r_j = -f_int(u_j) on the free DOFs
 *      (no external load besides the prescribed edge); the gaps at u_j are
 *      g_j = g0 + u_y,j and the slip already taken s_j = u_x,j - u_x,n at the
 *      bottom nodes;
 *   3. the out-of-balance force with the last contact forces,
 *      R_j = r_j - N^T lambda_N - T^T lambda_T: stop when |R_j| <= tol |f_ref|
 *      (f_ref: the internal forces of the first iteration of the increment)
 *      and the last |du| <= tol |u|;
 *   4. ds_problem_refactor(K_t) (a handle created with the first tangent),
 *      then ds_solve_iteration(r_j, g_j, s_j) -> du and the total contact
 *      forces; u_j+1 = u_j + du.
 *
 * Every iteration prints |R_j| / |f_ref|, |du| / |u| and the contact states;
 * once the states settle the residual falls quadratically. `--out FILE`
 * writes each converged increment (the prescribed edge, u, lambda_N,
 * lambda_T) for tests/hyperelastic_host.rs, which checks them against its
 * own assembly of the same body.
 *
 * Build (see the Makefile):
 *   cc -O2 -std=c99 -Wall -Wextra -Iinclude c_examples/hyperelastic_host.c \
 *      target/release/libdualsplit.a -lm -lpthread -ldl -o hyperelastic_host
 *
 * Exit status: 0 on success, 1 if an increment's Newton loop did not converge,
 * 2 on a library error, 3 on bad command-line options.
 */

#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "dualsplit.h"
/* Triplets (the COO storage), xmalloc / xcalloc and coo_matrix. */
#include "block2d_scene.h"

/* Newton iterations of one increment before the program gives up. */
#define MAX_ITER 30

typedef struct {
    long nx, ny, n_press, n_drag;
    double w, h, young, nu, mu_f, curved, press, drag, tol;
    const char *out;
} Params;

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

static void usage(FILE *out)
{
    fprintf(out,
            "usage: hyperelastic_host [options]\n"
            "  --nx N, --ny N        elements along x and y (default 24 x 12)\n"
            "  --E e, --nu nu        small-strain Young's modulus and Poisson ratio\n"
            "                        of the neo-Hookean material (default 100, 0.3)\n"
            "  --W w, --H h          block width and height (default 2, 1)\n"
            "  --mu mu               Coulomb coefficient (default 0.3)\n"
            "  --curved c            foundation gap g0 = c (x - W/2)^2 (default 0.1)\n"
            "  --press v, --drag v   final press (down) and drag (along x) of the top\n"
            "                        edge (default 0.15, 0.2)\n"
            "  --increments P D      increments of the press and of the drag (default 3 3)\n"
            "  --tol t               Newton's tolerance on |R| / |f_ref| (default 1e-10)\n"
            "  --out FILE            write each converged increment to FILE\n");
}

static int parse_args(int argc, char **argv, Params *p)
{
    int k;
    p->nx = 24; p->ny = 12; p->n_press = 3; p->n_drag = 3;
    p->w = 2.0; p->h = 1.0; p->young = 100.0; p->nu = 0.3;
    p->mu_f = 0.3; p->curved = 0.1; p->press = 0.15; p->drag = 0.2; p->tol = 1e-10;
    p->out = NULL;
    for (k = 1; k < argc; k++) {
        const char *a = argv[k];
        const char *v = (k + 1 < argc) ? argv[k + 1] : NULL;
        int ok = 1;
        if (strcmp(a, "--help") == 0 || strcmp(a, "-h") == 0) {
            usage(stdout);
            exit(0);
        }
        if (v == NULL) {
            fprintf(stderr, "hyperelastic_host: option %s needs a value\n", a);
            return -1;
        }
        if (strcmp(a, "--nx") == 0) ok = parse_long(v, &p->nx) && p->nx >= 1 && p->nx <= 2000;
        else if (strcmp(a, "--ny") == 0) ok = parse_long(v, &p->ny) && p->ny >= 1 && p->ny <= 2000;
        else if (strcmp(a, "--E") == 0) ok = parse_double(v, &p->young) && p->young > 0.0;
        else if (strcmp(a, "--nu") == 0) ok = parse_double(v, &p->nu) && p->nu > -1.0 && p->nu < 0.5;
        else if (strcmp(a, "--W") == 0) ok = parse_double(v, &p->w) && p->w > 0.0;
        else if (strcmp(a, "--H") == 0) ok = parse_double(v, &p->h) && p->h > 0.0;
        else if (strcmp(a, "--mu") == 0) ok = parse_double(v, &p->mu_f) && p->mu_f >= 0.0;
        else if (strcmp(a, "--curved") == 0) ok = parse_double(v, &p->curved) && p->curved >= 0.0;
        else if (strcmp(a, "--press") == 0) ok = parse_double(v, &p->press) && p->press > 0.0;
        else if (strcmp(a, "--drag") == 0) ok = parse_double(v, &p->drag);
        else if (strcmp(a, "--tol") == 0) ok = parse_double(v, &p->tol) && p->tol > 0.0;
        else if (strcmp(a, "--out") == 0) p->out = v;
        else if (strcmp(a, "--increments") == 0) {
            const char *v2 = (k + 2 < argc) ? argv[k + 2] : NULL;
            ok = v2 != NULL && parse_long(v, &p->n_press) && p->n_press >= 1 &&
                 parse_long(v2, &p->n_drag) && p->n_drag >= 0;
            k++;
        } else {
            fprintf(stderr, "hyperelastic_host: unknown option %s\n", a);
            return -1;
        }
        if (!ok) {
            fprintf(stderr, "hyperelastic_host: bad value '%s' for %s\n", v, a);
            return -1;
        }
        k++;
    }
    return 0;
}

/* ------------------------------------------------------------------------- */
/* the neo-Hookean Q4 element                                                  */
/* ------------------------------------------------------------------------- */

/* Internal forces fe (8) and tangent ke (8 x 8, row-major) of the Q4 element
   with reference coordinates (xe, ye) and displacements ue (u1x, u1y, u2x, ...)
   for the Lame constants (lam, mu).  Returns 0, or -1 where the element is
   inverted (J <= 0 at a Gauss point). */
static int neo_hookean_q4(const double xe[4], const double ye[4], const double ue[8], double lam,
                          double mu, double fe[8], double ke[64])
{
    static const double xi_a[4] = {-1.0, 1.0, 1.0, -1.0};
    static const double eta_a[4] = {-1.0, -1.0, 1.0, 1.0};
    const double gp = 1.0 / sqrt(3.0);
    int ig, jg, a, b, i, k, jj, l, ii, kk;

    for (a = 0; a < 8; a++) fe[a] = 0.0;
    for (a = 0; a < 64; a++) ke[a] = 0.0;
    for (ig = 0; ig < 2; ig++)
        for (jg = 0; jg < 2; jg++) {
            double xi = ig ? gp : -gp, eta = jg ? gp : -gp;
            double dxi[4], deta[4], gx[4][2];
            double j00 = 0.0, j01 = 0.0, j10 = 0.0, j11 = 0.0, det0;
            double f[2][2], c[2][2], ci[2][2], s[2][2], p[2][2], dc, jdet, lnj;
            double cm[2][2][2][2], at[2][2][2][2];

            for (a = 0; a < 4; a++) {
                dxi[a] = 0.25 * xi_a[a] * (1.0 + eta * eta_a[a]);
                deta[a] = 0.25 * eta_a[a] * (1.0 + xi * xi_a[a]);
                j00 += dxi[a] * xe[a];
                j01 += dxi[a] * ye[a];
                j10 += deta[a] * xe[a];
                j11 += deta[a] * ye[a];
            }
            det0 = j00 * j11 - j01 * j10;
            for (a = 0; a < 4; a++) {
                gx[a][0] = (j11 * dxi[a] - j01 * deta[a]) / det0;
                gx[a][1] = (-j10 * dxi[a] + j00 * deta[a]) / det0;
            }
            /* F = I + sum_a u_a (x) grad N_a */
            for (i = 0; i < 2; i++)
                for (jj = 0; jj < 2; jj++) {
                    f[i][jj] = i == jj ? 1.0 : 0.0;
                    for (a = 0; a < 4; a++) f[i][jj] += ue[2 * a + i] * gx[a][jj];
                }
            jdet = f[0][0] * f[1][1] - f[0][1] * f[1][0];
            if (!(jdet > 0.0)) return -1;
            lnj = log(jdet);
            for (i = 0; i < 2; i++)
                for (jj = 0; jj < 2; jj++) c[i][jj] = f[0][i] * f[0][jj] + f[1][i] * f[1][jj];
            dc = c[0][0] * c[1][1] - c[0][1] * c[1][0];
            ci[0][0] = c[1][1] / dc;
            ci[1][1] = c[0][0] / dc;
            ci[0][1] = ci[1][0] = -c[0][1] / dc;
            for (i = 0; i < 2; i++)
                for (jj = 0; jj < 2; jj++)
                    s[i][jj] = mu * ((i == jj ? 1.0 : 0.0) - ci[i][jj]) + lam * lnj * ci[i][jj];
            for (i = 0; i < 2; i++)
                for (jj = 0; jj < 2; jj++) p[i][jj] = f[i][0] * s[0][jj] + f[i][1] * s[1][jj];
            for (ii = 0; ii < 2; ii++)
                for (jj = 0; jj < 2; jj++)
                    for (kk = 0; kk < 2; kk++)
                        for (l = 0; l < 2; l++)
                            cm[ii][jj][kk][l] = lam * ci[ii][jj] * ci[kk][l] +
                                                (mu - lam * lnj) * (ci[ii][kk] * ci[jj][l] +
                                                                    ci[ii][l] * ci[jj][kk]);
            /* A_iJkL = F_iI C_IJKL F_kK + delta_ik S_JL */
            for (i = 0; i < 2; i++)
                for (jj = 0; jj < 2; jj++)
                    for (k = 0; k < 2; k++)
                        for (l = 0; l < 2; l++) {
                            double v = i == k ? s[jj][l] : 0.0;
                            for (ii = 0; ii < 2; ii++)
                                for (kk = 0; kk < 2; kk++)
                                    v += f[i][ii] * cm[ii][jj][kk][l] * f[k][kk];
                            at[i][jj][k][l] = v;
                        }
            for (a = 0; a < 4; a++)
                for (i = 0; i < 2; i++) {
                    fe[2 * a + i] += det0 * (p[i][0] * gx[a][0] + p[i][1] * gx[a][1]);
                    for (b = 0; b < 4; b++)
                        for (k = 0; k < 2; k++) {
                            double v = 0.0;
                            for (jj = 0; jj < 2; jj++)
                                for (l = 0; l < 2; l++) v += gx[a][jj] * at[i][jj][k][l] * gx[b][l];
                            ke[8 * (2 * a + i) + 2 * b + k] += det0 * v;
                        }
                }
        }
    return 0;
}

/* ------------------------------------------------------------------------- */
/* the body                                                                    */
/* ------------------------------------------------------------------------- */

typedef struct {
    long nx, ny, nnode, ndof, neq, m;
    double lam, mu;
    double *xy;  /* 2 per node: reference coordinates                  */
    long *eq;    /* ndof: free equation >= 0, or -1 on the top edge     */
    double *g0;  /* m: the gap below bottom node i                      */
    Triplets kt; /* the tangent on the free equations, fixed order      */
} Body;

static void body_build(Body *bd, const Params *p)
{
    long i, j, k, c;
    bd->nx = p->nx;
    bd->ny = p->ny;
    bd->nnode = (p->nx + 1) * (p->ny + 1);
    bd->ndof = 2 * bd->nnode;
    bd->m = p->nx + 1;
    bd->lam = p->young * p->nu / ((1.0 + p->nu) * (1.0 - 2.0 * p->nu));
    bd->mu = p->young / (2.0 * (1.0 + p->nu));
    bd->xy = (double *)xmalloc((size_t)bd->ndof * sizeof(double));
    for (j = 0; j <= p->ny; j++)
        for (i = 0; i <= p->nx; i++) {
            bd->xy[2 * (j * (p->nx + 1) + i)] = p->w * (double)i / (double)p->nx;
            bd->xy[2 * (j * (p->nx + 1) + i) + 1] = p->h * (double)j / (double)p->ny;
        }
    bd->eq = (long *)xmalloc((size_t)bd->ndof * sizeof(long));
    bd->neq = 0;
    for (k = 0; k < bd->nnode; k++)
        for (c = 0; c < 2; c++) bd->eq[2 * k + c] = k / (p->nx + 1) == p->ny ? -1 : bd->neq++;
    bd->g0 = (double *)xmalloc((size_t)bd->m * sizeof(double));
    for (i = 0; i < bd->m; i++) {
        double dx = bd->xy[2 * i] - 0.5 * p->w;
        bd->g0[i] = p->curved * dx * dx;
    }
    trip_init(&bd->kt, 64 * p->nx * p->ny);
}

/* Assembles the tangent on the free equations into bd->kt (always the same
   entries in the same order: the pattern ds_problem_refactor expects) and the
   internal forces fint (ndof) at the displacement u (ndof).  Returns 0, or -1
   where an element is inverted. */
static int body_assemble(Body *bd, const double *u, double *fint)
{
    long el, a, b, nelem = bd->nx * bd->ny;
    for (a = 0; a < bd->ndof; a++) fint[a] = 0.0;
    bd->kt.n = 0;
    for (el = 0; el < nelem; el++) {
        long n0 = (el / bd->nx) * (bd->nx + 1) + el % bd->nx;
        long nodes[4] = {n0, n0 + 1, n0 + 1 + (bd->nx + 1), n0 + (bd->nx + 1)};
        long ed[8];
        double xe[4], ye[4], ue[8], fe[8], ke[64];
        for (a = 0; a < 4; a++) {
            xe[a] = bd->xy[2 * nodes[a]];
            ye[a] = bd->xy[2 * nodes[a] + 1];
            ed[2 * a] = 2 * nodes[a];
            ed[2 * a + 1] = 2 * nodes[a] + 1;
        }
        for (a = 0; a < 8; a++) ue[a] = u[ed[a]];
        if (neo_hookean_q4(xe, ye, ue, bd->lam, bd->mu, fe, ke) != 0) return -1;
        for (a = 0; a < 8; a++) {
            fint[ed[a]] += fe[a];
            for (b = 0; b < 8; b++) {
                long ra = bd->eq[ed[a]], cb = bd->eq[ed[b]];
                if (ra >= 0 && cb >= 0) trip_add(&bd->kt, ra, cb, ke[8 * a + b]);
            }
        }
    }
    return 0;
}

static void body_free(Body *bd)
{
    free(bd->xy);
    free(bd->eq);
    free(bd->g0);
    trip_free(&bd->kt);
}

static double norm2(const double *x, long n)
{
    double s = 0.0;
    long i;
    for (i = 0; i < n; i++) s += x[i] * x[i];
    return sqrt(s);
}

static void library_error(const char *what, DsStatus st)
{
    fprintf(stderr, "hyperelastic_host: %s failed: %s (%d): %s\n", what,
            ds_status_string((int32_t)st), (int)st, ds_last_error_message());
}

/* ------------------------------------------------------------------------- */
/* main: the host's Newton loop                                                */
/* ------------------------------------------------------------------------- */

int main(int argc, char **argv)
{
    Params par;
    Body bd;
    Triplets nmat, tmat;
    DsMatrix km, nm, tm;
    DsProblem *pb = NULL;
    DsOptions opts;
    DsReport rep;
    DsStatus st;
    FILE *out = NULL;
    long i, inc, n_inc, m, neq, ndof;
    double *u, *u_n, *fint, *r, *res, *g, *slip, *du, *du_free, *lam_n, *lam_t, *mu;
    int failed = 0;

    if (parse_args(argc, argv, &par) != 0) {
        usage(stderr);
        return 3;
    }
    body_build(&bd, &par);
    m = bd.m;
    neq = bd.neq;
    ndof = bd.ndof;
    u = (double *)xcalloc((size_t)ndof, sizeof(double));
    u_n = (double *)xcalloc((size_t)ndof, sizeof(double));
    fint = (double *)xcalloc((size_t)ndof, sizeof(double));
    r = (double *)xcalloc((size_t)neq, sizeof(double));
    res = (double *)xcalloc((size_t)neq, sizeof(double));
    du_free = (double *)xcalloc((size_t)neq, sizeof(double));
    du = (double *)xcalloc((size_t)ndof, sizeof(double));
    g = (double *)xcalloc((size_t)m, sizeof(double));
    slip = (double *)xcalloc((size_t)m, sizeof(double));
    lam_n = (double *)xcalloc((size_t)m, sizeof(double));
    lam_t = (double *)xcalloc((size_t)m, sizeof(double));
    mu = (double *)xcalloc((size_t)m, sizeof(double));
    for (i = 0; i < m; i++) mu[i] = par.mu_f;
    /* Contacts: bottom node i (node i, y DOF, then x DOF). */
    trip_init(&nmat, m);
    trip_init(&tmat, m);
    for (i = 0; i < m; i++) {
        trip_add(&nmat, i, bd.eq[2 * i + 1], -1.0);
        trip_add(&tmat, i, bd.eq[2 * i], 1.0);
    }
    nm = coo_matrix(&nmat, m, neq);
    tm = coo_matrix(&tmat, m, neq);
    ds_options_default(&opts);
    opts.threads = 1;
    if (par.out != NULL) {
        out = fopen(par.out, "w");
        if (out == NULL) {
            fprintf(stderr, "hyperelastic_host: cannot write %s\n", par.out);
            return 3;
        }
        fprintf(out, "body %ld %ld %.17g %.17g %.17g %.17g %.17g %.17g\n", par.nx, par.ny, par.w,
                par.h, par.young, par.nu, par.mu_f, par.curved);
    }
    printf("neo-Hookean block %ld x %ld, %ld free DOFs, %ld contacts, Coulomb mu = %g\n", par.nx,
           par.ny, neq, m, par.mu_f);
    n_inc = par.n_press + par.n_drag;
    for (inc = 0; inc < n_inc && !failed; inc++) {
        double top_x, top_y, f_ref = 0.0, du_rel = INFINITY;
        int it, converged = 0;
        long k;
        if (inc < par.n_press) {
            top_x = 0.0;
            top_y = -par.press * (double)(inc + 1) / (double)par.n_press;
        } else {
            top_x = par.drag * (double)(inc + 1 - par.n_press) / (double)par.n_drag;
            top_y = -par.press;
        }
        /* 1. the increment starts at u_n with the top edge moved. */
        memcpy(u_n, u, (size_t)ndof * sizeof(double));
        for (k = 0; k < ndof; k++)
            if (bd.eq[k] < 0) u[k] = k % 2 == 0 ? top_x : top_y;
        printf("increment %ld: top edge at (%.4f, %.4f)\n", inc + 1, top_x, top_y);
        for (it = 0; it < MAX_ITER; it++) {
            double res_rel;
            /* 2. tangent, internal forces, residual, gaps and slip at u_j. */
            if (body_assemble(&bd, u, fint) != 0) {
                fprintf(stderr, "hyperelastic_host: an element inverted\n");
                failed = 1;
                break;
            }
            for (k = 0; k < ndof; k++)
                if (bd.eq[k] >= 0) r[bd.eq[k]] = -fint[k];
            if (it == 0) f_ref = norm2(fint, ndof);
            for (i = 0; i < m; i++) {
                g[i] = bd.g0[i] + u[2 * i + 1];
                slip[i] = u[2 * i] - u_n[2 * i];
            }
            /* 3. the out-of-balance force with the last contact forces. */
            memcpy(res, r, (size_t)neq * sizeof(double));
            for (i = 0; i < m; i++) {
                res[bd.eq[2 * i + 1]] += lam_n[i]; /* -N^T lambda_N: N = -e_y */
                res[bd.eq[2 * i]] -= lam_t[i];     /* -T^T lambda_T: T = +e_x */
            }
            res_rel = norm2(res, neq) / f_ref;
            if (res_rel <= par.tol && du_rel <= par.tol) {
                converged = 1;
                printf("  converged after %d iterations: |R| / |f_ref| = %.3e\n", it, res_rel);
                break;
            }
            /* 4. the tangent on the handle, and the contact solve of the
                  linearised problem. */
            km = coo_matrix(&bd.kt, neq, neq);
            if (pb == NULL) st = ds_problem_new_opts(2, &km, &nm, &tm, &opts, &pb);
            else st = ds_problem_refactor(pb, &km);
            if (st != DS_STATUS_OK) {
                library_error(pb == NULL ? "ds_problem_new_opts" : "ds_problem_refactor", st);
                failed = 2;
                break;
            }
            st = ds_solve_iteration(pb, &opts, DS_FRICTION_COULOMB, r, g, mu, it > 0 ? slip : NULL,
                                    NULL, du_free, lam_n, lam_t, &rep);
            if (st != DS_STATUS_OK) {
                library_error("ds_solve_iteration", st);
                failed = 2;
                break;
            }
            for (k = 0; k < ndof; k++) du[k] = bd.eq[k] >= 0 ? du_free[bd.eq[k]] : 0.0;
            for (k = 0; k < ndof; k++) u[k] += du[k];
            du_rel = norm2(du, ndof) / norm2(u, ndof);
            printf("  iteration %d: |R| / |f_ref| = %.3e, |du| / |u| = %.3e, "
                   "open / stick / slip = %ld / %ld / %ld, contact err %.1e (%ld outer)\n",
                   it, res_rel, du_rel, (long)rep.n_open, (long)rep.n_stick, (long)rep.n_slip,
                   rep.err, (long)rep.outer_iterations);
        }
        if (!converged && !failed) {
            fprintf(stderr, "hyperelastic_host: increment %ld did not converge in %d iterations\n",
                    inc + 1, MAX_ITER);
            failed = 1;
        }
        if (converged && out != NULL) {
            fprintf(out, "increment %ld %.17g %.17g\n", inc + 1, top_x, top_y);
            for (k = 0; k < ndof; k++) fprintf(out, "%.17g\n", u[k]);
            for (i = 0; i < m; i++) fprintf(out, "%.17g %.17g\n", lam_n[i], lam_t[i]);
        }
    }
    if (out != NULL) fclose(out);
    ds_problem_free(pb);
    trip_free(&nmat);
    trip_free(&tmat);
    body_free(&bd);
    free(u); free(u_n); free(fint); free(r); free(res); free(du_free); free(du);
    free(g); free(slip); free(lam_n); free(lam_t); free(mu);
    if (!failed) printf("SUMMARY: %ld increments converged\n", n_inc);
    return failed;
}
