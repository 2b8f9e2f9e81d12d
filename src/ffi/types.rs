//! The C enums. Enum-valued inputs are `int32_t` in C (a C caller may pass any
//! integer), so each enum here is parsed from an `i32`, answering
//! `DS_STATUS_BAD_ARGUMENT` for an unknown value. The enums are force-exported to the
//! header (cbindgen.toml `[export] include`).

use super::error::{CError as Error, CResult as Result};
use super::status::DsStatus;
use crate::options::{DualForm, Method, Ordering};
use crate::sparse::Storage;

/// Layout of a DsMatrix (its `format` field), named as in CSparse.
#[repr(C)]
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum DsFormat {
    /// Compressed sparse row: `p` holds nrows+1 row pointers, `i` the column indices.
    Csr = 0,
    /// Compressed sparse column (CSparse `cs` with nz = -1, packed `cholmod_sparse`):
    /// `p` holds ncols+1 column pointers, `i` the row indices.
    Csc = 1,
    /// Triplets (CSparse `cs` with nz >= 0): `i` holds nnz row indices, `p` nnz column
    /// indices. Duplicates are summed.
    Coo = 2,
    /// Dense, column-major (LAPACK, Fortran arrays): entry (r, c) at
    /// `x[r + c * nnz]`, the DsMatrix's `nnz` field holding the leading dimension
    /// (LDA >= nrows); `p`, `i` and `index_type` are not read, `base` only names
    /// rows and columns in messages. For K (full storage: checked symmetric;
    /// DS_STORAGE_UPPER / LOWER: the other triangle is not read) every entry is
    /// kept and K is factored by dense Cholesky (a Schur complement from MUMPS,
    /// PARDISO or PETSc); N and T keep their nonzeros. Added in version 0.7.
    Dense = 3,
}

/// Integer width of a DsMatrix's `p` and `i` arrays (its `index_type` field).
#[repr(C)]
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum DsIndexType {
    /// `int32_t` (Fortran default INTEGER, CSparse `cs_di`, CHOLMOD `int`).
    I32 = 0,
    /// `int64_t` (`SuiteSparse_long`, CSparse `cs_dl`, CHOLMOD `long`).
    I64 = 1,
}

/// Which part of a symmetric matrix a DsMatrix stores (its `storage` field). Only K
/// may use UPPER or LOWER; N and T must be FULL.
#[repr(C)]
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum DsStorage {
    /// Every entry is stored; K is checked for symmetry (CHOLMOD stype 0).
    Full = 0,
    /// Only entries with row <= column (CHOLMOD stype 1); entries below the diagonal
    /// are DS_STATUS_BAD_INDEX.
    Upper = 1,
    /// Only entries with row >= column (CHOLMOD stype -1); entries above the diagonal
    /// are DS_STATUS_BAD_INDEX.
    Lower = 2,
}

/// The iterative method run on the condensed dual (DsOptions `method`).
#[repr(C)]
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum DsMethod {
    /// Pop's dual splitting, Schur complement variant: the tangential step on
    /// S = A22 - A21 A11^-1 A12 over the current contact set, then the normal step on
    /// A11, both by projected Gauss-Seidel (the default until version 0.5).
    Split = 0,
    /// Plain block Gauss-Seidel on (lambda_N, lambda_T): tangential step on A22, normal
    /// step on A11, both by projected Gauss-Seidel.
    BlockGs = 1,
    /// Projected Gauss-Seidel on the whole dual, contact by contact (Siconos NSGS).
    Pgs = 2,
    /// Semismooth Newton (primal-dual active set) on the condensed dual, started by
    /// up to 40 Gauss-Seidel sweeps and globalised by backtracking and a fallback
    /// to Gauss-Seidel sweeps: the high-accuracy method.
    Newton = 3,
    /// Pop's splitting (Schur variant) with MPRGP / MPGP (Dostal) for the normal and
    /// tangential sub-problems.
    SplitMprgp = 4,
    /// MPRGP / MPGP on the whole dual; for Coulomb, the fixed point p = mu lambda_N
    /// outside.
    Mprgp = 5,
    /// The library's choice: semismooth Newton on a dense dual (falling back to
    /// DS_METHOD_SPLIT_MPRGP from Newton's best iterate when Newton stalls or
    /// reaches max_outer); on a matrix-free one Newton with Krylov steps, then
    /// MPRGP. DsReport.method names the method that gave the answer; the handle's
    /// log (level 1) says why. Added in version 0.5; the default from 0.6.
    Auto = 6,
}

