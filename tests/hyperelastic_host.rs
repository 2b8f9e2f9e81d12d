//! The nonlinear host example, c_examples/hyperelastic_host.c: a neo-Hookean
//! block in plane strain and in 3D, pressed 15 % of its height onto a rigid
//! foundation (an initial gap profile) and dragged over it with Coulomb friction (in 3D 17
//! degrees off the T rows), its own Newton loop in C calling
//! `ds_problem_refactor` and `ds_solve_iteration` every iteration. Built
//! against the static library of this test run and run.
//!
//! Checked:
//! - every increment converges, in at most 8 host iterations;
//! - quadratic convergence once the contact states settle: where an
//!   iteration's open / stick / slip counts equal the last one's, the next
//!   out-of-balance force is at most 10 |R|^2 (relative), down to rounding;
//! - the converged state of every increment against the conditions of the
//!   nonlinear problem, evaluated by this test's own assembly of the body
//!   (a second neo-Hookean Q4 / H8 written here): equilibrium -f_int(u) = N^T
//!   lambda_N + T^T lambda_T on the free DOFs, Signorini on the gaps
//!   g0 + u_vert, Coulomb's bound, stick where the force is inside the cone
//!   (no slip over the increment), slip along the force on its rim;
//! - the path is not trivial: contacts stick while the block is pressed and
//!   slip when it is dragged.

// The element's small tensors read best with explicit indices.
#![allow(clippy::needless_range_loop)]

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

/// One increment as printed: its iterations, the residual it converged at
/// and the Krylov products (inner iterations) of its contact solves.
#[derive(Debug, Default)]
struct Printed {
    iterations: Vec<Iteration>,
    converged: Option<f64>,
    inner: usize,
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
            let inner: usize = number_after(l, "outer,").parse().unwrap();
            incs.last_mut().unwrap().inner += inner;
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

/// One converged increment: the top face's displacement (3 values, the
/// unused ones zero), u (all DOFs), lambda_N (m), lambda_T ((d - 1) m).
type Converged = ([f64; 3], Vec<f64>, Vec<f64>, Vec<f64>);

/// The body as the example writes it, and its converged increments.
struct Written {
    d: usize,
    /// Elements along each axis (the vertical one the last).
    ne: Vec<usize>,
    /// The block's sides along the same axes.
    sides: Vec<f64>,
    young: f64,
    nu: f64,
    mu_f: f64,
    curved: f64,
    increments: Vec<Converged>,
}

impl Written {
    /// Nodes along each axis.
    fn nn(&self) -> Vec<usize> {
        self.ne.iter().map(|e| e + 1).collect()
    }
    /// The bottom nodes (the contacts): the first layer.
    fn m(&self) -> usize {
        self.nn()[..self.d - 1].iter().product()
    }
    fn n_nodes(&self) -> usize {
        self.nn().iter().product()
    }
}

fn parse_out(text: &str) -> Written {
    let mut lines = text.lines();
    let head: Vec<&str> = lines.next().unwrap().split_whitespace().collect();
    assert_eq!(head[0], "body");
    let f = |i: usize| head[i].parse::<f64>().unwrap();
    let n = |i: usize| head[i].parse::<usize>().unwrap();
    let d = n(1);
    // body d nx ny nz W D H E nu mu curved (2D: nz = 0 and D unused).
    let (ne, sides) = if d == 2 {
        (vec![n(2), n(3)], vec![f(5), f(7)])
    } else {
        (vec![n(2), n(3), n(4)], vec![f(5), f(6), f(7)])
    };
    let mut b = Written {
        d,
        ne,
        sides,
        young: f(8),
        nu: f(9),
        mu_f: f(10),
        curved: f(11),
        increments: Vec::new(),
    };
    let (ndof, m) = (d * b.n_nodes(), b.m());
    while let Some(l) = lines.next() {
        let v: Vec<&str> = l.split_whitespace().collect();
        assert_eq!(v[0], "increment");
        let top = [1, 2, 3].map(|k| v[k + 1].parse::<f64>().unwrap());
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
            lt.extend_from_slice(&p[1..d]);
        }
        b.increments.push((top, u, ln, lt));
    }
    b
}

