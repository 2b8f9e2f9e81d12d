//! README's minimal C example compiles against the real header and library, runs,
//! and prints the hand-derived answer its comment states (lambda_N = 10 - 4 * 0.5 = 8;
//! slip since |f_x| = 1 > p = 0.4, so lambda_T = 0.4).

mod ctools;

use ctools::{SYSTEM_LIBS, c_compiler, manifest_dir, out_dir, run_ok, static_lib, stdout_of};
use std::process::Command;

#[test]
fn readme_minimal_example_runs() {
    let readme = std::fs::read_to_string(manifest_dir().join("README.md")).unwrap();
    let start = readme.find("```c\n").expect("README has a ```c block") + 5;
    let len = readme[start..].find("```").expect("the ```c block ends");
    let dir = out_dir("readme");
    let src = dir.join("minimal.c");
    std::fs::write(&src, &readme[start..start + len]).unwrap();
    let exe = dir.join("minimal");
    let mut cc = c_compiler();
    cc.arg("-std=c99")
        .arg("-Wall")
        .arg("-Werror")
        .arg("-I")
        .arg(manifest_dir().join("include"))
        .arg(&src)
        .arg(static_lib())
        .args(SYSTEM_LIBS)
        .arg("-o")
        .arg(&exe);
    run_ok(&mut cc, "compile README's example");
    let out = run_ok(&mut Command::new(&exe), "run README's example");
    let text = stdout_of(&out);
    assert!(text.starts_with("lambda_N 8 lambda_T 0.4 err "), "{text}");
}