/// How the products with the condensed dual A = B K^-1 B^T are formed (DsOptions
/// `dual_form`).
#[repr(C)]
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum DsDualForm {
    /// Dense A while d m <= 8000 dual unknowns, matrix-free beyond, and also
    /// below where the contact face ordered last would be a dense block that
    /// dominates the factor (thin slabs, long 2D strips; with DS_METHOD_AUTO,
    /// DS_METHOD_NEWTON or DS_METHOD_MPRGP: docs/design.md section 6); a method that
    /// reads entries of A (all but DS_METHOD_AUTO, DS_METHOD_NEWTON and
    /// DS_METHOD_MPRGP) assembles A when it needs it.
    /// The default.
    Auto = 0,
    /// Assemble the dense (d m) x (d m) matrix A (DS_STATUS_OUT_OF_MEMORY if it does
    /// not fit).
    Dense = 1,
    /// Never form A nor anything c x c: each product is one solve with K's factor
    /// (a handle created with it factors K in the best plain ordering);
    /// DS_METHOD_AUTO, DS_METHOD_NEWTON (Krylov steps) and DS_METHOD_MPRGP run
    /// this way (the others: DS_STATUS_BAD_ARGUMENT).
    MatrixFree = 2,
}

/// The fill-reducing ordering of K's factorisation (DsOptions field `ordering`,
/// read by ds_problem_new_opts; as CHOLMOD's ordering policy or MUMPS's ICNTL(7)).
#[repr(C)]
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum DsOrdering {
    /// In 2D: AMD, and METIS as well where AMD's factor has large fronts (more
    /// than 500 flops per entry of L), the one with fewer flops kept; in 3D:
    /// METIS (AMD where METIS fails). The default.
    Auto = 0,
    /// Approximate minimum degree.
    Amd = 1,
    /// Nested dissection (METIS_NodeND, METIS 5 built into the library).
    Metis = 2,
    /// Reported only (DsReport.ordering, DsInfo.ordering; as an option:
    /// DS_STATUS_BAD_ARGUMENT): K has every entry stored (DS_FORMAT_DENSE, or a
    /// sparse pattern that is full) and was factored by dense Cholesky, without a
    /// fill-reducing ordering. Added in version 0.7.
    Dense = 3,
}

/// Friction law of one increment (the `friction` argument of ds_solve / ds_step).
#[repr(C)]
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum DsFriction {
    /// Given friction: `bound` holds the slip bounds p_i >= 0 (force units), and
    /// |lambda_T,i| <= p_i.
    Tresca = 0,
    /// Coulomb friction: `bound` holds the coefficients mu_i >= 0 (dimensionless), and
    /// |lambda_T,i| <= mu_i lambda_N,i, solved by fixed point on p = mu lambda_N.
    Coulomb = 1,
}

/// An enum that C passes as an `int32_t`.
pub(crate) trait CEnum: Copy + 'static {
    /// The C type name, e.g. "DsFormat".
    const NAME: &'static str;
    /// Every variant with its C name; the C value of a variant is its index.
    const ALL: &'static [(Self, &'static str)];

    /// The variant with C value `v`, if any.
    fn from_i32(v: i32) -> Option<Self> {
        usize::try_from(v)
            .ok()
            .and_then(|i| Self::ALL.get(i))
            .map(|&(e, _)| e)
    }

    /// The variant with C value `v`, or `BadArgument` naming `what` and the valid values.
    fn parse(v: i32, what: &str) -> Result<Self> {
        Self::from_i32(v).ok_or_else(|| {
            let valid: Vec<String> = Self::ALL
                .iter()
                .enumerate()
                .map(|(i, (_, name))| format!("{name} = {i}"))
                .collect();
            Error::new(
                DsStatus::BadArgument,
                format!(
                    "{what} = {v} is not a valid {} ({})",
                    Self::NAME,
                    valid.join(", ")
                ),
            )
        })
    }
}

impl CEnum for DsFormat {
    const NAME: &'static str = "DsFormat";
    const ALL: &'static [(Self, &'static str)] = &[
        (DsFormat::Csr, "DS_FORMAT_CSR"),
        (DsFormat::Csc, "DS_FORMAT_CSC"),
        (DsFormat::Coo, "DS_FORMAT_COO"),
        (DsFormat::Dense, "DS_FORMAT_DENSE"),
    ];
}

