//! The Fortran path: include/dualsplit.f90 (a Fortran 2003 ISO_C_BINDING module) and
//! the examples c_examples/minimal.f90 and c_examples/block2d.f90, built with
//! gfortran against the static library cargo built for this test run.
//!
//! - `module_matches_the_header` (no compiler needed): every C function of
//!   include/dualsplit.h has a bind(C) interface with as many arguments and a public
//!   Fortran procedure of the same name, every enum constant a parameter of the same
//!   value, every struct a bind(C) type with the same fields in the same order and
//!   the interoperable types of the C fields;
//! - `module_layout_matches_c`: sizes and field offsets of DsMatrix, DsOptions,
//!   DsReport, DsProgress as gfortran lays them out equal the C compiler's;
//! - `minimal_example_runs`: README's example in Fortran, strings, optional
//!   arguments and the monitor and log callbacks (BIND(C) Fortran procedures)
//!   included;
//! - `host_iteration_f90_matches_the_closed_form`: c_examples/host_iteration.f90,
//!   a host's two Newton iterations on one node through ds_solve_iteration (the
//!   slip argument optional), a refactor between them, and a NaN slip refused;
//! - `block2d_f90_matches_the_c_driver`: the Fortran block (1-based CSR of default
//!   INTEGER, upper triangle or full) and c_examples/block2d.c solve the same history
//!   to 1e-12: u, lambda_N and lambda_T of every step.
//!
//! Without gfortran the last four print "SKIPPED: ... needs gfortran" and pass,
//! unless CI=true (then they fail).

mod ctools;

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;
use std::time::Instant;

use ctools::*;

const GFORTRAN_HINT: &str = "apt-get install gfortran";
/// Strict: the module and the examples are Fortran 2003. -ffp-contract=off keeps
/// a*b+c two roundings (as C99), so the Fortran assembly reproduces the C one.
const FFLAGS: [&str; 5] = ["-O2", "-std=f2003", "-Wall", "-ffp-contract=off", "-g"];

fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("read {}: {e}", path.display()))
}

// -------------------------------------------------------------------------------------
// The module against the header (text only)
// -------------------------------------------------------------------------------------

/// The header without its comments.
fn strip_c_comments(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    let mut rest = s;
    while !rest.is_empty() {
        if let Some(tail) = rest.strip_prefix("/*") {
            let end = tail.find("*/").expect("unterminated comment");
            rest = &tail[end + 2..];
        } else if rest.starts_with("//") {
            rest = rest.find('\n').map_or("", |e| &rest[e..]);
        } else {
            let c = rest.chars().next().unwrap();
            out.push(c);
            rest = &rest[c.len_utf8()..];
        }
    }
    out
}

fn is_ident(c: char) -> bool {
    c.is_ascii_alphanumeric() || c == '_'
}

/// (name, number of parameters) of every function the header declares (preprocessor
/// lines, such as the ds_options_default macro, are not declarations).
fn c_functions(h: &str) -> Vec<(String, usize)> {
    let h: String = h
        .lines()
        .filter(|l| !l.trim_start().starts_with('#'))
        .collect::<Vec<_>>()
        .join("\n");
    let h = h.as_str();
    let mut out = Vec::new();
    let mut from = 0;
    while let Some(k) = h[from..].find("ds_") {
        let start = from + k;
        from = start + 3;
        if h[..start].chars().next_back().is_some_and(is_ident) {
            continue;
        }
        let end = start + h[start..].find(|c: char| !is_ident(c)).unwrap_or(0);
        let after = h[end..].trim_start();
        if !after.starts_with('(') {
            continue;
        }
        let close = after.find(')').expect("a ')' after a parameter list");
        let params = after[1..close].trim();
        let n = if params.is_empty() || params == "void" {
            0
        } else {
            params.split(',').count()
        };
        out.push((h[start..end].to_string(), n));
        from = end;
    }
    out
}

/// (name, value) of every enum constant.
fn c_enum_constants(h: &str) -> Vec<(String, i64)> {
    h.lines()
        .map(str::trim)
        .filter(|l| l.starts_with("DS_") && l.contains('='))
        .map(|l| {
            let (name, value) = l.trim_end_matches(',').split_once('=').unwrap();
            let value = value
                .trim()
                .parse()
                .unwrap_or_else(|_| panic!("enum value in {l}"));
            (name.trim().to_string(), value)
        })
        .collect()
}

/// name -> [(C type, field)] of every `typedef struct Name { ... } Name;`.
fn c_structs(h: &str) -> BTreeMap<String, Vec<(String, String)>> {
    let mut out = BTreeMap::new();
    let mut rest = h;
    while let Some(k) = rest.find("typedef struct ") {
        rest = &rest[k + "typedef struct ".len()..];
        let name_end = rest.find(|c: char| !is_ident(c)).unwrap();
        let name = rest[..name_end].to_string();
        let after = rest[name_end..].trim_start();
        if !after.starts_with('{') {
            continue; // the opaque DsProblem
        }
        let body = &after[1..after.find('}').unwrap()];
        let fields = body
            .split(';')
            .map(str::trim)
            .filter(|f| !f.is_empty())
            .map(|f| {
                let f = f.split_whitespace().collect::<Vec<_>>().join(" ");
                let split = f.rfind(|c: char| !is_ident(c)).unwrap();
                (f[..=split].trim().to_string(), f[split + 1..].to_string())
            })
            .collect();
        out.insert(name, fields);
    }
    out
}

/// The interoperable Fortran type of a C field type.
fn fortran_type_of(c_type: &str) -> &'static str {
    if c_type.contains('*') {
        return "type(c_ptr)";
    }
    match c_type {
        "int32_t" | "uint32_t" => "integer(c_int32_t)",
        "int64_t" | "uint64_t" => "integer(c_int64_t)",
        "double" => "real(c_double)",
        "DsHostSolveFn" | "DsHostSolveSingleFn" | "DsHostSolveRowsFn" | "DsHostInverseFn" => {
            "type(c_funptr)"
        }
        other => panic!("no Fortran type known for the C field type {other}"),
    }
}

