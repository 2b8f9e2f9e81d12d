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
        assert!(h.contains(&format!("enum DsStatus {f}(")), "generated header lacks {f}");
    }
}