impl CEnum for DsIndexType {
    const NAME: &'static str = "DsIndexType";
    const ALL: &'static [(Self, &'static str)] = &[
        (DsIndexType::I32, "DS_INDEX_TYPE_I32"),
        (DsIndexType::I64, "DS_INDEX_TYPE_I64"),
    ];
}

impl CEnum for DsStorage {
    const NAME: &'static str = "DsStorage";
    const ALL: &'static [(Self, &'static str)] = &[
        (DsStorage::Full, "DS_STORAGE_FULL"),
        (DsStorage::Upper, "DS_STORAGE_UPPER"),
        (DsStorage::Lower, "DS_STORAGE_LOWER"),
    ];
}

impl CEnum for DsMethod {
    const NAME: &'static str = "DsMethod";
    const ALL: &'static [(Self, &'static str)] = &[
        (DsMethod::Split, "DS_METHOD_SPLIT"),
        (DsMethod::BlockGs, "DS_METHOD_BLOCK_GS"),
        (DsMethod::Pgs, "DS_METHOD_PGS"),
        (DsMethod::Newton, "DS_METHOD_NEWTON"),
        (DsMethod::SplitMprgp, "DS_METHOD_SPLIT_MPRGP"),
        (DsMethod::Mprgp, "DS_METHOD_MPRGP"),
        (DsMethod::Auto, "DS_METHOD_AUTO"),
    ];
}

impl CEnum for DsDualForm {
    const NAME: &'static str = "DsDualForm";
    const ALL: &'static [(Self, &'static str)] = &[
        (DsDualForm::Auto, "DS_DUAL_FORM_AUTO"),
        (DsDualForm::Dense, "DS_DUAL_FORM_DENSE"),
        (DsDualForm::MatrixFree, "DS_DUAL_FORM_MATRIX_FREE"),
    ];
}

impl CEnum for DsOrdering {
    const NAME: &'static str = "DsOrdering";
    const ALL: &'static [(Self, &'static str)] = &[
        (DsOrdering::Auto, "DS_ORDERING_AUTO"),
        (DsOrdering::Amd, "DS_ORDERING_AMD"),
        (DsOrdering::Metis, "DS_ORDERING_METIS"),
        (DsOrdering::Dense, "DS_ORDERING_DENSE"),
    ];
}

/// How a handle on the host's solves obtains the contacts' d x d diagonal
/// blocks of A (DsHostSolver `blocks`) where the host gives no entries of
/// K^-1. Added in version 0.10.
#[repr(C)]
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum DsHostBlocks {
    /// The host's inverse_entries where given (one call); else
    /// DS_HOST_BLOCKS_FACTOR where K is handed over, the factor fits
    /// max_memory (the machine's memory where 0) and its flops are fewer than
    /// the solves' (c solves of 4 nnz(L) flops against 2.5 times the
    /// factorisation's); else DS_HOST_BLOCKS_SOLVES. The default (a zeroed
    /// struct): a host that hands K over expects it used.
    Auto = 0,
    /// By d m of the host's solves, 32 right-hand sides per call (from its
    /// inverse_entries where given): nothing of K's factor in the library's
    /// memory. 9-75 factorisations of K on the benchmark's 3D blocks.
    Solves = 1,
    /// By the library's own factor of K, which must be handed over
    /// (DS_STATUS_BAD_ARGUMENT without it): factored once when the blocks
    /// are formed (creation, ds_problem_set_contacts), its selected inversion
    /// giving the blocks, and freed before the call returns; its bytes count
    /// in the call's memory prediction and max_memory. 1.5-2.5
    /// factorisations of K in all on the benchmark's 3D blocks.
    /// inverse_entries is not called. Every product still calls the host.
    Factor = 2,
}

impl CEnum for DsHostBlocks {
    const NAME: &'static str = "DsHostBlocks";
    const ALL: &'static [(Self, &'static str)] = &[
        (DsHostBlocks::Auto, "DS_HOST_BLOCKS_AUTO"),
        (DsHostBlocks::Solves, "DS_HOST_BLOCKS_SOLVES"),
        (DsHostBlocks::Factor, "DS_HOST_BLOCKS_FACTOR"),
    ];
}