/// The internal forces of the neo-Hookean mesh at u (all DOFs), written here
/// independently of the C example: on each box element (Q4 or H8, 2^d Gauss
/// points) the first Piola-Kirchhoff stress P = F S with S = mu (I - C^-1) +
/// lambda ln J C^-1 (in 2D plane strain), f_a = sum over the Gauss points of
/// P grad N_a det J0.
fn internal_forces(b: &Written, u: &[f64]) -> Vec<f64> {
    let d = b.d;
    let nn = b.nn();
    let lam = b.young * b.nu / ((1.0 + b.nu) * (1.0 - 2.0 * b.nu));
    let mu = b.young / (2.0 * (1.0 + b.nu));
    let h: Vec<f64> = (0..d).map(|k| b.sides[k] / b.ne[k] as f64).collect();
    let det0: f64 = h.iter().map(|x| x / 2.0).product();
    let g = 1.0 / 3f64.sqrt();
    // The element's corners in local coordinates (-1 or 1 per axis) and its
    // nodes' offsets in the grid: the same set, in any order.
    let corners: Vec<Vec<f64>> = (0..1usize << d)
        .map(|c| {
            (0..d)
                .map(|k| if c >> k & 1 == 1 { 1.0 } else { -1.0 })
                .collect()
        })
        .collect();
    let node = |ix: &[usize]| -> usize {
        let mut id = 0;
        for k in (0..d).rev() {
            id = id * nn[k] + ix[k];
        }
        id
    };
    let mut f = vec![0.0; u.len()];
    let n_el: usize = b.ne.iter().product();
    for e in 0..n_el {
        let mut ex = vec![0; d];
        let mut rest = e;
        for k in 0..d {
            ex[k] = rest % b.ne[k];
            rest /= b.ne[k];
        }
        let nodes: Vec<usize> = corners
            .iter()
            .map(|c| {
                let ix: Vec<usize> = (0..d).map(|k| ex[k] + usize::from(c[k] > 0.0)).collect();
                node(&ix)
            })
            .collect();
        for gp in &corners {
            let xi: Vec<f64> = gp.iter().map(|c| g * c).collect();
            let grad: Vec<Vec<f64>> = corners
                .iter()
                .map(|c| {
                    (0..d)
                        .map(|i| {
                            let mut v = c[i] / h[i];
                            for k in (0..d).filter(|&k| k != i) {
                                v *= 0.5 * (1.0 + xi[k] * c[k]);
                            }
                            v
                        })
                        .collect()
                })
                .collect();
            let mut ff = vec![vec![0.0; d]; d];
            for i in 0..d {
                ff[i][i] = 1.0;
                for (a, &nd) in nodes.iter().enumerate() {
                    for j in 0..d {
                        ff[i][j] += u[d * nd + i] * grad[a][j];
                    }
                }
            }
            let fm = faer::Mat::<f64>::from_fn(d, d, |i, j| ff[i][j]);
            let jd = fm.determinant();
            assert!(jd > 0.0, "an inverted element");
            let c = fm.transpose() * &fm;
            let ci = faer::linalg::solvers::DenseSolveCore::inverse(&c.full_piv_lu());
            let mut s = vec![vec![0.0; d]; d];
            for i in 0..d {
                for j in 0..d {
                    let id = if i == j { 1.0 } else { 0.0 };
                    s[i][j] = mu * (id - ci[(i, j)]) + lam * jd.ln() * ci[(i, j)];
                }
            }
            for (a, &nd) in nodes.iter().enumerate() {
                for i in 0..d {
                    let mut v = 0.0;
                    for j in 0..d {
                        let p: f64 = (0..d).map(|k| ff[i][k] * s[k][j]).sum();
                        v += p * grad[a][j];
                    }
                    f[d * nd + i] += v * det0;
                }
            }
        }
    }
    f
}

fn norm(x: &[f64]) -> f64 {
    x.iter().map(|v| v * v).sum::<f64>().sqrt()
}

/// What `check_run` saw: contacts stuck while pressed, contacts slipping in
/// the last increment, and the host iterations of each increment.
struct Run {
    stuck: usize,
    slipping: usize,
    iterations: Vec<usize>,
    /// Krylov products of all the contact solves.
    inner: usize,
}

