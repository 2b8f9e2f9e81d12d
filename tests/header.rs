//! The checked-in C header include/dualsplit.h must be what cbindgen generates from
//! src/ffi/ with cbindgen.toml. Regenerate it with
//!
//!     DUALSPLIT_BLESS=1 cargo test --test header

use std::path::{Path, PathBuf};

fn generate() -> String {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let config = cbindgen::Config::from_file(root.join("cbindgen.toml"))
        .expect("cbindgen.toml is readable and valid");
    let bindings = cbindgen::Builder::new()
        .with_crate(&root)
        .with_config(config)
        .generate()
        .expect("cbindgen generates the header");
    let mut out = Vec::new();
    bindings.write(&mut out);
    String::from_utf8(out).expect("the header is UTF-8")
}

fn header_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("include/dualsplit.h")
}

#[test]
fn header_is_up_to_date() {
    let generated = generate();
    let path = header_path();
    if std::env::var("DUALSPLIT_BLESS").as_deref() == Ok("1") {
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(&path, &generated).unwrap();
        return;
    }
    let checked_in = std::fs::read_to_string(&path).unwrap_or_default();
    if checked_in != generated {
        let first = checked_in
            .lines()
            .zip(generated.lines())
            .position(|(a, b)| a != b)
            .unwrap_or(checked_in.lines().count().min(generated.lines().count()));
        panic!(
            "include/dualsplit.h is out of date with src/ffi/ (first difference at line {}).\n\
             Regenerate it with:\n\n    DUALSPLIT_BLESS=1 cargo test --test header\n\n\
             and check the new header in.",
            first + 1
        );
    }
}

#[test]
fn header_has_the_spec_names() {
    let h = generate();
    // No Rust-internal type reaches C: every struct and enum is a Ds one.
    for line in h.lines() {
        if let Some(rest) = line
            .strip_prefix("typedef struct ")
            .or_else(|| line.strip_prefix("typedef enum "))
        {
            assert!(rest.starts_with("Ds"), "the header exposes `{line}`");
        }
    }
    for name in [
        "DS_STATUS_OK",
        "DS_STATUS_NULL_POINTER",
        "DS_STATUS_BAD_SIZE",
        "DS_STATUS_BAD_INDEX",
        "DS_STATUS_NOT_FINITE",
        "DS_STATUS_NOT_SYMMETRIC",
        "DS_STATUS_NOT_POSITIVE_DEFINITE",
        "DS_STATUS_NEGATIVE_FRICTION",
        "DS_STATUS_NOT_CONVERGED",
        "DS_STATUS_OUT_OF_MEMORY",
        "DS_STATUS_BAD_ARGUMENT",
        "DS_STATUS_IO_ERROR",
        "DS_STATUS_PANIC",
        "DS_FORMAT_CSR",
        "DS_FORMAT_CSC",
        "DS_FORMAT_COO",
        "DS_INDEX_TYPE_I32",
        "DS_INDEX_TYPE_I64",
        "DS_STORAGE_FULL",
        "DS_STORAGE_UPPER",
        "DS_STORAGE_LOWER",
        "DS_METHOD_SPLIT",
        "DS_METHOD_BLOCK_GS",
        "DS_METHOD_PGS",
        "DS_FRICTION_TRESCA",
        "DS_FRICTION_COULOMB",
        "typedef struct DsProblem DsProblem;",
        "typedef struct DsMatrix {",
        "typedef struct DsOptions {",
        "typedef struct DsReport {",
        "typedef struct DsHostSolver {",
        "const char *ds_status_string(int32_t status);",
        "const char *ds_last_error_message(void);",
        "void ds_options_default(struct DsOptions *opts);",
        "enum DsStatus ds_options_init(struct DsOptions *opts, size_t size);",
        "const char *ds_version(void);",
        "#define ds_options_default(opts) ds_options_init((opts), sizeof *(opts))",
        "void ds_problem_free(struct DsProblem *problem);",
        "enum DsStatus ds_history_reset(struct DsProblem *problem);",
        "#ifndef DUALSPLIT_H",
        "extern \"C\" {",
    ] {
        assert!(h.contains(name), "generated header lacks `{name}`");
    }
    for f in [
        "ds_problem_new",
        "ds_problem_new_host",
        "ds_problem_refactor",
        "ds_problem_set_contacts",
        "ds_problem_set_compliance",
        "ds_problem_sizes",
        "ds_solve",
        "ds_step",
        "ds_solve_iteration",
    ] {
        assert!(
            h.contains(&format!("enum DsStatus {f}(")),
            "generated header lacks {f}"
        );
    }
}

/// The compiler named by `var` (default `default`), if it runs.
fn compiler(var: &str, default: &str) -> Option<String> {
    let cc = std::env::var(var).unwrap_or_else(|_| default.to_string());
    let ok = std::process::Command::new(&cc)
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    ok.then_some(cc)
}

