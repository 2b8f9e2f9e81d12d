//! Tests of the dual's forms against each other and of the products' solves.
use super::*;

/// A 2D grid Laplacian plus a small shift (SPD), nx x ny nodes, one DOF each.
pub(crate) fn grid(nx: usize, ny: usize) -> Csc {
    let id = |i: usize, j: usize| i + nx * j;
    let mut t = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            t.push((id(i, j), id(i, j), 4.1));
            if i + 1 < nx {
                t.push((id(i, j), id(i + 1, j), -1.0));
                t.push((id(i + 1, j), id(i, j), -1.0));
            }
            if j + 1 < ny {
                t.push((id(i, j), id(i, j + 1), -1.0));
                t.push((id(i, j + 1), id(i, j), -1.0));
            }
        }
    }
    Csc::from_triplets(nx * ny, nx * ny, &t)
}

/// d = 2 contacts at `dofs` of a body with `ndof` DOFs: contact i's
/// normal row is -e_j, its tangent row e_(j+1 mod ndof), j = dofs[i].
fn contacts_at(dofs: &[usize], ndof: usize) -> (Csc, Csc) {
    let m = dofs.len();
    let nt: Vec<_> = dofs
        .iter()
        .enumerate()
        .map(|(i, &j)| (i, j, -1.0))
        .collect();
    let tt: Vec<_> = (dofs.iter().enumerate())
        .map(|(i, &j)| (i, (j + 1) % ndof, 1.0))
        .collect();
    (
        Csc::from_triplets(m, ndof, &nt),
        Csc::from_triplets(m, ndof, &tt),
    )
}

/// K's factor in the METIS ordering on `threads`.
fn metis_factor(k: &Csc, threads: usize) -> std::sync::Arc<Factor> {
    let pool = std::sync::Arc::new(crate::threads::Threads::new(threads));
    Factor::with_last(k, &[], crate::Ordering::Metis, pool).unwrap()
}

#[test]
fn trailing_block_and_solves_give_the_same_a() {
    let (nx, ny) = (9, 7);
    let k = grid(nx, ny);
    // Contacts on the bottom row, normals and tangents touching two DOFs each.
    let m = 5;
    let mut nt = Vec::new();
    let mut tt = Vec::new();
    for i in 0..m {
        nt.push((i, 2 * i, -1.0));
        nt.push((i, 2 * i + 1, 0.25));
        tt.push((i, 2 * i + 1, 1.0));
        tt.push((i, 2 * i, 0.5 + i as f64));
    }
    let n = Csc::from_triplets(m, nx * ny, &nt);
    let t = Csc::from_triplets(m, nx * ny, &tt);
    let last = contact_dofs(&stack_rows(&n, &t));
    let f1 = Factor::with_last(
        &k,
        &last,
        crate::Ordering::Auto,
        std::sync::Arc::new(crate::threads::Threads::sequential()),
    )
    .unwrap();
    let f0 = Factor::new(&k).unwrap();
    let a1 = Dual::build(&f1, &n, &t, 2, DualForm::Auto).unwrap();
    assert_eq!(a1.condensation, Condensation::TrailingBlock);
    let a0 = Dual::build(&f0, &n, &t, 2, DualForm::Auto).unwrap();
    assert_eq!(a0.condensation, Condensation::Solves);
    let scale = a0.a.iter().fold(0.0f64, |s, v| s.max(v.abs()));
    for (x, y) in a0.a.iter().zip(&a1.a) {
        assert!((x - y).abs() <= 1e-13 * scale, "{x} vs {y}");
    }
    // And A is positive definite here: its diagonal is positive.
    for j in 0..a0.c {
        assert!(a0.a[j + j * a0.c] > 0.0);
    }
}

