//! `make install` into a temporary prefix, then the library used the way a C or
//! Fortran code uses an installed library:
//!
//! - the files: lib/libdualsplit.so.<version> with soname libdualsplit.so.<major>
//!   and the two links, lib/libdualsplit.a, include/dualsplit.h,
//!   include/dualsplit.f90, lib/pkgconfig/dualsplit.pc;
//! - a C program (README's minimal example) compiled with
//!   `pkg-config --cflags --libs dualsplit`, which must record libdualsplit.so.<major>
//!   (the soname) as its dependency and run with LD_LIBRARY_PATH=<prefix>/lib;
//! - the same program linked with the installed static library;
//! - the Fortran module source compiled from the prefix with c_examples/minimal.f90
//!   (gfortran) and linked through pkg-config;
//! - lib/cmake/dualsplit/dualsplitConfig.cmake and its version file:
//!   `find_package(dualsplit <this major.minor> REQUIRED)` and `dualsplit::dualsplit` build and run
//!   a C program, and a request for another minor version is refused (0.x);
//! - README's CMake snippet (pkg-config from CMake);
//! - `make demo` with CARGO_TARGET_DIR set: the Makefile links the library cargo
//!   built there and puts the demo under it.
//!
//! The CMake checks need cmake: without it they print "SKIPPED: ..." unless
//! CI=true (.ci/run installs it).
//!
//! `make install` runs `cargo rustc --release` from inside `cargo test`. To stay
//! clear of the build lock and of the files of the running test build, it builds in
//! its own target folder, target/tmp/install-build (kept between runs: the first
//! run pays one release build of the dependencies, a few minutes on 2 cores; later
//! runs rebuild only what changed).
//!
//! Needs make, pkg-config and a C compiler: without make or pkg-config the test
//! prints "SKIPPED: ..." and passes, unless CI=true (then it fails).

mod ctools;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use ctools::*;

const VERSION: &str = env!("CARGO_PKG_VERSION");

fn major() -> &'static str {
    VERSION.split('.').next().unwrap()
}

/// README's minimal example: one node pressed onto the foundation, Tresca friction.
const CONSUMER_C: &str = r#"#include "dualsplit.h"
#include <stdio.h>

int main(void) {
    int32_t kp[] = {0, 1, 2}, ki[] = {0, 1};   double kx[] = {2.0, 4.0};
    int32_t np[] = {0, 0, 1}, ni[] = {0};      double nx[] = {-1.0};
    int32_t tp[] = {0, 1, 1}, ti[] = {0};      double tx[] = {1.0};
    DsMatrix K = {DS_FORMAT_CSC, DS_INDEX_TYPE_I32, 0, DS_STORAGE_FULL, 2, 2, 0, kp, ki, kx};
    DsMatrix N = {DS_FORMAT_CSC, DS_INDEX_TYPE_I32, 0, DS_STORAGE_FULL, 1, 2, 0, np, ni, nx};
    DsMatrix T = {DS_FORMAT_CSC, DS_INDEX_TYPE_I32, 0, DS_STORAGE_FULL, 1, 2, 0, tp, ti, tx};
    DsProblem *pb = NULL;
    if (ds_problem_new(2, &K, &N, &T, &pb) != DS_STATUS_OK) {
        fprintf(stderr, "%s\n", ds_last_error_message());
        return 1;
    }
    DsOptions opts; ds_options_default(&opts);
    double f[] = {1.0, -10.0}, g[] = {0.5}, p[] = {0.4};
    double u[2], ln[1], lt[1]; DsReport rep;
    DsStatus s = ds_solve(pb, &opts, DS_FRICTION_TRESCA, f, g, p, u, ln, lt, &rep);
    if (s == DS_STATUS_OK)
        printf("lambda_N %.12g lambda_T %.12g u %.12g %.12g\n", ln[0], lt[0], u[0], u[1]);
    ds_problem_free(pb);
    return s == DS_STATUS_OK ? 0 : 1;
}
"#;

