//! Problem folders: K.mtx, N.mtx, T.mtx, f.txt, g.txt and mu.txt or p.txt, and
//! optionally the interface law (cn.txt, mn.txt, kt.txt, lt_prev.txt: see
//! [`Interface`]), written from a problem and read back with every size checked
//! against the others before any entry is read.

use super::matrix::*;
use super::text::*;
use super::{FrictionData, Interface, ProblemFolder};
use crate::error::{Error, ErrorKind, Result};
use crate::friction::Friction;
use crate::sparse::{Csc, Format, Indices, MatrixView, Storage};
use std::fs;
use std::path::{Path, PathBuf};

pub(super) fn check_len(name: &str, x: &[f64], len: usize, of: &str) -> Result<()> {
    if x.len() == len {
        Ok(())
    } else {
        Err(Error::new(
            ErrorKind::BadSize,
            format!("{name} has length {}, expected {len} ({of})", x.len()),
        ))
    }
}

pub(super) fn check_finite(name: &str, x: &[f64]) -> Result<()> {
    match x.iter().position(|v| !v.is_finite()) {
        None => Ok(()),
        Some(i) => Err(Error::new(
            ErrorKind::NotFinite,
            format!("{name}[{i}] = {} is not finite", x[i]),
        )),
    }
}

/// Writes one increment problem to the folder `dir` (created if needed): `K.mtx`,
/// `N.mtx`, `T.mtx`, `f.txt`, `g.txt` and `mu.txt` (Coulomb) or `p.txt` (Tresca).
/// Existing files of these names are replaced, and the other friction file
/// (`p.txt` when writing `mu.txt` and the reverse) is removed, so that the folder
/// always describes exactly this problem. Other files are left alone.
///
/// `k` is written as given (pass both triangles: a reader expects a full symmetric
/// K). Nothing is checked beyond what a reader needs: shapes, finiteness, d.
///
/// Errors: `BadArgument` (d not 2 or 3), `BadSize` (shapes or lengths do not fit
/// together), `NotFinite` (a NaN or infinity, which the folder could not hold),
/// `Io` (a file cannot be written).
#[allow(clippy::too_many_arguments)]
pub fn write_problem(
    dir: &Path,
    d: usize,
    k: &Csc,
    n: &Csc,
    t: &Csc,
    f: &[f64],
    g: &[f64],
    friction: Friction<'_>,
) -> Result<()> {
    if d != 2 && d != 3 {
        return Err(Error::new(
            ErrorKind::BadArgument,
            format!("d = {d}: the contact dimension must be 2 or 3"),
        ));
    }
    let ndof = k.nrows;
    let m = n.nrows;
    let shape = |ok: bool, msg: String| {
        if ok {
            Ok(())
        } else {
            Err(Error::new(ErrorKind::BadSize, msg))
        }
    };
    shape(
        k.ncols == ndof,
        format!("K is {} x {}, not square", k.nrows, k.ncols),
    )?;
    shape(
        n.ncols == ndof,
        format!("N has {} columns, K has {ndof}", n.ncols),
    )?;
    shape(
        t.ncols == ndof,
        format!("T has {} columns, K has {ndof}", t.ncols),
    )?;
    shape(
        t.nrows == (d - 1) * m,
        format!(
            "T has {} rows, expected (d-1) * rows(N) = {}",
            t.nrows,
            (d - 1) * m
        ),
    )?;
    let (fname, other, values) = match friction {
        Friction::Coulomb(mu) => ("mu", "p", mu),
        Friction::Tresca(p) => ("p", "mu", p),
    };
    check_len("f", f, ndof, "rows of K")?;
    check_len("g", g, m, "rows of N")?;
    check_len(fname, values, m, "rows of N")?;
    for (name, a) in [("K", k), ("N", n), ("T", t)] {
        check_finite(name, &a.values)?;
    }
    check_finite("f", f)?;
    check_finite("g", g)?;
    check_finite(fname, values)?;
    fs::create_dir_all(dir)
        .map_err(|e| io_err(format!("cannot create folder {}: {e}", dir.display())))?;
    write_matrix(&dir.join("K.mtx"), k)?;
    write_matrix(&dir.join("N.mtx"), n)?;
    write_matrix(&dir.join("T.mtx"), t)?;
    write_vector(&dir.join("f.txt"), f)?;
    write_vector(&dir.join("g.txt"), g)?;
    write_vector(&dir.join(format!("{fname}.txt")), values)?;
    let stale = dir.join(format!("{other}.txt"));
    match fs::remove_file(&stale) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(io_err(format!(
            "cannot remove {} (it would contradict {fname}.txt): {e}",
            stale.display()
        ))),
        _ => Ok(()),
    }
}

/// The interface files of the folder's module docs and [`Interface`], with
/// the length each must have in contacts (1) or rows of T (0: d - 1 per
/// contact), and whether `inf` is allowed.
const INTERFACE_FILES: [(&str, bool, bool); 4] = [
    ("cn.txt", true, true),
    ("mn.txt", true, false),
    ("kt.txt", true, true),
    ("lt_prev.txt", false, false),
];

