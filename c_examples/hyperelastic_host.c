/*
 * hyperelastic_host.c -- a nonlinear host: a neo-Hookean block in plane strain
 * (or in 3D, --dim 3), pressed onto a rigid foundation and dragged over it
 * with Coulomb friction, under large deformation. The program runs its own Newton loop in
 * every load increment, refactors its tangent at every iteration and asks
 * dualsplit for the contact solve of each linearised problem
 * (ds_solve_iteration), the way a nonlinear finite element code would.
 *
 *   - Q4 (2D) or H8 (3D) elements on a structured grid, 2^d Gauss points,
 *     total Lagrangian; compressible neo-Hookean
 *     W = mu/2 (I1 - 3) - mu ln J + lambda/2 (ln J)^2 (in plane strain
 *     I1 = C11 + C22 + 1); the second Piola-Kirchhoff stress
 *     S = mu (I - C^-1) + lambda ln J C^-1 and its tangent
 *     lambda C^-1 x C^-1 + (mu - lambda ln J) (C^-1 (x) C^-1 symmetrised);
 *   - a W x H (x D) block meshed with nx x ny (x nz) elements, the vertical
 *     axis the last; the top face is moved by a prescribed displacement
 *     (press, then drag along x, or in 3D theta degrees off x), its DOFs
 *     eliminated;
 *   - every bottom node is a contact with the foundation, whose initial gap
 *     below the node is g0 = c |x_h - centre|^2 (x_h its horizontal reference
 *     coordinates), measured along the vertical from the node's reference
 *     position: N row -e_vert on the node's vertical DOF (N u <= g0 reads
 *     u_vert >= -g0), T rows e_x (and e_y) on its horizontal DOFs; Coulomb
 *     friction mu_f. The gap profile is the node's own (it does not follow
 *     the node as it slides): the contact is linear in u, and the nonlinearity
 *     the host's Newton loop meets is the material's and the contact states'.
 *
 * The host's loop, per load increment from the converged u_n (see
 * ds_solve_iteration in dualsplit.h):
 *
 *   1. move the top edge to the increment's prescribed displacement;
 *   2. assemble the tangent K_t(u_j) and the internal forces f_int(u_j); the
 *      residual without contact forces is r_j = -f_int(u_j) on the free DOFs
 *      (no external load besides the prescribed face); the gaps at u_j are
 *      g_j = g0 + u_vert,j and the slip already taken s_j = u_h,j - u_h,n at
 *      the bottom nodes;
 *   3. the out-of-balance force with the last contact forces,
 *      R_j = r_j - N^T lambda_N - T^T lambda_T: stop when |R_j| <= tol |f_ref|
 *      (f_ref: the internal forces of the first iteration of the increment)
 *      and the last |du| <= tol |u|;
 *   4. ds_problem_refactor(K_t) (a handle created with the first tangent),
 *      then ds_solve_iteration(r_j, g_j, s_j) -> du and the total contact
 *      forces; u_j+1 = u_j + du. The contact solve is asked for
 *      tol_j = max(tol, 0.1 (|R_j| / |f_ref|)^2), at most 1e-2: an inexact
 *      Newton step, as accurate as the linearisation needs, so the loop
 *      still converges quadratically and its last iterations solve to tol
 *      (--exact-contact: every solve to tol).
 *
 * Every iteration prints |R_j| / |f_ref|, |du| / |u| and the contact states;
 * once the states settle the residual falls quadratically. `--out FILE`
 * writes each converged increment (the prescribed face, u, lambda_N,
 * lambda_T) for tests/hyperelastic_host.rs, which checks them against its
 * own assembly of the same body. `--times` adds the seconds of each
 * iteration's refactor and contact solve, and `--dump DIR` writes the last
 * tangent (with the last r and gaps) as a problem folder: `cargo run
 * --release --example host_newton -- --baseline-of DIR` times the best plain
 * factorisation of that tangent, the unit of BENCHMARKS.md.
 *
 * Build (see the Makefile):
 *   cc -O2 -std=c99 -Wall -Wextra -Iinclude c_examples/hyperelastic_host.c \
 *      target/release/libdualsplit.a -lm -lpthread -ldl -o hyperelastic_host
 *
 * Exit status: 0 on success, 1 if an increment's Newton loop did not converge,
 * 2 on a library error, 3 on bad command-line options.
 */

