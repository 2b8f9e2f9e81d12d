//! The nonlinear host example, c_examples/hyperelastic_host.c: a neo-Hookean
//! block in plane strain, pressed 15 % of its height onto a curved rigid
//! foundation and dragged over it with Coulomb friction, its own Newton loop
//! in C calling `ds_problem_refactor` and `ds_solve_iteration` every
//! iteration. Built against the static library of this test run and run.
//!
//! Checked:
//! - every increment converges, in at most 8 host iterations;
//! - quadratic convergence once the contact states settle: where an
//!   iteration's open / stick / slip counts equal the last one's, the next
//!   out-of-balance force is at most 10 |R|^2 (relative), down to rounding;
//! - the converged state of every increment against the conditions of the
//!   nonlinear problem, evaluated by this test's own assembly of the body
//!   (a second neo-Hookean Q4 written here): equilibrium -f_int(u) = N^T
//!   lambda_N + T^T lambda_T on the free DOFs, Signorini on the gaps
//!   g0 + u_y, Coulomb's bound, stick where the force is inside the cone
//!   (no slip over the increment), slip along the force on its rim;
//! - the path is not trivial: contacts stick while the block is pressed and
//!   slip when it is dragged.

mod ctools;

use ctools::{c_compiler, manifest_dir, run_ok, static_lib, stdout_of};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

fn example() -> &'static Path {
    static EXE: OnceLock<PathBuf> = OnceLock::new();
    EXE.get_or_init(|| {
        let root = manifest_dir();
        let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("hyperelastic_host");
        std::fs::create_dir_all(&dir).expect("create the output folder");
        let exe = dir.join("hyperelastic_host");
        let mut cmd = c_compiler();
        cmd.args(["-std=c99", "-Wall", "-Wextra", "-Werror", "-I"])
            .arg(root.join("include"))
            .arg("-I")
            .arg(root.join("c_examples"))
            .arg(root.join("c_examples").join("hyperelastic_host.c"))
            .arg(static_lib())
            .args(ctools::SYSTEM_LIBS)
            .arg("-o")
            .arg(&exe);
        run_ok(&mut cmd, "compiling hyperelastic_host.c");
        exe
    })
}

/// One host iteration as printed: |R| / |f_ref| and (open, stick, slip).
#[derive(Debug, Clone, Copy)]
struct Iteration {
    residual: f64,
    states: (usize, usize, usize),
}

/// One increment as printed: its iterations and the residual it converged at.
#[derive(Debug, Default)]
struct Printed {
    iterations: Vec<Iteration>,
    converged: Option<f64>,
}

fn number_after<'a>(line: &'a str, key: &str) -> &'a str {
    let at = line
        .find(key)
        .unwrap_or_else(|| panic!("'{key}' in '{line}'"));
    line[at + key.len()..]
        .trim_start()
        .split([',', ' '])
        .next()
        .unwrap()
}

fn parse_stdout(out: &str) -> Vec<Printed> {
    let mut incs: Vec<Printed> = Vec::new();
    for line in out.lines() {
        let l = line.trim();
        if l.starts_with("increment ") {
            incs.push(Printed::default());
        } else if l.starts_with("iteration ") {
            let residual: f64 = number_after(l, "|R| / |f_ref| =").parse().unwrap();
            let s = number_after(l, "open / stick / slip =");
            let rest = &l[l.find("open / stick / slip =").unwrap() + 21..];
            let v: Vec<usize> = rest
                .split(',')
                .next()
                .unwrap()
                .split('/')
                .map(|x| x.trim().parse().unwrap())
                .collect();
            assert_eq!(v[0].to_string(), s);
            incs.last_mut().unwrap().iterations.push(Iteration {
                residual,
                states: (v[0], v[1], v[2]),
            });
        } else if l.starts_with("converged after") {
            let r: f64 = number_after(l, "|R| / |f_ref| =").parse().unwrap();
            incs.last_mut().unwrap().converged = Some(r);
        }
    }
    incs
}

/// One converged increment: the top edge (x, y), u (all DOFs), lambda_N,
/// lambda_T.
type Converged = ((f64, f64), Vec<f64>, Vec<f64>, Vec<f64>);

/// The body as the example writes it, and its converged increments.
struct Written {
    nx: usize,
    ny: usize,
    w: f64,
    h: f64,
    young: f64,
    nu: f64,
    mu_f: f64,
    curved: f64,
    increments: Vec<Converged>,
}

