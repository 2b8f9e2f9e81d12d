/* Bad input through the C API, for the valgrind run (tests/valgrind.rs): every
 * error path a C caller can reach on one small problem, each checked for its
 * status and a non-empty message, the handle checked usable after each, and
 * everything freed. Exit status 0 when every check passes.
 *
 * The problem: two 2D nodes (DOFs x0, y0, x1, y1), K = 3 I + ones(4), two
 * contacts with normal -e_y and tangent e_x. */
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
    ds_problem_free(pb);
    ds_problem_free(NULL);
    printf("%s: %d failure(s)\n", failures ? "FAILED" : "OK", failures);
    return failures ? 1 : 0;
}
