//! CHOLMOD as the host of `examples/host_solver --cholmod` (the feature
//! `cholmod`, which links -lcholmod; Debian: libsuitesparse-dev): K factored
//! by CHOLMOD (its default analysis: AMD or METIS, supernodal where that
//! pays), whole solves by `cholmod_l_solve2`, and with `--rows` the solves on
//! rows by `cholmod_l_solve2` with Bset, one column at a time, on a
//! simplicial copy of the factor (CHOLMOD solves with Bset on a simplicial
//! factor only). CHOLMOD 3 to 5 solve in double only here: the approximate
//! solves are exact ones.
//!
//! Only the handles and the four small structs below cross the boundary;
//! `cholmod_common` is opaque (its bytes, allocated here, are larger than
//! any CHOLMOD version's struct).

use dualsplit::{Csc, KSolve};
use std::ffi::{c_int, c_void};

/// cholmod_dense (the same in CHOLMOD 3 to 5).
#[repr(C)]
struct Dense {
    nrow: usize,
    ncol: usize,
    nzmax: usize,
    d: usize,
    x: *mut c_void,
    z: *mut c_void,
    xtype: c_int,
    dtype: c_int,
}

/// cholmod_sparse (the same in CHOLMOD 3 to 5).
#[repr(C)]
struct Sparse {
    nrow: usize,
    ncol: usize,
    nzmax: usize,
    p: *mut c_void,
    i: *mut c_void,
    nz: *mut c_void,
    x: *mut c_void,
    z: *mut c_void,
    stype: c_int,
    itype: c_int,
    xtype: c_int,
    dtype: c_int,
    sorted: c_int,
    packed: c_int,
}

impl Dense {
    /// A header over `x`, real double, `ncol` columns of `nrow` (leading
    /// dimension `nrow`): no copy.
    fn over(x: &mut [f64], nrow: usize, ncol: usize) -> Dense {
        debug_assert!(x.len() >= nrow * ncol);
        Dense {
            nrow,
            ncol,
            nzmax: nrow * ncol,
            d: nrow,
            x: x.as_mut_ptr().cast(),
            z: std::ptr::null_mut(),
            xtype: CHOLMOD_REAL,
            dtype: CHOLMOD_DOUBLE,
        }
    }
}

const CHOLMOD_A: c_int = 0;
const CHOLMOD_LONG: c_int = 2;
const CHOLMOD_PATTERN: c_int = 0;
const CHOLMOD_REAL: c_int = 1;
const CHOLMOD_DOUBLE: c_int = 0;

#[link(name = "cholmod")]
unsafe extern "C" {
    fn cholmod_l_start(c: *mut c_void) -> c_int;
    fn cholmod_l_finish(c: *mut c_void) -> c_int;
    fn cholmod_l_analyze(a: *mut Sparse, c: *mut c_void) -> *mut c_void;
    fn cholmod_l_factorize(a: *mut Sparse, l: *mut c_void, c: *mut c_void) -> c_int;
    fn cholmod_l_copy_factor(l: *mut c_void, c: *mut c_void) -> *mut c_void;
    fn cholmod_l_change_factor(
        to_xtype: c_int,
        to_ll: c_int,
        to_super: c_int,
        to_packed: c_int,
        to_monotonic: c_int,
        l: *mut c_void,
        c: *mut c_void,
    ) -> c_int;
    #[allow(clippy::too_many_arguments)]
    fn cholmod_l_solve2(
        sys: c_int,
        l: *mut c_void,
        b: *mut Dense,
        bset: *mut Sparse,
        x: *mut *mut Dense,
        xset: *mut *mut Sparse,
        y: *mut *mut Dense,
        e: *mut *mut Dense,
        c: *mut c_void,
    ) -> c_int;
    fn cholmod_l_allocate_sparse(
        nrow: usize,
        ncol: usize,
        nzmax: usize,
        sorted: c_int,
        packed: c_int,
        stype: c_int,
        xtype: c_int,
        c: *mut c_void,
    ) -> *mut Sparse;
    fn cholmod_l_free_factor(l: *mut *mut c_void, c: *mut c_void) -> c_int;
    fn cholmod_l_free_dense(x: *mut *mut Dense, c: *mut c_void) -> c_int;
    fn cholmod_l_free_sparse(a: *mut *mut Sparse, c: *mut c_void) -> c_int;
}