/* clock_gettime under -std=c99 */
#define _POSIX_C_SOURCE 199309L

#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "dualsplit.h"
/* Triplets (the COO storage), xmalloc / xcalloc and coo_matrix. */
#include "block2d_scene.h"

/* pi (M_PI is not C99). */
#define PI 3.14159265358979323846

/* The contact solve's tolerance at host iteration j: FORCING |R_j|^2 / |f_ref|^2,
   at most FORCING_MAX and at least --tol (step 4). */
#define FORCING 0.1
#define FORCING_MAX 1e-2

/* Newton iterations of one increment before the program gives up. */
#define MAX_ITER 30

typedef struct {
    int dim, times, form, exact;
    long nx, ny, nz, n_press, n_drag;
    double w, h, dz, young, nu, mu_f, curved, press, drag, theta, tol;
    const char *out, *dump;
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
            "  --dim 2|3             plane strain (default) or 3D\n"
            "  --nx N, --ny N        elements along the block (default 24 x 12 in 2D,\n"
            "  --nz N                8 x 8 x 4 in 3D; the vertical axis is the last)\n"
            "  --E e, --nu nu        small-strain Young's modulus and Poisson ratio\n"
            "                        of the neo-Hookean material (default 100, 0.3)\n"
            "  --W w, --H h, --D d   block width, height and depth (3D) (default 2, 1\n"
            "                        and 1)\n"
            "  --mu mu               Coulomb coefficient (default 0.3)\n"
            "  --curved c            foundation gap g0 = c |x_h - centre|^2 (default 0.1)\n"
            "  --press v, --drag v   final press (down) and drag of the top face\n"
            "                        (default 0.15, 0.2)\n"
            "  --theta deg           3D: the drag's direction off the x axis (default 17)\n"
            "  --increments P D      increments of the press and of the drag (default 3 3)\n"
            "  --tol t               Newton's tolerance on |R| / |f_ref| (default 1e-10)\n"
            "  --exact-contact       every contact solve to tol (default: to\n"
            "                        max(tol, 0.1 (|R_j| / |f_ref|)^2), at most 1e-2)\n"
            "  --times               print the seconds of each refactor and solve\n"
            "  --form F              the dual's form: auto (default), dense or\n"
            "                        matrix-free (DsOptions.dual_form)\n"
            "  --out FILE            write each converged increment to FILE\n"
            "  --dump DIR            write the last tangent with the last residual and\n"
            "                        gaps to DIR (ds_problem_dump; not the slip taken)\n");
}

