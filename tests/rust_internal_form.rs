//! Matrices a Rust caller builds in internal form (`dualsplit::Csc`, whose
//! fields are public) are checked by `ContactProblem::from_csc`,
//! `from_csc_with` and `analyse_csc`: a broken invariant is an error
//! of the right kind with a message naming the matrix, never a panic inside
//! the factorisation and never a silently wrong answer (an unsymmetric K used
//! through one triangle).

use dualsplit::{ContactProblem, Csc, ErrorKind, Options};

/// K of two springs in series (2 DOFs, both triangles stored), one 2D contact
/// on DOF 1: N = [0, -1], T = [1, 0].
fn clean() -> (Csc, Csc, Csc) {
    let k = Csc {
        nrows: 2,
        ncols: 2,
        col_ptr: vec![0, 2, 4],
        row_idx: vec![0, 1, 0, 1],
        values: vec![2.0, -1.0, -1.0, 2.0],
    };
    let n = Csc {
        nrows: 1,
        ncols: 2,
        col_ptr: vec![0, 0, 1],
        row_idx: vec![0],
        values: vec![-1.0],
    };
    let t = Csc {
        nrows: 1,
        ncols: 2,
        col_ptr: vec![0, 1, 1],
        row_idx: vec![0],
        values: vec![1.0],
    };
    (k, n, t)
}

/// Both entry points refuse (k, n, t) with `kind`, the message naming `what`.
fn refused(k: Csc, n: Csc, t: Csc, kind: ErrorKind, what: &str) {
    let e = ContactProblem::analyse_csc(2, &k, &n, &t, &Options::default())
        .expect_err("analyse_csc accepted a broken matrix");
    assert_eq!(e.kind, kind, "analyse_csc: {}", e.message);
    assert!(e.message.starts_with(what), "{}", e.message);
    let e = match ContactProblem::from_csc(2, k, n, t) {
        Ok(_) => panic!("from_csc accepted a broken matrix"),
        Err(e) => e,
    };
    assert_eq!(e.kind, kind, "from_csc: {}", e.message);
    assert!(e.message.starts_with(what), "{}", e.message);
}

#[test]
fn the_clean_matrices_solve_to_the_hand_derived_answer() {
    let (k, n, t) = clean();
    let mut pb = ContactProblem::from_csc(2, k, n, t).unwrap();
    // f = (0, -3) pushes DOF 1 down onto the obstacle (gap 0.5): free, u_1 would
    // be -2; in contact u_1 = -0.5, u_0 = -0.25, and the contact force
    // lambda_N = 3 - 2 (0.5) + 0.25 = 2.25 closes K u = f - N^T lambda_N
    // (row 1: -u_0 + 2 u_1 = -3 + lambda_N).
    let sol = pb
        .solve(
            &[0.0, -3.0],
            &[0.5],
            dualsplit::Friction::Tresca(&[0.0]),
            &Options::default(),
        )
        .unwrap();
    assert!((sol.u[1] + 0.5).abs() < 1e-12, "{:?}", sol.u);
    assert!((sol.u[0] + 0.25).abs() < 1e-12, "{:?}", sol.u);
    assert!((sol.lambda_n[0] - 2.25).abs() < 1e-12, "{:?}", sol.lambda_n);
}

#[test]
fn broken_stiffness_matrices_are_refused_with_their_kind() {
    let (k, n, t) = clean();
    let mut bad = k.clone();
    bad.row_idx[1] = 2;
    refused(bad, n.clone(), t.clone(), ErrorKind::BadIndex, "K");
    let mut bad = k.clone();
    bad.row_idx.swap(0, 1);
    bad.values.swap(0, 1);
    refused(bad, n.clone(), t.clone(), ErrorKind::BadIndex, "K");
    let mut bad = k.clone();
    bad.values[3] = f64::NAN;
    refused(bad, n.clone(), t.clone(), ErrorKind::NotFinite, "K");
    let mut bad = k.clone();
    bad.values[2] = -1.5;
    refused(bad, n.clone(), t.clone(), ErrorKind::NotSymmetric, "K");
    let mut bad = k.clone();
    bad.col_ptr.pop();
    refused(bad, n.clone(), t.clone(), ErrorKind::BadSize, "K");
    let mut bad = k.clone();
    bad.col_ptr[2] = 5;
    refused(bad, n.clone(), t.clone(), ErrorKind::BadSize, "K");
    let mut bad = k;
    bad.col_ptr[1] = 5;
    refused(bad, n, t, ErrorKind::BadIndex, "K");
}

#[test]
fn broken_contact_matrices_are_refused_with_their_kind() {
    let (k, n, t) = clean();
    let mut bad = n.clone();
    bad.row_idx[0] = 1;
    refused(k.clone(), bad, t.clone(), ErrorKind::BadIndex, "N");
    let mut bad = t.clone();
    bad.values[0] = f64::INFINITY;
    refused(k.clone(), n.clone(), bad, ErrorKind::NotFinite, "T");
    let mut bad = t;
    bad.col_ptr[0] = 1;
    refused(k, n, bad, ErrorKind::BadIndex, "T");
}