fn parse_out(text: &str) -> Written {
    let mut lines = text.lines();
    let head: Vec<&str> = lines.next().unwrap().split_whitespace().collect();
    assert_eq!(head[0], "body");
    let f = |i: usize| head[i].parse::<f64>().unwrap();
    let (nx, ny): (usize, usize) = (head[1].parse().unwrap(), head[2].parse().unwrap());
    let ndof = 2 * (nx + 1) * (ny + 1);
    let m = nx + 1;
    let mut increments = Vec::new();
    while let Some(l) = lines.next() {
        let v: Vec<&str> = l.split_whitespace().collect();
        assert_eq!(v[0], "increment");
        let top = (v[2].parse().unwrap(), v[3].parse().unwrap());
        let u: Vec<f64> = (0..ndof)
            .map(|_| lines.next().unwrap().trim().parse().unwrap())
            .collect();
        let (mut ln, mut lt) = (Vec::new(), Vec::new());
        for _ in 0..m {
            let p: Vec<f64> = lines
                .next()
                .unwrap()
                .split_whitespace()
                .map(|x| x.parse().unwrap())
                .collect();
            ln.push(p[0]);
            lt.push(p[1]);
        }
        increments.push((top, u, ln, lt));
    }
    Written {
        nx,
        ny,
        w: f(3),
        h: f(4),
        young: f(5),
        nu: f(6),
        mu_f: f(7),
        curved: f(8),
        increments,
    }
}

/// The internal forces of the neo-Hookean Q4 mesh at u (all DOFs), written
/// here independently of the C example: first Piola-Kirchhoff P = F S with
/// S = mu (I - C^-1) + lambda ln J C^-1 (plane strain), f_a = sum over the
/// 2 x 2 Gauss points of P grad N_a det J0.
fn internal_forces(b: &Written, u: &[f64]) -> Vec<f64> {
    let (nx, ny) = (b.nx, b.ny);
    let lam = b.young * b.nu / ((1.0 + b.nu) * (1.0 - 2.0 * b.nu));
    let mu = b.young / (2.0 * (1.0 + b.nu));
    let (dx, dy) = (b.w / nx as f64, b.h / ny as f64);
    let mut f = vec![0.0; u.len()];
    let g = 1.0 / 3f64.sqrt();
    let corners = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)];
    for ey in 0..ny {
        for ex in 0..nx {
            let n0 = ey * (nx + 1) + ex;
            let nodes = [n0, n0 + 1, n0 + 1 + nx + 1, n0 + nx + 1];
            for (xi, eta) in [(-g, -g), (g, -g), (-g, g), (g, g)] {
                // Rectangular elements: grad N_a = (xi_a (1 + eta eta_a) / (2 dx),
                // eta_a (1 + xi xi_a) / (2 dy)), det J0 = dx dy / 4.
                let grad: Vec<[f64; 2]> = corners
                    .iter()
                    .map(|&(xa, ya)| {
                        [
                            xa * (1.0 + eta * ya) / (2.0 * dx),
                            ya * (1.0 + xi * xa) / (2.0 * dy),
                        ]
                    })
                    .collect();
                let mut ff = [[1.0, 0.0], [0.0, 1.0]];
                for (a, &nd) in nodes.iter().enumerate() {
                    for i in 0..2 {
                        for j in 0..2 {
                            ff[i][j] += u[2 * nd + i] * grad[a][j];
                        }
                    }
                }
                let jd = ff[0][0] * ff[1][1] - ff[0][1] * ff[1][0];
                assert!(jd > 0.0, "an inverted element");
                let c = [
                    [
                        ff[0][0] * ff[0][0] + ff[1][0] * ff[1][0],
                        ff[0][0] * ff[0][1] + ff[1][0] * ff[1][1],
                    ],
                    [
                        ff[0][1] * ff[0][0] + ff[1][1] * ff[1][0],
                        ff[0][1] * ff[0][1] + ff[1][1] * ff[1][1],
                    ],
                ];
                let dc = c[0][0] * c[1][1] - c[0][1] * c[1][0];
                let ci = [[c[1][1] / dc, -c[0][1] / dc], [-c[1][0] / dc, c[0][0] / dc]];
                let mut s = [[0.0; 2]; 2];
                for i in 0..2 {
                    for j in 0..2 {
                        let id = if i == j { 1.0 } else { 0.0 };
                        s[i][j] = mu * (id - ci[i][j]) + lam * jd.ln() * ci[i][j];
                    }
                }
                for (a, &nd) in nodes.iter().enumerate() {
                    for i in 0..2 {
                        let mut v = 0.0;
                        for j in 0..2 {
                            let p = ff[i][0] * s[0][j] + ff[i][1] * s[1][j];
                            v += p * grad[a][j];
                        }
                        f[2 * nd + i] += v * dx * dy / 4.0;
                    }
                }
            }
        }
    }
    f
}

fn norm(x: &[f64]) -> f64 {
    x.iter().map(|v| v * v).sum::<f64>().sqrt()
}

