//! The general-purpose reference: Clarabel (interior point, conic) on the primal
//! Tresca problem
//!
//! ```text
//! min 1/2 u^T K u - f^T u + sum_i p_i t_i   s.t.  N u <= g,  |T_i u| <= t_i,
//! ```
//!
//! with variables x = [u (n); t (m)]. In Clarabel's form A x + s = b, s in a cone:
//! N u + s = g, s >= 0 (multipliers z_N = lambda_N); in 2D |T_i u| <= t_i as the two
//! inequalities t_i -+ T_i u >= 0 (multipliers z+, z-, lambda_T,i = z+ - z-); in 3D
//! the cone (t_i, T_i u) in SOC(3) (multipliers (z0, z1), lambda_T,i = -z1). The
//! stationarity of the Lagrangian, K u - f + N^T z_N + T^T lambda_T = 0 and
//! z+ + z- = p_i (|z1| <= z0 = p_i), is the equilibrium of docs/design.md section 1.

use crate::row::Row;
use crate::scene::Scene;
use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettingsBuilder, DefaultSolver, IPSolver, NonnegativeConeT, SecondOrderConeT,
    SolverStatus, SupportedConeT,
};
use std::time::Instant;

/// One Clarabel run: its answer mapped to our unknowns.
pub struct Answer {
    pub wall: f64,
    pub status: SolverStatus,
    pub iterations: u32,
    pub u: Vec<f64>,
    pub lambda: Vec<f64>,
}

/// Solves the Tresca problem of `sc` with Clarabel at the gap / feasibility
/// tolerance `tol` (Clarabel's defaults are 1e-8), within `time_limit` seconds.
pub fn solve(sc: &Scene, tol: f64, time_limit: f64) -> Answer {
    let (d, ndof, m) = (sc.d, sc.k.nrows, sc.n.nrows);
    let nv = ndof + m;
    // P: the upper triangle of K, zero on the t block.
    let mut pc = Vec::with_capacity(nv + 1);
    let mut pr = Vec::new();
    let mut px = Vec::new();
    pc.push(0);
    for j in 0..ndof {
        for k in sc.k.col_ptr[j]..sc.k.col_ptr[j + 1] {
            if sc.k.row_idx[k] <= j {
                pr.push(sc.k.row_idx[k]);
                px.push(sc.k.values[k]);
            }
        }
        pc.push(pr.len());
    }
    for _ in 0..m {
        pc.push(pr.len());
    }
    let p_mat = CscMatrix::new(nv, nv, pc, pr, px);
    let mut q: Vec<f64> = sc.f.iter().map(|v| -v).collect();
    q.extend_from_slice(&sc.p);
    // Constraint rows: m normal rows, then per contact 2 rows (2D) or 3 rows (3D).
    let per = if d == 2 { 2 } else { 3 };
    let nrows = m + per * m;
    let mut ai = Vec::new();
    let mut aj = Vec::new();
    let mut ax = Vec::new();
    let mut b = vec![0.0; nrows];
    let (nt, tt) = (sc.n.transpose(), sc.t.transpose());
    for i in 0..m {
        for k in nt.col_ptr[i]..nt.col_ptr[i + 1] {
            ai.push(i);
            aj.push(nt.row_idx[k]);
            ax.push(nt.values[k]);
        }
    }
    b[..m].copy_from_slice(&sc.g);
    for i in 0..m {
        let r0 = m + per * i;
        if d == 2 {
            // t_i - T_i u >= 0: row [T_i, -e_i]; t_i + T_i u >= 0: row [-T_i, -e_i].
            for k in tt.col_ptr[i]..tt.col_ptr[i + 1] {
                ai.push(r0);
                aj.push(tt.row_idx[k]);
                ax.push(tt.values[k]);
                ai.push(r0 + 1);
                aj.push(tt.row_idx[k]);
                ax.push(-tt.values[k]);
            }
            for r in [r0, r0 + 1] {
                ai.push(r);
                aj.push(ndof + i);
                ax.push(-1.0);
            }
        } else {
            // s = (t_i, T_i u) in SOC(3): rows [0, -e_i], [-T_i, 0].
            ai.push(r0);
            aj.push(ndof + i);
            ax.push(-1.0);
            for s in 0..2 {
                let row = 2 * i + s;
                for k in tt.col_ptr[row]..tt.col_ptr[row + 1] {
                    ai.push(r0 + 1 + s);
                    aj.push(tt.row_idx[k]);
                    ax.push(-tt.values[k]);
                }
            }
        }
    }
    let a_mat = CscMatrix::new_from_triplets(nrows, nv, ai, aj, ax);
    let mut cones: Vec<SupportedConeT<f64>> = vec![NonnegativeConeT(m)];
    if d == 2 {
        cones.push(NonnegativeConeT(2 * m));
    } else {
        cones.extend((0..m).map(|_| SecondOrderConeT(3)));
    }
    let settings = DefaultSettingsBuilder::default()
        .verbose(false)
        .time_limit(time_limit)
        .max_iter(500)
        .tol_gap_abs(tol)
        .tol_gap_rel(tol)
        .tol_feas(tol)
        .build()
        .expect("valid Clarabel settings");
    let start = Instant::now();
    let mut solver = DefaultSolver::new(&p_mat, &q, &a_mat, &b, &cones, settings)
        .expect("Clarabel accepts the problem");
    solver.solve();
    let wall = start.elapsed().as_secs_f64();
    let sol = &solver.solution;
    let u = sol.x[..ndof].to_vec();
    let mut lambda = vec![0.0; d * m];
    lambda[..m].copy_from_slice(&sol.z[..m]);
    for i in 0..m {
        let r0 = m + per * i;
        if d == 2 {
            lambda[m + i] = sol.z[r0] - sol.z[r0 + 1];
        } else {
            lambda[m + 2 * i] = -sol.z[r0 + 1];
            lambda[m + 2 * i + 1] = -sol.z[r0 + 2];
        }
    }
    Answer {
        wall,
        status: sol.status,
        iterations: sol.iterations,
        u,
        lambda,
    }
}

