/*
 * block2d_scene.h -- the demo's 2D block: the triplet storage and the Q4 element
 * of c_examples/block2d.c, and the whole scene assembled for the examples that
 * factor K with another solver (mumps_schur.c, mumps_mpi_schur.c): plane-strain
 * Q4 block pressed onto a curved rigid foundation and sheared, top edge
 * prescribed, every bottom node a contact. Every function is static inline (no
 * warning for the ones a program does not use): include it in one translation
 * unit.
 *
 *   - node (i,j) = j (nx+1) + i at (i W/nx, j H/ny); the top row is prescribed;
 *   - eq[dof] >= 0 numbers the free equations, -(1+p) the prescribed DOF p;
 *   - K_ff (free x free) in `kff` (both triangles), K_fp in `kfp` (load: f = -K_fp
 *     u_p);
 *   - contact i on bottom node i: N row (0,-1) on its y DOF, T row (1,0) on its x
 *     DOF, gap g_i = curved (x_i - W/2)^2, Coulomb mu_i = mu;
 *   - the load history of block2d.c: press (5 steps), shear (5), unload (4), lift.
 */
#ifndef BLOCK2D_SCENE_H
#define BLOCK2D_SCENE_H

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

#include "dualsplit.h"

/* ------------------------------------------------------------------------- */
/* triplet (COO) storage, grown as needed                                     */
/* ------------------------------------------------------------------------- */

typedef struct {
    int32_t *row;
    int32_t *col;
    double *val;
    long n;
    long cap;
} Triplets;

static inline void die_oom(void)
{
    fprintf(stderr, "out of memory\n");
    exit(2);
}

static inline void *xmalloc(size_t nbytes)
{
    void *p = malloc(nbytes > 0 ? nbytes : 1);
    if (p == NULL) die_oom();
    return p;
}

static inline void *xcalloc(size_t count, size_t size)
{
    void *p = calloc(count > 0 ? count : 1, size > 0 ? size : 1);
    if (p == NULL) die_oom();
    return p;
}

static inline void trip_init(Triplets *t, long cap)
{
    t->n = 0;
    t->cap = cap > 16 ? cap : 16;
    t->row = (int32_t *)xmalloc((size_t)t->cap * sizeof(int32_t));
    t->col = (int32_t *)xmalloc((size_t)t->cap * sizeof(int32_t));
    t->val = (double *)xmalloc((size_t)t->cap * sizeof(double));
}

static inline void trip_add(Triplets *t, long r, long c, double v)
{
    if (t->n == t->cap) {
        long cap = 2 * t->cap;
        int32_t *row = (int32_t *)realloc(t->row, (size_t)cap * sizeof(int32_t));
        int32_t *col;
        double *val;
        if (row == NULL) die_oom();
        t->row = row;
        col = (int32_t *)realloc(t->col, (size_t)cap * sizeof(int32_t));
        if (col == NULL) die_oom();
        t->col = col;
        val = (double *)realloc(t->val, (size_t)cap * sizeof(double));
        if (val == NULL) die_oom();
        t->val = val;
        t->cap = cap;
    }
    t->row[t->n] = (int32_t)r;
    t->col[t->n] = (int32_t)c;
    t->val[t->n] = v;
    t->n++;
}

static inline void trip_free(Triplets *t)
{
    free(t->row);
    free(t->col);
    free(t->val);
    t->row = t->col = NULL;
    t->val = NULL;
    t->n = t->cap = 0;
}

/* A borrowed 0-based int32 COO matrix for the library (p = columns, i = rows). */
static inline DsMatrix coo_matrix(const Triplets *t, long nrows, long ncols)
{
    DsMatrix a;
    a.format = DS_FORMAT_COO;
    a.index_type = DS_INDEX_TYPE_I32;
    a.base = 0;
    a.storage = DS_STORAGE_FULL;
    a.nrows = nrows;
    a.ncols = ncols;
    a.nnz = t->n;
    a.p = t->col;
    a.i = t->row;
    a.x = t->val;
    return a;
}

/* ------------------------------------------------------------------------- */
/* element                                                                     */
/* ------------------------------------------------------------------------- */

/* Plane-strain elasticity matrix. */
static inline void plane_strain_d(double e, double nu, double d[3][3])
{
    double c = e / ((1.0 + nu) * (1.0 - 2.0 * nu));
    d[0][0] = c * (1.0 - nu); d[0][1] = c * nu;         d[0][2] = 0.0;
    d[1][0] = c * nu;         d[1][1] = c * (1.0 - nu); d[1][2] = 0.0;
    d[2][0] = 0.0;            d[2][1] = 0.0;            d[2][2] = c * (1.0 - 2.0 * nu) / 2.0;
}