/// The module's statements: comments removed, continuation lines joined, lower case.
fn fortran_statements(f: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut cur = String::new();
    for line in f.lines() {
        let code = match line.find('!') {
            Some(k) if !line[..k].contains('\'') && !line[..k].contains('"') => &line[..k],
            _ => line,
        };
        let code = code.trim();
        let (code, continued) = match code.strip_suffix('&') {
            Some(c) => (c.trim_end(), true),
            None => (code, false),
        };
        let code = code.strip_prefix('&').unwrap_or(code).trim_start();
        if !cur.is_empty() && !code.is_empty() {
            cur.push(' ');
        }
        cur.push_str(code);
        if !continued {
            if !cur.trim().is_empty() {
                out.push(cur.trim().to_lowercase());
            }
            cur.clear();
        }
    }
    out
}

#[test]
fn module_matches_the_header() {
    let root = manifest_dir();
    let header = strip_c_comments(&read(&root.join("include/dualsplit.h")));
    let stmts = fortran_statements(&read(&root.join("include/dualsplit.f90")));

    // public names
    let public: Vec<String> = stmts
        .iter()
        .filter_map(|s| s.strip_prefix("public ::"))
        .flat_map(|l| l.split(',').map(|n| n.trim().to_string()))
        .collect();

    // functions: a bind(C) interface per C function, same number of arguments, and a
    // public Fortran procedure with the C name
    let functions = c_functions(&header);
    assert!(
        functions.len() >= 11,
        "parsed only {} functions from the header: {functions:?}",
        functions.len()
    );
    let mut problems = Vec::new();
    for (name, n_params) in &functions {
        let tag = format!("bind(c, name=\"{name}\")");
        let Some(stmt) = stmts.iter().find(|s| s.contains(&tag)) else {
            problems.push(format!("{name}: no interface with {tag}"));
            continue;
        };
        let open = stmt.find('(').unwrap();
        let close = open + stmt[open..].find(')').unwrap();
        let args = stmt[open + 1..close].trim();
        let n_args = if args.is_empty() {
            0
        } else {
            args.split(',').count()
        };
        if n_args != *n_params {
            problems.push(format!(
                "{name}: the C function has {n_params} parameters, the interface {n_args}: {stmt}"
            ));
        }
        if !public.iter().any(|p| p == name) {
            problems.push(format!("{name}: no public Fortran procedure of that name"));
        }
    }

    // enum constants
    let constants = c_enum_constants(&header);
    assert!(constants.len() >= 20, "parsed only {constants:?}");
    for (name, value) in &constants {
        let decl = format!(
            "integer(c_int32_t), parameter, public :: {} = {value}",
            name.to_lowercase()
        );
        if !stmts.contains(&decl) {
            problems.push(format!("enum {name} = {value}: no `{decl}`"));
        }
    }

    // structs
    let structs = c_structs(&header);
    for want in ["DsMatrix", "DsOptions", "DsReport", "DsProgress", "DsInfo"] {
        assert!(structs.contains_key(want), "no struct {want} parsed");
    }
    for (name, fields) in &structs {
        let head = format!("type, bind(c), public :: {}", name.to_lowercase());
        let Some(start) = stmts.iter().position(|s| *s == head) else {
            problems.push(format!("struct {name}: no `{head}`"));
            continue;
        };
        let body: Vec<(String, String)> = stmts[start + 1..]
            .iter()
            .take_while(|s| !s.starts_with("end type"))
            .map(|s| {
                let (ty, field) = s.split_once("::").expect("a component declaration");
                // A default initialisation (`= c_null_funptr`) is not C's.
                let field = field.split('=').next().unwrap_or(field);
                (ty.trim().to_string(), field.trim().to_string())
            })
            .collect();
        let want: Vec<(String, String)> = fields
            .iter()
            .map(|(ty, f)| (fortran_type_of(ty).to_string(), f.to_lowercase()))
            .collect();
        if body != want {
            problems.push(format!(
                "struct {name}: the Fortran type has\n    {body:?}\n  the header\n    {want:?}"
            ));
        }
    }

    assert!(
        problems.is_empty(),
        "include/dualsplit.f90 is out of step with include/dualsplit.h:\n  {}",
        problems.join("\n  ")
    );
    println!(
        "module covers {} functions, {} enum constants, {} structs",
        functions.len(),
        constants.len(),
        structs.len()
    );
}

// -------------------------------------------------------------------------------------
// Building with gfortran
// -------------------------------------------------------------------------------------

/// The compiled module (dualsplit.o and dualsplit.mod in one folder), once per run;
/// None without a Fortran compiler.
fn fortran_module() -> Option<&'static (String, PathBuf)> {
    static MODULE: OnceLock<Option<(String, PathBuf)>> = OnceLock::new();
    MODULE
        .get_or_init(|| {
            let fc = fortran_compiler()?;
            let dir = out_dir("fortran");
            let t = Instant::now();
            run_ok(
                Command::new(&fc)
                    .args(FFLAGS)
                    .arg("-pedantic")
                    .arg(format!("-J{}", dir.display()))
                    .arg("-c")
                    .arg(manifest_dir().join("include/dualsplit.f90"))
                    .arg("-o")
                    .arg(dir.join("dualsplit.o")),
                "compiling include/dualsplit.f90",
            );
            println!("module compiled in {:.2} s", t.elapsed().as_secs_f64());
            Some((fc, dir))
        })
        .as_ref()
}

/// How build_fortran links a program.
#[derive(Clone, Copy, PartialEq)]
enum Link {
    /// With the module's object and the library.
    Library,
    /// Alone: the program only uses the module's types and constants.
    TypesOnly,
}

