//! The same problem handed to the C API in every matrix layout (CSR, CSC, COO) x
//! index base (0, 1) x index width (int32, int64) x storage of K (full, upper,
//! lower) gives bit-identical u, lambda_n and lambda_t: the layout is only a way of
//! reading the caller's arrays, never a different problem.
//!
//! The problem: a 2D chain of 6 nodes on a rigid foundation, K with x-y coupling
//! (inclined springs and bars), every node a contact with normal -e_y and tangent
//! e_x, loads that close most contacts, push them sideways (some stick, some slip)
//! and leave one open.

use dualsplit::internals::ffi::*;
use std::ffi::CStr;
use std::ptr::null_mut;

const NODES: usize = 6;
const NDOF: usize = 2 * NODES;
const M: usize = NODES;

/// 0-based (row, column, value) entries, column by column, rows increasing.
type Triplets = Vec<(usize, usize, f64)>;

/// The stiffness of the chain, assembled so that it is exactly symmetric.
fn stiffness() -> Triplets {
    let mut k = vec![0.0; NDOF * NDOF];
    let mut touched = [false; NDOF * NDOF];
    let mut add = |dofs: &[usize], c: &[f64], stiffness: f64, sign: &[f64]| {
        for (a, &ra) in dofs.iter().enumerate() {
            for (b, &rb) in dofs.iter().enumerate() {
                k[ra * NDOF + rb] += stiffness * ((sign[a] * c[a]) * (sign[b] * c[b]));
                touched[ra * NDOF + rb] = true;
            }
        }
    };
    for j in 0..NODES {
        let (x, y) = (2 * j, 2 * j + 1);
        // Ground springs: horizontal, vertical and inclined (x-y coupling).
        add(&[x, y], &[1.0, 0.0], 1.0 + 0.1 * j as f64, &[1.0, 1.0]);
        add(&[x, y], &[0.0, 1.0], 2.0, &[1.0, 1.0]);
        add(&[x, y], &[0.6, 0.8], 1.5, &[1.0, 1.0]);
        if j + 1 < NODES {
            let (x2, y2) = (x + 2, y + 2);
            // Horizontal bar, inclined bar (couples x_j with y_j+1), shear spring.
            add(&[x, x2], &[1.0, 1.0], 4.0, &[1.0, -1.0]);
            add(
                &[x, y, x2, y2],
                &[0.6, 0.8, 0.6, 0.8],
                3.0,
                &[1.0, 1.0, -1.0, -1.0],
            );
            add(&[y, y2], &[1.0, 1.0], 2.5, &[1.0, -1.0]);
        }
    }
    let mut t = Vec::new();
    for c in 0..NDOF {
        for r in 0..NDOF {
            if touched[r * NDOF + c] {
                assert_eq!(k[r * NDOF + c], k[c * NDOF + r], "K is exactly symmetric");
                t.push((r, c, k[r * NDOF + c]));
            }
        }
    }
    t
}

/// N: row j is -e_y of node j, so N u <= g keeps node j above the foundation.
fn normals() -> Triplets {
    (0..M).map(|j| (j, 2 * j + 1, -1.0)).collect()
}

/// T: row j is e_x of node j.
fn tangents() -> Triplets {
    (0..M).map(|j| (j, 2 * j, 1.0)).collect()
}

const FX: [f64; NODES] = [0.6, 0.1, -0.3, 0.9, 0.0, 0.2];
const G: [f64; M] = [0.0, 0.01, 0.0, 0.02, 3.0, 0.0];
const P: [f64; M] = [0.2, 1.0, 1.0, 0.3, 1.0, 0.5];
const MU: [f64; M] = [0.1, 0.4, 0.4, 0.15, 0.4, 0.3];

fn load() -> Vec<f64> {
    (0..NODES).flat_map(|j| [FX[j], -2.0]).collect()
}

// ---------------------------------------------------------------------------------

/// How a matrix is laid out for the library.
#[derive(Copy, Clone, Debug, PartialEq)]
struct Layout {
    format: DsFormat,
    base: i32,
    index: DsIndexType,
    storage: DsStorage,
    /// Unsorted indices inside each column/row; COO also in reverse order with each
    /// entry split into two halves (duplicates, summed exactly by the library).
    scrambled: bool,
}

/// A matrix in one layout, owning its arrays.
struct Laid {
    nrows: usize,
    ncols: usize,
    layout: Layout,
    p32: Vec<i32>,
    i32: Vec<i32>,
    p64: Vec<i64>,
    i64: Vec<i64>,
    x: Vec<f64>,
}