/* Q4 stiffness, 2x2 Gauss, unit thickness.  Local nodes counter-clockwise,
   DOFs ordered (u1x, u1y, u2x, u2y, ...).  Returns 0, or -1 on a bad Jacobian. */
static inline int q4_stiffness(const double xe[4], const double ye[4], double d[3][3], double ke[8][8])
{
    static const double xi_a[4] = {-1.0, 1.0, 1.0, -1.0};
    static const double eta_a[4] = {-1.0, -1.0, 1.0, 1.0};
    const double gp = 1.0 / sqrt(3.0);
    int ig, jg, a, b, k, l;

    for (a = 0; a < 8; a++)
        for (b = 0; b < 8; b++) ke[a][b] = 0.0;
    for (ig = 0; ig < 2; ig++) {
        for (jg = 0; jg < 2; jg++) {
            double xi = ig ? gp : -gp, eta = jg ? gp : -gp;
            double dxi[4], deta[4], dx[4], dy[4];
            double j00 = 0.0, j01 = 0.0, j10 = 0.0, j11 = 0.0, det;
            double bm[3][8], db[3][8];

            for (a = 0; a < 4; a++) {
                dxi[a] = 0.25 * xi_a[a] * (1.0 + eta * eta_a[a]);
                deta[a] = 0.25 * eta_a[a] * (1.0 + xi * xi_a[a]);
                j00 += dxi[a] * xe[a];
                j01 += dxi[a] * ye[a];
                j10 += deta[a] * xe[a];
                j11 += deta[a] * ye[a];
            }
            det = j00 * j11 - j01 * j10;
            if (!(det > 0.0)) return -1;
            for (a = 0; a < 4; a++) {
                dx[a] = (j11 * dxi[a] - j01 * deta[a]) / det;
                dy[a] = (-j10 * dxi[a] + j00 * deta[a]) / det;
            }
            for (a = 0; a < 4; a++) {
                bm[0][2 * a] = dx[a]; bm[0][2 * a + 1] = 0.0;
                bm[1][2 * a] = 0.0;   bm[1][2 * a + 1] = dy[a];
                bm[2][2 * a] = dy[a]; bm[2][2 * a + 1] = dx[a];
            }
            for (k = 0; k < 3; k++)
                for (b = 0; b < 8; b++) {
                    double s = 0.0;
                    for (l = 0; l < 3; l++) s += d[k][l] * bm[l][b];
                    db[k][b] = s;
                }
            for (a = 0; a < 8; a++)
                for (b = 0; b < 8; b++) {
                    double s = 0.0;
                    for (k = 0; k < 3; k++) s += bm[k][a] * db[k][b];
                    ke[a][b] += s * det;
                }
        }
    }
    return 0;
}

/* ------------------------------------------------------------------------- */
/* the scene                                                                   */
/* ------------------------------------------------------------------------- */

#define N_PRESS 5
#define N_SHEAR 5
#define N_UNLOAD 4
#define N_STEPS (N_PRESS + N_SHEAR + N_UNLOAD + 1)

typedef struct {
    long nx, ny, ndof, neq, npre, m;
    double w;
    long *eq;        /* ndof: free equation >= 0, or -(1+p) for prescribed p */
    int *pcomp;      /* npre: 0 = x, 1 = y component of prescribed DOF p     */
    long *elem_dofs; /* 8 per element: the element's mesh DOFs               */
    double *ke;      /* 64 per element: its stiffness, row-major             */
    Triplets kff;    /* K_ff, both triangles, 0-based equations              */
    Triplets kfp;    /* K_fp: (equation, prescribed p)                       */
    Triplets nmat;   /* N: m x neq                                           */
    Triplets tmat;   /* T: m x neq                                           */
    double *g0, *mu; /* m                                                    */
    double step_ux[N_STEPS], step_uy[N_STEPS];
} Scene;

/* Builds the block: nx x ny elements on W x H, E, nu; gap curvature `curved`,
   Coulomb coefficient mu; final press uy and shear ux of the top edge.  Returns
   0, or -1 on a bad element. */