/// Compiles a Fortran program using the module (with `extra_flags` after FFLAGS).
fn build_fortran(
    test: &str,
    source: &Path,
    exe_name: &str,
    extra_flags: &[&str],
    link: Link,
) -> Option<PathBuf> {
    let Some((fc, dir)) = fortran_module() else {
        tool_missing(test, "gfortran", GFORTRAN_HINT);
        return None;
    };
    let exe = dir.join(exe_name);
    let mut cmd = Command::new(fc);
    cmd.args(FFLAGS)
        .args(extra_flags)
        .arg(format!("-J{}", dir.display())) // reads dualsplit.mod, writes any other .mod
        .arg(source);
    if link == Link::Library {
        cmd.arg(dir.join("dualsplit.o"))
            .arg(static_lib())
            .args(SYSTEM_LIBS);
    }
    run_ok(
        cmd.arg("-o").arg(&exe),
        &format!("compiling {}", source.display()),
    );
    Some(exe)
}

/// c_examples/block2d.f90, built once per run for the tests that run it.
fn block2d_f(test: &str) -> Option<&'static Path> {
    static EXE: OnceLock<Option<PathBuf>> = OnceLock::new();
    let exe = EXE.get_or_init(|| {
        fortran_module()?;
        let src = manifest_dir().join("c_examples/block2d.f90");
        build_fortran(test, &src, "block2d_f", &[], Link::Library)
    });
    if exe.is_none() {
        tool_missing(test, "gfortran", GFORTRAN_HINT);
    }
    exe.as_deref()
}

#[test]
fn module_layout_matches_c() {
    let dir = out_dir("fortran_layout");
    let f90 = dir.join("layout.f90");
    std::fs::write(&f90, LAYOUT_F90).unwrap();
    // c_sizeof is Fortran 2008 (the last -std counts)
    let Some(fexe) = build_fortran(
        "fortran::module_layout_matches_c",
        &f90,
        "layout_f",
        &["-std=f2008"],
        Link::TypesOnly,
    ) else {
        return;
    };
    let c_src = dir.join("layout.c");
    std::fs::write(&c_src, LAYOUT_C).unwrap();
    let cexe = dir.join("layout_c");
    run_ok(
        c_compiler()
            .arg("-std=c99")
            .arg("-I")
            .arg(manifest_dir().join("include"))
            .arg(&c_src)
            .arg("-o")
            .arg(&cexe),
        "compiling layout.c",
    );
    let f = stdout_of(&run_ok(&mut Command::new(&fexe), "layout_f"));
    let c = stdout_of(&run_ok(&mut Command::new(&cexe), "layout_c"));
    let norm = |s: &str| -> Vec<String> {
        s.lines()
            .map(|l| l.split_whitespace().collect::<Vec<_>>().join(" "))
            .filter(|l| !l.is_empty())
            .collect()
    };
    println!("C:\n{c}Fortran:\n{f}");
    assert_eq!(
        norm(&f),
        norm(&c),
        "struct layouts differ between gfortran and C"
    );
}

