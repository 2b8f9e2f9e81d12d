/* CHOLMOD's own factorisation of a symmetric positive definite K, for the
 * benchmark's baseline column (examples/factor.rs builds and runs it).
 *
 *   cholmod_factor K.mtx REPS [metis]
 *
 * K.mtx: Matrix Market, both triangles or one. CHOLMOD's default ordering
 * policy (AMD, then METIS when AMD's factor is dense enough, the better kept), or
 * METIS alone with the third argument. Prints one line per repetition:
 *   analyse_s factor_s lnz flops ordering
 * (ordering: amd, metis, nesdis, natural, given, colamd or other), analyse and
 * factorisation each timed with the wall clock. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <cholmod.h>

static double now(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t.tv_sec + 1e-9 * t.tv_nsec;
}

static const char *ordering_name(int o) {
    switch (o) {
    case CHOLMOD_NATURAL: return "natural";
    case CHOLMOD_GIVEN: return "given";
    case CHOLMOD_AMD: return "amd";
    case CHOLMOD_METIS: return "metis";
    case CHOLMOD_NESDIS: return "nesdis";
    case CHOLMOD_COLAMD: return "colamd";
    default: return "other";
    }
}

int main(int argc, char **argv) {
    if (argc < 3) {
        fprintf(stderr, "usage: %s K.mtx REPS [metis]\n", argv[0]);
        return 2;
    }
    int reps = atoi(argv[2]);
    int metis_only = argc > 3 && strcmp(argv[3], "metis") == 0;
    cholmod_common c;
    cholmod_start(&c);
    c.supernodal = CHOLMOD_SUPERNODAL;
    if (metis_only) {
        c.nmethods = 1;
        c.method[0].ordering = CHOLMOD_METIS;
        c.postorder = 1;
    }
    FILE *f = fopen(argv[1], "r");
    if (!f) {
        perror(argv[1]);
        return 3;
    }
    cholmod_sparse *a0 = cholmod_read_sparse(f, &c);
    fclose(f);
    if (!a0) {
        fprintf(stderr, "cannot read %s\n", argv[1]);
        return 3;
    }
    /* A general (both triangles) matrix becomes symmetric, lower triangle. */
    cholmod_sparse *a = a0->stype != 0 ? a0 : cholmod_copy(a0, -1, 1, &c);
    for (int r = 0; r < reps; r++) {
        double t0 = now();
        cholmod_factor *l = cholmod_analyze(a, &c);
        double t1 = now();
        if (!l || !cholmod_factorize(a, l, &c) || c.status != CHOLMOD_OK) {
            fprintf(stderr, "CHOLMOD failed (status %d)\n", c.status);
            return 4;
        }
        double t2 = now();
        printf("%.6f %.6f %.6g %.6g %s\n", t1 - t0, t2 - t1, c.lnz, c.fl,
               ordering_name(c.method[c.selected].ordering));
        cholmod_free_factor(&l, &c);
    }
    if (a != a0) cholmod_free_sparse(&a, &c);
    cholmod_free_sparse(&a0, &c);
    cholmod_finish(&c);
    return 0;
}
