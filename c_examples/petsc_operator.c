/*
 * petsc_operator.c -- the library on a distributed K: a 3D elastic block
 * assembled into a PETSc MPIAIJ matrix over the MPI ranks, K^-1 applied by a
 * KSP (a direct Cholesky by MUMPS by default, or CG with algebraic multigrid),
 * and every rank running the library's identical contact iteration on those
 * solves (ds_problem_new_host, SPMD): the callback is collective, every rank
 * calls it the same number of times, and every rank gets bitwise the same
 * multipliers and u. That holds where nothing local to a rank decides a
 * branch: threads = 1, max_seconds = 0, the same nonzero max_memory on every
 * rank (0 would let each rank weigh its own machine's memory in the AUTO
 * choices), a callback that fails on every rank or none, and no allocation
 * failing on one rank alone (see DsHostSolveFn in dualsplit.h); this example
 * sets threads = 1 and max_memory explicitly.
 *
 * The block: nx x ny x nz trilinear hexahedra on 1 x 1 x (nz / nx), E = 1,
 * nu = 0.3; the top face is pressed down (3 steps) then sheared along x (3
 * steps); every bottom node is a contact with a paraboloid foundation (gap
 * g = 0.5 ((x - 1/2)^2 + (y - 1/2)^2) times the press), Coulomb mu = 0.3.
 *
 * Checks: the multipliers and u of every rank are bitwise those of rank 0
 * ("identical"); rank 0 also steps the same history on the library's own
 * factor of the whole K and prints the largest deviation (relative to the
 * history's largest u and multiplier), which must stay below --check-tol
 * (default 1e-8; 1e-10 with the direct solve measured 1e-13).
 *
 * Options: --nx N --ny N --nz N (default 24 x 24 x 4), --iterative (CG + GAMG,
 * rtol 1e-13, instead of MUMPS's Cholesky; the host then also offers
 * DsHostSolver.solve_single, answered by the same KSP at rtol 1e-7, which the
 * library takes for its loose products; --no-loose: not offered), --mumps-inverse (the contacts'
 * blocks from MUMPS's selected entries of K^-1, DsHostSolver.inverse_entries,
 * instead of d m solves; direct solve only), --no-k (K not handed over to the
 * library), --no-serial (skip the own-path check: large blocks), --check-tol t,
 * --quiet.
 *
 * Build (Debian: apt-get install petsc-dev openmpi-bin):
 *   mpicc -O2 -std=c99 -Iinclude $(pkg-config --cflags PETSc) c_examples/petsc_operator.c \
 *      target/release/libdualsplit.a $(pkg-config --libs PETSc) -lm -lpthread -ldl \
 *      -o petsc_operator
 *   mpirun -np 2 ./petsc_operator
 *
 * Output (rank 0): a table per step, "CREATE seconds=.. host_solves=..
 * host_seconds=.." (the creation, its contact blocks as DS_HOST_BLOCKS_AUTO,
 * the default, takes them: MUMPS's entries with --mumps-inverse, else the
 * library's own factor of the K handed over where it pays, else d m solves) and
 * "SUMMARY ranks=.. dofs=.. contacts=.. dual=.. steps=.. max_err=.. max_dev=..
 * identical=.. host_solves=.. loose_solves=.. host_seconds=.. library_seconds=..
 * cost_matches=.. check=ok|FAILED" (over the steps: the host's solves, of them
 * the loose ones at rtol 1e-7, the seconds inside them,
 * and the library's own seconds as ds_problem_last_cost reports them;
 * cost_matches=1 when its count of the host's right-hand sides equals the
 * callback's on every step). Exit status: 0, 1 (a
 * step did not converge or a check failed), 2 (a library or PETSc error), 3
 * (bad options).
 */

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <petscksp.h>

#include "dualsplit.h"

#define N_PRESS 3
#define N_SHEAR 3
#define N_HIST (N_PRESS + N_SHEAR)