/// Sizes and offsets of the three bind(C) types as gfortran lays them out.
const LAYOUT_F90: &str = r#"program layout
   use dualsplit
   use, intrinsic :: iso_c_binding, only: c_sizeof, c_loc, c_intptr_t
   implicit none
   type(DsMatrix), target :: m
   type(DsOptions), target :: o
   type(DsReport), target :: r
   type(DsProgress), target :: g
   type(DsInfo), target :: i
   type(DsHostSolver), target :: h
   type(DsCost), target :: k
   write (*, '(a,99(1x,i0))') 'DsMatrix', c_sizeof(m), off(c_loc(m), c_loc(m%format)), &
      off(c_loc(m), c_loc(m%index_type)), off(c_loc(m), c_loc(m%base)), &
      off(c_loc(m), c_loc(m%storage)), off(c_loc(m), c_loc(m%nrows)), &
      off(c_loc(m), c_loc(m%ncols)), off(c_loc(m), c_loc(m%nnz)), off(c_loc(m), c_loc(m%p)), &
      off(c_loc(m), c_loc(m%i)), off(c_loc(m), c_loc(m%x))
   write (*, '(a,99(1x,i0))') 'DsOptions', c_sizeof(o), off(c_loc(o), c_loc(o%struct_size)), &
      off(c_loc(o), c_loc(o%method)), off(c_loc(o), c_loc(o%tol)), &
      off(c_loc(o), c_loc(o%max_outer)), off(c_loc(o), c_loc(o%max_inner)), &
      off(c_loc(o), c_loc(o%dual_form)), off(c_loc(o), c_loc(o%max_seconds)), &
      off(c_loc(o), c_loc(o%stall_window)), off(c_loc(o), c_loc(o%stall_factor)), &
      off(c_loc(o), c_loc(o%threads)), off(c_loc(o), c_loc(o%ordering)), &
      off(c_loc(o), c_loc(o%max_memory)), off(c_loc(o), c_loc(o%host_loop))
   write (*, '(a,99(1x,i0))') 'DS_OPTIONS_SIZE', DS_OPTIONS_SIZE
   write (*, '(a,99(1x,i0))') 'DsReport', c_sizeof(r), off(c_loc(r), c_loc(r%status)), &
      off(c_loc(r), c_loc(r%method)), off(c_loc(r), c_loc(r%err)), &
      off(c_loc(r), c_loc(r%equilibrium_residual)), off(c_loc(r), c_loc(r%outer_iterations)), &
      off(c_loc(r), c_loc(r%inner_iterations)), off(c_loc(r), c_loc(r%n_open)), &
      off(c_loc(r), c_loc(r%n_stick)), off(c_loc(r), c_loc(r%n_slip)), &
      off(c_loc(r), c_loc(r%factor_seconds)), off(c_loc(r), c_loc(r%condense_seconds)), &
      off(c_loc(r), c_loc(r%solve_seconds)), off(c_loc(r), c_loc(r%ordering)), &
      off(c_loc(r), c_loc(r%threads)), off(c_loc(r), c_loc(r%factor_nnz)), &
      off(c_loc(r), c_loc(r%factor_flops)), off(c_loc(r), c_loc(r%analyse_seconds)), &
      off(c_loc(r), c_loc(r%memory_predicted)), off(c_loc(r), c_loc(r%memory_peak))
   write (*, '(a,99(1x,i0))') 'DsProgress', c_sizeof(g), off(c_loc(g), c_loc(g%iteration)), &
      off(c_loc(g), c_loc(g%err)), off(c_loc(g), c_loc(g%n_open)), &
      off(c_loc(g), c_loc(g%n_stick)), off(c_loc(g), c_loc(g%n_slip)), &
      off(c_loc(g), c_loc(g%elapsed_seconds))
   write (*, '(a,99(1x,i0))') 'DsInfo', c_sizeof(i), off(c_loc(i), c_loc(i%struct_size)), &
      off(c_loc(i), c_loc(i%d)), off(c_loc(i), c_loc(i%n)), off(c_loc(i), c_loc(i%m)), &
      off(c_loc(i), c_loc(i%c)), off(c_loc(i), c_loc(i%nnz_k)), &
      off(c_loc(i), c_loc(i%factor_nnz)), off(c_loc(i), c_loc(i%factor_flops)), &
      off(c_loc(i), c_loc(i%ordering)), off(c_loc(i), c_loc(i%setup_form)), &
      off(c_loc(i), c_loc(i%method)), off(c_loc(i), c_loc(i%solve_form)), &
      off(c_loc(i), c_loc(i%setup_bytes)), off(c_loc(i), c_loc(i%resident_bytes)), &
      off(c_loc(i), c_loc(i%solve_bytes)), off(c_loc(i), c_loc(i%refactor_bytes)), &
      off(c_loc(i), c_loc(i%memory_limit)), &
      off(c_loc(i), c_loc(i%analyse_seconds)), &
      off(c_loc(i), c_loc(i%compliant_contacts)), off(c_loc(i), c_loc(i%power_law_contacts)), &
      off(c_loc(i), c_loc(i%blocks_age)), off(c_loc(i), c_loc(i%err_factor))
   write (*, '(a,99(1x,i0))') 'DS_INFO_SIZE', DS_INFO_SIZE
   write (*, '(a,99(1x,i0))') 'DsCost', c_sizeof(k), off(c_loc(k), c_loc(k%struct_size)), &
      off(c_loc(k), c_loc(k%solved)), off(c_loc(k), c_loc(k%solve_seconds)), &
      off(c_loc(k), c_loc(k%rhs_seconds)), off(c_loc(k), c_loc(k%iterate_seconds)), &
      off(c_loc(k), c_loc(k%recover_seconds)), off(c_loc(k), c_loc(k%host_solves)), &
      off(c_loc(k), c_loc(k%host_seconds)), off(c_loc(k), c_loc(k%library_seconds))
   write (*, '(a,99(1x,i0))') 'DS_COST_SIZE', DS_COST_SIZE
   write (*, '(a,99(1x,i0))') 'DsHostSolver', c_sizeof(h), off(c_loc(h), c_loc(h%struct_size)), &
      off(c_loc(h), c_loc(h%n)), off(c_loc(h), c_loc(h%solve)), off(c_loc(h), c_loc(h%context)), &
      off(c_loc(h), c_loc(h%inverse_entries)), off(c_loc(h), c_loc(h%solve_single)), &
      off(c_loc(h), c_loc(h%solve_rows)), off(c_loc(h), c_loc(h%blocks))
   write (*, '(a,99(1x,i0))') 'DS_HOST_SOLVER_SIZE', DS_HOST_SOLVER_SIZE
contains
   integer function off(base, field)
      type(c_ptr), intent(in) :: base, field
      off = int(transfer(field, 0_c_intptr_t) - transfer(base, 0_c_intptr_t))
   end function off
end program layout
"#;