/// The arrays of `interface` in the order of [`INTERFACE_FILES`].
fn interface_arrays(interface: &Interface) -> [Option<&Vec<f64>>; 4] {
    [
        interface.cn.as_ref(),
        interface.mn.as_ref(),
        interface.kt.as_ref(),
        interface.lt_prev.as_ref(),
    ]
}

/// Writes the interface files of `interface` into the problem folder `dir`
/// (written by [`write_problem`] first): each present array to its file, and
/// the file of each absent one removed, so that the folder describes exactly
/// this law (a folder with none of them is rigid). `inf` is written as `inf`.
///
/// Errors: `NotFinite` (a NaN, or an infinity where the file cannot hold one:
/// `mn.txt`, `lt_prev.txt`), `Io` (a file cannot be written or removed).
pub fn write_interface(dir: &Path, interface: &Interface) -> Result<()> {
    for ((file, _, inf_ok), x) in INTERFACE_FILES.iter().zip(interface_arrays(interface)) {
        let path = dir.join(file);
        match x {
            Some(x) => {
                if let Some(i) = x
                    .iter()
                    .position(|v| v.is_nan() || (v.is_infinite() && !inf_ok))
                {
                    return Err(Error::new(
                        ErrorKind::NotFinite,
                        format!("{file}[{i}] = {}: the folder cannot hold it", x[i]),
                    ));
                }
                write_vector(&path, x)?;
            }
            None => match fs::remove_file(&path) {
                Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                    return Err(io_err(format!(
                        "cannot remove {} (the law written has none): {e}",
                        path.display()
                    )));
                }
                _ => {}
            },
        }
    }
    Ok(())
}

/// Reads the interface files present in `dir` for m contacts of dimension d.
fn read_interface(dir: &Path, m: usize, d: usize) -> Result<Interface> {
    let mut out = [None, None, None, None];
    for (slot, (file, per_contact, inf_ok)) in out.iter_mut().zip(INTERFACE_FILES) {
        let Some(path) = existing(dir, file) else {
            continue;
        };
        let v = if inf_ok {
            parse_vector_with_inf(&read_text(&path)?, &path)?
        } else {
            read_vector(&path)?
        };
        let len = if per_contact { m } else { (d - 1) * m };
        if v.len() != len {
            return Err(bad_size(format!(
                "{} has {} values, expected {len} ({})",
                path.display(),
                v.len(),
                if per_contact {
                    "one per contact"
                } else {
                    "one per row of T"
                }
            )));
        }
        *slot = Some(v);
    }
    let [cn, mn, kt, lt_prev] = out;
    Ok(Interface {
        cn,
        mn,
        kt,
        lt_prev,
    })
}

/// A file of the folder that may be missing.
pub(super) fn existing(dir: &Path, name: &str) -> Option<PathBuf> {
    let p = dir.join(name);
    p.is_file().then_some(p)
}

/// A matrix file of a folder, read whole, with its header parsed.
pub(super) struct MatrixFile {
    path: PathBuf,
    text: String,
    h: Header,
}

impl MatrixFile {
    fn read(path: PathBuf) -> Result<MatrixFile> {
        let text = read_text(&path)?;
        let h = parse_header(&text, &path)?;
        Ok(MatrixFile { path, text, h })
    }

    /// "line `l`: `r` x `c`", the declared size and where.
    fn size(&self) -> String {
        format!(
            "line {}: {} x {}",
            self.h.size_line, self.h.nrows, self.h.ncols
        )
    }

    fn name(&self) -> std::path::Display<'_> {
        self.path.display()
    }

    /// Reads the entries (the dimensions are checked by the caller) and frees the
    /// text.
    fn parse(self) -> Result<Csc> {
        parse_entries(&self.text, &self.path, &self.h)
    }
}

pub(super) fn bad_size(message: String) -> Error {
    Error::new(ErrorKind::BadSize, message)
}

