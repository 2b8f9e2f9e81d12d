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
        "const char *ds_status_string(int32_t status);",
        "const char *ds_last_error_message(void);",
        "void ds_options_default(struct DsOptions *opts);",
        "void ds_problem_free(struct DsProblem *problem);",
        "enum DsStatus ds_history_reset(struct DsProblem *problem);",
        "#ifndef DUALSPLIT_H",
        "extern \"C\" {",
    ] {
        assert!(h.contains(name), "generated header lacks `{name}`");
    }
    for f in [
        "ds_problem_new",
        "ds_problem_refactor",
        "ds_problem_set_contacts",
        "ds_problem_sizes",
        "ds_solve",
        "ds_step",
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
    use dualsplit::ffi::*;
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
    offsets!(DsOptions: struct_size, method, tol, max_outer, max_inner);
    offsets!(DsReport: status, method, err, equilibrium_residual, outer_iterations,
        inner_iterations, n_open, n_stick, n_slip, factor_seconds, condense_seconds,
        solve_seconds);
    check("DS_STATUS_PANIC".into(), DsStatus::Panic as usize);
    check("DS_STATUS_IO_ERROR".into(), DsStatus::IoError as usize);
    check("DS_FORMAT_COO".into(), DsFormat::Coo as usize);
    check("DS_INDEX_TYPE_I64".into(), DsIndexType::I64 as usize);
    check("DS_STORAGE_LOWER".into(), DsStorage::Lower as usize);
    check("DS_METHOD_PGS".into(), DsMethod::Pgs as usize);
    check("DS_FRICTION_COULOMB".into(), DsFriction::Coulomb as usize);
    // The functions have the spec's C types.
    src.push_str(
        "static void signatures(void) {\n\
         DsStatus (*a)(int32_t, const DsMatrix *, const DsMatrix *, const DsMatrix *, DsProblem **) = ds_problem_new;\n\
         DsStatus (*b)(DsProblem *, const DsOptions *, int32_t, const double *, const double *, const double *, double *, double *, double *, DsReport *) = ds_solve;\n\
         DsStatus (*c)(DsProblem *, const DsOptions *, int32_t, const double *, const double *, const double *, double *, double *, double *, DsReport *) = ds_step;\n\
         DsStatus (*d)(const DsProblem *, int64_t *, int64_t *, int32_t *) = ds_problem_sizes;\n\
         const char *(*e)(int32_t) = ds_status_string;\n\
         const char *(*f)(void) = ds_last_error_message;\n\
         void (*g)(DsOptions *) = ds_options_default;\n\
         (void)a; (void)b; (void)c; (void)d; (void)e; (void)f; (void)g;\n}\n\
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
            eprintln!("skipped: no {default} compiler");
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
