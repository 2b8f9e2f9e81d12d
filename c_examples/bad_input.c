/* Bad input through the C API, for the valgrind run (tests/valgrind.rs): every
 * error path a C caller can reach on one small problem, each checked for its
 * status and a non-empty message, the handle checked usable after each, and
 * everything freed. Exit status 0 when every check passes.
 *
 * The problem: two 2D nodes (DOFs x0, y0, x1, y1), K = 3 I + ones(4), two
 * contacts with normal -e_y and tangent e_x; and a K as finite element codes
 * write it (one-sided entries, stored zeros, duplicates) through every
 * ordering (fe_code_k). */
#include "dualsplit.h"
#include <math.h>
#include <stdio.h>
#include <string.h>

static int failures = 0;

static void check(int ok, const char *what)
{
    if (!ok) {
        fprintf(stderr, "FAIL: %s (last error: %s)\n", what, ds_last_error_message());
        failures++;
    }
}

static void expect(DsStatus got, DsStatus want, const char *what)
{
    const char *msg = ds_last_error_message();
    printf("%-44s %-32s %s\n", what, ds_status_string(got), msg);
    check(got == want, what);
    if (want != DS_STATUS_OK) check(msg != NULL && msg[0] != '\0', "message not empty");
}

/* K dense 4 x 4, CSC int32 base 0. */
static int32_t kp[] = {0, 4, 8, 12, 16};
static int32_t ki[] = {0, 1, 2, 3, 0, 1, 2, 3, 0, 1, 2, 3, 0, 1, 2, 3};
static double kx[16];
static int32_t np_[] = {0, 0, 1, 1, 2}, ni[] = {0, 1};
static double nx[] = {-1.0, -1.0};
static int32_t tp[] = {0, 1, 1, 2, 2}, ti[] = {0, 1};
static double tx[] = {1.0, 1.0};

static DsMatrix mat(int32_t nrows, int32_t *p, int32_t *i, double *x)
{
    DsMatrix m = {DS_FORMAT_CSC, DS_INDEX_TYPE_I32, 0, DS_STORAGE_FULL, nrows, 4, 0, p, i, x};
    return m;
}

static double f[] = {0.2, -1.0, -0.3, -1.0}, g[] = {0.0, 0.0}, p[] = {0.1, 0.5};

static DsStatus solve(DsProblem *pb, const double *ff, const double *gg, const double *pp,
                      double *u, double *ln, double *lt)
{
    DsReport rep;
    return ds_solve(pb, NULL, DS_FRICTION_TRESCA, ff, gg, pp, u, ln, lt, &rep);
}

static void usable(DsProblem *pb, const double *u_ref)
{
    double u[4], ln[2], lt[2];
    DsStatus s = solve(pb, f, g, p, u, ln, lt);
    check(s == DS_STATUS_OK, "handle usable after the error");
    for (int k = 0; k < 4 && u_ref; k++)
        check(u[k] == u_ref[k], "same answer after the error");
}

/* A K as finite element codes write it, through every ordering: a 3D grid of
 * GX x GY x GZ nodes with two DOFs each (K = L (x) I_2, L the 7-point
 * Laplacian, 6.5 on its diagonal), given in COO with every diagonal entry as
 * two duplicates, and for each in-plane diagonal neighbour pair an entry of
 * 1e-18 stored on one side only (its mirror cancelled to an exact zero and
 * dropped) or with a stored 0.0 on the other side. METIS_NodeND used to
 * corrupt its heap on such a one-sided graph. The bottom nodes are contacts
 * (N = -e_y, T = e_x); each ordering's u must agree with AMD's. */
enum { GX = 8, GY = 8, GZ = 4, GN = GX * GY * GZ, GDOF = 2 * GN, GM = GX * GY };

static int node_of(int x, int y, int z) { return x + GX * (y + GY * z); }