/// Runs the example with `args`, asserts the printed convergence and checks
/// the converged increments.
fn check_run(name: &str, args: &[&str]) -> Run {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("hyperelastic_host");
    let file = dir.join(format!("{name}.txt"));
    let out = run_ok(
        Command::new(example()).args(args).arg("--out").arg(&file),
        name,
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
            "{name}, increment {}: {} iterations\n{stdout}",
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
                "{name}, increment {}: |R| went from {now:.3e} to {next:.3e} with settled \
                 states\n{stdout}",
                k + 1
            );
            if now > 1e-12 && now < 1e-2 {
                quadratic += 1;
            }
        }
        assert!(
            quadratic >= 2,
            "{name}, increment {}: only {quadratic} steps in the quadratic range\n{stdout}",
            k + 1
        );
    }
    // The converged states against the nonlinear problem's conditions.
    let b = parse_out(&std::fs::read_to_string(&file).expect("the increments file"));
    assert_eq!(b.increments.len(), 6);
    let (d, m) = (b.d, b.m());
    let dt = d - 1;
    let nn = b.nn();
    let layer = b.m();
    let top_layer = (nn[d - 1] - 1) * layer;
    let mut u_prev = vec![0.0; b.increments[0].1.len()];
    let (mut stuck_when_pressed, mut slipping_at_the_end) = (0, 0);
    for (k, (top, u, ln, lt)) in b.increments.iter().enumerate() {
        let what = format!("{name}, increment {}", k + 1);
        // The top face is where the increment put it.
        for node in top_layer..top_layer + layer {
            for c in 0..d {
                assert_eq!(u[d * node + c], top[c], "{what}: top face");
            }
        }
        let fint = internal_forces(&b, u);
        // Equilibrium on the free DOFs: -f_int - N^T lambda_N - T^T lambda_T
        // = 0, N = -e_vert and T = the horizontal unit rows at bottom node i.
        let mut r: Vec<f64> = fint.iter().map(|v| -v).collect();
        for i in 0..m {
            r[d * i + dt] += ln[i];
            for c in 0..dt {
                r[d * i + c] -= lt[dt * i + c];
            }
        }
        let free = d * top_layer;
        let eq = norm(&r[..free]) / norm(&fint);
        assert!(eq <= 1e-9, "{what}: equilibrium residual {eq:.3e}");
        let l_scale = ln.iter().fold(0.0f64, |a, &v| a.max(v.abs()));
        let u_scale = u.iter().fold(0.0f64, |a, &v| a.max(v.abs()));
        for i in 0..m {
            let x = (i % nn[0]) as f64 * b.sides[0] / b.ne[0] as f64 - 0.5 * b.sides[0];
            let y = if d == 3 {
                (i / nn[0]) as f64 * b.sides[1] / b.ne[1] as f64 - 0.5 * b.sides[1]
            } else {
                0.0
            };
            let gap = b.curved * (x * x + y * y) + u[d * i + dt];
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
            let force = &lt[dt * i..dt * (i + 1)];
            let slip: Vec<f64> = (0..dt).map(|c| u[d * i + c] - u_prev[d * i + c]).collect();
            let (lf, ls) = (norm(force), norm(&slip));
            assert!(
                lf <= bound + 1e-8 * l_scale,
                "{what}: |lambda_T[{i}]| = {lf:.6e} > mu lambda_N = {bound:.6e}"
            );
            if lf < bound - 1e-6 * l_scale {
                assert!(
                    ls <= 1e-8 * u_scale,
                    "{what}: node {i} inside the cone slips by {ls:.3e}"
                );
                if k < 3 && ln[i] > 1e-3 * l_scale {
                    stuck_when_pressed += 1;
                }
            } else if ln[i] > 1e-6 * l_scale {
                // The slip over the increment along the force: s = alpha
                // lambda_T, alpha >= 0.
                let alpha = slip
                    .iter()
                    .zip(force)
                    .map(|(a, b)| a * b)
                    .sum::<f64>()
                    .max(0.0)
                    / (lf * lf);
                let off: Vec<f64> = slip.iter().zip(force).map(|(a, b)| a - alpha * b).collect();
                assert!(
                    norm(&off) <= 1e-8 * u_scale,
                    "{what}: node {i} slips by {slip:?}, not along its force {force:?}"
                );
                if k == 5 && ls > 1e-6 * u_scale {
                    slipping_at_the_end += 1;
                }
            }
        }
        u_prev.clone_from(u);
    }
    Run {
        stuck: stuck_when_pressed,
        slipping: slipping_at_the_end,
        iterations: printed.iter().map(|inc| inc.iterations.len()).collect(),
        inner: printed.iter().map(|inc| inc.inner).sum(),
    }
}

/// The example's contact solves follow the host's residual by default (an
/// inexact Newton step, docs/design.md section 9); `--exact-contact` solves
/// each to the final tolerance. Both must land on the nonlinear solution,
/// and the loose solves must cost no host iteration and fewer Krylov
/// products in all.
fn check_both(name: &str, args: &[&str]) -> Run {
    let forced = check_run(name, args);
    let exact_name = format!("{name}_exact");
    let mut exact_args = args.to_vec();
    exact_args.push("--exact-contact");
    let exact = check_run(&exact_name, &exact_args);
    for (k, (f, e)) in forced.iterations.iter().zip(&exact.iterations).enumerate() {
        assert!(
            f <= e,
            "{name}, increment {}: {f} host iterations with the forced contact \
             tolerance, {e} with every solve to tol",
            k + 1
        );
    }
    assert!(
        forced.inner < exact.inner,
        "{name}: {} Krylov products with the forced contact tolerance, {} with every \
         solve to tol",
        forced.inner,
        exact.inner
    );
    forced
}

#[test]
fn the_plane_strain_host_converges_quadratically_to_the_nonlinear_solution() {
    let run = check_both("plane_strain", &[]);
    assert!(
        run.stuck >= 10,
        "sticking contacts while pressed: {}",
        run.stuck
    );
    assert!(
        run.slipping >= 10,
        "slipping contacts at the end: {}",
        run.slipping
    );
}

/// 3D (H8, 8 x 8 x 4 elements, 81 contacts), dragged 17 degrees off the T
/// rows: the slip turns within the friction disc.
#[test]
fn the_3d_host_converges_quadratically_to_the_nonlinear_solution() {
    let run = check_both("3d", &["--dim", "3"]);
    assert!(
        run.stuck >= 10,
        "sticking contacts while pressed: {}",
        run.stuck
    );
    assert!(
        run.slipping >= 30,
        "slipping contacts at the end: {}",
        run.slipping
    );
}