/// The products take the tree solves, split on two threads and in one
/// bin on one, and agree: over the whole factor for contacts spread over
/// the body (their paths cover L), and restricted to the paths of a
/// strip's bottom row.
#[test]
fn matrix_free_products_on_two_threads_take_the_tree_solves() {
    for (nx, ny, step, restricted) in [(160, 160, 7, false), (2000, 20, 1, true)] {
        let k = grid(nx, ny);
        // d = 2: a normal and a tangent row per contact, on every step-th
        // DOF of the body or along the bottom row.
        let dofs: Vec<usize> = if restricted {
            (0..nx).collect()
        } else {
            (0..nx * ny).step_by(step).collect()
        };
        let (n, t) = contacts_at(&dofs, nx * ny);
        let free_on = |threads: usize| {
            let f = metis_factor(&k, threads);
            let dual = Dual::build(&f, &n, &t, 2, DualForm::MatrixFree).unwrap();
            // The own solves' bytes, besides the bound on the narrowed ones'.
            let b = stack_rows(&n, &t);
            let own = own_solves_bytes(&f, &b)
                - narrow_bytes(&f, b.nrows)
                - b.nrows * std::mem::size_of::<usize>();
            (dual, own)
        };
        let (one, own_one) = free_on(1);
        let (two, own_two) = free_on(2);
        fn own(d: &Dual) -> Option<&OwnSolves> {
            match &d.free.as_ref().expect("matrix-free").solves {
                Solves::Factor(fs) => fs.own.as_ref(),
                Solves::Host(_) => None,
            }
        }
        let on_one = &own(&one).expect("a sparse factor takes the tree").split;
        assert_eq!(on_one.restricted(), restricted);
        assert!(on_one.threads() == 1 && own_one > 0);
        let split = &own(&two).expect("two threads take the tree").split;
        assert_eq!(split.restricted(), restricted);
        assert_eq!(split.threads(), 2);
        assert!(own_two >= nx * ny * (F64 + 4), "{own_two}");
        let c = one.c;
        let x: Vec<f64> = (0..c).map(|i| (i as f64 * 0.31).cos()).collect();
        let (mut y1, mut y2) = (vec![0.0; c], vec![0.0; c]);
        one.apply(&x, &mut y1);
        two.apply(&x, &mut y2);
        let scale = y1.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        for (a, b) in y1.iter().zip(&y2) {
            assert!((a - b).abs() <= 1e-13 * scale, "{a} vs {b}");
        }
        two.apply_rough(&x, &mut y2);
        for (a, b) in y1.iter().zip(&y2) {
            assert!((a - b).abs() <= 1e-5 * scale, "{a} vs {b}");
        }
    }
}

/// Products narrowed to some contacts' rows (`Dual::narrow_to`) equal the
/// whole products there, in double and single precision, on one and two
/// threads, and are zero elsewhere; each narrowing replaces the last
/// (the second set overlaps the first, so values a solve left behind
/// would show); no narrowing where the rows' paths cover the factor.
#[test]
fn narrowed_products_equal_the_whole_ones_at_their_rows() {
    // A strip with contacts along its bottom row (d = 2): the paths of a
    // stretch of them hold a small part of the factor.
    let (nx, ny) = (2000, 20);
    let k = grid(nx, ny);
    let (n, t) = contacts_at(&(0..nx).collect::<Vec<_>>(), nx * ny);
    for threads in [1, 2] {
        let f = metis_factor(&k, threads);
        let dual = Dual::build(&f, &n, &t, 2, DualForm::MatrixFree).unwrap();
        let c = dual.c;
        for stretch in [300..700, 600..650] {
            let mut rows: Vec<usize> = stretch.clone().chain(stretch.map(|i| nx + i)).collect();
            rows.sort_unstable();
            assert!(dual.narrow_to(&rows), "{threads} thread(s)");
            let mut x = vec![0.0; c];
            for &r in &rows {
                x[r] = (r as f64 * 0.37).sin();
            }
            let mut whole = vec![0.0; c];
            dual.apply(&x, &mut whole);
            let scale = whole.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            for (rough, tol) in [(false, 1e-13), (true, 1e-5)] {
                let mut y = vec![f64::NAN; c];
                dual.apply_narrow(&x, &mut y, rough);
                for r in 0..c {
                    let want = if rows.binary_search(&r).is_ok() {
                        whole[r]
                    } else {
                        0.0
                    };
                    assert!(
                        (y[r] - want).abs() <= tol * scale,
                        "row {r}: {} vs {want} ({threads} thread(s), rough {rough})",
                        y[r]
                    );
                }
            }
        }
        dual.widen();
    }
    // Contacts spread over a square: their paths hold the whole factor.
    let (nx, step) = (60, 7);
    let k = grid(nx, nx);
    let dofs: Vec<usize> = (0..nx * nx).step_by(step).collect();
    let (n, t) = contacts_at(&dofs, nx * nx);
    let f = metis_factor(&k, 1);
    let dual = Dual::build(&f, &n, &t, 2, DualForm::MatrixFree).unwrap();
    let all: Vec<usize> = (0..dual.c).collect();
    assert!(!dual.narrow_to(&all));
}