/// Our error measure (docs/design.md section 5) of a Clarabel answer, two ways:
/// with u recovered from its multipliers, u = K^-1 (f - B^T lambda) (as the library
/// measures its own answers), and with Clarabel's own primal u. Returns
/// (err_recovered, err_primal, equilibrium residual of its own u).
pub fn errors(sc: &Scene, ans: &Answer) -> (f64, f64, f64) {
    use dualsplit::internals::Factor;
    use dualsplit::internals::natural_map_error;
    let (d, ndof, m) = (sc.d, sc.k.nrows, sc.n.nrows);
    // rho and B from the library's condensed dual.
    let pb = dualsplit::ContactProblem::from_csc(d, sc.k.clone(), sc.n.clone(), sc.t.clone())
        .expect("valid scene");
    let dual = pb.dual();
    let bmat = dual.rows();
    let fac = Factor::new(&sc.k).expect("K is SPD");
    let c = d * m;
    // b = B K^-1 f - [g; 0]
    let mut x = sc.f.clone();
    fac.solve_vec(&mut x);
    let mut bvec = vec![0.0; c];
    bmat.mul_vec(&x, &mut bvec);
    for (bi, gi) in bvec.iter_mut().zip(&sc.g) {
        *bi -= gi;
    }
    let v_of = |u: &[f64]| {
        let mut v = vec![0.0; c];
        bmat.mul_vec(u, &mut v);
        for (vi, gi) in v.iter_mut().zip(&sc.g) {
            *vi -= gi;
        }
        v
    };
    let mut btl = vec![0.0; ndof];
    bmat.mul_t_vec(&ans.lambda, &mut btl);
    let mut u_rec: Vec<f64> = (0..ndof).map(|i| sc.f[i] - btl[i]).collect();
    fac.solve_vec(&mut u_rec);
    let e_rec = natural_map_error(&ans.lambda, &v_of(&u_rec), dual.rho(), &bvec, &sc.p, d);
    let e_pri = natural_map_error(&ans.lambda, &v_of(&ans.u), dual.rho(), &bvec, &sc.p, d);
    let mut ku = vec![0.0; ndof];
    sc.k.mul_vec(&ans.u, &mut ku);
    let res: f64 = (0..ndof)
        .map(|i| (ku[i] - sc.f[i] + btl[i]).powi(2))
        .sum::<f64>()
        .sqrt();
    let nf = sc.f.iter().map(|v| v * v).sum::<f64>().sqrt();
    (e_rec, e_pri, res / nf)
}

/// The Clarabel rows of one scene: each tolerance in `tols`, then the peak memory.
pub fn run(sc: &Scene, base: &Row, tols: &[f64], time_limit: f64) -> Vec<Row> {
    let mut answers = Vec::new();
    for &tol in tols {
        let ans = solve(sc, tol, time_limit);
        let done = matches!(
            ans.status,
            SolverStatus::Solved | SolverStatus::AlmostSolved
        );
        eprintln!(
            "  clarabel tol {tol:.0e}: {:?} in {:.2} s, {} iterations",
            ans.status, ans.wall, ans.iterations
        );
        answers.push((tol, ans));
        if !done {
            break;
        }
    }
    let peak = crate::row::peak_mb();
    let mut rows = Vec::new();
    for (tol, ans) in &answers {
        let (e_rec, e_pri, eq) = errors(sc, ans);
        rows.push(Row {
            friction: "tresca".into(),
            kind: "clarabel".into(),
            method: "clarabel".into(),
            tol: Some(*tol),
            reps: Some(1),
            time_s: Some(ans.wall),
            time_min_s: Some(ans.wall),
            err: Some(e_rec),
            eq_res: Some(eq),
            outer: Some(ans.iterations as usize),
            status: format!("{:?}", ans.status),
            note: format!("err_primal_u={e_pri:.3e}"),
            ..base.clone()
        });
    }
    rows.push(Row {
        kind: "mem".into(),
        method: "clarabel".into(),
        mem_mb: peak,
        ..base.clone()
    });
    rows
}