static int fe_code_k(void)
{
    static int64_t ri[40 * GDOF], ci[40 * GDOF];
    static double vx[40 * GDOF];
    int64_t nnz = 0;
    for (int z = 0; z < GZ; z++)
        for (int y = 0; y < GY; y++)
            for (int x = 0; x < GX; x++) {
                int a = node_of(x, y, z);
                for (int s = 0; s < 2; s++) {
                    int64_t da = 2 * a + s;
                    ri[nnz] = da; ci[nnz] = da; vx[nnz++] = 2.5; /* 2.5 + 4.0 = 6.5 */
                    ri[nnz] = da; ci[nnz] = da; vx[nnz++] = 4.0;
                    const int nb[6][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0},
                                          {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
                    for (int k = 0; k < 6; k++) {
                        int bx = x + nb[k][0], by = y + nb[k][1], bz = z + nb[k][2];
                        if (bx < 0 || by < 0 || bz < 0 || bx >= GX || by >= GY || bz >= GZ)
                            continue;
                        ri[nnz] = 2 * node_of(bx, by, bz) + s; ci[nnz] = da; vx[nnz++] = -1.0;
                    }
                    /* The in-plane diagonal neighbour (x + 1, y + 1): one side only, or
                       a stored zero on the other, by the parity of the node. */
                    if (x + 1 < GX && y + 1 < GY) {
                        int64_t db = 2 * node_of(x + 1, y + 1, z) + s;
                        int upper = (a + s) % 2 == 0;
                        ri[nnz] = upper ? da : db; ci[nnz] = upper ? db : da; vx[nnz++] = 1e-18;
                        if ((a / 2) % 2 == 0) {
                            ri[nnz] = upper ? db : da; ci[nnz] = upper ? da : db; vx[nnz++] = 0.0;
                        }
                    }
                }
            }
    DsMatrix K = {DS_FORMAT_COO, DS_INDEX_TYPE_I64, 0, DS_STORAGE_FULL, GDOF, GDOF, nnz,
                  ci, ri, vx};
    /* COO: p holds the column indices, i the row indices (the header's DsMatrix). */
    static int64_t nr[GM], nc[GM], tr[GM], tc[GM];
    static double nv[GM], tv[GM], ff[GDOF], gg[GM], pp[GM];
    for (int c = 0; c < GM; c++) {
        int a = node_of(c % GX, c / GX, 0);
        nr[c] = c; nc[c] = 2 * a + 1; nv[c] = -1.0;
        tr[c] = c; tc[c] = 2 * a; tv[c] = 1.0;
        gg[c] = 0.01 * (c % 3);
        pp[c] = 0.05;
    }
    for (int k = 0; k < GDOF; k++) ff[k] = (k % 2) ? -0.2 : 0.03;
    DsMatrix N = {DS_FORMAT_COO, DS_INDEX_TYPE_I64, 0, DS_STORAGE_FULL, GM, GDOF, GM, nc, nr, nv};
    DsMatrix T = {DS_FORMAT_COO, DS_INDEX_TYPE_I64, 0, DS_STORAGE_FULL, GM, GDOF, GM, tc, tr, tv};
    static double u0[GDOF], u[GDOF], ln[GM], lt[GM];
    const DsOrdering orders[3] = {DS_ORDERING_AMD, DS_ORDERING_METIS, DS_ORDERING_AUTO};
    const char *names[3] = {"FE-code K, AMD", "FE-code K, METIS", "FE-code K, AUTO"};
    int bad = 0;
    for (int o = 0; o < 3; o++) {
        DsOptions opts;
        ds_options_default(&opts);
        opts.threads = 1;
        opts.ordering = orders[o];
        DsProblem *pb = NULL;
        expect(ds_problem_new_opts(3 - 1, &K, &N, &T, &opts, &pb), DS_STATUS_OK, names[o]);
        if (!pb) { bad++; continue; }
        DsReport rep;
        double *out = o == 0 ? u0 : u;
        expect(ds_solve(pb, &opts, DS_FRICTION_TRESCA, ff, gg, pp, out, ln, lt, &rep),
               DS_STATUS_OK, "  its solve");
        for (int k = 0; o > 0 && k < GDOF; k++)
            if (fabs(u[k] - u0[k]) > 1e-10 * (1.0 + fabs(u0[k]))) { bad++; break; }
        ds_problem_free(pb);
    }
    check(bad == 0, "FE-code K: every ordering gives AMD's answer");
    return bad;
}

int main(void)
{
    for (int e = 0; e < 16; e++) kx[e] = (e / 4 == e % 4) ? 4.0 : 1.0;
    DsMatrix K = mat(4, kp, ki, kx), N = mat(2, np_, ni, nx), T = mat(2, tp, ti, tx);
    DsProblem *pb = NULL;
    expect(ds_problem_new(2, &K, &N, &T, &pb), DS_STATUS_OK, "create");
    if (!pb) return 1;
    double u_ref[4], ln[2], lt[2];
    expect(solve(pb, f, g, p, u_ref, ln, lt), DS_STATUS_OK, "reference solve");

    DsProblem *other = NULL;
    /* Null pointers and a null handle. */
    expect(ds_problem_new(2, NULL, &N, &T, &other), DS_STATUS_NULL_POINTER, "K NULL");
    expect(ds_problem_new(2, &K, &N, &T, NULL), DS_STATUS_NULL_POINTER, "out NULL");
    expect(solve(NULL, f, g, p, u_ref, ln, lt), DS_STATUS_NULL_POINTER, "handle NULL");
    expect(ds_problem_refactor(NULL, &K), DS_STATUS_NULL_POINTER, "refactor NULL handle");
    expect(ds_history_reset(NULL), DS_STATUS_NULL_POINTER, "reset NULL handle");
    double u[4];
    expect(solve(pb, NULL, g, p, u, ln, lt), DS_STATUS_NULL_POINTER, "f NULL");
    usable(pb, u_ref);
    /* d out of range. */
    expect(ds_problem_new(4, &K, &N, &T, &other), DS_STATUS_BAD_ARGUMENT, "d = 4");
    expect(ds_problem_new(-1, &K, &N, &T, &other), DS_STATUS_BAD_ARGUMENT, "d = -1");
    /* Wrong sizes, bad indices. */
    DsMatrix Nbad = N;
    Nbad.ncols = 3;
    expect(ds_problem_set_contacts(pb, &Nbad, &T), DS_STATUS_BAD_SIZE, "N 2 x 3");
    int32_t ni_bad[] = {0, 7};
    DsMatrix Nidx = mat(2, np_, ni_bad, nx);
    expect(ds_problem_set_contacts(pb, &Nidx, &T), DS_STATUS_BAD_INDEX, "N row index 7");
    usable(pb, u_ref);
    /* NaN and infinity. */
    double kx_nan[16];
    memcpy(kx_nan, kx, sizeof kx);
    kx_nan[5] = NAN;
    DsMatrix Knan = mat(4, kp, ki, kx_nan);
    expect(ds_problem_new(2, &Knan, &N, &T, &other), DS_STATUS_NOT_FINITE, "K NaN");
    expect(ds_problem_refactor(pb, &Knan), DS_STATUS_NOT_FINITE, "refactor K NaN");
    double f_inf[] = {0.2, INFINITY, -0.3, -1.0};
    expect(solve(pb, f_inf, g, p, u, ln, lt), DS_STATUS_NOT_FINITE, "f inf");
    usable(pb, u_ref);
    /* Not symmetric, indefinite. */
    double kx_uns[16];
    memcpy(kx_uns, kx, sizeof kx);
    kx_uns[1] = 1.5;
    DsMatrix Kuns = mat(4, kp, ki, kx_uns);
    expect(ds_problem_new(2, &Kuns, &N, &T, &other), DS_STATUS_NOT_SYMMETRIC, "K unsymmetric");
    double kx_ind[16];
    for (int e = 0; e < 16; e++) kx_ind[e] = (e / 4 == e % 4) ? 1.0 : 2.0;
    DsMatrix Kind = mat(4, kp, ki, kx_ind);
    expect(ds_problem_new(2, &Kind, &N, &T, &other), DS_STATUS_NOT_POSITIVE_DEFINITE,
           "K indefinite");
    expect(ds_problem_refactor(pb, &Kind), DS_STATUS_NOT_POSITIVE_DEFINITE,
           "refactor K indefinite");
    usable(pb, u_ref);
    /* Negative friction, bad friction enum, bad options. */
    double p_neg[] = {0.1, -0.5};
    expect(solve(pb, f, g, p_neg, u, ln, lt), DS_STATUS_NEGATIVE_FRICTION, "p < 0");
    DsReport rep;
    expect(ds_solve(pb, NULL, 7, f, g, p, u, ln, lt, &rep), DS_STATUS_BAD_ARGUMENT,
           "friction 7");
    DsOptions o;
    ds_options_default(&o);
    o.tol = -1.0;
    expect(ds_solve(pb, &o, DS_FRICTION_TRESCA, f, g, p, u, ln, lt, &rep),
           DS_STATUS_BAD_ARGUMENT, "tol < 0");
    /* Not converged: one iteration only. */
    ds_options_default(&o);
    o.method = DS_METHOD_PGS;
    o.max_outer = 1;
    o.tol = 1e-15;
    DsStatus s = ds_solve(pb, &o, DS_FRICTION_TRESCA, f, g, p, u, ln, lt, &rep);
    printf("%-44s %-32s\n", "max_outer = 1", ds_status_string(s));
    check(s == DS_STATUS_OK || s == DS_STATUS_NOT_CONVERGED, "max_outer = 1");
    usable(pb, u_ref);
    check(other == NULL, "no handle created on error");
    /* The status strings of every code, and one past the end. */
    for (int c = -1; c <= 20; c++) check(ds_status_string(c) != NULL, "status string");
    fe_code_k();
    ds_problem_free(pb);
    ds_problem_free(NULL);
    printf("%s: %d failure(s)\n", failures ? "FAILED" : "OK", failures);
    return failures ? 1 : 0;
}
