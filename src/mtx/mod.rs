//! Matrix Market matrices, plain-text vectors and problem folders.
//!
//! A *problem folder* holds one increment problem (docs/design.md section 1) so that it
//! can be taken out of a simulation, replayed alone (`dualsplit solve DIR`), sent
//! in a bug report and tried with other methods:
//!
//! | file | content |
//! |---|---|
//! | `K.mtx` | K, n x n, symmetric (both triangles, or a `symmetric` header) |
//! | `N.mtx` | N, m x n |
//! | `T.mtx` | T, (d-1) m x n, contact by contact |
//! | `f.txt` | f, n numbers |
//! | `g.txt` | g, m numbers |
//! | `mu.txt` *or* `p.txt` | Coulomb coefficients or Tresca bounds, m numbers |
//! | `cn.txt` (optional) | normal compliance c_N per contact, m numbers, `inf` rigid |
//! | `mn.txt` (optional) | its exponent m_N, m numbers (default 1) |
//! | `kt.txt` (optional) | tangential stiffness k_T, m numbers, `inf` rigid stick |
//! | `lt_prev.txt` (optional) | the tangential force the return mapping starts from, (d-1) m numbers (default 0) |
//!
//! The last four are the interface law of docs/design.md section 8 (all absent:
//! rigid contacts).
//! Exactly one of `mu.txt` and `p.txt` must be present. Any other file in the
//! folder is ignored. d is inferred from rows(T) = (d-1) rows(N); with no contacts
//! (m = 0) it cannot be, and d = 2 is taken (the solution, u = K^-1 f, does not
//! depend on d then). Sizes that do not fit together are [`BadSize`](crate::ErrorKind::BadSize).
//!
//! # Matrix Market
//!
//! Read: `%%MatrixMarket matrix coordinate real general` or `... symmetric`
//! (`integer` instead of `real` is accepted too; keywords are case-insensitive),
//! and `%%MatrixMarket matrix array real general|symmetric`: a size line
//! "rows columns", then one value per line, column by column (symmetric: the
//! lower triangle, diagonal included); every value is kept, zeros too, so a
//! dense K read from an array file is factored densely.
//! Comment lines (starting with `%`) and blank lines may appear anywhere after the
//! header line. Indices are 1-based. Duplicate entries are summed. A `symmetric`
//! file stores one triangle (the lower one, as the format says, or the upper one,
//! but not a mix) and is mirrored. Every malformed file is rejected with
//! [`crate::ErrorKind::Io`] and a message that names the file and the line: a bad header,
//! a bad size line, an entry count that does not match the size line, an index out
//! of range, a token that is not a number, a NaN or an infinity.
//!
//! Written: `coordinate real general`, 1-based, every stored entry (explicit zeros
//! included) column by column, values in Rust's shortest round-trip exponent form
//! (`{:e}`, e.g. `-6.5119912894458026e-4`), which reads back bit for bit.
//!
//! # Vectors
//!
//! One number per line, in the same number format. Blank lines and lines starting
//! with `%` or `#` are skipped on reading.
//!
//! # Sizes and memory
//!
//! The readers never allocate from a size a file declares beyond what the file
//! itself, or the folder around it, justifies, and every allocation they make
//! themselves is fallible, so a tiny file declaring huge sizes is an error, at
//! once, not an abort or gigabytes of memory:
//!
//! - The entries of a matrix are stored as they are read, in room reserved for at
//!   most the declared count *and* at most what the text can hold (an entry line
//!   takes 6 bytes or more). An absurd entry count is then an `Io` error, with the
//!   line, for the missing entries.
//! - Assembling the compressed columns takes memory in O(rows + columns), which
//!   no entry count bounds (N of a large model has few entries and many columns).
//!   A matrix read on its own (`parse_matrix`, `read_matrix`) may declare at
//!   most max(`MAX_UNCONFIRMED_DIM` = 2^22, length of the file in bytes) rows
//!   and columns; more is [`BadSize`](crate::ErrorKind::BadSize), before any allocation. In a
//!   problem folder (`read_problem`) the vectors confirm the sizes instead: the
//!   headers of K.mtx, N.mtx and T.mtx are read first and checked against each
//!   other and against the lengths of f.txt, g.txt and mu.txt / p.txt (which
//!   their own bytes justify), so sizes that do not fit are `BadSize`, with the
//!   files and the declared sizes named, before any entry is read.
//! - A vector has no declared length: it grows as its values are read.
//! - An allocation that fails all the same (sizes that are consistent, on a
//!   machine without the memory) is [`crate::ErrorKind::OutOfMemory`], with the file and
//!   the declared sizes in the message.
//!
//! An `array` file holds one value per line: its room is capped by the text as
//! for the entries of a coordinate file (a value line takes 2 bytes or more).