fn check_consumer_output(stdout: &str, what: &str) {
    assert_eq!(
        stdout.trim(),
        "lambda_N 8 lambda_T 0.4 u 0.3 -0.5",
        "{what}: unexpected output"
    );
}

fn pkg_config(prefix: &Path, args: &[&str]) -> String {
    let out = run_ok(
        Command::new("pkg-config")
            .args(args)
            .arg("dualsplit")
            .env("PKG_CONFIG_PATH", prefix.join("lib/pkgconfig")),
        &format!("pkg-config {args:?} dualsplit"),
    );
    stdout_of(&out).trim().to_string()
}

fn words(s: &str) -> Vec<String> {
    s.split_whitespace().map(String::from).collect()
}

#[test]
fn make_install_then_build_with_pkg_config() {
    let test = "install::make_install_then_build_with_pkg_config";
    if !have_program("make") {
        return tool_missing(test, "make", "apt-get install make");
    }
    if !have_program("pkg-config") {
        return tool_missing(test, "pkg-config", "apt-get install pkg-config");
    }
    let root = manifest_dir();
    let work = out_dir("install");
    let prefix = work.join("prefix");
    let _ = std::fs::remove_dir_all(&prefix);
    let build_dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("install-build");

    // ---- make install -------------------------------------------------------------
    let t = Instant::now();
    run_ok(
        Command::new("make")
            .arg("install")
            .arg(format!("PREFIX={}", prefix.display()))
            .env("CARGO_TARGET_DIR", &build_dir)
            .env_remove("MAKEFLAGS")
            .env_remove("MFLAGS")
            .current_dir(&root),
        "make install",
    );
    let install_s = t.elapsed().as_secs_f64();

    let lib = prefix.join("lib");
    let real = format!("libdualsplit.so.{VERSION}");
    let soname = format!("libdualsplit.so.{}", major());
    for f in [
        lib.join(&real),
        lib.join("libdualsplit.a"),
        prefix.join("include/dualsplit.h"),
        prefix.join("include/dualsplit.f90"),
        lib.join("pkgconfig/dualsplit.pc"),
        lib.join("cmake/dualsplit/dualsplitConfig.cmake"),
        lib.join("cmake/dualsplit/dualsplitConfigVersion.cmake"),
    ] {
        assert!(f.is_file(), "make install did not install {}", f.display());
    }
    assert_eq!(
        std::fs::read_link(lib.join(&soname))
            .expect("the soname link")
            .to_str(),
        Some(real.as_str())
    );
    assert_eq!(
        std::fs::read_link(lib.join("libdualsplit.so"))
            .expect("the development link")
            .to_str(),
        Some(soname.as_str())
    );
    assert_eq!(
        std::fs::read(prefix.join("include/dualsplit.h")).unwrap(),
        std::fs::read(root.join("include/dualsplit.h")).unwrap()
    );
    match readelf_dynamic(&lib.join(&real)) {
        Some(d) => assert_eq!(
            dynamic_entries(&d, "SONAME"),
            std::slice::from_ref(&soname),
            "the soname of the installed shared library:\n{d}"
        ),
        None => eprintln!("note: readelf not found, the soname is checked through the consumer"),
    }

    // ---- pkg-config ---------------------------------------------------------------
    assert_eq!(pkg_config(&prefix, &["--modversion"]), VERSION);
    let flags = pkg_config(&prefix, &["--cflags", "--libs"]);
    println!("pkg-config --cflags --libs dualsplit: {flags}");
    assert!(flags.contains(&format!("-I{}", prefix.join("include").display())));
    assert!(flags.contains("-ldualsplit"));

    // ---- a C consumer through pkg-config, shared library ------------------------------
    let src = work.join("consumer.c");
    std::fs::write(&src, CONSUMER_C).unwrap();
    let exe = work.join("consumer_shared");
    let cc = c_compiler_path();
    run_ok(
        Command::new(&cc)
            .arg(&src)
            .args(words(&flags))
            .arg("-o")
            .arg(&exe),
        "cc consumer.c $(pkg-config --cflags --libs dualsplit)",
    );
    if let Some(d) = readelf_dynamic(&exe) {
        let needed = dynamic_entries(&d, "NEEDED");
        assert!(
            needed.contains(&soname),
            "the consumer must depend on the soname {soname}, not on the file it linked: {needed:?}"
        );
    }
    let out = run_ok(
        Command::new(&exe).env("LD_LIBRARY_PATH", &lib),
        "the pkg-config consumer",
    );
    check_consumer_output(&stdout_of(&out), "shared");

    // ---- the same program with the installed static library ---------------------------
    let exe_static = work.join("consumer_static");
    run_ok(
        Command::new(&cc)
            .arg(&src)
            .arg(format!("-I{}", prefix.join("include").display()))
            .arg(lib.join("libdualsplit.a"))
            .args(SYSTEM_LIBS)
            .arg("-o")
            .arg(&exe_static),
        "cc consumer.c libdualsplit.a",
    );
    check_consumer_output(
        &stdout_of(&run_ok(
            &mut Command::new(&exe_static),
            "the static consumer",
        )),
        "static",
    );

    // ---- the installed Fortran module source ------------------------------------------
    match fortran_compiler() {
        None => tool_missing(
            test,
            "gfortran (for the Fortran part)",
            "apt-get install gfortran",
        ),
        Some(fc) => {
            let fdir = work.join("fortran");
            std::fs::create_dir_all(&fdir).unwrap();
            run_ok(
                Command::new(&fc)
                    .arg(format!("-J{}", fdir.display()))
                    .arg("-c")
                    .arg(prefix.join("include/dualsplit.f90"))
                    .arg("-o")
                    .arg(fdir.join("dualsplit.o")),
                "gfortran -c <prefix>/include/dualsplit.f90",
            );
            let fexe = fdir.join("minimal_f");
            run_ok(
                Command::new(&fc)
                    .arg(format!("-J{}", fdir.display()))
                    .arg(root.join("c_examples/minimal.f90"))
                    .arg(fdir.join("dualsplit.o"))
                    .args(words(&pkg_config(&prefix, &["--libs"])))
                    .arg("-o")
                    .arg(&fexe),
                "gfortran minimal.f90 $(pkg-config --libs dualsplit)",
            );
            let out = run_ok(
                Command::new(&fexe).env("LD_LIBRARY_PATH", &lib),
                "minimal_f against the installed library",
            );
            assert!(stdout_of(&out).contains("minimal_f: ok"));
        }
    }

    // ---- CMake: the installed package, and README's snippet ------------------------
    if have_program("cmake") {
        cmake_package(&prefix, &work);
        cmake_snippet(&prefix, &work);
    } else {
        tool_missing(test, "cmake", "apt-get install cmake");
    }

    // ---- make demo with CARGO_TARGET_DIR ---------------------------------------------
    let out = run_ok(
        Command::new("make")
            .arg("demo")
            .arg("DEMO_ARGS=--nx 16 --ny 8")
            .env("CARGO_TARGET_DIR", &build_dir)
            .env_remove("MAKEFLAGS")
            .env_remove("MFLAGS")
            .current_dir(&root),
        "make demo with CARGO_TARGET_DIR",
    );
    let demo = build_dir.join("c_examples/block2d");
    assert!(demo.is_file(), "make demo did not build {}", demo.display());
    let text = stdout_of(&out);
    assert!(text.contains("all_converged=1"), "{text}");

    eprintln!(
        "make install took {install_s:.1} s (build folder {}); whole test {:.1} s",
        build_dir.display(),
        t.elapsed().as_secs_f64()
    );
}