/// Reads a problem folder (see the module documentation). K is checked for
/// symmetry with the library's own test (`sparse::SYMMETRY_TOL`, the same as the C
/// API's) unless the file has a `symmetric` header.
///
/// Sizes are checked before anything of their size is allocated: first the header
/// (banner and size line) of K.mtx, N.mtx and T.mtx, then the vectors, whose
/// lengths the files themselves justify (a number takes 2 bytes or more); then K
/// must be n x n with n = len(f), N m x n with m = len(g) = len(mu or p), T
/// (d-1) m x n with d = 2 or 3 (T has no rows when m = 0). Only then are the
/// entries of the matrices read, so a file that declares sizes the folder does not
/// confirm (such as a 63-byte N.mtx declaring 3.4e8 columns) costs nothing. The
/// [`MAX_UNCONFIRMED_DIM`] limit of [`read_matrix`] does not apply here.
///
/// Errors: `Io` for a missing or malformed file (the message names the file, and
/// the line where there is one); `BadSize` for files whose sizes do not fit
/// together (the message names the files and the declared sizes); `NotSymmetric`
/// if K is not symmetric (the message names K.mtx and the pair, 1-based as in the
/// file); `OutOfMemory` if an allocation fails for sizes the folder confirms (the
/// message names the file).
pub fn read_problem(dir: &Path) -> Result<ProblemFolder> {
    if !dir.is_dir() {
        return Err(io_err(format!(
            "{}: no such folder (a problem folder holds K.mtx N.mtx T.mtx f.txt g.txt \
             and mu.txt or p.txt)",
            dir.display()
        )));
    }
    let name = |f: &str| dir.join(f).display().to_string();
    let kfile = MatrixFile::read(dir.join("K.mtx"))?;
    let nfile = MatrixFile::read(dir.join("N.mtx"))?;
    let tfile = MatrixFile::read(dir.join("T.mtx"))?;
    let (kh, nh, th) = (kfile.h, nfile.h, tfile.h);
    if kh.nrows != kh.ncols {
        return Err(bad_size(format!(
            "{}: K is {} x {} ({}), not square",
            kfile.name(),
            kh.nrows,
            kh.ncols,
            kfile.size()
        )));
    }
    let ndof = kh.nrows;
    let m = nh.nrows;
    for file in [&nfile, &tfile] {
        if file.h.ncols != ndof {
            return Err(bad_size(format!(
                "{} has {} columns ({}), but {} has {ndof} rows and columns ({})",
                file.name(),
                file.h.ncols,
                file.size(),
                kfile.name(),
                kfile.size()
            )));
        }
    }
    let d = if m == 0 {
        if th.nrows != 0 {
            return Err(bad_size(format!(
                "{} has {} rows ({}), but {} has none ({}: no contacts, so T must have none)",
                tfile.name(),
                th.nrows,
                tfile.size(),
                nfile.name(),
                nfile.size()
            )));
        }
        2
    } else if th.nrows == m {
        2
    } else if m.checked_mul(2) == Some(th.nrows) {
        3
    } else {
        return Err(bad_size(format!(
            "{} has {} rows ({}), but rows(T) must be (d-1) * rows(N) with d = 2 or 3, \
             and {} has {m} rows ({})",
            tfile.name(),
            th.nrows,
            tfile.size(),
            nfile.name(),
            nfile.size()
        )));
    };
    let vector = |file: &str, len: usize, of: &MatrixFile| -> Result<Vec<f64>> {
        let v = read_vector(&dir.join(file))?;
        if v.len() != len {
            return Err(bad_size(format!(
                "{} has {} values, expected {len} (the rows of {}, {})",
                name(file),
                v.len(),
                of.name(),
                of.size()
            )));
        }
        Ok(v)
    };
    let f = vector("f.txt", ndof, &kfile)?;
    let g = vector("g.txt", m, &nfile)?;
    let friction = match (existing(dir, "mu.txt"), existing(dir, "p.txt")) {
        (Some(_), Some(_)) => {
            return Err(io_err(format!(
                "{} holds both mu.txt (Coulomb) and p.txt (Tresca): keep only one",
                dir.display()
            )));
        }
        (Some(_), None) => FrictionData::Coulomb(vector("mu.txt", m, &nfile)?),
        (None, Some(_)) => FrictionData::Tresca(vector("p.txt", m, &nfile)?),
        (None, None) => {
            return Err(io_err(format!(
                "{} holds neither mu.txt (Coulomb coefficients) nor p.txt (Tresca bounds)",
                dir.display()
            )));
        }
    };
    let interface = read_interface(dir, m, d)?;
    // Every size is now confirmed by the vectors: read the entries, one file at a
    // time (each text is freed once parsed).
    let kpath = kfile.path.clone();
    let k = symmetric_checked(kfile.parse()?, &kpath)?;
    let n = nfile.parse()?;
    let t = tfile.parse()?;
    Ok(ProblemFolder {
        d,
        k,
        n,
        t,
        f,
        g,
        friction,
        interface,
    })
}

/// Runs K (square, both triangles) through the library's symmetric validation, the
/// one the C API applies to a fully stored K, with 1-based messages.
pub(super) fn symmetric_checked(k: Csc, path: &Path) -> Result<Csc> {
    let mut rows = Vec::new();
    let mut cols = Vec::new();
    let what = || format!("the {} entries of K for its symmetry check", k.nnz());
    try_room(&mut rows, k.nnz(), path, what())?;
    try_room(&mut cols, k.nnz(), path, what())?;
    for j in 0..k.ncols {
        for &r in &k.row_idx[k.col_ptr[j]..k.col_ptr[j + 1]] {
            rows.push(r as i64 + 1);
            cols.push(j as i64 + 1);
        }
    }
    let view = MatrixView {
        format: Format::Coo,
        storage: Storage::Full,
        base: 1,
        nrows: k.nrows,
        ncols: k.ncols,
        p: Indices::I64(&cols),
        i: Indices::I64(&rows),
        x: &k.values,
    };
    Csc::symmetric_from_view(&view, "K")
        .map_err(|e| Error::new(e.kind, format!("{}: {}", path.display(), e.message)))
}