/* What the callback needs: the KSP, its vectors, the scatter of a solution to
   every rank, and what it did; with --mumps-inverse the MUMPS factor for the
   entries of K^-1 (MatMumpsGetInverseTranspose). */
typedef struct {
    KSP ksp;
    Mat factor;
    long entries;
    Vec b, x, all;
    VecScatter to_all;
    PetscInt lo, hi;
    long solves, loose;
    double seconds;
    double *column; /* one right-hand side in double, for the loose solves */
} Host;

/* The KSP's tolerance for the library's exact and loose (solve_single) solves. */
#define RTOL 1e-13
#define RTOL_LOOSE 1e-7

/* col (n, the same on every rank) := K^-1 col by the KSP; collective. 0, or
   the callback's error code. */
static int32_t ksp_column(Host *h, int64_t n, double *col)
{
    PetscScalar *pb;
    const PetscScalar *pa;
    KSPConvergedReason why;
    PetscInt i;
    if (VecGetArray(h->b, &pb)) return -1;
    for (i = h->lo; i < h->hi; i++) pb[i - h->lo] = col[i];
    if (VecRestoreArray(h->b, &pb)) return -1;
    if (KSPSolve(h->ksp, h->b, h->x)) return -2;
    if (KSPGetConvergedReason(h->ksp, &why)) return -2;
    if (why < 0) return 1000 + (int32_t)(-why); /* the host's code: 1000 + |reason| */
    if (VecScatterBegin(h->to_all, h->x, h->all, INSERT_VALUES, SCATTER_FORWARD)) return -3;
    if (VecScatterEnd(h->to_all, h->x, h->all, INSERT_VALUES, SCATTER_FORWARD)) return -3;
    if (VecGetArrayRead(h->all, &pa)) return -3;
    memcpy(col, pa, (size_t)n * sizeof(double));
    if (VecRestoreArrayRead(h->all, &pa)) return -3;
    return 0;
}

/* DsHostSolveFn: x (n x ncols, leading dimension ld, the same on every rank)
   := K^-1 x, one KSP solve per column; collective. */
static int32_t ksp_solve_cb(void *context, int64_t n, int64_t ncols, double *x, int64_t ld)
{
    Host *h = (Host *)context;
    double t0 = MPI_Wtime();
    int64_t j;
    for (j = 0; j < ncols; j++) {
        int32_t code = ksp_column(h, n, x + j * ld);
        if (code != 0) return code;
    }
    h->solves += (long)ncols;
    h->seconds += MPI_Wtime() - t0;
    return 0;
}

/* DsHostSolveSingleFn (the iterative KSP): x (floats) := K^-1 x to the loose
   tolerance RTOL_LOOSE, which the library's loose products allow; the KSP is
   set back to RTOL after. Collective. */
static int32_t ksp_solve_loose_cb(void *context, int64_t n, int64_t ncols, float *x, int64_t ld)
{
    Host *h = (Host *)context;
    double t0 = MPI_Wtime();
    int32_t code = 0;
    int64_t i, j;
    if (KSPSetTolerances(h->ksp, RTOL_LOOSE, 1e-300, PETSC_DEFAULT, 2000)) return -4;
    for (j = 0; j < ncols && code == 0; j++) {
        float *col = x + j * ld;
        for (i = 0; i < n; i++) h->column[i] = (double)col[i];
        code = ksp_column(h, n, h->column);
        for (i = 0; i < n && code == 0; i++) col[i] = (float)h->column[i];
    }
    if (KSPSetTolerances(h->ksp, RTOL, 1e-300, PETSC_DEFAULT, 2000)) return -4;
    if (code != 0) return code;
    h->solves += (long)ncols;
    h->loose += (long)ncols;
    h->seconds += MPI_Wtime() - t0;
    return 0;
}

/* DsHostInverseFn: values[k] := entry (rows[k], cols[k]) of K^-1 by MUMPS's
   selected inversion (ICNTL(30)); collective. The requested pattern goes in
   as a sparse matrix held by rank 0, which receives the entries in place
   and broadcasts them. */