/// Builds the consumer with find_package(dualsplit) from the prefix, shared and
/// static, and checks that the version file refuses another 0.x minor version.
fn cmake_package(prefix: &Path, work: &Path) {
    let dir = work.join("cmake-package");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("main.c"), CONSUMER_C).unwrap();
    let (major, minor) = {
        let mut it = VERSION.split('.');
        (it.next().unwrap(), it.next().unwrap())
    };
    let lists = |want: &str| {
        format!(
            "cmake_minimum_required(VERSION 3.13)\nproject(consumer C)\n\
             find_package(dualsplit {want} REQUIRED)\n\
             add_executable(app_shared main.c)\n\
             target_link_libraries(app_shared PRIVATE dualsplit::dualsplit)\n\
             add_executable(app_static main.c)\n\
             target_link_libraries(app_static PRIVATE dualsplit::dualsplit_static)\n"
        )
    };
    let configure = |build: &Path| {
        Command::new("cmake")
            .arg("-S")
            .arg(&dir)
            .arg("-B")
            .arg(build)
            .arg(format!("-DCMAKE_PREFIX_PATH={}", prefix.display()))
            .output()
            .unwrap()
    };
    // Another minor version of 0.x: refused.
    let other = format!("{major}.{}", minor.parse::<u32>().unwrap() + 1);
    std::fs::write(dir.join("CMakeLists.txt"), lists(&other)).unwrap();
    let refused = configure(&dir.join("build-other"));
    assert!(
        !refused.status.success(),
        "find_package(dualsplit {other}) accepted version {VERSION}"
    );
    // This version: found, built, run.
    std::fs::write(
        dir.join("CMakeLists.txt"),
        lists(&format!("{major}.{minor}")),
    )
    .unwrap();
    let build = dir.join("build");
    let conf = configure(&build);
    assert!(
        conf.status.success(),
        "find_package(dualsplit {major}.{minor}) failed:\n{}",
        String::from_utf8_lossy(&conf.stderr)
    );
    run_ok(
        Command::new("cmake").arg("--build").arg(&build),
        "cmake --build (find_package)",
    );
    for exe in ["app_shared", "app_static"] {
        let out = run_ok(
            Command::new(build.join(exe)).env("LD_LIBRARY_PATH", prefix.join("lib")),
            exe,
        );
        check_consumer_output(&stdout_of(&out), exe);
    }
    println!("find_package(dualsplit): ok");
}