impl From<DsHostBlocks> for crate::HostBlocks {
    fn from(b: DsHostBlocks) -> crate::HostBlocks {
        match b {
            DsHostBlocks::Solves => crate::HostBlocks::Solves,
            DsHostBlocks::Factor => crate::HostBlocks::Factor,
            DsHostBlocks::Auto => crate::HostBlocks::Auto,
        }
    }
}

impl From<DsOrdering> for Ordering {
    fn from(o: DsOrdering) -> Ordering {
        match o {
            DsOrdering::Auto => Ordering::Auto,
            DsOrdering::Amd => Ordering::Amd,
            DsOrdering::Metis => Ordering::Metis,
            DsOrdering::Dense => Ordering::Dense,
        }
    }
}

impl From<Ordering> for DsOrdering {
    fn from(o: Ordering) -> DsOrdering {
        match o {
            Ordering::Auto => DsOrdering::Auto,
            Ordering::Amd => DsOrdering::Amd,
            Ordering::Metis => DsOrdering::Metis,
            Ordering::Dense => DsOrdering::Dense,
        }
    }
}

impl From<DsDualForm> for DualForm {
    fn from(f: DsDualForm) -> DualForm {
        match f {
            DsDualForm::Auto => DualForm::Auto,
            DsDualForm::Dense => DualForm::Dense,
            DsDualForm::MatrixFree => DualForm::MatrixFree,
        }
    }
}

impl From<DualForm> for DsDualForm {
    fn from(f: DualForm) -> DsDualForm {
        match f {
            DualForm::Auto => DsDualForm::Auto,
            DualForm::Dense => DsDualForm::Dense,
            DualForm::MatrixFree => DsDualForm::MatrixFree,
        }
    }
}

impl CEnum for DsFriction {
    const NAME: &'static str = "DsFriction";
    const ALL: &'static [(Self, &'static str)] = &[
        (DsFriction::Tresca, "DS_FRICTION_TRESCA"),
        (DsFriction::Coulomb, "DS_FRICTION_COULOMB"),
    ];
}

impl From<DsStorage> for Storage {
    fn from(s: DsStorage) -> Storage {
        match s {
            DsStorage::Full => Storage::Full,
            DsStorage::Upper => Storage::Upper,
            DsStorage::Lower => Storage::Lower,
        }
    }
}

// DsMethod lists the methods in the order of `Method::ALL` (options.rs): a
// method added there without its C value fails to compile here, and
// `c_values_are_indices` checks that the names match.
const _: () = assert!(<DsMethod as CEnum>::ALL.len() == Method::ALL.len());

impl From<DsMethod> for Method {
    fn from(m: DsMethod) -> Method {
        Method::ALL[m as usize]
    }
}

impl From<Method> for DsMethod {
    fn from(m: Method) -> DsMethod {
        <DsMethod as CEnum>::ALL[m as usize].0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check<E: CEnum + PartialEq + std::fmt::Debug>(value: impl Fn(E) -> i32) {
        for (i, &(e, _)) in E::ALL.iter().enumerate() {
            assert_eq!(value(e), i as i32, "{}", E::NAME);
            assert_eq!(E::from_i32(i as i32), Some(e));
        }
        assert_eq!(E::from_i32(-1), None);
        assert_eq!(E::from_i32(E::ALL.len() as i32), None);
        let e = E::parse(77, "K.format").unwrap_err();
        assert_eq!(e.status, DsStatus::BadArgument);
        assert!(e.message.contains("K.format = 77"), "{}", e.message);
    }

    #[test]
    fn c_values_are_indices() {
        check::<DsFormat>(|e| e as i32);
        check::<DsIndexType>(|e| e as i32);
        check::<DsStorage>(|e| e as i32);
        check::<DsMethod>(|e| e as i32);
        check::<DsFriction>(|e| e as i32);
        check::<DsDualForm>(|e| e as i32);
        check::<DsHostBlocks>(|e| e as i32);
        for f in DualForm::ALL {
            assert_eq!(DualForm::from(DsDualForm::from(f)), f);
        }
        for m in Method::ALL {
            assert_eq!(Method::from(DsMethod::from(m)), m);
            let c_name = format!("DS_METHOD_{}", m.name().to_uppercase().replace('-', "_"));
            assert_eq!(<DsMethod as CEnum>::ALL[m as usize].1, c_name);
            assert_eq!(
                DsMethod::from(m) as usize,
                Method::ALL.iter().position(|&x| x == m).unwrap()
            );
        }
    }
}
