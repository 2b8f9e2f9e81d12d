//! A program built against an older header runs against this library: a C program
//! that declares the 0.1 and 0.2 structs and prototypes itself (not this header),
//! fills its options with the function ds_options_default, solves README's
//! one-node problem (hand-derived answer: lambda_N = 8, lambda_T = 0.4, u = (0.3,
//! -0.5)), and checks with a guard region after each struct that the library
//! wrote nothing past the old sizes.

mod ctools;

use ctools::{SYSTEM_LIBS, c_compiler, out_dir, run_ok, static_lib, stdout_of};
use dualsplit::internals::ffi::DsReport;
use std::process::Command;

/// The old program. OLD_OPTIONS_SIZE is 32 (0.1) or 40 (0.2, with dual_form).
const OLD_PROGRAM: &str = r#"
#include <stdint.h>
#include <stdio.h>
#include <string.h>

typedef struct {
    int32_t format, index_type, base, storage;
    int64_t nrows, ncols, nnz;
    const void *p, *i;
    const double *x;
} DsMatrix;

typedef struct {
    uint32_t struct_size;
    int32_t method;
    double tol;
    int64_t max_outer, max_inner;
#if OLD_OPTIONS_SIZE == 40
    int32_t dual_form;
#endif
} DsOptions;

typedef struct {
    int32_t status, method;
    double err, equilibrium_residual;
    int64_t outer_iterations, inner_iterations, n_open, n_stick, n_slip;
    double factor_seconds, condense_seconds, solve_seconds;
} DsReport;

void ds_options_default(DsOptions *opts);
int32_t ds_problem_new(int32_t d, const DsMatrix *k, const DsMatrix *n, const DsMatrix *t,
                       void **out);
int32_t ds_solve(void *problem, const DsOptions *opts, int32_t friction, const double *f,
                 const double *g, const double *bound, double *u, double *lambda_n,
                 double *lambda_t, DsReport *report);
void ds_problem_free(void *problem);

#define GUARD 64
struct GuardedOptions { DsOptions o; unsigned char guard[GUARD]; };
struct GuardedReport { DsReport r; unsigned char guard[GUARD]; };

static int guard_intact(const unsigned char *g) {
    for (int k = 0; k < GUARD; k++)
        if (g[k] != 0xA5) return 0;
    return 1;
}

int main(void) {
    if (sizeof(DsOptions) != OLD_OPTIONS_SIZE) { printf("layout %d\n", (int)sizeof(DsOptions)); return 2; }
    int32_t kp[] = {0, 1, 2}, ki[] = {0, 1};   double kx[] = {2.0, 4.0};
    int32_t np[] = {0, 0, 1}, ni[] = {0};      double nx[] = {-1.0};
    int32_t tp[] = {0, 1, 1}, ti[] = {0};      double tx[] = {1.0};
    DsMatrix K = {1, 0, 0, 0, 2, 2, 0, kp, ki, kx};
    DsMatrix N = {1, 0, 0, 0, 1, 2, 0, np, ni, nx};
    DsMatrix T = {1, 0, 0, 0, 1, 2, 0, tp, ti, tx};
    void *pb = NULL;
    if (ds_problem_new(2, &K, &N, &T, &pb) != 0) { printf("new failed\n"); return 3; }
    struct GuardedOptions go;
    struct GuardedReport gr;
    memset(&go, 0xA5, sizeof go);
    memset(&gr, 0xA5, sizeof gr);
    ds_options_default(&go.o);
    if (!guard_intact(go.guard)) { printf("options guard overwritten by ds_options_default\n"); return 4; }
    go.o.tol = 1e-12;
    double f[] = {1.0, -10.0}, g[] = {0.5}, p[] = {0.4};
    double u[2], ln[1], lt[1];
    int32_t s = ds_solve(pb, &go.o, 0, f, g, p, u, ln, lt, &gr.r);
    if (!guard_intact(go.guard)) { printf("options guard overwritten by ds_solve\n"); return 5; }
    if (!guard_intact(gr.guard)) { printf("report guard overwritten by ds_solve\n"); return 6; }
    printf("status %d report %d struct_size %u lambda_N %.15g lambda_T %.15g u %.15g %.15g err %.3g\n",
           (int)s, (int)gr.r.status, go.o.struct_size, ln[0], lt[0], u[0], u[1], gr.r.err);
    ds_problem_free(pb);
    return s == 0 ? 0 : 1;
}
"#;

fn run_old_program(options_size: usize) -> String {
    let dir = out_dir(&format!("old_abi_{options_size}"));
    let src = dir.join("old.c");
    std::fs::write(&src, OLD_PROGRAM).unwrap();
    let exe = dir.join("old");
    let mut cc = c_compiler();
    cc.arg("-std=c99")
        .arg("-Wall")
        .arg("-Werror")
        .arg(format!("-DOLD_OPTIONS_SIZE={options_size}"))
        .arg(&src)
        .arg(static_lib())
        .args(SYSTEM_LIBS)
        .arg("-o")
        .arg(&exe);
    run_ok(&mut cc, "compile the old-header program");
    stdout_of(&run_ok(
        &mut Command::new(&exe),
        "run the old-header program",
    ))
}

fn number_after(text: &str, key: &str) -> f64 {
    let rest = &text[text.find(key).unwrap_or_else(|| panic!("{key} in {text}")) + key.len()..];
    rest.split_whitespace().next().unwrap().parse().unwrap()
}

#[test]
fn programs_built_against_the_0_1_and_0_2_headers_run_and_keep_their_memory() {
    // The report of 0.1 to 0.3 is the first 88 bytes of this one: 0.4 and 0.5
    // appended their fields, which a caller with older options never gets.
    assert_eq!(std::mem::offset_of!(DsReport, ordering), 88);
    assert_eq!(std::mem::offset_of!(DsReport, memory_predicted), 120);
    assert_eq!(std::mem::size_of::<DsReport>(), 136);
    for size in [32, 40] {
        let out = run_old_program(size);
        println!("{size}: {out}");
        assert!(
            out.starts_with("status 0 report 0 struct_size 32 "),
            "{out}"
        );
        assert!(
            (number_after(&out, "lambda_N ") - 8.0).abs() < 1e-12,
            "{out}"
        );
        assert!(
            (number_after(&out, "lambda_T ") - 0.4).abs() < 1e-12,
            "{out}"
        );
        let u0 = number_after(&out, " u ");
        assert!((u0 - 0.3).abs() < 1e-12, "{out}");
    }
}