const LAYOUT_C: &str = r#"#include <stddef.h>
#include <stdio.h>
#include "dualsplit.h"
#define O(T, f) (int)offsetof(T, f)
int main(void)
{
    printf("DsMatrix %d %d %d %d %d %d %d %d %d %d %d\n", (int)sizeof(DsMatrix),
           O(DsMatrix, format), O(DsMatrix, index_type), O(DsMatrix, base), O(DsMatrix, storage),
           O(DsMatrix, nrows), O(DsMatrix, ncols), O(DsMatrix, nnz), O(DsMatrix, p),
           O(DsMatrix, i), O(DsMatrix, x));
    printf("DsOptions %d %d %d %d %d %d %d %d %d %d %d %d %d %d\n", (int)sizeof(DsOptions),
           O(DsOptions, struct_size), O(DsOptions, method), O(DsOptions, tol),
           O(DsOptions, max_outer), O(DsOptions, max_inner), O(DsOptions, dual_form),
           O(DsOptions, max_seconds), O(DsOptions, stall_window), O(DsOptions, stall_factor),
           O(DsOptions, threads), O(DsOptions, ordering), O(DsOptions, max_memory),
           O(DsOptions, host_loop));
    printf("DS_OPTIONS_SIZE %d\n", (int)sizeof(DsOptions));
    printf("DsReport %d %d %d %d %d %d %d %d %d %d %d %d %d %d %d %d %d %d %d %d\n", (int)sizeof(DsReport),
           O(DsReport, status), O(DsReport, method), O(DsReport, err),
           O(DsReport, equilibrium_residual), O(DsReport, outer_iterations),
           O(DsReport, inner_iterations), O(DsReport, n_open), O(DsReport, n_stick),
           O(DsReport, n_slip), O(DsReport, factor_seconds), O(DsReport, condense_seconds),
           O(DsReport, solve_seconds), O(DsReport, ordering), O(DsReport, threads),
           O(DsReport, factor_nnz), O(DsReport, factor_flops), O(DsReport, analyse_seconds),
           O(DsReport, memory_predicted), O(DsReport, memory_peak));
    printf("DsProgress %d %d %d %d %d %d %d\n", (int)sizeof(DsProgress),
           O(DsProgress, iteration), O(DsProgress, err), O(DsProgress, n_open),
           O(DsProgress, n_stick), O(DsProgress, n_slip), O(DsProgress, elapsed_seconds));
    printf("DsInfo %d %d %d %d %d %d %d %d %d %d %d %d %d %d %d %d %d %d %d %d %d %d %d\n", (int)sizeof(DsInfo),
           O(DsInfo, struct_size), O(DsInfo, d), O(DsInfo, n), O(DsInfo, m), O(DsInfo, c),
           O(DsInfo, nnz_k), O(DsInfo, factor_nnz), O(DsInfo, factor_flops),
           O(DsInfo, ordering), O(DsInfo, setup_form), O(DsInfo, method),
           O(DsInfo, solve_form), O(DsInfo, setup_bytes), O(DsInfo, resident_bytes),
           O(DsInfo, solve_bytes), O(DsInfo, refactor_bytes), O(DsInfo, memory_limit),
           O(DsInfo, analyse_seconds), O(DsInfo, compliant_contacts),
           O(DsInfo, power_law_contacts), O(DsInfo, blocks_age), O(DsInfo, err_factor));
    printf("DS_INFO_SIZE %d\n", (int)sizeof(DsInfo));
    printf("DsCost %d %d %d %d %d %d %d %d %d %d\n", (int)sizeof(DsCost),
           O(DsCost, struct_size), O(DsCost, solved), O(DsCost, solve_seconds),
           O(DsCost, rhs_seconds), O(DsCost, iterate_seconds), O(DsCost, recover_seconds),
           O(DsCost, host_solves), O(DsCost, host_seconds), O(DsCost, library_seconds));
    printf("DS_COST_SIZE %d\n", (int)sizeof(DsCost));
    printf("DsHostSolver %d %d %d %d %d %d %d %d %d\n", (int)sizeof(DsHostSolver),
           O(DsHostSolver, struct_size), O(DsHostSolver, n), O(DsHostSolver, solve),
           O(DsHostSolver, context), O(DsHostSolver, inverse_entries),
           O(DsHostSolver, solve_single), O(DsHostSolver, solve_rows),
           O(DsHostSolver, blocks));
    printf("DS_HOST_SOLVER_SIZE %d\n", (int)sizeof(DsHostSolver));
    return 0;
}
"#;

/// c_examples/host_solver.f90: the library on a Fortran BIND(C) callback's
/// solves of K gives the hand-derived answer (lambda_N = 8, lambda_T = 0.4,
/// u = (0.3, -0.5)), a callback returning 5 gives DS_STATUS_HOST_SOLVE_FAILED
/// (16) with the code in the message and the outputs untouched, the same
/// handle solves again, and with the solve on rows (DsHostSolver%solve_rows)
/// a new handle gives the same answer.
#[test]
fn host_solver_example_runs() {
    let src = manifest_dir().join("c_examples/host_solver.f90");
    let Some(exe) = build_fortran(
        "fortran::host_solver_example_runs",
        &src,
        "host_solver_f",
        &[],
        Link::Library,
    ) else {
        return;
    };
    let stdout = stdout_of(&run_ok(&mut Command::new(&exe), "host_solver_f"));
    println!("{stdout}");
    assert!(stdout.contains("host_solver_f: ok"), "{stdout}");
    let result: Vec<f64> = stdout
        .lines()
        .find_map(|l| l.strip_prefix("RESULT"))
        .expect("a RESULT line")
        .split_whitespace()
        .map(|t| t.parse().expect("a number"))
        .collect();
    for (k, w) in [8.0, 0.4, 0.3, -0.5].iter().enumerate() {
        assert!(
            (result[k] - w).abs() <= 1e-12,
            "RESULT[{k}] = {}",
            result[k]
        );
    }
    let failed = stdout
        .lines()
        .find_map(|l| l.strip_prefix("FAILED "))
        .expect("a FAILED line");
    assert!(
        failed.starts_with("16 ") && failed.contains("code 5"),
        "{failed}"
    );
    assert!(
        stdout.lines().any(|l| l.starts_with("AGAIN 0 ")),
        "{stdout}"
    );
    // ds_problem_last_cost through the module: OK, the host's right-hand
    // sides as the callback counted them (the program checks the equality).
    let cost: Vec<&str> = stdout
        .lines()
        .find_map(|l| l.strip_prefix("COST "))
        .expect("a COST line")
        .split_whitespace()
        .collect();
    assert_eq!(cost[0], "0", "{stdout}");
    assert_eq!(cost[1], cost[2], "{stdout}");
    // The solve on rows through the module: OK, called (the program checks
    // the answer against the hand-derived one).
    let rows: Vec<&str> = stdout
        .lines()
        .find_map(|l| l.strip_prefix("ROWS "))
        .expect("a ROWS line")
        .split_whitespace()
        .collect();
    assert_eq!(rows[0], "0", "{stdout}");
    assert!(rows[1].parse::<i64>().unwrap() > 0, "{stdout}");
}