impl Laid {
    fn new(nrows: usize, ncols: usize, entries: &Triplets, layout: Layout) -> Laid {
        let mut e: Triplets = entries
            .iter()
            .copied()
            .filter(|&(r, c, _)| match layout.storage {
                DsStorage::Full => true,
                DsStorage::Upper => r <= c,
                DsStorage::Lower => r >= c,
            })
            .collect();
        let base = layout.base as i64;
        let (mut p, mut i, mut x): (Vec<i64>, Vec<i64>, Vec<f64>) = (vec![], vec![], vec![]);
        match layout.format {
            DsFormat::Coo => {
                if layout.scrambled {
                    e.reverse();
                    e = e
                        .into_iter()
                        .flat_map(|(r, c, v)| [(r, c, v * 0.5), (r, c, v * 0.5)])
                        .collect();
                }
                for (r, c, v) in e {
                    p.push(c as i64 + base);
                    i.push(r as i64 + base);
                    x.push(v);
                }
            }
            DsFormat::Csc | DsFormat::Csr => {
                let csr = layout.format == DsFormat::Csr;
                // (outer, inner) = (column, row) for CSC, (row, column) for CSR.
                let mut oi: Vec<(usize, usize, f64)> = e
                    .iter()
                    .map(|&(r, c, v)| if csr { (r, c, v) } else { (c, r, v) })
                    .collect();
                oi.sort_by_key(|&(o, i, _)| (o, i));
                let outer = if csr { nrows } else { ncols };
                p.push(base);
                for o in 0..outer {
                    let mut slice: Vec<_> = oi.iter().filter(|t| t.0 == o).collect();
                    if layout.scrambled {
                        slice.reverse();
                    }
                    for &&(_, inner, v) in &slice {
                        i.push(inner as i64 + base);
                        x.push(v);
                    }
                    p.push(i.len() as i64 + base);
                }
            }
            DsFormat::Dense => unreachable!("tests/dense_k.rs covers the dense format"),
        }
        Laid {
            nrows,
            ncols,
            layout,
            p32: p.iter().map(|&v| i32::try_from(v).unwrap()).collect(),
            i32: i.iter().map(|&v| i32::try_from(v).unwrap()).collect(),
            p64: p,
            i64: i,
            x,
        }
    }

    fn ds(&self) -> DsMatrix {
        let (p, i) = match self.layout.index {
            DsIndexType::I32 => (self.p32.as_ptr().cast(), self.i32.as_ptr().cast()),
            DsIndexType::I64 => (self.p64.as_ptr().cast(), self.i64.as_ptr().cast()),
        };
        DsMatrix {
            format: self.layout.format as i32,
            index_type: self.layout.index as i32,
            base: self.layout.base,
            storage: self.layout.storage as i32,
            nrows: self.nrows as i64,
            ncols: self.ncols as i64,
            // Only read for COO; a CSR/CSC caller may leave garbage here.
            nnz: if self.layout.format == DsFormat::Coo {
                self.x.len() as i64
            } else {
                -12345
            },
            p,
            i,
            x: self.x.as_ptr(),
        }
    }
}

/// Every layout of K (general matrices use the FULL ones).
fn layouts(storages: &[DsStorage]) -> Vec<Layout> {
    let mut v = Vec::new();
    for format in [DsFormat::Csr, DsFormat::Csc, DsFormat::Coo] {
        for base in [0, 1] {
            for index in [DsIndexType::I32, DsIndexType::I64] {
                for &storage in storages {
                    for scrambled in [false, true] {
                        v.push(Layout {
                            format,
                            base,
                            index,
                            storage,
                            scrambled,
                        });
                    }
                }
            }
        }
    }
    v
}

const ALL_STORAGE: [DsStorage; 3] = [DsStorage::Full, DsStorage::Upper, DsStorage::Lower];

fn full(layout: Layout) -> Layout {
    Layout {
        storage: DsStorage::Full,
        ..layout
    }
}

fn message() -> String {
    // SAFETY: never NULL; valid until the next ds_ call on this thread.
    unsafe { CStr::from_ptr(ds_last_error_message()) }
        .to_string_lossy()
        .into_owned()
}

#[derive(Clone, Debug, PartialEq)]
struct Answer {
    u: Vec<f64>,
    lambda_n: Vec<f64>,
    lambda_t: Vec<f64>,
    n_open: i64,
    n_stick: i64,
    n_slip: i64,
}

fn create(k: &Laid, n: &Laid, t: &Laid) -> *mut DsProblem {
    let mut h: *mut DsProblem = null_mut();
    // SAFETY: the matrices own their arrays, which outlive the call.
    let s = unsafe { ds_problem_new(2, &k.ds(), &n.ds(), &t.ds(), &mut h) };
    assert_eq!(s, DsStatus::Ok, "{:?}: {}", k.layout, message());
    h
}