mod folder;
mod matrix;
mod text;

pub use folder::{read_problem, write_interface, write_problem};
pub use matrix::{
    MAX_UNCONFIRMED_DIM, format_matrix, format_vector, parse_matrix, parse_vector, read_matrix,
    read_vector, write_matrix, write_vector,
};

use crate::friction::Friction;
use crate::sparse::Csc;
#[cfg(test)]
use text::*;

/// The friction data of a problem folder, owned.
#[derive(Clone, Debug, PartialEq)]
pub enum FrictionData {
    /// `p.txt`: Tresca slip bounds, one per contact.
    Tresca(Vec<f64>),
    /// `mu.txt`: Coulomb coefficients, one per contact.
    Coulomb(Vec<f64>),
}

impl FrictionData {
    /// Borrows the data as the solver's [`Friction`].
    pub fn as_friction(&self) -> Friction<'_> {
        match self {
            FrictionData::Tresca(p) => Friction::Tresca(p),
            FrictionData::Coulomb(mu) => Friction::Coulomb(mu),
        }
    }

    /// "tresca" or "coulomb".
    pub fn law_name(&self) -> &'static str {
        match self {
            FrictionData::Tresca(_) => "tresca",
            FrictionData::Coulomb(_) => "coulomb",
        }
    }

    /// The per-contact values (p or mu).
    pub fn values(&self) -> &[f64] {
        match self {
            FrictionData::Tresca(v) | FrictionData::Coulomb(v) => v,
        }
    }
}

/// The optional interface files of a problem folder (docs/design.md section
/// 8), each None where its file is absent: `cn.txt` (c_N per contact, `inf`
/// for rigid), `mn.txt` (m_N, default 1), `kt.txt` (k_T, `inf` for rigid
/// stick), `lt_prev.txt` (the tangential force the return mapping starts
/// from, one value per row of T; default zero). Lengths are checked by
/// [`read_problem`]; the values by `ContactProblem::set_compliance`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Interface {
    /// `cn.txt`, length m.
    pub cn: Option<Vec<f64>>,
    /// `mn.txt`, length m.
    pub mn: Option<Vec<f64>>,
    /// `kt.txt`, length m.
    pub kt: Option<Vec<f64>>,
    /// `lt_prev.txt`, length (d - 1) m.
    pub lt_prev: Option<Vec<f64>>,
}

impl Interface {
    /// True when no interface file is present (every contact rigid).
    pub fn is_empty(&self) -> bool {
        self == &Interface::default()
    }

    /// The number of the m contacts with a compliant law (a finite c_N or
    /// k_T; a missing file is rigid), as a problem counts them.
    pub fn compliant_contacts(&self, m: usize) -> usize {
        let at = |v: &Option<Vec<f64>>, i: usize| v.as_ref().map_or(f64::INFINITY, |v| v[i]);
        (0..m)
            .filter(|&i| crate::compliance::compliant(at(&self.cn, i), at(&self.kt, i)))
            .count()
    }
}

/// One problem read from a folder by [`read_problem`].
#[derive(Clone, Debug, PartialEq)]
pub struct ProblemFolder {
    /// Contact dimension, 2 or 3 (2 when there are no contacts).
    pub d: usize,
    /// K, n x n, both triangles (checked symmetric, or mirrored from a
    /// `symmetric` file).
    pub k: Csc,
    /// N, m x n.
    pub n: Csc,
    /// T, (d-1) m x n.
    pub t: Csc,
    /// f, length n.
    pub f: Vec<f64>,
    /// g, length m.
    pub g: Vec<f64>,
    /// mu (Coulomb) or p (Tresca), length m.
    pub friction: FrictionData,
    /// The interface law, where the folder holds one.
    pub interface: Interface,
}

impl ProblemFolder {
    /// Number of DOFs n.
    pub fn n_dofs(&self) -> usize {
        self.k.nrows
    }

    /// Number of contacts m.
    pub fn n_contacts(&self) -> usize {
        self.n.nrows
    }
}

#[cfg(test)]
mod tests {
    use super::matrix::*;
    use super::*;
    use crate::error::ErrorKind;
    use std::path::Path;