static int32_t mumps_inverse_cb(void *context, int64_t count, const int64_t *rows,
                                const int64_t *cols, double *values)
{
    Host *h = (Host *)context;
    double t0 = MPI_Wtime();
    PetscMPIInt rank;
    PetscInt nglob, k;
    Mat spt;
    MPI_Comm_rank(PETSC_COMM_WORLD, &rank);
    if (MatGetSize(h->factor, &nglob, NULL)) return -10;
    if (MatCreate(PETSC_COMM_WORLD, &spt)) return -10;
    if (MatSetSizes(spt, rank == 0 ? nglob : 0, rank == 0 ? nglob : 0, nglob, nglob)) return -10;
    if (MatSetType(spt, MATAIJ) || MatSetUp(spt)) return -10;
    MatSetOption(spt, MAT_NEW_NONZERO_ALLOCATION_ERR, PETSC_FALSE);
    if (rank == 0)
        for (k = 0; k < count; k++) {
            PetscInt r = (PetscInt)rows[k], c = (PetscInt)cols[k];
            if (MatSetValue(spt, r, c, 1.0, INSERT_VALUES)) return -11;
        }
    if (MatAssemblyBegin(spt, MAT_FINAL_ASSEMBLY) || MatAssemblyEnd(spt, MAT_FINAL_ASSEMBLY))
        return -11;
    if (MatMumpsGetInverseTranspose(h->factor, spt)) return -12;
    /* Back to plain solves: dense right-hand side, the solution distributed
       over the ranks as PETSc's MatSolve_MUMPS expects it. */
    {
        PetscMPIInt size;
        MPI_Comm_size(PETSC_COMM_WORLD, &size);
        if (MatMumpsSetIcntl(h->factor, 30, 0) || MatMumpsSetIcntl(h->factor, 20, 0) ||
            MatMumpsSetIcntl(h->factor, 21, size > 1 ? 1 : 0))
            return -12;
    }
    if (rank == 0)
        for (k = 0; k < count; k++) {
            PetscInt r = (PetscInt)rows[k], c = (PetscInt)cols[k];
            if (MatGetValues(spt, 1, &r, 1, &c, &values[k])) return -13;
        }
    (void)MPI_Bcast(values, (int)count, MPI_DOUBLE, 0, PETSC_COMM_WORLD);
    MatDestroy(&spt);
    h->entries += (long)count;
    h->seconds += MPI_Wtime() - t0;
    return 0;
}

/* The stiffness of a box hexahedron hx x hy x hz (2 x 2 x 2 Gauss points),
   local node a = i + 2 j + 4 k at corner (i, j, k), DOF 3 a + component. */
static void h8_stiffness(double hx, double hy, double hz, double e, double nu, double ke[24][24])
{
    double lam = e * nu / ((1 + nu) * (1 - 2 * nu)), mu = e / (2 * (1 + nu));
    double g = 1.0 / sqrt(3.0), det = hx * hy * hz / 8.0;
    int p, a, b, r, s;
    memset(ke, 0, 24 * 24 * sizeof(double));
    for (p = 0; p < 8; p++) {
        double xi = (p & 1 ? g : -g), eta = (p & 2 ? g : -g), zeta = (p & 4 ? g : -g);
        double dn[8][3], bm[6][24], db[6][24];
        memset(bm, 0, sizeof bm);
        for (a = 0; a < 8; a++) {
            double sa = (a & 1) ? 1 : -1, ta = (a & 2) ? 1 : -1, ua = (a & 4) ? 1 : -1;
            dn[a][0] = 0.125 * sa * (1 + ta * eta) * (1 + ua * zeta) * 2.0 / hx;
            dn[a][1] = 0.125 * ta * (1 + sa * xi) * (1 + ua * zeta) * 2.0 / hy;
            dn[a][2] = 0.125 * ua * (1 + sa * xi) * (1 + ta * eta) * 2.0 / hz;
            bm[0][3 * a] = dn[a][0];
            bm[1][3 * a + 1] = dn[a][1];
            bm[2][3 * a + 2] = dn[a][2];
            bm[3][3 * a] = dn[a][1];
            bm[3][3 * a + 1] = dn[a][0];
            bm[4][3 * a + 1] = dn[a][2];
            bm[4][3 * a + 2] = dn[a][1];
            bm[5][3 * a] = dn[a][2];
            bm[5][3 * a + 2] = dn[a][0];
        }
        for (b = 0; b < 24; b++) {
            db[0][b] = (lam + 2 * mu) * bm[0][b] + lam * (bm[1][b] + bm[2][b]);
            db[1][b] = (lam + 2 * mu) * bm[1][b] + lam * (bm[0][b] + bm[2][b]);
            db[2][b] = (lam + 2 * mu) * bm[2][b] + lam * (bm[0][b] + bm[1][b]);
            db[3][b] = mu * bm[3][b];
            db[4][b] = mu * bm[4][b];
            db[5][b] = mu * bm[5][b];
        }
        for (r = 0; r < 24; r++)
            for (s = 0; s < 24; s++) {
                double v = 0.0;
                for (b = 0; b < 6; b++) v += bm[b][r] * db[b][s];
                ke[r][s] += v * det;
            }
    }
}