fn solve(h: *mut DsProblem, method: DsMethod, friction: DsFriction) -> Answer {
    let mut opts = std::mem::MaybeUninit::<DsOptions>::uninit();
    // SAFETY: opts is writable for sizeof(DsOptions) bytes, which init fills.
    let mut opts = unsafe {
        let st = ds_options_init(opts.as_mut_ptr(), std::mem::size_of::<DsOptions>());
        assert_eq!(st, DsStatus::Ok);
        opts.assume_init()
    };
    opts.method = method as i32;
    let bound = match friction {
        DsFriction::Tresca => P,
        DsFriction::Coulomb => MU,
    };
    let f = load();
    let (mut u, mut ln, mut lt) = (vec![0.0; NDOF], vec![0.0; M], vec![0.0; M]);
    let mut r = std::mem::MaybeUninit::<DsReport>::uninit();
    // SAFETY: arrays of the problem's sizes; the report is written on success.
    let s = unsafe {
        ds_solve(
            h,
            &opts,
            friction as i32,
            f.as_ptr(),
            G.as_ptr(),
            bound.as_ptr(),
            u.as_mut_ptr(),
            ln.as_mut_ptr(),
            lt.as_mut_ptr(),
            r.as_mut_ptr(),
        )
    };
    assert_eq!(s, DsStatus::Ok, "{}", message());
    // SAFETY: written by ds_solve on DS_STATUS_OK.
    let r = unsafe { r.assume_init() };
    assert!(r.err <= 1e-10, "err = {}", r.err);
    Answer {
        u,
        lambda_n: ln,
        lambda_t: lt,
        n_open: r.n_open,
        n_stick: r.n_stick,
        n_slip: r.n_slip,
    }
}

fn free(h: *mut DsProblem) {
    // SAFETY: h came from ds_problem_new and is freed once.
    unsafe { ds_problem_free(h) };
}

/// The CHOLMOD / CSparse layout: CSC, 0-based, int64, full.
fn reference_layout() -> Layout {
    Layout {
        format: DsFormat::Csc,
        base: 0,
        index: DsIndexType::I64,
        storage: DsStorage::Full,
        scrambled: false,
    }
}

fn laid_problem(k_layout: Layout) -> (Laid, Laid, Laid) {
    let nt = full(k_layout);
    (
        Laid::new(NDOF, NDOF, &stiffness(), k_layout),
        Laid::new(M, NDOF, &normals(), nt),
        Laid::new(M, NDOF, &tangents(), nt),
    )
}

const CASES: [(DsMethod, DsFriction); 3] = [
    (DsMethod::Split, DsFriction::Tresca),
    (DsMethod::Pgs, DsFriction::Tresca),
    (DsMethod::Split, DsFriction::Coulomb),
];

#[test]
fn the_problem_has_every_contact_state() {
    let (k, n, t) = laid_problem(reference_layout());
    let h = create(&k, &n, &t);
    let a = solve(h, DsMethod::Split, DsFriction::Tresca);
    assert!(a.n_open >= 1, "{a:?}");
    assert!(a.n_stick >= 1, "{a:?}");
    assert!(a.n_slip >= 1, "{a:?}");
    assert!(a.lambda_t.iter().any(|&l| l != 0.0));
    free(h);
}

#[test]
fn every_layout_gives_bit_identical_results() {
    let (k, n, t) = laid_problem(reference_layout());
    let h = create(&k, &n, &t);
    let reference: Vec<Answer> = CASES.iter().map(|&(m, f)| solve(h, m, f)).collect();
    free(h);
    let all = layouts(&ALL_STORAGE);
    assert_eq!(all.len(), 3 * 2 * 2 * 3 * 2);
    for layout in all {
        let (k, n, t) = laid_problem(layout);
        let h = create(&k, &n, &t);
        for (&(method, friction), want) in CASES.iter().zip(&reference) {
            let got = solve(h, method, friction);
            assert_eq!(&got, want, "{layout:?}, {method:?}, {friction:?}");
        }
        free(h);
    }
}

#[test]
fn refactor_and_set_contacts_accept_every_layout() {
    let (k, n, t) = laid_problem(reference_layout());
    let h = create(&k, &n, &t);
    let reference = solve(h, DsMethod::Split, DsFriction::Tresca);
    for layout in layouts(&ALL_STORAGE) {
        let (k2, n2, t2) = laid_problem(layout);
        // The pattern of K is the same whatever the layout it arrives in.
        // SAFETY: h is live; the matrices own their arrays.
        let s = unsafe { ds_problem_refactor(h, &k2.ds()) };
        assert_eq!(s, DsStatus::Ok, "{layout:?}: {}", message());
        if layout.storage == DsStorage::Full {
            // SAFETY: as above.
            let s = unsafe { ds_problem_set_contacts(h, &n2.ds(), &t2.ds()) };
            assert_eq!(s, DsStatus::Ok, "{layout:?}: {}", message());
        }
        let got = solve(h, DsMethod::Split, DsFriction::Tresca);
        assert_eq!(got, reference, "{layout:?}");
    }
    free(h);
}