#[test]
fn host_iteration_f90_matches_the_closed_form() {
    let src = manifest_dir().join("c_examples/host_iteration.f90");
    let Some(exe) = build_fortran(
        "fortran::host_iteration_f90_matches_the_closed_form",
        &src,
        "host_iteration_f",
        &[],
        Link::Library,
    ) else {
        return;
    };
    let stdout = stdout_of(&run_ok(&mut Command::new(&exe), "host_iteration_f"));
    println!("{stdout}");
    assert!(stdout.contains("host_iteration_f: ok"), "{stdout}");
    let rows: Vec<Vec<f64>> = stdout
        .lines()
        .filter_map(|l| l.strip_prefix("ITERATION"))
        .map(|l| l.split_whitespace().map(|t| t.parse().unwrap()).collect())
        .collect();
    // du_x, du_y, lambda_N, lambda_T, open, stick, slip (the file's closed form).
    let want = [
        [3.0, 0.0, 8.0, 4.0, 0.0, 0.0, 1.0],
        [-3.0, 0.0, 8.0, 2.5, 0.0, 1.0, 0.0],
    ];
    assert_eq!(rows.len(), 2, "{stdout}");
    for (got, want) in rows.iter().zip(&want) {
        assert_eq!(got.len(), want.len(), "{stdout}");
        for (g, w) in got.iter().zip(want) {
            assert!((g - w).abs() <= 1e-9, "{got:?} against {want:?}");
        }
    }
    assert!(stdout.lines().any(|l| l == "NAN_SLIP 4"), "{stdout}");
}

#[test]
fn minimal_example_runs() {
    let src = manifest_dir().join("c_examples/minimal.f90");
    let Some(exe) = build_fortran(
        "fortran::minimal_example_runs",
        &src,
        "minimal_f",
        &[],
        Link::Library,
    ) else {
        return;
    };
    let stdout = stdout_of(&run_ok(&mut Command::new(&exe), "minimal_f"));
    println!("{stdout}");
    assert!(stdout.contains("minimal_f: ok"), "{stdout}");
    assert!(stdout.lines().any(|l| l == "SIZES 2 1 2"), "{stdout}");
    // ds_analyse and ds_problem_info through the module; the report's memory.
    assert!(stdout.lines().any(|l| l == "INFO 2 2 1"), "{stdout}");
    assert!(stdout.lines().any(|l| l == "MEMORY 1"), "{stdout}");
    let result: Vec<f64> = stdout
        .lines()
        .find_map(|l| l.strip_prefix("RESULT"))
        .expect("a RESULT line")
        .split_whitespace()
        .map(|t| t.parse().expect("a number"))
        .collect();
    let want = [8.0, 0.4, 0.3, -0.5];
    for (k, w) in want.iter().enumerate() {
        assert!(
            (result[k] - w).abs() <= 1e-12,
            "RESULT[{k}] = {} != {w}",
            result[k]
        );
    }
    assert_eq!(&result[5..], &[0.0, 0.0, 1.0], "open/stick/slip counts");
    // the Fortran monitor ran once per outer iteration, the log sink got both levels,
    // and a monitor returning nonzero stopped the solve
    let monitor: Vec<&str> = stdout
        .lines()
        .find_map(|l| l.strip_prefix("MONITOR "))
        .expect("a MONITOR line")
        .split_whitespace()
        .collect();
    assert!(
        monitor.len() == 2 && monitor[0] == monitor[1] && monitor[0] != "0",
        "monitor calls vs outer iterations: {monitor:?}"
    );
    assert!(stdout.lines().any(|l| l.starts_with("LOG 1 ")), "{stdout}");
    assert!(stdout.lines().any(|l| l.starts_with("LOG 2 ")), "{stdout}");
    assert!(
        stdout.lines().any(|l| l.starts_with("STOP 13 ")),
        "{stdout}"
    );
    let error = stdout
        .lines()
        .find(|l| l.starts_with("ERROR"))
        .expect("an ERROR line");
    assert!(
        error.starts_with("ERROR 3 ") && error.contains("column index 3"),
        "the Fortran strings of a rejected K: {error}"
    );
}

// -------------------------------------------------------------------------------------
// block2d.f90 against block2d.c
// -------------------------------------------------------------------------------------

/// Compiled into c_examples/block2d.c with -Dds_step=dslog_ds_step: every ds_step of
/// the unmodified C driver passes through here, and its results go to
/// $DUALSPLIT_STEP_LOG in the format of block2d.f90's --dump, with 17 digits.
const STEP_LOG_C: &str = r#"#include <stdio.h>
#include <stdlib.h>
#include "dualsplit.h"

enum DsStatus dslog_ds_step(struct DsProblem *problem, const struct DsOptions *opts,
                            int32_t friction, const double *f_total, const double *g0,
                            const double *bound, double *u, double *lambda_n,
                            double *lambda_t, struct DsReport *report)
{
    static FILE *log = NULL;
    static long step = 0;
    int64_t n = 0, m = 0, k;
    int32_t d = 2;
    enum DsStatus st;
    if (log == NULL) {
        const char *path = getenv("DUALSPLIT_STEP_LOG");
        log = fopen(path != NULL ? path : "ds_step.log", "w");
        if (log == NULL) {
            perror("dslog_ds_step: open the log");
            exit(9);
        }
    }
    /* before ds_step, which sets the last error message the driver may print */
    ds_problem_sizes(problem, &n, &m, &d);
    st = ds_step(problem, opts, friction, f_total, g0, bound, u, lambda_n, lambda_t, report);
    step++;
    fprintf(log, "step %ld %d %lld %lld %lld %lld\n", step, (int)st,
            (long long)(report ? report->n_open : 0), (long long)(report ? report->n_stick : 0),
            (long long)(report ? report->n_slip : 0),
            (long long)(report ? report->outer_iterations : 0));
    if (st == DS_STATUS_OK) {
        for (k = 0; k < n; k++) fprintf(log, "u %ld %lld %.16e\n", step, (long long)k + 1, u[k]);
        for (k = 0; k < m; k++)
            fprintf(log, "ln %ld %lld %.16e\n", step, (long long)k + 1, lambda_n[k]);
        for (k = 0; k < (d - 1) * m; k++)
            fprintf(log, "lt %ld %lld %.16e\n", step, (long long)k + 1, lambda_t[k]);
    }
    fflush(log);
    return st;
}
"#;