/// A CHOLMOD factor of K and what its solves reuse.
pub struct Cholmod {
    n: usize,
    /// cholmod_common's bytes (opaque here).
    common: Box<[u64]>,
    factor: *mut c_void,
    /// The simplicial copy for the solves with Bset, made at the first one.
    simplicial: *mut c_void,
    /// The whole solves' and the Bset solves' results and workspace.
    x: *mut Dense,
    y: *mut Dense,
    e: *mut Dense,
    xr: *mut Dense,
    yr: *mut Dense,
    er: *mut Dense,
    bset: *mut Sparse,
    xset: *mut Sparse,
    /// A right-hand side of the Bset solves, zero off the rows.
    b: Vec<f64>,
    /// Offer the solves on rows.
    rows: bool,
}

// SAFETY: the handles are used by one thread at a time (KSolve's contract:
// the library calls its host from the thread that calls into the problem).
unsafe impl Send for Cholmod {}

impl Cholmod {
    /// CHOLMOD's factor of `k` (SPD, full or upper storage); None where
    /// CHOLMOD fails. `rows`: offer the solves on rows.
    pub fn new(k: &Csc, rows: bool) -> Option<Cholmod> {
        let mut common = vec![0u64; 1 << 13].into_boxed_slice();
        let c = common.as_mut_ptr().cast::<c_void>();
        // SAFETY: c points to 64 KiB, more than any cholmod_common.
        unsafe { cholmod_l_start(c) };
        let mut p: Vec<i64> = k.col_ptr.iter().map(|&v| v as i64).collect();
        let mut i: Vec<i64> = k.row_idx.iter().map(|&v| v as i64).collect();
        let mut x = k.values.clone();
        let mut a = Sparse {
            nrow: k.nrows,
            ncol: k.ncols,
            nzmax: i.len(),
            p: p.as_mut_ptr().cast(),
            i: i.as_mut_ptr().cast(),
            nz: std::ptr::null_mut(),
            x: x.as_mut_ptr().cast(),
            z: std::ptr::null_mut(),
            stype: 1, // the upper triangle is read, the lower ignored
            itype: CHOLMOD_LONG,
            xtype: CHOLMOD_REAL,
            dtype: CHOLMOD_DOUBLE,
            sorted: 1,
            packed: 1,
        };
        // SAFETY: `a` describes the arrays above, alive during the calls.
        let factor = unsafe { cholmod_l_analyze(&mut a, c) };
        // SAFETY: as above; factor is CHOLMOD's (checked non-NULL).
        if factor.is_null() || unsafe { cholmod_l_factorize(&mut a, factor, c) } == 0 {
            return None;
        }
        Some(Cholmod {
            n: k.nrows,
            common,
            factor,
            simplicial: std::ptr::null_mut(),
            x: std::ptr::null_mut(),
            y: std::ptr::null_mut(),
            e: std::ptr::null_mut(),
            xr: std::ptr::null_mut(),
            yr: std::ptr::null_mut(),
            er: std::ptr::null_mut(),
            bset: std::ptr::null_mut(),
            xset: std::ptr::null_mut(),
            b: vec![0.0; k.nrows],
            rows,
        })
    }

    fn common(&mut self) -> *mut c_void {
        self.common.as_mut_ptr().cast()
    }

    /// The simplicial copy and the Bset pattern, made at the first solve on
    /// rows; false where CHOLMOD fails.
    fn ready_for_rows(&mut self) -> bool {
        if !self.simplicial.is_null() {
            return true;
        }
        let c = self.common();
        // SAFETY: the factor is CHOLMOD's; the copy becomes a simplicial LL'
        // (numeric values kept), the pattern an n x 1 sparse of nzmax n.
        unsafe {
            self.simplicial = cholmod_l_copy_factor(self.factor, c);
            if self.simplicial.is_null()
                || cholmod_l_change_factor(CHOLMOD_REAL, 1, 0, 1, 1, self.simplicial, c) == 0
            {
                return false;
            }
            self.bset = cholmod_l_allocate_sparse(self.n, 1, self.n, 1, 1, 0, CHOLMOD_PATTERN, c);
        }
        !self.bset.is_null()
    }
}

