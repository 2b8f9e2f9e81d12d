//! Small scenes the unit tests of several modules solve.

use crate::sparse::Csc;

/// A thin slab of springs, nx x ny x nz nodes with 3 DOFs each: every two
/// nodes at most one cell diagonal apart joined by a unit spring along
/// their line (a lattice that resists shear through its diagonals, as an
/// elastic solid does), plus `anchor` on the diagonal.
pub(crate) fn lattice(nx: usize, ny: usize, nz: usize, anchor: f64) -> Csc {
    let id = |i: usize, j: usize, l: usize| i + nx * (j + ny * l);
    let mut t = Vec::new();
    for l in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let a = id(i, j, l);
                for r in 0..3 {
                    t.push((3 * a + r, 3 * a + r, anchor));
                }
                // Offsets (di, dj, dl) in {-1, 0, 1}^3 after (0, 0, 0) in
                // the order of off = (di + 1) + 3 (dj + 1) + 9 (dl + 1):
                // each pair once.
                for off in 14..27usize {
                    let o = [off % 3, (off / 3) % 3, off / 9].map(|v| v as i64 - 1);
                    let (i2, j2, l2) = (i as i64 + o[0], j as i64 + o[1], l as i64 + o[2]);
                    if i2 < 0 || j2 < 0 || l2 < 0 {
                        continue;
                    }
                    let (i2, j2, l2) = (i2 as usize, j2 as usize, l2 as usize);
                    if i2 >= nx || j2 >= ny || l2 >= nz {
                        continue;
                    }
                    let b = id(i2, j2, l2);
                    let len = ((o[0] * o[0] + o[1] * o[1] + o[2] * o[2]) as f64).sqrt();
                    let e = o.map(|v| v as f64 / len);
                    for r in 0..3 {
                        for s in 0..3 {
                            let v = e[r] * e[s];
                            t.push((3 * a + r, 3 * a + s, v));
                            t.push((3 * b + r, 3 * b + s, v));
                            t.push((3 * a + r, 3 * b + s, -v));
                            t.push((3 * b + r, 3 * a + s, -v));
                        }
                    }
                }
            }
        }
    }
    let n = 3 * nx * ny * nz;
    Csc::from_triplets(n, n, &t)
}

/// Every bottom node of an nx x ny lattice slab a contact: N = e_z, T =
/// e_x, e_y (3 DOFs per node, the bottom layer first), as matrices with
/// `ndof` columns.
pub(crate) fn slab_contacts(nx: usize, ny: usize, ndof: usize) -> (Csc, Csc) {
    let m = nx * ny;
    let nmat: Vec<_> = (0..m).map(|i| (i, 3 * i + 2, 1.0)).collect();
    let tmat: Vec<_> = (0..2 * m).map(|r| (r, 3 * (r / 2) + r % 2, 1.0)).collect();
    (
        Csc::from_triplets(m, ndof, &nmat),
        Csc::from_triplets(2 * m, ndof, &tmat),
    )
}