#[test]
fn matrix_free_products_and_diagonal_match_the_dense_a() {
    let (nx, ny) = (11, 6);
    let k = grid(nx, ny);
    // Contacts on the bottom row, rows touching two DOFs each, one contact with
    // empty rows (its A block is zero), d = 3 (two tangent rows per contact).
    let m = 5;
    let (mut nt, mut tt) = (Vec::new(), Vec::new());
    for i in 0..m - 1 {
        nt.push((i, 2 * i, -1.0));
        nt.push((i, 2 * i + 1, 0.3));
        tt.push((2 * i, 2 * i + 1, 1.0));
        tt.push((2 * i + 1, 2 * i, 0.5));
        tt.push((2 * i + 1, 2 * i + 1, -0.25 * i as f64));
    }
    let n = Csc::from_triplets(m, nx * ny, &nt);
    let t = Csc::from_triplets(2 * m, nx * ny, &tt);
    let last = contact_dofs(&stack_rows(&n, &t));
    let f = Factor::with_last(
        &k,
        &last,
        crate::Ordering::Auto,
        std::sync::Arc::new(crate::threads::Threads::sequential()),
    )
    .unwrap();
    let dense = Dual::build(&f, &n, &t, 3, DualForm::Dense).unwrap();
    let free = Dual::build(&f, &n, &t, 3, DualForm::MatrixFree).unwrap();
    assert_eq!(dense.condensation, Condensation::TrailingBlock);
    assert_eq!(free.condensation, Condensation::MatrixFree);
    assert!(free.is_matrix_free() && free.a.is_empty());
    // The contact DOFs are the factor's last: their paths are the trailing
    // supernodes, and the products take the restricted solves.
    assert!(
        free.free
            .as_ref()
            .and_then(|o| match &o.solves {
                Solves::Factor(fs) => fs.own.as_ref(),
                Solves::Host(_) => None,
            })
            .is_some_and(|o| o.split.restricted())
    );
    let c = dense.c;
    let scale = dense.a.iter().fold(0.0f64, |s, v| s.max(v.abs()));
    for j in 0..c {
        let dj = dense.a[j + j * c];
        assert!((free.diag(j) - dj).abs() <= 1e-13 * scale, "diag {j}");
    }
    for (x, y) in dense.rho.iter().zip(&free.rho) {
        assert!((x - y).abs() <= 1e-12 * x.abs(), "rho {x} vs {y}");
    }
    // Products with a few vectors, sparse and dense.
    let mut y0 = vec![0.0; c];
    let mut y1 = vec![0.0; c];
    for s in 0..4 {
        let x: Vec<f64> = (0..c)
            .map(|i| {
                if s < 2 && (i + s) % 3 == 0 {
                    0.0
                } else {
                    (i as f64 * 0.7 + s as f64).sin()
                }
            })
            .collect();
        dense.apply(&x, &mut y0);
        free.apply(&x, &mut y1);
        let xs = x.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        for (a, b) in y0.iter().zip(&y1) {
            assert!((a - b).abs() <= 1e-13 * scale * xs * c as f64, "{a} vs {b}");
        }
        // In single precision (the rough products): to about 1e-7 of the
        // largest entry of A times |x| (1.0-1.5e-7 measured here).
        free.apply_rough(&x, &mut y1);
        let worst = y0
            .iter()
            .zip(&y1)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f64, f64::max);
        assert!(worst <= 1e-6 * scale * xs, "single precision: {worst:e}");
    }
    // A leading block (the normal unknowns alone), with a dense x.
    let m = dense.m;
    let x: Vec<f64> = (0..m).map(|i| 1.0 + i as f64).collect();
    let (mut z0, mut z1) = (vec![0.0; m], vec![0.0; m]);
    dense.apply(&x, &mut z0);
    free.apply(&x, &mut z1);
    for i in 0..m {
        let want: f64 = (0..m).map(|j| dense.a[i + j * c] * x[j]).sum();
        assert!((z0[i] - want).abs() <= 1e-13 * scale * m as f64 * m as f64);
        assert!((z1[i] - want).abs() <= 1e-12 * scale * m as f64 * m as f64);
    }
    // Auto picks dense at this size; without trailing DOFs the dense form is
    // formed by solves, and the matrix-free one works on the plain factor,
    // with the same products.
    let auto = Dual::build(&f, &n, &t, 3, DualForm::Auto).unwrap();
    assert!(!auto.is_matrix_free());
    let plain = Factor::new(&k).unwrap();
    let by_solves = Dual::build(&plain, &n, &t, 3, DualForm::Dense).unwrap();
    assert_eq!(by_solves.condensation, Condensation::Solves);
    let free_plain = Dual::build(&plain, &n, &t, 3, DualForm::MatrixFree).unwrap();
    assert_eq!(free_plain.condensation, Condensation::MatrixFree);
    assert!(!free_plain.trailing);
    let x: Vec<f64> = (0..c).map(|i| (i as f64 * 0.3).cos()).collect();
    dense.apply(&x, &mut y0);
    free_plain.apply(&x, &mut y1);
    for (a, b) in y0.iter().zip(&y1) {
        assert!((a - b).abs() <= 1e-12 * scale * c as f64, "{a} vs {b}");
    }
}