static inline int scene_build(Scene *s, long nx, long ny, double e, double nu, double w, double h,
                       double curved, double mu, double uy, double ux)
{
    long nnode = (nx + 1) * (ny + 1), nelem = nx * ny, i, j, k, el, a, b, c;
    double dmat[3][3], *xy;

    s->nx = nx;
    s->ny = ny;
    s->w = w;
    s->ndof = 2 * nnode;
    xy = (double *)xmalloc((size_t)s->ndof * sizeof(double));
    for (j = 0; j <= ny; j++)
        for (i = 0; i <= nx; i++) {
            xy[2 * (j * (nx + 1) + i)] = w * (double)i / (double)nx;
            xy[2 * (j * (nx + 1) + i) + 1] = h * (double)j / (double)ny;
        }
    s->eq = (long *)xmalloc((size_t)s->ndof * sizeof(long));
    s->pcomp = (int *)xmalloc((size_t)s->ndof * sizeof(int));
    s->neq = s->npre = 0;
    for (k = 0; k < nnode; k++)
        for (c = 0; c < 2; c++) {
            if (k / (nx + 1) == ny) {
                s->pcomp[s->npre] = (int)c;
                s->eq[2 * k + c] = -(1 + s->npre++);
            } else {
                s->eq[2 * k + c] = s->neq++;
            }
        }
    plane_strain_d(e, nu, dmat);
    s->elem_dofs = (long *)xmalloc((size_t)(8 * nelem) * sizeof(long));
    s->ke = (double *)xmalloc((size_t)(64 * nelem) * sizeof(double));
    trip_init(&s->kff, 64 * nelem);
    trip_init(&s->kfp, 16 * nx);
    for (el = 0; el < nelem; el++) {
        long n0 = (el / nx) * (nx + 1) + el % nx;
        long nodes[4] = {n0, n0 + 1, n0 + 1 + (nx + 1), n0 + (nx + 1)};
        double xe[4], ye[4], ke[8][8];
        long *ed = s->elem_dofs + 8 * el;
        for (a = 0; a < 4; a++) {
            xe[a] = xy[2 * nodes[a]];
            ye[a] = xy[2 * nodes[a] + 1];
            ed[2 * a] = 2 * nodes[a];
            ed[2 * a + 1] = 2 * nodes[a] + 1;
        }
        if (q4_stiffness(xe, ye, dmat, ke) != 0) {
            free(xy);
            return -1;
        }
        for (a = 0; a < 8; a++)
            for (b = 0; b < 8; b++) {
                long ra = s->eq[ed[a]], cb = s->eq[ed[b]];
                s->ke[64 * el + 8 * a + b] = ke[a][b];
                if (ra >= 0 && cb >= 0) trip_add(&s->kff, ra, cb, ke[a][b]);
                else if (ra >= 0) trip_add(&s->kfp, ra, -1 - cb, ke[a][b]);
            }
    }
    s->m = nx + 1;
    trip_init(&s->nmat, s->m);
    trip_init(&s->tmat, s->m);
    s->g0 = (double *)xmalloc((size_t)s->m * sizeof(double));
    s->mu = (double *)xmalloc((size_t)s->m * sizeof(double));
    for (i = 0; i <= nx; i++) {
        double dxc = xy[2 * i] - 0.5 * w;
        trip_add(&s->nmat, i, s->eq[2 * i + 1], -1.0);
        trip_add(&s->tmat, i, s->eq[2 * i], 1.0);
        s->g0[i] = curved * dxc * dxc;
        s->mu[i] = mu;
    }
    free(xy);
    for (k = 0; k < N_STEPS; k++) {
        if (k < N_PRESS) {
            s->step_uy[k] = uy * (double)(k + 1) / N_PRESS;
            s->step_ux[k] = 0.0;
        } else if (k < N_PRESS + N_SHEAR) {
            s->step_uy[k] = uy;
            s->step_ux[k] = ux * (double)(k - N_PRESS + 1) / N_SHEAR;
        } else if (k < N_STEPS - 1) {
            s->step_uy[k] = uy * (1.0 - (double)(k - N_PRESS - N_SHEAR + 1) / N_UNLOAD) + 0.0;
            s->step_ux[k] = ux;
        } else {
            s->step_uy[k] = -0.2 * uy;
            s->step_ux[k] = ux;
        }
    }
    return 0;
}

/* The load of step k: f = -K_fp u_p (f has neq entries). */
static inline void scene_load(const Scene *s, long k, double *f)
{
    long i, a;
    for (i = 0; i < s->neq; i++) f[i] = 0.0;
    for (a = 0; a < s->kfp.n; a++) {
        long p = s->kfp.col[a];
        double up = s->pcomp[p] == 0 ? s->step_ux[k] : s->step_uy[k];
        f[s->kfp.row[a]] -= s->kfp.val[a] * up;
    }
}

static inline void scene_free(Scene *s)
{
    trip_free(&s->kff);
    trip_free(&s->kfp);
    trip_free(&s->nmat);
    trip_free(&s->tmat);
    free(s->eq);
    free(s->pcomp);
    free(s->elem_dofs);
    free(s->ke);
    free(s->g0);
    free(s->mu);
}

#endif