/// c_examples/block2d.c, unmodified, with its ds_step calls logged.
fn c_driver_with_log() -> &'static Path {
    static EXE: OnceLock<PathBuf> = OnceLock::new();
    EXE.get_or_init(|| {
        let root = manifest_dir();
        let dir = out_dir("fortran_c_driver");
        let shim = dir.join("step_log.c");
        std::fs::write(&shim, STEP_LOG_C).unwrap();
        let obj = dir.join("block2d.o");
        run_ok(
            c_compiler()
                .args([
                    "-std=c99",
                    "-Wall",
                    "-Wextra",
                    "-Dds_step=dslog_ds_step",
                    "-c",
                ])
                .arg("-I")
                .arg(root.join("include"))
                .arg(root.join("c_examples/block2d.c"))
                .arg("-o")
                .arg(&obj),
            "compiling c_examples/block2d.c",
        );
        let exe = dir.join("block2d_logged");
        run_ok(
            c_compiler()
                .args(["-std=c99", "-Wall", "-Wextra"])
                .arg("-I")
                .arg(root.join("include"))
                .arg(&obj)
                .arg(&shim)
                .arg(static_lib())
                .args(SYSTEM_LIBS)
                .arg("-o")
                .arg(&exe),
            "linking block2d with the step log",
        );
        exe
    })
}

/// One step of a dump: status, counts, and the vectors.
#[derive(Debug, Default, Clone, PartialEq)]
struct StepDump {
    status: i64,
    counts: [i64; 3],
    outer: i64,
    u: Vec<f64>,
    ln: Vec<f64>,
    lt: Vec<f64>,
}

fn parse_dump(text: &str) -> BTreeMap<usize, StepDump> {
    let mut steps: BTreeMap<usize, StepDump> = BTreeMap::new();
    for line in text.lines() {
        let tok: Vec<&str> = line.split_whitespace().collect();
        if tok.is_empty() {
            continue;
        }
        let int = |k: usize| -> i64 {
            tok[k]
                .parse()
                .unwrap_or_else(|_| panic!("bad integer {} in: {line}", tok[k]))
        };
        let step = int(1) as usize;
        let s = steps.entry(step).or_default();
        match tok[0] {
            "step" => {
                s.status = int(2);
                s.counts = [int(3), int(4), int(5)];
                s.outer = int(6);
            }
            "u" | "ln" | "lt" => {
                let idx = int(2) as usize;
                let v: f64 = tok[3]
                    .parse()
                    .unwrap_or_else(|_| panic!("bad value {} in: {line}", tok[3]));
                let vec = match tok[0] {
                    "u" => &mut s.u,
                    "ln" => &mut s.ln,
                    _ => &mut s.lt,
                };
                assert_eq!(vec.len() + 1, idx, "indices in order: {line}");
                vec.push(v);
            }
            other => panic!("unknown dump line {other}: {line}"),
        }
    }
    steps
}

fn summary(stdout: &str) -> HashMap<String, String> {
    stdout
        .lines()
        .find_map(|l| l.strip_prefix("SUMMARY "))
        .unwrap_or_else(|| panic!("no SUMMARY line in:\n{stdout}"))
        .split_whitespace()
        .filter_map(|kv| kv.split_once('='))
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect()
}

fn max_abs(v: &[f64]) -> f64 {
    v.iter().fold(0.0f64, |m, x| m.max(x.abs()))
}

fn max_diff(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()))
}

/// Relative differences of one Fortran run against the C run.
struct Agreement {
    u: f64,
    forces: f64,
    bitwise: bool,
    count_mismatches: Vec<usize>,
}

/// Compares two dumps: u relative to the largest |u| of the history, the multipliers
/// relative to the largest contact force of the history. Contact counts are compared
/// at every step where no contact force is at rounding level (0 < lambda_N,i <=
/// 1e-9 max|lambda|: the state of such a contact is decided by rounding).
fn compare(c: &BTreeMap<usize, StepDump>, f: &BTreeMap<usize, StepDump>, what: &str) -> Agreement {
    assert_eq!(
        c.keys().collect::<Vec<_>>(),
        f.keys().collect::<Vec<_>>(),
        "{what}: the same steps"
    );
    let u_scale = c.values().map(|s| max_abs(&s.u)).fold(0.0, f64::max);
    let force_scale = c
        .values()
        .map(|s| max_abs(&s.ln).max(max_abs(&s.lt)))
        .fold(0.0, f64::max);
    assert!(
        u_scale > 0.0 && force_scale > 0.0,
        "{what}: a history with loads"
    );
    let mut agreement = Agreement {
        u: 0.0,
        forces: 0.0,
        bitwise: true,
        count_mismatches: Vec::new(),
    };
    for (step, cs) in c {
        let fs = &f[step];
        assert_eq!(cs.status, fs.status, "{what}: step {step}: status");
        assert_eq!(cs.u.len(), fs.u.len(), "{what}: step {step}: length of u");
        assert_eq!(
            cs.ln.len(),
            fs.ln.len(),
            "{what}: step {step}: number of contacts"
        );
        agreement.u = agreement.u.max(max_diff(&cs.u, &fs.u) / u_scale);
        agreement.forces = agreement
            .forces
            .max(max_diff(&cs.ln, &fs.ln) / force_scale)
            .max(max_diff(&cs.lt, &fs.lt) / force_scale);
        agreement.bitwise &= cs.u == fs.u && cs.ln == fs.ln && cs.lt == fs.lt;
        let degenerate = cs
            .ln
            .iter()
            .chain(&fs.ln)
            .any(|&l| l > 0.0 && l <= 1e-9 * force_scale);
        if cs.counts != fs.counts {
            assert!(
                degenerate,
                "{what}: step {step}: open/stick/slip {:?} (C) vs {:?} (Fortran)",
                cs.counts, fs.counts
            );
            agreement.count_mismatches.push(*step);
        }
    }
    agreement
}