impl KSolve for Cholmod {
    fn n(&self) -> usize {
        self.n
    }

    fn solve(&mut self, x: &mut [f64], ncols: usize) -> Result<(), i32> {
        let n = self.n;
        let mut b = Dense::over(x, n, ncols);
        let c = self.common();
        // SAFETY: b describes x (n x ncols); X, Y, E are CHOLMOD's (or NULL)
        // and reallocated by it as needed.
        let ok = unsafe {
            cholmod_l_solve2(
                CHOLMOD_A,
                self.factor,
                &mut b,
                std::ptr::null_mut(),
                &mut self.x,
                std::ptr::null_mut(),
                &mut self.y,
                &mut self.e,
                c,
            )
        };
        if ok == 0 {
            return Err(-1);
        }
        // SAFETY: X is n x ncols, leading dimension d, after a success.
        let xd = unsafe { &*self.x };
        let got = unsafe { std::slice::from_raw_parts(xd.x.cast::<f64>(), xd.d * ncols) };
        for j in 0..ncols {
            x[j * n..(j + 1) * n].copy_from_slice(&got[j * xd.d..j * xd.d + n]);
        }
        Ok(())
    }

    fn solve_rows(
        &mut self,
        rows: &[usize],
        x: &mut [f64],
        ncols: usize,
        _approximate: bool,
    ) -> Option<Result<(), i32>> {
        if !self.rows {
            return None;
        }
        if !self.ready_for_rows() {
            return Some(Err(-2));
        }
        let len = rows.len();
        // SAFETY: bset is an n x 1 pattern of nzmax n >= len (made above).
        unsafe {
            let s = &mut *self.bset;
            let p = std::slice::from_raw_parts_mut(s.p.cast::<i64>(), 2);
            p[0] = 0;
            p[1] = len as i64;
            let i = std::slice::from_raw_parts_mut(s.i.cast::<i64>(), len);
            i.iter_mut().zip(rows).for_each(|(d, &r)| *d = r as i64);
        }
        for col in x.chunks_mut(len.max(1)).take(ncols) {
            rows.iter()
                .zip(col.iter())
                .for_each(|(&r, &v)| self.b[r] = v);
            let mut b = Dense::over(&mut self.b, self.n, 1);
            let c = self.common();
            // SAFETY: b describes self.b (n x 1), read only at Bset; the
            // results and workspace are CHOLMOD's (or NULL).
            let ok = unsafe {
                cholmod_l_solve2(
                    CHOLMOD_A,
                    self.simplicial,
                    &mut b,
                    self.bset,
                    &mut self.xr,
                    &mut self.xset,
                    &mut self.yr,
                    &mut self.er,
                    c,
                )
            };
            rows.iter().for_each(|&r| self.b[r] = 0.0);
            if ok == 0 {
                return Some(Err(-3));
            }
            // SAFETY: X is n x 1 after a success, defined on Xset, which
            // holds Bset (the rows).
            let got = unsafe { std::slice::from_raw_parts((*self.xr).x.cast::<f64>(), self.n) };
            rows.iter()
                .zip(col.iter_mut())
                .for_each(|(&r, v)| *v = got[r]);
        }
        Some(Ok(()))
    }
}

impl Drop for Cholmod {
    fn drop(&mut self) {
        let c = self.common();
        // SAFETY: each handle is CHOLMOD's or NULL (freeing NULL is a no-op).
        unsafe {
            for d in [
                &mut self.x,
                &mut self.y,
                &mut self.e,
                &mut self.xr,
                &mut self.yr,
                &mut self.er,
            ] {
                cholmod_l_free_dense(d, c);
            }
            cholmod_l_free_sparse(&mut self.bset, c);
            cholmod_l_free_sparse(&mut self.xset, c);
            cholmod_l_free_factor(&mut self.simplicial, c);
            cholmod_l_free_factor(&mut self.factor, c);
            cholmod_l_finish(c);
        }
    }
}