/// MPRGP's estimate of |A + D| lives as long as the operator: none at first,
/// kept once given (a non-positive or non-finite one is not), cleared when the
/// compliance shift changes the operator.
#[test]
fn the_norm_estimate_is_kept_until_the_operator_changes() {
    let (nx, ny) = (8, 5);
    let k = grid(nx, ny);
    let (n, t) = contacts_at(&[0, 2, 4], nx * ny);
    let f = metis_factor(&k, 1);
    let mut dual = Dual::build(&f, &n, &t, 2, DualForm::MatrixFree).unwrap();
    assert_eq!(dual.whole_norm(), None);
    dual.keep_whole_norm(f64::NAN);
    dual.keep_whole_norm(0.0);
    assert_eq!(dual.whole_norm(), None);
    dual.keep_whole_norm(2.5);
    assert_eq!(dual.whole_norm(), Some(2.5));
    dual.set_shift(&[1.0; 6]);
    assert_eq!(dual.whole_norm(), None, "A + D is another operator");
}

/// A compliance shift on a dense A is undone exactly: A's own diagonal is
/// kept while D sits on it, so an empty shift gives A back bitwise (and rho
/// with it), after several shifts in a row.
#[test]
fn an_empty_shift_restores_a_bitwise() {
    let (nx, ny) = (8, 5);
    let k = grid(nx, ny);
    let (n, t) = contacts_at(&[0, 2, 4], nx * ny);
    let f = metis_factor(&k, 1);
    let mut dual = Dual::build(&f, &n, &t, 2, DualForm::Dense).unwrap();
    let (a, rho) = (dual.a.clone(), dual.rho.clone());
    let c = dual.c;
    let third: Vec<f64> = (0..c).map(|j| 1.0 / 3.0 + j as f64 * 0.1).collect();
    dual.set_shift(&third);
    assert_ne!(dual.a, a, "the shift is on A's diagonal");
    dual.set_shift(&vec![1e-3; c]);
    dual.set_shift(&[]);
    assert!(
        dual.a
            .iter()
            .zip(&a)
            .all(|(x, y)| x.to_bits() == y.to_bits()),
        "A restored bitwise"
    );
    assert_eq!(dual.rho, rho);
    assert!(dual.shift().is_empty());
}