    /// An allocation that cannot succeed (more than isize::MAX bytes, refused
    /// without touching memory) is `OutOfMemory`, naming the file.
    #[test]
    fn mtx_failed_allocations_are_out_of_memory() {
        let path = Path::new("dir/X.mtx");
        let mut v: Vec<u64> = Vec::new();
        let e = try_room(&mut v, usize::MAX / 4, path, "room for the test").unwrap_err();
        assert_eq!(e.kind, ErrorKind::OutOfMemory);
        assert!(
            e.message.starts_with(&format!(
                "{}: cannot allocate room for the test",
                path.display()
            )),
            "{}",
            e.message
        );
        // Growing one by one is fallible too, and keeps amortised doubling.
        let mut v: Vec<u64> = Vec::new();
        for k in 0..100 {
            try_push(&mut v, k, path, "values").unwrap();
        }
        assert_eq!(v, (0..100).collect::<Vec<_>>());
    }

    /// The entries' room is capped by the text: an absurd count reserves nothing
    /// of its size, and the header alone allocates nothing of the declared sizes.
    #[test]
    fn mtx_header_and_unconfirmed_limit() {
        let path = Path::new("H.mtx");
        let text = "%%MatrixMarket matrix coordinate real general\n% c\n\n7 5 3\n";
        let h = parse_header(text, path).unwrap();
        assert_eq!(
            (h.nrows, h.ncols, h.nnz, h.symmetric, h.array, h.size_line),
            (7, 5, 3, false, false, 4)
        );
        check_unconfirmed(&h, text, path).unwrap();
        let big = Header {
            ncols: MAX_UNCONFIRMED_DIM + 1,
            ..h
        };
        let e = check_unconfirmed(&big, text, path).unwrap_err();
        assert_eq!(e.kind, ErrorKind::BadSize);
        assert!(e.message.starts_with("H.mtx line 4: "), "{}", e.message);
        // A file at least as long as the dimension confirms it.
        let long = " ".repeat(MAX_UNCONFIRMED_DIM + 1);
        check_unconfirmed(&big, &long, path).unwrap();
    }

    /// An array file is the matrix of its values, column by column, every value
    /// kept (zeros too); a symmetric one holds the lower triangle.
    #[test]
    fn mtx_array_files() {
        let path = Path::new("A.mtx");
        let general = "%%MatrixMarket matrix array real general\n% c\n2 3\n1\n0\n3\n4\n-5e-1\n6\n";
        let a = parse_matrix(general, path).unwrap();
        let want = Csc::from_triplets(
            2,
            3,
            &[
                (0, 0, 1.0),
                (1, 0, 0.0),
                (0, 1, 3.0),
                (1, 1, 4.0),
                (0, 2, -0.5),
                (1, 2, 6.0),
            ],
        );
        assert_eq!(a, want);
        let sym = "%%MatrixMarket matrix array real symmetric\n3 3\n4\n1\n0\n5\n2\n6\n";
        let s = parse_matrix(sym, path).unwrap();
        let mut t = Vec::new();
        for (r, c, v) in [
            (0, 0, 4.0),
            (1, 0, 1.0),
            (2, 0, 0.0),
            (1, 1, 5.0),
            (2, 1, 2.0),
            (2, 2, 6.0),
        ] {
            t.push((r, c, v));
            if r != c {
                t.push((c, r, v));
            }
        }
        assert_eq!(s, Csc::from_triplets(3, 3, &t));
        assert_eq!(s.nnz(), 9, "a dense K read from an array file stays dense");
        for (text, words) in [
            (
                "%%MatrixMarket matrix array real general\n2 2 4\n1\n2\n3\n4\n",
                "two integers",
            ),
            (
                "%%MatrixMarket matrix array real general\n2 2\n1\n2\n3\n",
                "end of file",
            ),
            (
                "%%MatrixMarket matrix array real general\n1 2\n1\n2\n3\n",
                "more entries",
            ),
            (
                "%%MatrixMarket matrix array real general\n1 1\n1 2\n",
                "one number",
            ),
            (
                "%%MatrixMarket matrix array real symmetric\n2 3\n",
                "square",
            ),
        ] {
            let e = parse_matrix(text, path).unwrap_err();
            assert!(e.message.contains(words), "{text:?}: {}", e.message);
        }
    }

    #[test]
    fn mtx_messages_clip_long_lines() {
        assert_eq!(clip("short"), "short");
        let long = "é".repeat(100);
        let c = clip(&long);
        assert_eq!(c.chars().count(), 63);
        assert!(c.ends_with("..."));
        let e = parse_vector(
            &format!("1\n{} 2\n", "9".repeat(10_000)),
            Path::new("v.txt"),
        )
        .unwrap_err();
        assert!(e.message.len() < 200, "{}", e.message);
    }
}