/// Builds the consumer with the first ```cmake block of README.md against the prefix.
fn cmake_snippet(prefix: &Path, work: &Path) {
    let readme = std::fs::read_to_string(manifest_dir().join("README.md")).unwrap();
    let Some(start) = readme.find("```cmake\n") else {
        panic!("README.md has no ```cmake block");
    };
    let body = &readme[start + "```cmake\n".len()..];
    let snippet = &body[..body.find("```").expect("the end of the cmake block")];
    let dir = work.join("cmake");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("build")).unwrap();
    std::fs::write(dir.join("CMakeLists.txt"), snippet).unwrap();
    std::fs::write(dir.join("main.c"), CONSUMER_C).unwrap();
    run_ok(
        Command::new("cmake")
            .arg("-S")
            .arg(&dir)
            .arg("-B")
            .arg(dir.join("build"))
            .arg(format!("-DCMAKE_PREFIX_PATH={}", prefix.display()))
            .env("PKG_CONFIG_PATH", prefix.join("lib/pkgconfig")),
        "cmake configure with README's snippet",
    );
    run_ok(
        Command::new("cmake").arg("--build").arg(dir.join("build")),
        "cmake --build",
    );
    let exe = dir.join("build/fem_app");
    let out = run_ok(
        Command::new(&exe).env("LD_LIBRARY_PATH", prefix.join("lib")),
        "the CMake-built consumer",
    );
    check_consumer_output(&stdout_of(&out), "cmake");
    println!("README's CMake snippet: ok");
}