#[test]
fn a_dual_whose_single_copy_was_lent_gives_the_same_products() {
    // A refactor or set_contacts that failed after taking the old dual's
    // single-precision copy leaves that dual without it: its rough
    // products (whole and narrowed) make it again, bit for bit.
    let (nx, ny) = (300, 12);
    let k = grid(nx, ny);
    let (n, t) = contacts_at(&(0..nx).collect::<Vec<_>>(), nx * ny);
    let f = metis_factor(&k, 1);
    let mut dual = Dual::build(&f, &n, &t, 2, DualForm::MatrixFree).unwrap();
    let c = dual.c;
    let x: Vec<f64> = (0..c).map(|r| (r as f64 * 0.37).sin()).collect();
    let mut rows: Vec<usize> = (40..90).chain(nx + 40..nx + 90).collect();
    rows.sort_unstable();
    let mut xr = vec![0.0; c];
    rows.iter().for_each(|&r| xr[r] = x[r]);
    let products = |dual: &Dual| {
        let (mut whole, mut exact, mut narrow) = (vec![0.0; c], vec![0.0; c], vec![0.0; c]);
        dual.apply_rough(&x, &mut whole);
        dual.apply(&x, &mut exact);
        assert!(dual.narrow_to(&rows));
        dual.apply_narrow(&xr, &mut narrow, true);
        dual.widen();
        (whole, exact, narrow)
    };
    let before = products(&dual);
    // The rough product differs from the exact one: it reads the copy.
    assert_ne!(before.0, before.1);
    let lent = dual
        .lend_single()
        .expect("a matrix-free dual on the factor");
    assert_eq!(lent.len(), f.values().len());
    assert_eq!(lent, f.single_values().unwrap());
    assert_eq!(products(&dual), before);
    // Lent twice: the second time the copy made again; then the narrowed
    // product first makes it.
    assert_eq!(dual.lend_single().unwrap(), lent);
    assert!(dual.single_copy().unwrap().1.is_empty());
    let mut narrow = vec![0.0; c];
    assert!(dual.narrow_to(&rows));
    dual.apply_narrow(&xr, &mut narrow, true);
    dual.widen();
    assert_eq!(narrow, before.2);
    assert_eq!(dual.single_copy().unwrap().1, lent);
    // A new dual takes a lent copy of the right length as it is, and one
    // of another length not at all.
    for (single, same) in [(lent.clone(), true), (vec![0.5f32; 3], false)] {
        let at = single.as_ptr() as usize;
        let made = Made {
            single: Some(single),
            blocks: None,
        };
        let other = Dual::build_keeping(&f, &n, &t, 2, Condensation::MatrixFree, made).unwrap();
        assert_eq!(other.single_copy().unwrap().0 == at, same);
        assert_eq!(products(&other), before, "lent copy taken: {same}");
    }
    // Only to a dual on the same factor: lend_single_of checks it.
    let refactored = metis_factor(&k, 1);
    assert!(dual.lend_single_of(&refactored).is_none());
    assert_eq!(dual.lend_single_of(&f).unwrap(), lent);
    // A dense dual lends nothing.
    let mut dense = Dual::build(&f, &n, &t, 2, DualForm::Dense).unwrap();
    assert!(dense.lend_single().is_none());
}

/// A panic inside the kept factor's slot (a Newton step that panicked while
/// it held it) leaves the slot empty, and it keeps a factor again after.
#[test]
fn a_panic_in_the_kept_factor_slot_leaves_it_empty_and_usable() {
    let (nx, ny) = (6, 3);
    let k = grid(nx, ny);
    let n = Csc::from_triplets(2, nx * ny, &[(0, 0, 1.0), (1, 1, 1.0)]);
    let t = Csc::from_triplets(2, nx * ny, &[(0, 6, 1.0), (1, 7, 1.0)]);
    let f = Factor::new(&k).unwrap();
    let dual = Dual::build(&f, &n, &t, 2, DualForm::Dense).unwrap();
    let keep = |dual: &Dual| {
        let eye = faer::Mat::<f64>::identity(2, 2);
        let llt = crate::dense::LltF32::of(eye.as_ref(), faer::Par::Seq).unwrap();
        let claim = dual.ledger.claim(16);
        dual.with_kept_factor(|slot| {
            *slot = Some(crate::dense::Reused {
                key: vec![0, 1],
                llt,
                _claim: claim,
            })
        });
    };
    let before = dual.ledger.live();
    keep(&dual);
    assert!(dual.with_kept_factor(|slot| slot.is_some()));
    assert_eq!(dual.ledger.live(), before + 16, "claimed while kept");
    let hit = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        dual.with_kept_factor(|_| panic!("a step that panicked"))
    }));
    assert!(hit.is_err());
    assert!(dual.with_kept_factor(|slot| slot.is_none()), "emptied");
    assert_eq!(dual.ledger.live(), before, "and its claim released");
    keep(&dual);
    assert!(
        dual.with_kept_factor(|slot| slot.is_some()),
        "and kept again"
    );
}