/// The header compiles as C11 and C++11, and its structs and enums have the sizes,
/// field offsets and values of the Rust definitions (static assertions checked by
/// the C compiler). Skipped when no compiler is found.
#[test]
fn header_compiles_and_matches_the_rust_layout() {
    use dualsplit::internals::ffi::*;
    use std::mem::{offset_of, size_of};
    let mut src = String::from(
        "#include \"dualsplit.h\"\n#include <stddef.h>\n\
         #ifdef __cplusplus\n#define DS_ASSERT(c) static_assert(c, #c)\n\
         #else\n#define DS_ASSERT(c) _Static_assert(c, #c)\n#endif\n",
    );
    let mut check = |expr: String, value: usize| {
        src.push_str(&format!("DS_ASSERT({expr} == {value});\n"));
    };
    check("sizeof(DsMatrix)".into(), size_of::<DsMatrix>());
    check("sizeof(DsOptions)".into(), size_of::<DsOptions>());
    check("sizeof(DsReport)".into(), size_of::<DsReport>());
    check("sizeof(DsStatus)".into(), size_of::<DsStatus>());
    macro_rules! offsets {
        ($ty:ident: $($field:ident),*) => {
            $(check(
                format!("offsetof({}, {})", stringify!($ty), stringify!($field)),
                offset_of!($ty, $field),
            );)*
        };
    }
    offsets!(DsMatrix: format, index_type, base, storage, nrows, ncols, nnz, p, i, x);
    check("sizeof(DsProgress)".into(), size_of::<DsProgress>());
    check("sizeof(DsHostSolver)".into(), size_of::<DsHostSolver>());
    offsets!(DsHostSolver: struct_size, n, solve, context, inverse_entries, solve_single, solve_rows, blocks);
    check("sizeof(DsCost)".into(), size_of::<DsCost>());
    offsets!(DsCost: struct_size, solved, solve_seconds, rhs_seconds, iterate_seconds,
        recover_seconds, host_solves, host_seconds, library_seconds);
    offsets!(DsOptions: struct_size, method, tol, max_outer, max_inner, dual_form,
        max_seconds, stall_window, stall_factor);
    offsets!(DsReport: status, method, err, equilibrium_residual, outer_iterations,
        inner_iterations, n_open, n_stick, n_slip, factor_seconds, condense_seconds,
        solve_seconds);
    offsets!(DsProgress: iteration, err, n_open, n_stick, n_slip, elapsed_seconds);
    // Every enum value.
    let statuses = [
        "OK",
        "NULL_POINTER",
        "BAD_SIZE",
        "BAD_INDEX",
        "NOT_FINITE",
        "NOT_SYMMETRIC",
        "NOT_POSITIVE_DEFINITE",
        "NEGATIVE_FRICTION",
        "NOT_CONVERGED",
        "OUT_OF_MEMORY",
        "BAD_ARGUMENT",
        "IO_ERROR",
        "PANIC",
        "STOPPED",
        "STALLED",
        "TIME_LIMIT",
        "HOST_SOLVE_FAILED",
        "BUSY",
    ];
    assert_eq!(statuses.len(), DsStatus::ALL.len());
    for (name, status) in statuses.iter().zip(DsStatus::ALL) {
        check(format!("DS_STATUS_{name}"), status as usize);
    }
    for (name, v) in [
        ("DS_FORMAT_CSR", DsFormat::Csr as usize),
        ("DS_FORMAT_CSC", DsFormat::Csc as usize),
        ("DS_FORMAT_COO", DsFormat::Coo as usize),
        ("DS_INDEX_TYPE_I32", DsIndexType::I32 as usize),
        ("DS_INDEX_TYPE_I64", DsIndexType::I64 as usize),
        ("DS_STORAGE_FULL", DsStorage::Full as usize),
        ("DS_STORAGE_UPPER", DsStorage::Upper as usize),
        ("DS_STORAGE_LOWER", DsStorage::Lower as usize),
        ("DS_METHOD_SPLIT", DsMethod::Split as usize),
        ("DS_METHOD_BLOCK_GS", DsMethod::BlockGs as usize),
        ("DS_METHOD_PGS", DsMethod::Pgs as usize),
        ("DS_METHOD_NEWTON", DsMethod::Newton as usize),
        ("DS_METHOD_SPLIT_MPRGP", DsMethod::SplitMprgp as usize),
        ("DS_METHOD_MPRGP", DsMethod::Mprgp as usize),
        ("DS_DUAL_FORM_AUTO", DsDualForm::Auto as usize),
        ("DS_DUAL_FORM_DENSE", DsDualForm::Dense as usize),
        ("DS_DUAL_FORM_MATRIX_FREE", DsDualForm::MatrixFree as usize),
        ("DS_HOST_BLOCKS_SOLVES", DsHostBlocks::Solves as usize),
        ("DS_HOST_BLOCKS_FACTOR", DsHostBlocks::Factor as usize),
        ("DS_HOST_BLOCKS_AUTO", DsHostBlocks::Auto as usize),
        ("DS_FRICTION_TRESCA", DsFriction::Tresca as usize),
        ("DS_FRICTION_COULOMB", DsFriction::Coulomb as usize),
    ] {
        check(name.into(), v);
    }
    // The version macros are Cargo's.
    for (name, v) in [
        ("DS_VERSION_MAJOR", env!("CARGO_PKG_VERSION_MAJOR")),
        ("DS_VERSION_MINOR", env!("CARGO_PKG_VERSION_MINOR")),
        ("DS_VERSION_PATCH", env!("CARGO_PKG_VERSION_PATCH")),
    ] {
        check(name.into(), v.parse().unwrap());
    }
    // The functions have the spec's C types.
    src.push_str(
        "static void signatures(void) {\n\
         DsStatus (*a)(int32_t, const DsMatrix *, const DsMatrix *, const DsMatrix *, DsProblem **) = ds_problem_new;\n\
         DsStatus (*b)(DsProblem *, const DsOptions *, int32_t, const double *, const double *, const double *, double *, double *, double *, DsReport *) = ds_solve;\n\
         DsStatus (*c)(DsProblem *, const DsOptions *, int32_t, const double *, const double *, const double *, double *, double *, double *, DsReport *) = ds_step;\n\
         DsStatus (*c2)(DsProblem *, const DsOptions *, int32_t, const double *, const double *, const double *, const double *, const double *, double *, double *, double *, DsReport *) = ds_solve_iteration;\n\
         DsStatus (*d)(const DsProblem *, int64_t *, int64_t *, int32_t *) = ds_problem_sizes;\n\
         const char *(*e)(int32_t) = ds_status_string;\n\
         const char *(*f)(void) = ds_last_error_message;\n\
         void (*g)(DsOptions *) = ds_options_default;\n\
         DsStatus (*h)(DsOptions *, size_t) = ds_options_init;\n\
         void (*i)(DsProblem *) = ds_problem_free;\n\
         DsStatus (*j)(DsProblem *, const DsMatrix *) = ds_problem_refactor;\n\
         DsStatus (*k)(DsProblem *, const DsMatrix *, const DsMatrix *) = ds_problem_set_contacts;\n\
         DsStatus (*l)(DsProblem *) = ds_history_reset;\n\
         DsStatus (*m)(DsProblem *, DsMonitorFn, void *) = ds_problem_set_monitor;\n\
         DsStatus (*n)(DsProblem *, int32_t, DsLogFn, void *) = ds_problem_set_log;\n\
         DsStatus (*o)(const DsProblem *, const char *, int32_t, const double *, const double *, const double *) = ds_problem_dump;\n\
         DsStatus (*t)(DsProblem *, const double *, const double *, const double *) = ds_problem_set_compliance;\n\
         const char *(*p)(void) = ds_version;\n\
         int32_t (*q)(const DsProgress *, void *) = (DsMonitorFn)0;\n\
         void (*r)(int32_t, const char *, void *) = (DsLogFn)0;\n\
         DsOptions opts; DsStatus s = ds_options_default(&opts);\n\
         (void)a; (void)b; (void)c; (void)c2; (void)d; (void)e; (void)f; (void)g; (void)h; (void)i;\n\
         (void)j; (void)k; (void)l; (void)m; (void)n; (void)o; (void)p; (void)q; (void)r; (void)s; (void)t;\n}\n\
         int main(void) { signatures(); return 0; }\n",
    );
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("header_check");
    std::fs::create_dir_all(&dir).unwrap();
    // The freshly generated header (equal to the checked-in one when
    // header_is_up_to_date passes), so that blessing in parallel cannot race.
    std::fs::write(dir.join("dualsplit.h"), generate()).unwrap();
    let include = dir.clone();
    for (var, default, file, std) in [
        ("CC", "cc", "check.c", "-std=c11"),
        ("CXX", "c++", "check.cpp", "-std=c++11"),
    ] {
        let Some(cc) = compiler(var, default) else {
            // .ci/run installs both; elsewhere a missing one is said loudly.
            assert!(
                std::env::var("CI").as_deref() != Ok("true"),
                "no {default} compiler under CI=true: .ci/run installs gcc and g++"
            );
            eprintln!(
                "SKIPPED: header check in {file}: no {default} compiler (apt-get install g++)"
            );
            continue;
        };
        let path = dir.join(file);
        std::fs::write(&path, &src).unwrap();
        let out = std::process::Command::new(&cc)
            .args([
                std,
                "-Wall",
                "-Wextra",
                "-Werror",
                "-pedantic",
                "-fsyntax-only",
                "-I",
            ])
            .arg(&include)
            .arg(&path)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{cc} rejects include/dualsplit.h:\n{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
}