fn run_with_dump(exe: &Path, args: &[&str], dump: &Path, c_log: bool) -> (String, String) {
    let _ = std::fs::remove_file(dump);
    let mut cmd = Command::new(exe);
    cmd.args(args);
    if c_log {
        cmd.env("DUALSPLIT_STEP_LOG", dump);
    } else {
        cmd.arg("--dump").arg(dump);
    }
    let stdout = stdout_of(&run_ok(&mut cmd, &format!("{} {args:?}", exe.display())));
    (stdout, read(dump))
}

#[test]
fn block2d_f90_matches_the_c_driver() {
    let test = "fortran::block2d_f90_matches_the_c_driver";
    let t0 = Instant::now();
    let Some(fexe) = block2d_f(test) else {
        return;
    };
    let cexe = c_driver_with_log();
    println!("built both drivers in {:.2} s", t0.elapsed().as_secs_f64());
    let dir = out_dir("fortran_block2d");

    // The demo's scene on the small mesh of tests/c_demo.rs, and a second parameter
    // set (another method, mesh, material, friction and foundation).
    let scenes: [&[&str]; 2] = [
        &["--nx", "16", "--ny", "8"],
        &[
            "--nx", "12", "--ny", "6", "--method", "pgs", "--E", "2.5e5", "--nu", "0.25", "--mu",
            "0.5", "--curved", "0.08", "--W", "3", "--H", "1.2", "--uy", "-0.04", "--ux", "0.06",
        ],
    ];
    let mut report = Vec::new();
    for (k, scene) in scenes.iter().enumerate() {
        let t = Instant::now();
        let (c_out, c_dump) = run_with_dump(cexe, scene, &dir.join(format!("c{k}.txt")), true);
        let c_steps = parse_dump(&c_dump);
        let c_sum = summary(&c_out);
        assert_eq!(c_sum["all_converged"], "1", "C driver, scene {k}:\n{c_out}");
        for storage in ["full", "upper"] {
            let mut args: Vec<&str> = scene.to_vec();
            args.extend(["--storage", storage]);
            let dump = dir.join(format!("f{k}_{storage}.txt"));
            let (f_out, f_dump) = run_with_dump(fexe, &args, &dump, false);
            println!("---- block2d_f {args:?}\n{f_out}");
            let f_sum = summary(&f_out);
            for key in [
                "method",
                "steps",
                "contacts",
                "dofs",
                "all_converged",
                "resultant_ok",
            ] {
                assert_eq!(
                    f_sum[key], c_sum[key],
                    "scene {k}, {storage}: SUMMARY {key}: Fortran vs C"
                );
            }
            assert!(f_out.contains("resultant check: ok"), "{f_out}");
            let a = compare(
                &c_steps,
                &parse_dump(&f_dump),
                &format!("scene {k}, {storage}"),
            );
            let line = format!(
                "scene {k} ({} steps), K {storage:5}: max |u_F - u_C| / max|u| = {:.3e}, \
                 max |lambda_F - lambda_C| / max|lambda| = {:.3e}, bitwise identical: {}, \
                 count differences at rounding-level steps: {:?}",
                c_steps.len(),
                a.u,
                a.forces,
                a.bitwise,
                a.count_mismatches
            );
            println!("{line}");
            assert!(
                a.u <= 1e-12 && a.forces <= 1e-12,
                "Fortran and C results differ by more than 1e-12: {line}"
            );
            if storage == "full" {
                // The same K, f, g entries in the same order: the same numbers.
                assert!(
                    a.count_mismatches.is_empty(),
                    "full storage: the contact states must agree at every step: {line}"
                );
            }
            report.push(line);
        }
        println!("scene {k}: {:.2} s", t.elapsed().as_secs_f64());
    }
    eprintln!("{}", report.join("\n"));
}

#[test]
fn block2d_f90_rejects_bad_options() {
    let Some(exe) = block2d_f("fortran::block2d_f90_rejects_bad_options") else {
        return;
    };
    for args in [
        &["--method", "simplex"][..],
        &["--nx", "0"][..],
        &["--storage", "lower"][..],
        &["--bogus", "1"][..],
        &["--nx"][..],
    ] {
        let out = Command::new(exe)
            .args(args)
            .output()
            .expect("run block2d_f");
        assert_eq!(
            out.status.code(),
            Some(3),
            "block2d_f {args:?} should exit with 3"
        );
    }
}

/// `ds_matrix_dense` (the Schur-complement workflow): a dense K in a
/// padded array, one triangle read, gives the COO answer and DS_ORDERING_DENSE.
#[test]
fn dense_k_through_the_module() {
    let src = manifest_dir().join("tests/data/fortran/dense_k.f90");
    let Some(exe) = build_fortran(
        "fortran::dense_k_through_the_module",
        &src,
        "dense_k_f",
        &[],
        Link::Library,
    ) else {
        return;
    };
    let stdout = stdout_of(&run_ok(&mut Command::new(&exe), "dense_k_f"));
    println!("{stdout}");
    let field = |key: &str| -> Vec<f64> {
        stdout
            .lines()
            .find_map(|l| l.strip_prefix(key))
            .unwrap_or_else(|| panic!("no {key} line:\n{stdout}"))
            .split_whitespace()
            .map(|t| t.parse().expect("a number"))
            .collect()
    };
    assert_eq!(field("ORDERING "), [3.0], "DS_ORDERING_DENSE");
    assert!(field("DIFF ").iter().all(|&d| d <= 1e-14), "{stdout}");
    // Closed form: the node closes (u_y = 0) and slips: lambda_T = p = 0.3,
    // 4 u_x = 0.5 - 0.3 (u_y = 0), lambda_N = 2 + (K u)_y = 2 + u_x.
    let r = field("DENSE ");
    let want = [0.05, 0.0, 2.05, 0.3];
    for (k, w) in want.iter().enumerate() {
        assert!((r[k] - w).abs() <= 1e-12, "DENSE[{k}] = {} != {w}", r[k]);
    }
}
