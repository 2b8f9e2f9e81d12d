//! What a dual path without A costs: on the benchmark's scenes, the best
//! plain factorisation of K, one solve with it (one product A x = B K^-1 B^T x
//! costs one solve), a block of 16 solves, and what the diagonal blocks of A (the
//! rho_i of the error measure) would cost without A: by one sparse forward solve
//! per contact row through the supernodes on its elimination-tree path, counted
//! from the symbolic factor (flops, not timed).
//!
//! ```text
//! cargo run --release --example dual_cost -- [--scenes A,B,..] [--threads K]
//! ```

#[path = "bench/scene.rs"]
#[allow(dead_code)]
mod scene;
#[path = "bench/stats.rs"]
#[allow(dead_code)]
mod stats;

use dualsplit::Ordering;
use dualsplit::internals::{Factor, Threads, stack_rows};
use faer::dyn_stack::{MemBuffer, MemStack};
use scene::{Scene, Spec};
use std::sync::Arc;
use std::time::Instant;

fn main() {
    let mut scenes = vec!["3d-30x30x15".to_string(), "3d-64x64x6".to_string()];
    let mut threads = 1;
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut k = 0;
    while k < args.len() {
        match args[k].as_str() {
            "--scenes" => {
                scenes = args[k + 1].split(',').map(String::from).collect();
                k += 1;
            }
            "--threads" => {
                threads = args[k + 1].parse().expect("--threads K");
                k += 1;
            }
            a => panic!("unknown argument {a}"),
        }
        k += 1;
    }
    println!(
        "| scene | n | c | ordering | factor s | nnz(L) | factor flops | 1 solve s | 16 solves s | solve / factor | diag(A) by forward solves: flops | / factor flops |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|");
    for name in &scenes {
        let spec = Spec::parse(name).unwrap_or_else(|| panic!("bad scene {name}"));
        let sc = Scene::build(spec);
        let pool = Arc::new(Threads::new(threads));
        let t0 = Instant::now();
        let fac = Factor::with_last(&sc.k, &[], Ordering::Auto, pool).expect("K is SPD");
        let t_factor = t0.elapsed().as_secs_f64();
        let (nnz, flops) = fac.nnz_and_flops();
        let n = sc.k.nrows;
        let solve = |w: usize| {
            let mut rhs = faer::Mat::<f64>::from_fn(n, w, |i, j| ((i * 31 + j * 17) % 97) as f64);
            let mut mem = MemBuffer::new(fac.solve_scratch(w));
            let runs: Vec<f64> = (0..3)
                .map(|_| {
                    let t = Instant::now();
                    fac.solve_in_place(rhs.as_mut(), MemStack::new(&mut mem));
                    t.elapsed().as_secs_f64()
                })
                .collect();
            stats::median(&runs)
        };
        let (t1, t16) = (solve(1), solve(16));
        let b = stack_rows(&sc.n, &sc.t);
        let diag_flops = fac.forward_flops_per_row(&b);
        println!(
            "| {name} | {n} | {} | {} | {t_factor:.3} | {nnz:.3e} | {flops:.3e} | {t1:.4} | {t16:.4} | {:.4} | {diag_flops:.3e} | {:.2} |",
            b.nrows,
            fac.ordering().name(),
            t1 / t_factor,
            diag_flops / flops
        );
    }
}