static int parse_args(int argc, char **argv, Params *p)
{
    int k, sized = 0;
    p->dim = 2; p->times = 0; p->exact = 0; p->form = DS_DUAL_FORM_AUTO;
    p->nx = 24; p->ny = 12; p->nz = 0; p->n_press = 3; p->n_drag = 3;
    p->w = 2.0; p->h = 1.0; p->dz = 1.0; p->young = 100.0; p->nu = 0.3;
    p->mu_f = 0.3; p->curved = 0.1; p->press = 0.15; p->drag = 0.2; p->theta = 17.0;
    p->tol = 1e-10;
    p->out = NULL;
    p->dump = NULL;
    for (k = 1; k < argc; k++) {
        const char *a = argv[k];
        const char *v = (k + 1 < argc) ? argv[k + 1] : NULL;
        long dim;
        int ok = 1;
        if (strcmp(a, "--help") == 0 || strcmp(a, "-h") == 0) {
            usage(stdout);
            exit(0);
        }
        if (strcmp(a, "--times") == 0) {
            p->times = 1;
            continue;
        }
        if (strcmp(a, "--exact-contact") == 0) {
            p->exact = 1;
            continue;
        }
        if (v == NULL) {
            fprintf(stderr, "hyperelastic_host: option %s needs a value\n", a);
            return -1;
        }
        if (strcmp(a, "--dim") == 0) {
            ok = parse_long(v, &dim) && (dim == 2 || dim == 3);
            p->dim = (int)dim;
        } else if (strcmp(a, "--nx") == 0) ok = sized = parse_long(v, &p->nx) && p->nx >= 1 && p->nx <= 2000;
        else if (strcmp(a, "--ny") == 0) ok = sized = parse_long(v, &p->ny) && p->ny >= 1 && p->ny <= 2000;
        else if (strcmp(a, "--nz") == 0) ok = parse_long(v, &p->nz) && p->nz >= 1 && p->nz <= 2000;
        else if (strcmp(a, "--E") == 0) ok = parse_double(v, &p->young) && p->young > 0.0;
        else if (strcmp(a, "--nu") == 0) ok = parse_double(v, &p->nu) && p->nu > -1.0 && p->nu < 0.5;
        else if (strcmp(a, "--W") == 0) ok = parse_double(v, &p->w) && p->w > 0.0;
        else if (strcmp(a, "--H") == 0) ok = parse_double(v, &p->h) && p->h > 0.0;
        else if (strcmp(a, "--D") == 0) ok = parse_double(v, &p->dz) && p->dz > 0.0;
        else if (strcmp(a, "--mu") == 0) ok = parse_double(v, &p->mu_f) && p->mu_f >= 0.0;
        else if (strcmp(a, "--curved") == 0) ok = parse_double(v, &p->curved) && p->curved >= 0.0;
        else if (strcmp(a, "--press") == 0) ok = parse_double(v, &p->press) && p->press > 0.0;
        else if (strcmp(a, "--drag") == 0) ok = parse_double(v, &p->drag);
        else if (strcmp(a, "--theta") == 0) ok = parse_double(v, &p->theta);
        else if (strcmp(a, "--tol") == 0) ok = parse_double(v, &p->tol) && p->tol > 0.0;
        else if (strcmp(a, "--form") == 0) {
            if (strcmp(v, "auto") == 0) p->form = DS_DUAL_FORM_AUTO;
            else if (strcmp(v, "dense") == 0) p->form = DS_DUAL_FORM_DENSE;
            else if (strcmp(v, "matrix-free") == 0) p->form = DS_DUAL_FORM_MATRIX_FREE;
            else ok = 0;
        } else if (strcmp(a, "--out") == 0) p->out = v;
        else if (strcmp(a, "--dump") == 0) p->dump = v;
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
    if (p->dim == 3 && !sized) {
        p->nx = 8;
        p->ny = 8;
    }
    if (p->dim == 3 && p->nz == 0) p->nz = 4;
    if (p->dim == 2) p->nz = 0;
    /* the equation numbers are passed as int32 */
    if ((double)(p->nx + 1) * (double)(p->ny + 1) * (double)(p->nz + 1) * 3.0 > 2.0e9) {
        fprintf(stderr, "hyperelastic_host: mesh too large for 32-bit indices\n");
        return -1;
    }
    return 0;
}

/* ------------------------------------------------------------------------- */
/* the neo-Hookean element (Q4 or H8 on a box of sides h[0..dim))              */
/* ------------------------------------------------------------------------- */

/* The inverse of the d x d symmetric matrix c (d = 2 or 3) into ci; returns
   its determinant. */
static double inverse_sym(int d, double c[3][3], double ci[3][3])
{
    double det;
    if (d == 2) {
        det = c[0][0] * c[1][1] - c[0][1] * c[1][0];
        ci[0][0] = c[1][1] / det;
        ci[1][1] = c[0][0] / det;
        ci[0][1] = ci[1][0] = -c[0][1] / det;
        return det;
    }
    ci[0][0] = c[1][1] * c[2][2] - c[1][2] * c[2][1];
    ci[0][1] = c[0][2] * c[2][1] - c[0][1] * c[2][2];
    ci[0][2] = c[0][1] * c[1][2] - c[0][2] * c[1][1];
    ci[1][1] = c[0][0] * c[2][2] - c[0][2] * c[2][0];
    ci[1][2] = c[0][2] * c[1][0] - c[0][0] * c[1][2];
    ci[2][2] = c[0][0] * c[1][1] - c[0][1] * c[1][0];
    det = c[0][0] * ci[0][0] + c[0][1] * (c[1][2] * c[2][0] - c[1][0] * c[2][2]) +
          c[0][2] * (c[1][0] * c[2][1] - c[1][1] * c[2][0]);
    ci[0][0] /= det; ci[0][1] /= det; ci[0][2] /= det;
    ci[1][1] /= det; ci[1][2] /= det; ci[2][2] /= det;
    ci[1][0] = ci[0][1]; ci[2][0] = ci[0][2]; ci[2][1] = ci[1][2];
    return det;
}

/* Internal forces fe (nen d) and tangent ke ((nen d)^2, row-major) of the
   element with sides hx[0..d) and node displacements ue (node by node,
   component by component; nen = 2^d nodes, counter-clockwise in each layer,
   the bottom layer first), for the Lame constants (lam, mu).  Returns 0, or
   -1 where the element is inverted (J <= 0 at a Gauss point). */
static int neo_hookean(int d, const double hx[3], const double *ue, double lam, double mu,
                       double *fe, double *ke)
{
    static const double corner[8][3] = {{-1, -1, -1}, {1, -1, -1}, {1, 1, -1}, {-1, 1, -1},
                                        {-1, -1, 1},  {1, -1, 1},  {1, 1, 1},  {-1, 1, 1}};
    const double gp = 1.0 / sqrt(3.0);
    int nen = d == 2 ? 4 : 8, ndof = nen * d, ng = nen, q, a, b, i, k, jj, l, ii, kk;
    double vol = d == 2 ? 0.25 * hx[0] * hx[1] : 0.125 * hx[0] * hx[1] * hx[2];

    for (a = 0; a < ndof; a++) fe[a] = 0.0;
    for (a = 0; a < ndof * ndof; a++) ke[a] = 0.0;
    for (q = 0; q < ng; q++) {
        double xi[3], gx[8][3], f[3][3], c[3][3], ci[3][3], s[3][3], p[3][3];
        double cm[3][3][3][3], at[3][3][3][3], jdet, lnj;
        /* the Gauss point of Q4 / H8 in the order of the corners */
        for (i = 0; i < d; i++) xi[i] = gp * corner[q][i];
        /* grad N_a: N_a = prod_k (1 + xi_k c_ak) / 2, d xi_i / d X_i = 2 / h_i */
        for (a = 0; a < nen; a++)
            for (i = 0; i < d; i++) {
                double v = corner[a][i] / hx[i];
                for (k = 0; k < d; k++)
                    if (k != i) v *= 0.5 * (1.0 + xi[k] * corner[a][k]);
                gx[a][i] = v;
            }
        /* F = I + sum_a u_a (x) grad N_a */
        for (i = 0; i < d; i++)
            for (jj = 0; jj < d; jj++) {
                f[i][jj] = i == jj ? 1.0 : 0.0;
                for (a = 0; a < nen; a++) f[i][jj] += ue[d * a + i] * gx[a][jj];
            }
        if (d == 2) jdet = f[0][0] * f[1][1] - f[0][1] * f[1][0];
        else
            jdet = f[0][0] * (f[1][1] * f[2][2] - f[1][2] * f[2][1]) -
                   f[0][1] * (f[1][0] * f[2][2] - f[1][2] * f[2][0]) +
                   f[0][2] * (f[1][0] * f[2][1] - f[1][1] * f[2][0]);
        if (!(jdet > 0.0)) return -1;
        lnj = log(jdet);
        for (i = 0; i < d; i++)
            for (jj = 0; jj < d; jj++) {
                c[i][jj] = 0.0;
                for (k = 0; k < d; k++) c[i][jj] += f[k][i] * f[k][jj];
            }
        inverse_sym(d, c, ci);
        for (i = 0; i < d; i++)
            for (jj = 0; jj < d; jj++)
                s[i][jj] = mu * ((i == jj ? 1.0 : 0.0) - ci[i][jj]) + lam * lnj * ci[i][jj];
        for (i = 0; i < d; i++)
            for (jj = 0; jj < d; jj++) {
                p[i][jj] = 0.0;
                for (k = 0; k < d; k++) p[i][jj] += f[i][k] * s[k][jj];
            }
        for (ii = 0; ii < d; ii++)
            for (jj = 0; jj < d; jj++)
                for (kk = 0; kk < d; kk++)
                    for (l = 0; l < d; l++)
                        cm[ii][jj][kk][l] = lam * ci[ii][jj] * ci[kk][l] +
                                            (mu - lam * lnj) *
                                                (ci[ii][kk] * ci[jj][l] + ci[ii][l] * ci[jj][kk]);
        /* A_iJkL = F_iI C_IJKL F_kK + delta_ik S_JL */
        for (i = 0; i < d; i++)
            for (jj = 0; jj < d; jj++)
                for (k = 0; k < d; k++)
                    for (l = 0; l < d; l++) {
                        double v = i == k ? s[jj][l] : 0.0;
                        for (ii = 0; ii < d; ii++)
                            for (kk = 0; kk < d; kk++) v += f[i][ii] * cm[ii][jj][kk][l] * f[k][kk];
                        at[i][jj][k][l] = v;
                    }
        for (a = 0; a < nen; a++)
            for (i = 0; i < d; i++) {
                double v = 0.0;
                for (jj = 0; jj < d; jj++) v += p[i][jj] * gx[a][jj];
                fe[d * a + i] += vol * v;
                for (b = 0; b < nen; b++)
                    for (k = 0; k < d; k++) {
                        double w = 0.0;
                        for (jj = 0; jj < d; jj++)
                            for (l = 0; l < d; l++) w += gx[a][jj] * at[i][jj][k][l] * gx[b][l];
                        ke[ndof * (d * a + i) + d * b + k] += vol * w;
                    }
            }
    }
    return 0;
}

/* ------------------------------------------------------------------------- */
/* the body                                                                    */
/* ------------------------------------------------------------------------- */

typedef struct {
    int d;
    long nx, ny, nz, nnode, ndof, neq, m, nelem;
    double lam, mu;
    double hx[3];  /* the element's sides                                  */
    long nn[3];    /* nodes along each axis (the vertical one the last)     */
    long *eq;      /* ndof: free equation >= 0, or -1 on the top face       */
    double *g0;    /* m: the gap below bottom node i                        */
    Triplets kt;   /* the tangent on the free equations, fixed order        */
} Body;

/* Node (i, j[, k]) of the grid; the vertical index is the last. */
static long node_of(const Body *bd, long i, long j, long k)
{
    return (k * bd->nn[1] + j) * bd->nn[0] + i;
}

static void body_build(Body *bd, const Params *p)
{
    long i, j, c, q, nvert;
    int d = p->dim;
    bd->d = d;
    bd->nx = p->nx;
    bd->ny = p->ny;
    bd->nz = d == 3 ? p->nz : 0;
    bd->nn[0] = p->nx + 1;
    bd->nn[1] = p->ny + 1;
    bd->nn[2] = d == 3 ? p->nz + 1 : 1;
    bd->nnode = bd->nn[0] * bd->nn[1] * bd->nn[2];
    bd->ndof = d * bd->nnode;
    bd->nelem = d == 3 ? p->nx * p->ny * p->nz : p->nx * p->ny;
    /* the bottom nodes: a row in 2D, a layer in 3D */
    bd->m = d == 3 ? bd->nn[0] * bd->nn[1] : bd->nn[0];
    bd->lam = p->young * p->nu / ((1.0 + p->nu) * (1.0 - 2.0 * p->nu));
    bd->mu = p->young / (2.0 * (1.0 + p->nu));
    bd->hx[0] = p->w / (double)p->nx;
    if (d == 2) {
        bd->hx[1] = p->h / (double)p->ny;
        bd->hx[2] = 0.0;
    } else {
        bd->hx[1] = p->dz / (double)p->ny;
        bd->hx[2] = p->h / (double)p->nz;
    }
    /* nodes along the vertical axis; the last layer (the top) is prescribed */
    nvert = bd->nn[d - 1];
    bd->eq = (long *)xmalloc((size_t)bd->ndof * sizeof(long));
    bd->neq = 0;
    for (q = 0; q < bd->nnode; q++) {
        long layer = d == 3 ? q / (bd->nn[0] * bd->nn[1]) : q / bd->nn[0];
        for (c = 0; c < d; c++) bd->eq[d * q + c] = layer == nvert - 1 ? -1 : bd->neq++;
    }
    bd->g0 = (double *)xmalloc((size_t)bd->m * sizeof(double));
    for (i = 0; i < bd->m; i++) {
        double x = (double)(i % bd->nn[0]) * bd->hx[0] - 0.5 * p->w;
        double y = d == 3 ? (double)(i / bd->nn[0]) * bd->hx[1] - 0.5 * p->dz : 0.0;
        bd->g0[i] = p->curved * (x * x + y * y);
    }
    j = d == 3 ? 576 : 64;
    trip_init(&bd->kt, j * bd->nelem);
}

/* Assembles the tangent on the free equations into bd->kt (always the same
   entries in the same order: the pattern ds_problem_refactor expects) and the
   internal forces fint (ndof) at the displacement u (ndof).  Returns 0, or -1
   where an element is inverted. */
static int body_assemble(Body *bd, const double *u, double *fint)
{
    int d = bd->d, nen = d == 2 ? 4 : 8, nd = nen * d;
    long el, a, b;
    for (a = 0; a < bd->ndof; a++) fint[a] = 0.0;
    bd->kt.n = 0;
    for (el = 0; el < bd->nelem; el++) {
        long ex = el % bd->nx, ey = (el / bd->nx) % bd->ny, ez = d == 3 ? el / (bd->nx * bd->ny) : 0;
        long nodes[8], ed[24];
        double ue[24], fe[24], ke[576];
        /* counter-clockwise in each layer, the bottom layer first */
        static const int off[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                                      {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
        for (a = 0; a < nen; a++) {
            int c;
            nodes[a] = node_of(bd, ex + off[a][0], ey + off[a][1], ez + off[a][2]);
            for (c = 0; c < d; c++) ed[d * a + c] = d * nodes[a] + c;
        }
        for (a = 0; a < nd; a++) ue[a] = u[ed[a]];
        if (neo_hookean(d, bd->hx, ue, bd->lam, bd->mu, fe, ke) != 0) return -1;
        for (a = 0; a < nd; a++) {
            fint[ed[a]] += fe[a];
            for (b = 0; b < nd; b++) {
                long ra = bd->eq[ed[a]], cb = bd->eq[ed[b]];
                if (ra >= 0 && cb >= 0) trip_add(&bd->kt, ra, cb, ke[nd * a + b]);
            }
        }
    }
    return 0;
}

static void body_free(Body *bd)
{
    free(bd->eq);
    free(bd->g0);
    trip_free(&bd->kt);
}

static double seconds(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
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
    long i, inc, n_inc, m, mt, neq, ndof;
    int d, dt, c;
    double *u, *u_n, *fint, *r, *res, *g, *slip, *du, *du_free, *lam_n, *lam_t, *mu;
    int failed = 0;

    if (parse_args(argc, argv, &par) != 0) {
        usage(stderr);
        return 3;
    }
    body_build(&bd, &par);
    d = bd.d;
    dt = d - 1;
    m = bd.m;
    mt = dt * m;
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
    slip = (double *)xcalloc((size_t)mt, sizeof(double));
    lam_n = (double *)xcalloc((size_t)m, sizeof(double));
    lam_t = (double *)xcalloc((size_t)mt, sizeof(double));
    mu = (double *)xcalloc((size_t)m, sizeof(double));
    for (i = 0; i < m; i++) mu[i] = par.mu_f;
    /* Contacts: bottom node i is node i; N on its vertical DOF, T rows dt i + c
       on its horizontal DOFs. */
    trip_init(&nmat, m);
    trip_init(&tmat, mt);
    for (i = 0; i < m; i++) {
        trip_add(&nmat, i, bd.eq[d * i + dt], -1.0);
        for (c = 0; c < dt; c++) trip_add(&tmat, dt * i + c, bd.eq[d * i + c], 1.0);
    }
    nm = coo_matrix(&nmat, m, neq);
    tm = coo_matrix(&tmat, mt, neq);
    ds_options_default(&opts);
    opts.threads = 1;
    opts.host_loop = 1; /* refactored at every iteration: AUTO weighs for it */
    opts.dual_form = par.form;
    if (par.out != NULL) {
        out = fopen(par.out, "w");
        if (out == NULL) {
            fprintf(stderr, "hyperelastic_host: cannot write %s\n", par.out);
            failed = 2;
        } else
            fprintf(out, "body %d %ld %ld %ld %.17g %.17g %.17g %.17g %.17g %.17g %.17g\n", d,
                    par.nx, par.ny, par.nz, par.w, par.dz, par.h, par.young, par.nu, par.mu_f,
                    par.curved);
    }
    printf("neo-Hookean block, %dD, %ld elements, %ld free DOFs, %ld contacts (c = %ld), "
           "Coulomb mu = %g\n",
           d, bd.nelem, neq, m, d * m, par.mu_f);
    n_inc = par.n_press + par.n_drag;
    for (inc = 0; inc < n_inc && !failed; inc++) {
        double top[3] = {0.0, 0.0, 0.0}, f_ref = 0.0, du_rel = INFINITY, drag = 0.0;
        int it, converged = 0;
        long k;
        if (inc < par.n_press) {
            top[dt] = -par.press * (double)(inc + 1) / (double)par.n_press;
        } else {
            drag = par.drag * (double)(inc + 1 - par.n_press) / (double)par.n_drag;
            top[dt] = -par.press;
        }
        if (d == 2) top[0] = drag;
        else {
            top[0] = drag * cos(par.theta * PI / 180.0);
            top[1] = drag * sin(par.theta * PI / 180.0);
        }
        /* 1. the increment starts at u_n with the top face moved. */
        memcpy(u_n, u, (size_t)ndof * sizeof(double));
        for (k = 0; k < ndof; k++)
            if (bd.eq[k] < 0) u[k] = top[k % d];
        printf("increment %ld: top face at (%.4f, %.4f, %.4f)\n", inc + 1, top[0], top[1], top[2]);
        for (it = 0; it < MAX_ITER; it++) {
            double res_rel, t0, t_refactor, t_solve;
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
                g[i] = bd.g0[i] + u[d * i + dt];
                for (c = 0; c < dt; c++) slip[dt * i + c] = u[d * i + c] - u_n[d * i + c];
            }
            /* 3. the out-of-balance force with the last contact forces. */
            memcpy(res, r, (size_t)neq * sizeof(double));
            for (i = 0; i < m; i++) {
                res[bd.eq[d * i + dt]] += lam_n[i]; /* -N^T lambda_N: N = -e_vert */
                for (c = 0; c < dt; c++) res[bd.eq[d * i + c]] -= lam_t[dt * i + c];
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
            t0 = seconds();
            if (pb == NULL) st = ds_problem_new_opts(d, &km, &nm, &tm, &opts, &pb);
            else st = ds_problem_refactor(pb, &km);
            if (st != DS_STATUS_OK) {
                library_error(pb == NULL ? "ds_problem_new_opts" : "ds_problem_refactor", st);
                failed = 2;
                break;
            }
            t_refactor = seconds() - t0;
            /* The contact solve need only be as accurate as this iteration's
               linearisation (an inexact Newton step): its tolerance follows
               |R_j|^2, so the host's quadratic convergence is kept, and the
               last iterations solve to tol. */
            opts.tol = par.exact ? par.tol : fmax(par.tol, fmin(FORCING_MAX, FORCING * res_rel * res_rel));
            t0 = seconds();
            st = ds_solve_iteration(pb, &opts, DS_FRICTION_COULOMB, r, g, mu, it > 0 ? slip : NULL,
                                    NULL, du_free, lam_n, lam_t, &rep);
            t_solve = seconds() - t0;
            if (st != DS_STATUS_OK) {
                library_error("ds_solve_iteration", st);
                failed = 2;
                break;
            }
            for (k = 0; k < ndof; k++) du[k] = bd.eq[k] >= 0 ? du_free[bd.eq[k]] : 0.0;
            for (k = 0; k < ndof; k++) u[k] += du[k];
            du_rel = norm2(du, ndof) / norm2(u, ndof);
            printf("  iteration %d: |R| / |f_ref| = %.3e, |du| / |u| = %.3e, "
                   "open / stick / slip = %ld / %ld / %ld, contact err %.1e (%ld outer, %ld inner)",
                   it, res_rel, du_rel, (long)rep.n_open, (long)rep.n_stick, (long)rep.n_slip,
                   rep.err, (long)rep.outer_iterations, (long)rep.inner_iterations);
            if (par.times)
                printf(", %s %.4f s, solve %.4f s", inc == 0 && it == 0 ? "creation" : "refactor",
                       t_refactor, t_solve);
            printf("\n");
        }
        if (!converged && !failed) {
            fprintf(stderr, "hyperelastic_host: increment %ld did not converge in %d iterations\n",
                    inc + 1, MAX_ITER);
            failed = 1;
        }
        if (converged && out != NULL) {
            fprintf(out, "increment %ld %.17g %.17g %.17g\n", inc + 1, top[0], top[1], top[2]);
            for (k = 0; k < ndof; k++) fprintf(out, "%.17g\n", u[k]);
            for (i = 0; i < m; i++) {
                fprintf(out, "%.17g", lam_n[i]);
                for (c = 0; c < dt; c++) fprintf(out, " %.17g", lam_t[dt * i + c]);
                fprintf(out, "\n");
            }
        }
    }
    if (out != NULL) fclose(out);
    /* The last tangent on the handle (assembled at the last iterate but one)
       with the last residual and gaps: for the benchmark's baseline
       factorisation of that tangent. The slip taken is not in the folder, so
       it does not replay the iteration. */
    if (par.dump != NULL && pb != NULL && !failed) {
        st = ds_problem_dump(pb, par.dump, DS_FRICTION_COULOMB, r, g, mu);
        if (st != DS_STATUS_OK) {
            library_error("ds_problem_dump", st);
            failed = 2;
        }
    }
    ds_problem_free(pb);
    trip_free(&nmat);
    trip_free(&tmat);
    body_free(&bd);
    free(u); free(u_n); free(fint); free(r); free(res); free(du_free); free(du);
    free(g); free(slip); free(lam_n); free(lam_t); free(mu);
    if (!failed) printf("SUMMARY: %ld increments converged\n", n_inc);
    return failed;
}