#[test]
fn the_hyperelastic_host_converges_quadratically_to_the_nonlinear_solution() {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("hyperelastic_host");
    let file = dir.join("increments.txt");
    let out = run_ok(
        Command::new(example()).arg("--out").arg(&file),
        "hyperelastic_host",
    );
    let stdout = stdout_of(&out);
    assert!(
        stdout.contains("SUMMARY: 6 increments converged"),
        "{stdout}"
    );
    let printed = parse_stdout(&stdout);
    assert_eq!(printed.len(), 6, "{stdout}");
    for (k, inc) in printed.iter().enumerate() {
        let it = &inc.iterations;
        assert!(
            inc.converged.is_some() && it.len() <= 8,
            "increment {}: {} iterations\n{stdout}",
            k + 1,
            it.len()
        );
        // The residuals after each iteration: the next iteration's, then the
        // converged one.
        let mut res: Vec<f64> = it.iter().map(|x| x.residual).collect();
        res.push(inc.converged.unwrap());
        let mut quadratic = 0;
        for j in 1..it.len() {
            if it[j].states != it[j - 1].states {
                continue;
            }
            let (now, next) = (res[j], res[j + 1]);
            assert!(
                next <= (10.0 * now * now).max(1e-12),
                "increment {}: |R| went from {now:.3e} to {next:.3e} with settled states\n{stdout}",
                k + 1
            );
            if now > 1e-12 && now < 1e-2 {
                quadratic += 1;
            }
        }
        assert!(
            quadratic >= 2,
            "increment {}: only {quadratic} steps in the quadratic range\n{stdout}",
            k + 1
        );
    }
    // The converged states against the nonlinear problem's conditions.
    let b = parse_out(&std::fs::read_to_string(&file).expect("the increments file"));
    assert_eq!(b.increments.len(), 6);
    let m = b.nx + 1;
    let top_row = b.ny * (b.nx + 1);
    let mut u_prev = vec![0.0; b.increments[0].1.len()];
    let (mut stuck_when_pressed, mut slipping_at_the_end) = (0, 0);
    for (k, (top, u, ln, lt)) in b.increments.iter().enumerate() {
        let what = format!("increment {}", k + 1);
        // The top edge is where the increment put it.
        for node in top_row..top_row + b.nx + 1 {
            assert_eq!((u[2 * node], u[2 * node + 1]), *top, "{what}: top edge");
        }
        let fint = internal_forces(&b, u);
        // Equilibrium on the free DOFs: -f_int - N^T lambda_N - T^T lambda_T
        // = 0, N = -e_y and T = e_x at bottom node i.
        let mut r: Vec<f64> = fint.iter().map(|v| -v).collect();
        for i in 0..m {
            r[2 * i + 1] += ln[i];
            r[2 * i] -= lt[i];
        }
        let free = 2 * top_row;
        let eq = norm(&r[..free]) / norm(&fint);
        assert!(eq <= 1e-9, "{what}: equilibrium residual {eq:.3e}");
        let l_scale = ln.iter().fold(0.0f64, |a, &v| a.max(v.abs()));
        let u_scale = u.iter().fold(0.0f64, |a, &v| a.max(v.abs()));
        for i in 0..m {
            let x = b.w * i as f64 / b.nx as f64 - 0.5 * b.w;
            let gap = b.curved * x * x + u[2 * i + 1];
            assert!(
                gap >= -1e-9 * u_scale,
                "{what}: node {i} penetrates by {gap:.3e}"
            );
            assert!(
                ln[i] >= -1e-9 * l_scale,
                "{what}: lambda_N[{i}] = {:.3e}",
                ln[i]
            );
            let compl = (ln[i] / l_scale).min(gap / u_scale);
            assert!(compl <= 1e-8, "{what}: complementarity at {i}: {compl:.3e}");
            let bound = b.mu_f * ln[i];
            assert!(
                lt[i].abs() <= bound + 1e-8 * l_scale,
                "{what}: |lambda_T[{i}]| = {:.6e} > mu lambda_N = {bound:.6e}",
                lt[i].abs()
            );
            let slip = u[2 * i] - u_prev[2 * i];
            if lt[i].abs() < bound - 1e-6 * l_scale {
                assert!(
                    slip.abs() <= 1e-8 * u_scale,
                    "{what}: node {i} inside the cone slips by {slip:.3e}"
                );
                if k < 3 && ln[i] > 1e-3 * l_scale {
                    stuck_when_pressed += 1;
                }
            } else if ln[i] > 1e-6 * l_scale {
                assert!(
                    slip * lt[i] >= -1e-10 * u_scale * l_scale,
                    "{what}: node {i} slips by {slip:.3e} against its force {:.3e}",
                    lt[i]
                );
                if k == 5 && slip.abs() > 1e-6 * u_scale {
                    slipping_at_the_end += 1;
                }
            }
        }
        u_prev.clone_from(u);
    }
    assert!(
        stuck_when_pressed >= 10,
        "sticking contacts while pressed: {stuck_when_pressed}"
    );
    assert!(
        slipping_at_the_end >= 10,
        "slipping contacts at the end: {slipping_at_the_end}"
    );
}