static void lib_error(int rank, const char *what, DsStatus st)
{
    fprintf(stderr, "petsc_operator (rank %d): %s failed: %s: %s\n", rank, what,
            ds_status_string((int32_t)st), ds_last_error_message());
}

static void dev_and_scale(const double *a, const double *b, long n, double *d, double *s)
{
    long k;
    for (k = 0; k < n; k++) {
        if (fabs(a[k] - b[k]) > *d) *d = fabs(a[k] - b[k]);
        if (fabs(a[k]) > *s) *s = fabs(a[k]);
    }
}

int main(int argc, char **argv)
{
    long nx = 24, ny = 24, nz = 4, nnode, nelem, ndof, neq, m, i, k, e, a, b, step;
    int rank, size, quiet = 0, iterative = 0, loose = 1, with_k = 1, serial = 1, exit_code = 0;
    int identical = 1, mumps_inverse = 0;
    double check_tol = 1e-8, hx, hy, hz, lz, ke[24][24], delta, max_err = 0.0, max_dev = 0.0;
    double su = 0.0, sl = 0.0, library_seconds = 0.0, create_seconds, create_host;
    DsCost cost;
    int cost_matches = 1;
    long create_solves;
    long *eq, *ctop, ntop = 0;
    int64_t *ki, *kj, *ni, *nj, *ti, *tj, kn = 0;
    double *kv, *nv, *tv, *g0, *mu, *f, *u, *ln, *lt, *u0, *ln0, *lt0, *buf;
    double *kfp_val;
    long *kfp_row, *kfp_col, nkfp = 0;
    Mat A;
    Host host;
    DsHostSolver solver;
    DsMatrix km, nm, tm;
    DsProblem *pb = NULL, *own = NULL;
    DsOptions opts;
    DsReport rep, rep0;
    DsStatus st;
    PC pc;

    MPI_Init(&argc, &argv);
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    for (k = 1; k < argc; k++) {
        const char *o = argv[k];
        if (!strcmp(o, "--quiet")) quiet = 1;
        else if (!strcmp(o, "--iterative")) iterative = 1;
        else if (!strcmp(o, "--no-loose")) loose = 0;
        else if (!strcmp(o, "--no-k")) with_k = 0;
        else if (!strcmp(o, "--no-serial")) serial = 0;
        else if (!strcmp(o, "--mumps-inverse")) mumps_inverse = 1;
        else if (k + 1 < argc && !strcmp(o, "--nx")) nx = atol(argv[++k]);
        else if (k + 1 < argc && !strcmp(o, "--ny")) ny = atol(argv[++k]);
        else if (k + 1 < argc && !strcmp(o, "--nz")) nz = atol(argv[++k]);
        else if (k + 1 < argc && !strcmp(o, "--check-tol")) check_tol = atof(argv[++k]);
        else {
            if (rank == 0) fprintf(stderr, "petsc_operator: unknown option %s\n", o);
            MPI_Finalize();
            return 3;
        }
    }
    if (nx < 1 || ny < 1 || nz < 1 || !(check_tol > 0) || (mumps_inverse && iterative)) {
        if (rank == 0) fprintf(stderr, "petsc_operator: bad sizes or tolerance\n");
        MPI_Finalize();
        return 3;
    }
    /* PETSc after our options: it reads its own from PETSC_OPTIONS only. */
    if (PetscInitializeNoArguments()) return 2;

    /* ---- the mesh, replicated on every rank (the contact data are small) ---- */
    lz = (double)nz / (double)nx;
    hx = 1.0 / (double)nx;
    hy = 1.0 / (double)ny;
    hz = lz / (double)nz;
    delta = 2e-3 * lz;
    nnode = (nx + 1) * (ny + 1) * (nz + 1);
    nelem = nx * ny * nz;
    ndof = 3 * nnode;
    eq = (long *)malloc((size_t)ndof * sizeof(long));
    ctop = (long *)malloc((size_t)ndof * sizeof(long));
    neq = 0;
    for (i = 0; i < nnode; i++)
        for (a = 0; a < 3; a++) {
            if (i / ((nx + 1) * (ny + 1)) == nz) {
                eq[3 * i + a] = -1 - ntop;
                ctop[ntop++] = a; /* prescribed top DOF: its component */
            } else
                eq[3 * i + a] = neq++;
        }
    h8_stiffness(hx, hy, hz, 1.0, 0.3, ke);

    /* K_ff (COO, both triangles) for the own path, K_fp for the loads. */
    ki = (int64_t *)malloc((size_t)(576 * nelem) * sizeof(int64_t));
    kj = (int64_t *)malloc((size_t)(576 * nelem) * sizeof(int64_t));
    kv = (double *)malloc((size_t)(576 * nelem) * sizeof(double));
    kfp_row = (long *)malloc((size_t)(576 * nx * ny) * sizeof(long));
    kfp_col = (long *)malloc((size_t)(576 * nx * ny) * sizeof(long));
    kfp_val = (double *)malloc((size_t)(576 * nx * ny) * sizeof(double));
    for (e = 0; e < nelem; e++) {
        long ex = e % nx, ey = (e / nx) % ny, ez = e / (nx * ny), dof[24];
        for (a = 0; a < 8; a++) {
            long nd = ((ez + (a >> 2 & 1)) * (ny + 1) + ey + (a >> 1 & 1)) * (nx + 1) + ex + (a & 1);
            for (b = 0; b < 3; b++) dof[3 * a + b] = 3 * nd + b;
        }
        for (a = 0; a < 24; a++)
            for (b = 0; b < 24; b++) {
                long ra = eq[dof[a]], cb = eq[dof[b]];
                if (ra >= 0 && cb >= 0) {
                    ki[kn] = ra;
                    kj[kn] = cb;
                    kv[kn++] = ke[a][b];
                } else if (ra >= 0) {
                    kfp_row[nkfp] = ra;
                    kfp_col[nkfp] = -1 - cb;
                    kfp_val[nkfp++] = ke[a][b];
                }
            }
    }
    /* Contacts: every bottom node; N u = -u_z <= g, T: u_x, u_y. */
    m = (nx + 1) * (ny + 1);
    ni = (int64_t *)malloc((size_t)m * sizeof(int64_t));
    nj = (int64_t *)malloc((size_t)m * sizeof(int64_t));
    nv = (double *)malloc((size_t)m * sizeof(double));
    ti = (int64_t *)malloc((size_t)(2 * m) * sizeof(int64_t));
    tj = (int64_t *)malloc((size_t)(2 * m) * sizeof(int64_t));
    tv = (double *)malloc((size_t)(2 * m) * sizeof(double));
    g0 = (double *)malloc((size_t)m * sizeof(double));
    mu = (double *)malloc((size_t)m * sizeof(double));
    for (i = 0; i < m; i++) {
        double x = (double)(i % (nx + 1)) * hx - 0.5, y = (double)(i / (nx + 1)) * hy - 0.5;
        ni[i] = i;
        nj[i] = eq[3 * i + 2];
        nv[i] = -1.0;
        ti[2 * i] = 2 * i;
        tj[2 * i] = eq[3 * i];
        tv[2 * i] = 1.0;
        ti[2 * i + 1] = 2 * i + 1;
        tj[2 * i + 1] = eq[3 * i + 1];
        tv[2 * i + 1] = 1.0;
        g0[i] = 0.5 * delta * (x * x + y * y) * 4.0;
        mu[i] = 0.3;
    }
    memset(&km, 0, sizeof km);
    km.format = DS_FORMAT_COO;
    km.index_type = DS_INDEX_TYPE_I64;
    km.storage = DS_STORAGE_FULL;
    km.nrows = km.ncols = neq;
    km.nnz = kn;
    km.p = kj;
    km.i = ki;
    km.x = kv;
    nm = km;
    nm.nrows = m;
    nm.nnz = m;
    nm.p = nj;
    nm.i = ni;
    nm.x = nv;
    tm = nm;
    tm.nrows = 2 * m;
    tm.nnz = 2 * m;
    tm.p = tj;
    tm.i = ti;
    tm.x = tv;

    /* ---- K distributed: each rank inserts its rows ------------------------- */
    if (MatCreateAIJ(PETSC_COMM_WORLD, PETSC_DECIDE, PETSC_DECIDE, neq, neq, 81, NULL, 81, NULL,
                     &A))
        return 2;
    MatSetOption(A, MAT_SYMMETRIC, PETSC_TRUE);
    MatGetOwnershipRange(A, &host.lo, &host.hi);
    for (k = 0; k < kn; k++)
        if (ki[k] >= host.lo && ki[k] < host.hi)
            MatSetValue(A, (PetscInt)ki[k], (PetscInt)kj[k], kv[k], ADD_VALUES);
    if (MatAssemblyBegin(A, MAT_FINAL_ASSEMBLY) || MatAssemblyEnd(A, MAT_FINAL_ASSEMBLY)) return 2;
    if (KSPCreate(PETSC_COMM_WORLD, &host.ksp) || KSPSetOperators(host.ksp, A, A)) return 2;
    KSPGetPC(host.ksp, &pc);
    if (iterative) {
        KSPSetType(host.ksp, KSPCG);
        PCSetType(pc, PCGAMG);
        KSPSetTolerances(host.ksp, RTOL, 1e-300, PETSC_DEFAULT, 2000);
    } else {
        KSPSetType(host.ksp, KSPPREONLY);
        PCSetType(pc, PCCHOLESKY);
        PCFactorSetMatSolverType(pc, MATSOLVERMUMPS);
    }
    if (KSPSetUp(host.ksp)) return 2;
    host.factor = NULL;
    host.entries = 0;
    if (mumps_inverse && PCFactorGetMatrix(pc, &host.factor)) return 2;
    MatCreateVecs(A, &host.x, &host.b);
    if (VecScatterCreateToAll(host.x, &host.to_all, &host.all)) return 2;
    host.solves = 0;
    host.loose = 0;
    host.seconds = 0.0;
    host.column = (double *)calloc((size_t)neq, sizeof(double));

    /* ---- the library on the KSP's solves, on every rank --------------------- */
    ds_options_default(&opts);
    opts.tol = 1e-10;
    opts.threads = 1;
    /* The same limit on every rank (SPMD): with 0 each rank would weigh its
       own machine's memory in the AUTO choices. */
    opts.max_memory = (uint64_t)16 << 30;
    opts.method = DS_METHOD_AUTO;
    opts.dual_form = DS_DUAL_FORM_MATRIX_FREE;
    memset(&solver, 0, sizeof solver);
    solver.struct_size = (uint32_t)sizeof solver;
    solver.n = neq;
    solver.solve = ksp_solve_cb;
    solver.context = &host;
    solver.inverse_entries = mumps_inverse ? mumps_inverse_cb : NULL;
    solver.solve_single = iterative && loose ? ksp_solve_loose_cb : NULL;
    {
        double t0 = MPI_Wtime();
        st = ds_problem_new_host(3, &solver, with_k ? &km : NULL, &nm, &tm, &opts, &pb);
        if (st != DS_STATUS_OK) {
            lib_error(rank, "ds_problem_new_host", st);
            MPI_Abort(MPI_COMM_WORLD, 2);
        }
        create_seconds = MPI_Wtime() - t0;
        create_host = host.seconds;
        create_solves = host.solves;
    }
    if (serial && rank == 0) {
        st = ds_problem_new_opts(3, &km, &nm, &tm, &opts, &own);
        if (st != DS_STATUS_OK) {
            lib_error(rank, "ds_problem_new_opts", st);
            MPI_Abort(MPI_COMM_WORLD, 2);
        }
    }
    f = (double *)calloc((size_t)neq, sizeof(double));
    u = (double *)calloc((size_t)neq, sizeof(double));
    u0 = (double *)calloc((size_t)neq, sizeof(double));
    buf = (double *)calloc((size_t)(neq + 3 * m), sizeof(double));
    ln = (double *)calloc((size_t)m, sizeof(double));
    lt = (double *)calloc((size_t)(2 * m), sizeof(double));
    ln0 = (double *)calloc((size_t)m, sizeof(double));
    lt0 = (double *)calloc((size_t)(2 * m), sizeof(double));
    if (rank == 0 && !quiet) {
        printf("petsc_operator: %d ranks, %ld x %ld x %ld hexahedra, %ld DOFs, %ld contacts "
               "(%ld dual unknowns), K^-1 by %s, K %s\n",
               size, nx, ny, nz, neq, m, 3 * m,
               iterative ? "CG + GAMG (rtol 1e-13)" : "MUMPS's Cholesky",
               with_k ? "handed over" : "not handed over");
        printf("%4s %5s %5s %5s %9s %6s %7s %9s %9s %10s %10s\n", "step", "open", "stick", "slip",
               "err", "outer", "solves", "host_s", "library_s", "identical", "dev_serial");
    }
    for (step = 0; step < N_HIST; step++) {
        double press = step < N_PRESS ? (double)(step + 1) / N_PRESS : 1.0;
        double shear = step < N_PRESS ? 0.0 : 0.5 * (double)(step + 1 - N_PRESS) / N_SHEAR;
        long solves0 = host.solves;
        double host0 = host.seconds, t0, t_step, du = 0.0, dl = 0.0;
        int same = 1;
        for (i = 0; i < neq; i++) f[i] = 0.0;
        for (k = 0; k < nkfp; k++) {
            long c = ctop[kfp_col[k]];
            double up = c == 2 ? -press * delta : c == 0 ? shear * delta : 0.0;
            f[kfp_row[k]] -= kfp_val[k] * up;
        }
        t0 = MPI_Wtime();
        st = ds_step(pb, &opts, DS_FRICTION_COULOMB, f, g0, mu, u, ln, lt, &rep);
        t_step = MPI_Wtime() - t0;
        if (st != DS_STATUS_OK) {
            lib_error(rank, "ds_step (host)", st);
            MPI_Abort(MPI_COMM_WORLD, st == DS_STATUS_NOT_CONVERGED ? 1 : 2);
        }
        /* What the step cost as the library measured it: its count of the
           host's right-hand sides must be this callback's. */
        cost.struct_size = (uint32_t)sizeof cost;
        st = ds_problem_last_cost(pb, &cost);
        if (st != DS_STATUS_OK) {
            lib_error(rank, "ds_problem_last_cost", st);
            MPI_Abort(MPI_COMM_WORLD, 2);
        }
        if (cost.host_solves != (int64_t)(host.solves - solves0)) cost_matches = 0;
        library_seconds += cost.library_seconds;
        if (rep.err > max_err) max_err = rep.err;
        /* Bitwise the same on every rank: rank r sends its answer to rank 0. */
        memcpy(buf, u, (size_t)neq * sizeof(double));
        memcpy(buf + neq, ln, (size_t)m * sizeof(double));
        memcpy(buf + neq + m, lt, (size_t)(2 * m) * sizeof(double));
        if (rank == 0) {
            int r;
            double *other = (double *)malloc((size_t)(neq + 3 * m) * sizeof(double));
            for (r = 1; r < size; r++) {
                (void)MPI_Recv(other, (int)(neq + 3 * m), MPI_DOUBLE, r, 7, MPI_COMM_WORLD,
                               MPI_STATUS_IGNORE);
                if (memcmp(other, buf, (size_t)(neq + 3 * m) * sizeof(double)) != 0) same = 0;
            }
            free(other);
        } else {
            (void)MPI_Send(buf, (int)(neq + 3 * m), MPI_DOUBLE, 0, 7, MPI_COMM_WORLD);
        }
        if (!same) identical = 0;
        if (own != NULL) {
            st = ds_step(own, &opts, DS_FRICTION_COULOMB, f, g0, mu, u0, ln0, lt0, &rep0);
            if (st != DS_STATUS_OK) {
                lib_error(rank, "ds_step (own factor)", st);
                MPI_Abort(MPI_COMM_WORLD, 2);
            }
            dev_and_scale(u0, u, neq, &du, &su);
            dev_and_scale(ln0, ln, m, &dl, &sl);
            dev_and_scale(lt0, lt, 2 * m, &dl, &sl);
            du = su > 0 ? du / su : du;
            dl = sl > 0 ? dl / sl : dl;
            if (du > max_dev) max_dev = du;
            if (dl > max_dev) max_dev = dl;
        }
        if (rank == 0 && !quiet)
            printf("%4ld %5lld %5lld %5lld %9.2e %6lld %7ld %9.3f %9.3f %10d %10.2e\n", step + 1,
                   (long long)rep.n_open, (long long)rep.n_stick, (long long)rep.n_slip, rep.err,
                   (long long)rep.outer_iterations, host.solves - solves0,
                   host.seconds - host0, t_step - (host.seconds - host0), same,
                   du > dl ? du : dl);
    }
    if (rank == 0) {
        int ok = identical && cost_matches && max_err <= 1e-10 && max_dev <= check_tol;
        printf("CREATE seconds=%.3f host_solves=%ld host_entries=%ld host_seconds=%.3f "
               "(the contact blocks)\n",
               create_seconds, create_solves, host.entries, create_host);
        printf("SUMMARY ranks=%d dofs=%ld contacts=%ld dual=%ld steps=%d max_err=%.3e "
               "max_dev=%.3e identical=%d host_solves=%ld loose_solves=%ld host_seconds=%.3f "
               "library_seconds=%.3f cost_matches=%d check=%s\n",
               size, neq, m, 3 * m, N_HIST, max_err, own != NULL ? max_dev : -1.0, identical,
               host.solves - create_solves, host.loose, host.seconds - create_host,
               library_seconds, cost_matches, ok ? "ok" : "FAILED");
        if (!ok) exit_code = 1;
    }
    (void)MPI_Bcast(&exit_code, 1, MPI_INT, 0, MPI_COMM_WORLD);

    ds_problem_free(pb);
    ds_problem_free(own);
    VecScatterDestroy(&host.to_all);
    VecDestroy(&host.all);
    VecDestroy(&host.x);
    VecDestroy(&host.b);
    KSPDestroy(&host.ksp);
    free(host.column);
    MatDestroy(&A);
    free(eq); free(ctop); free(ki); free(kj); free(kv); free(kfp_row); free(kfp_col);
    free(kfp_val); free(ni); free(nj); free(nv); free(ti); free(tj); free(tv); free(g0);
    free(mu); free(f); free(u); free(u0); free(buf); free(ln); free(lt); free(ln0); free(lt0);
    PetscFinalize();
    MPI_Finalize();
    return exit_code;
}
