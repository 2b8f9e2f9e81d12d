//! Scene generator of the benchmark: an elastic block on a rigid foundation with a
//! curved (parabolic) gap, plane-strain Q4 elements in 2D and trilinear H8 elements in
//! 3D on a uniform grid of unit cells, or (a name ending in `g`, `3d-64x64x6g`)
//! on a grid graded across the contact face: the cells' horizontal sizes grow
//! geometrically from the centre of the face to its edges, GRADING^(1 - 2/n)
//! times (3.6-3.9 on the benchmark's faces of n = 24 to 116 cells; the way a
//! host refines its mesh where the contact zone is), with the same extent as
//! the uniform grid and unit cells vertically.
//!
//! - The top face is clamped and moved by (s, -delta) (2D) or (s, 0, -delta) (3D): it
//!   presses the block onto the foundation and shears it, so that the contact zone
//!   has open, sticking and slipping contacts. The prescribed DOFs are eliminated
//!   into f (f = -K_fp u_p), K is the free block (SPD).
//! - Every node of the bottom face is a contact: N row = -1 on its vertical DOF,
//!   T row(s) = +1 on its horizontal DOF(s). The gap of a node at horizontal
//!   position x is g(x) = kappa |x - x_c|^2.
//!
//! On a uniform grid all elements have the same stiffness matrix: it is
//! computed once (on a graded grid once per column of cells), and K is
//! assembled node by node from it directly in compressed columns, in O(n) time
//! and memory, without a dense matrix or a list of element triplets (a list of
//! element triplets would be 32 million entries for the 2D 1e6 DOF scene,
//! twice the size of K itself). `check_assembly` compares this with the
//! element-by-element triplet assembly through `Csc::from_triplets` on small grids.

use dualsplit::Csc;

/// The size of a scene: cells per direction (nz = 0 in 2D), and whether the
/// grid is graded across the contact face.
#[derive(Copy, Clone, Debug)]
pub struct Spec {
    pub dim: usize,
    pub nx: usize,
    pub ny: usize,
    pub nz: usize,
    pub graded: bool,
}

/// The growth of a graded face's cells from its centre to its edges: the
/// largest over the smallest cell size tends to it as the cells get many
/// (GRADING^(1 - 2/n) for n cells; see [`cell_sizes`]).
pub const GRADING: f64 = 4.0;

impl Spec {
    pub fn name(&self) -> String {
        let g = if self.graded { "g" } else { "" };
        if self.dim == 2 {
            format!("2d-{}x{}{g}", self.nx, self.ny)
        } else {
            format!("3d-{}x{}x{}{g}", self.nx, self.ny, self.nz)
        }
    }

    /// Parses a name as returned by [`Spec::name`].
    pub fn parse(s: &str) -> Option<Spec> {
        let (s, graded) = match s.strip_suffix('g') {
            Some(r) => (r, true),
            None => (s, false),
        };
        let (dim, rest) = if let Some(r) = s.strip_prefix("2d-") {
            (2, r)
        } else if let Some(r) = s.strip_prefix("3d-") {
            (3, r)
        } else {
            return None;
        };
        let v: Vec<usize> = rest
            .split('x')
            .map(|t| t.parse().ok())
            .collect::<Option<_>>()?;
        match (dim, v.as_slice()) {
            (2, &[nx, ny]) if nx > 0 && ny > 0 => Some(Spec {
                dim,
                nx,
                ny,
                nz: 0,
                graded,
            }),
            (3, &[nx, ny, nz]) if nx > 0 && ny > 0 && nz > 0 => Some(Spec {
                dim,
                nx,
                ny,
                nz,
                graded,
            }),
            _ => None,
        }
    }

    /// Nodes per direction.
    fn nodes(&self) -> [usize; 3] {
        if self.dim == 2 {
            [self.nx + 1, self.ny + 1, 1]
        } else {
            [self.nx + 1, self.ny + 1, self.nz + 1]
        }
    }

    /// Nodes of one horizontal layer (the bottom face: the contacts).
    pub fn layer(&self) -> usize {
        let nn = self.nodes();
        if self.dim == 2 { nn[0] } else { nn[0] * nn[1] }
    }

    /// Number of free DOFs (all nodes but the clamped top layer).
    pub fn n_dofs(&self) -> usize {
        let nn = self.nodes();
        self.dim * (nn[0] * nn[1] * nn[2] - self.layer())
    }

    /// Number of contacts (the nodes of the bottom face).
    pub fn n_contacts(&self) -> usize {
        self.layer()
    }

    /// The cells' sizes along each axis (x, y, z; the vertical axis, y in 2D
    /// and z in 3D, uniform; the unused third axis one cell of size 1 in 2D).
    fn cell_sizes(&self) -> [Vec<f64>; 3] {
        let horizontal = |n: usize| cell_sizes(n, self.graded);
        if self.dim == 2 {
            [horizontal(self.nx), vec![1.0; self.ny], vec![1.0]]
        } else {
            [horizontal(self.nx), horizontal(self.ny), vec![1.0; self.nz]]
        }
    }
}

/// The sizes of `n` cells along a horizontal axis, summing to n: all 1, or
/// graded (cell i's size proportional to GRADING^u, u = |i + 1/2 - n/2| / (n/2)
/// the distance of its centre from the face's centre: fine where the contact
/// zone is, GRADING^(1 - 2/n) times coarser at the edges than at the centre
/// for even n).
fn cell_sizes(n: usize, graded: bool) -> Vec<f64> {
    if !graded {
        return vec![1.0; n];
    }
    let half = 0.5 * n as f64;
    let raw: Vec<f64> = (0..n)
        .map(|i| GRADING.powf((i as f64 + 0.5 - half).abs() / half))
        .collect();
    let scale = n as f64 / raw.iter().sum::<f64>();
    raw.iter().map(|h| h * scale).collect()
}

/// Node positions along an axis from its cells' sizes (n + 1 values from 0).
fn positions(sizes: &[f64]) -> Vec<f64> {
    let mut x = vec![0.0];
    for h in sizes {
        x.push(x.last().unwrap() + h);
    }
    x
}

/// The element stiffness matrices of a grid: one on a uniform grid, one per
/// column of cells (all cells of a column have the same size) on a graded one.
struct Stiffness {
    per_column: Vec<Vec<f64>>,
    nx: usize,
    graded: bool,
}

impl Stiffness {
    fn of(spec: &Spec) -> Stiffness {
        let [hx, hy, hz] = spec.cell_sizes();
        let dim = spec.dim;
        let per_column = if spec.graded {
            let rows = if dim == 2 { 1 } else { hy.len() };
            (0..rows)
                .flat_map(|ey| {
                    let (hx, hy, hz) = (&hx, &hy, &hz);
                    (0..hx.len()).map(move |ex| {
                        if dim == 2 {
                            element_stiffness(2, [hx[ex], 1.0, 1.0])
                        } else {
                            element_stiffness(3, [hx[ex], hy[ey], hz[0]])
                        }
                    })
                })
                .collect()
        } else {
            vec![element_stiffness(dim, [1.0; 3])]
        };
        Stiffness {
            per_column,
            nx: spec.nx,
            graded: spec.graded,
        }
    }

    /// The stiffness of the cell with lower corner e (cell indices).
    fn of_cell(&self, dim: usize, e: [usize; 3]) -> &[f64] {
        if !self.graded {
            return &self.per_column[0];
        }
        let row = if dim == 2 { 0 } else { e[1] };
        &self.per_column[row * self.nx + e[0]]
    }
}

/// The physical parameters of the scenes (nondimensional: unit cells, E = 1).
pub const YOUNG: f64 = 1.0;
pub const POISSON: f64 = 0.3;
/// Coulomb coefficient; the Tresca bound is MU times the mean contact pressure.
pub const MU: f64 = 0.3;

/// A contact problem: K (free DOFs, both triangles), N, T, f, g, and the friction
/// data of both laws.
pub struct Scene {
    pub spec: Spec,
    pub d: usize,
    pub k: Csc,
    pub n: Csc,
    pub t: Csc,
    pub f: Vec<f64>,
    pub g: Vec<f64>,
    /// Tresca bound per contact.
    pub p: Vec<f64>,
    /// Coulomb coefficient per contact.
    pub mu: Vec<f64>,
    /// The element matrices K and the loads of the top's motions are
    /// assembled from.
    stiffness: Stiffness,
}

/// The top displacement (vertical press delta, horizontal shift s) for a block of
/// height h.
fn top_motion(height: f64) -> (f64, f64) {
    let delta = 2e-3 * height;
    (delta, 0.5 * delta)
}

impl Scene {
    /// Builds the scene of `spec`.
    pub fn build(spec: Spec) -> Scene {
        let dim = spec.dim;
        let nn = spec.nodes();
        let (lx, ly, lz) = (spec.nx as f64, spec.ny as f64, spec.nz as f64);
        let height = if dim == 2 { ly } else { lz };
        let (delta, shift) = top_motion(height);
        let mut top = vec![0.0; dim];
        top[0] = shift;
        top[dim - 1] = -delta;
        let stiffness = Stiffness::of(&spec);
        let (k, f) = assemble(&spec, &stiffness, &top);
        let [hx, hy, _] = spec.cell_sizes();
        let (xs, ys) = (positions(&hx), positions(&hy));
        // A node's share of the face, per axis: half of each cell beside
        // it, and the whole cell at the face's edge (1 everywhere on the
        // uniform grid, as before grading: an edge node's bound is twice
        // its half cell's, a corner's four times).
        let share = |h: &[f64], i: usize| match (i.checked_sub(1).map(|p| h[p]), h.get(i)) {
            (Some(a), Some(&b)) => 0.5 * (a + b),
            (Some(a), None) => a,
            (None, Some(&b)) => b,
            (None, None) => 1.0,
        };
        // Contacts: the bottom layer, node q of the layer has index q.
        let m = spec.layer();
        let vert = dim - 1;
        let mut nt = Vec::with_capacity(m);
        let mut tt = Vec::with_capacity((dim - 1) * m);
        let mut g = Vec::with_capacity(m);
        // Half of the horizontal extent touches at the press delta (ignoring the
        // compression of the block).
        let reach = 0.25 * lx.max(if dim == 3 { ly } else { 0.0 });
        let kappa = delta / (reach * reach);
        let mut area = Vec::with_capacity(m);
        for q in 0..m {
            nt.push((q, dim * q + vert, -1.0));
            for s in 0..dim - 1 {
                tt.push(((dim - 1) * q + s, dim * q + s, 1.0));
            }
            let (i, j) = (q % nn[0], q / nn[0]);
            let x = xs[i] - 0.5 * lx;
            let y = if dim == 3 { ys[j] - 0.5 * ly } else { 0.0 };
            g.push(kappa * (x * x + y * y));
            area.push(share(&hx, i) * if dim == 3 { share(&hy, j) } else { 1.0 });
        }
        let ndof = spec.n_dofs();
        let n = Csc::from_triplets(m, ndof, &nt);
        let t = Csc::from_triplets((dim - 1) * m, ndof, &tt);
        // Tresca bound: mu times the mean pressure (E delta / h) on the node's
        // tributary area (1 cell on the uniform grid, a unit length in 2D).
        let pressure = YOUNG * delta / height;
        let p = area.iter().map(|a| MU * pressure * a).collect();
        let mu = vec![MU; m];
        Scene {
            spec,
            d: dim,
            k,
            n,
            t,
            f,
            g,
            p,
            mu,
            stiffness,
        }
    }

    /// The load vectors of the top motion's two parts: the vertical press alone
    /// and the horizontal shift alone (f = press + shear; f is linear in the
    /// prescribed displacement).
    #[allow(dead_code)] // examples/history.rs's; the benchmark has no use for it
    pub fn press_and_shear(&self) -> (Vec<f64>, Vec<f64>) {
        let dim = self.d;
        let mut top = vec![0.0; dim];
        top[dim - 1] = -self.press_depth();
        let press = self.load_of_top(&top);
        let shear = self.f.iter().zip(&press).map(|(a, b)| a - b).collect();
        (press, shear)
    }

    /// The shear load of a top moved sideways by `ratio` times mu delta
    /// (the press's delta, Coulomb's mu) in the direction `theta_deg`
    /// degrees off the x axis (off the T rows of x), in 3D; in 2D along x.
    /// `ratio` above 1 drags the face into gross slip.
    #[allow(dead_code)] // examples/history.rs's
    pub fn oblique_shear(&self, ratio: f64, theta_deg: f64) -> Vec<f64> {
        let dim = self.d;
        let s = ratio * MU * self.press_depth();
        let th = theta_deg.to_radians();
        let mut top = vec![0.0; dim];
        top[0] = s * th.cos();
        if dim == 3 {
            top[1] = s * th.sin();
        }
        self.load_of_top(&top)
    }

    /// The press delta of the scene's full top motion.
    fn press_depth(&self) -> f64 {
        let height = if self.d == 2 {
            self.spec.ny as f64
        } else {
            self.spec.nz as f64
        };
        top_motion(height).0
    }

    /// The load f = -K_fp u_p of the top moved by `top` (one value per
    /// component).
    fn load_of_top(&self, top: &[f64]) -> Vec<f64> {
        assemble(&self.spec, &self.stiffness, top).1
    }

    /// The load vector of the same scene with the top motion scaled by `s` (f is
    /// linear in the prescribed displacement).
    pub fn scaled_load(&self, s: f64) -> Vec<f64> {
        self.f.iter().map(|v| s * v).collect()
    }
}

/// The element stiffness of a cell of sizes h (x, y, z; h[2] unused in 2D):
/// Q4 in 2D, H8 in 3D.
fn element_stiffness(dim: usize, h: [f64; 3]) -> Vec<f64> {
    if dim == 2 {
        q4_stiffness(YOUNG, POISSON, [h[0], h[1]])
    } else {
        h8_stiffness(YOUNG, POISSON, h)
    }
}

/// Local node offsets of a Q4 / H8 element, in the element's node order.
fn local_offsets(dim: usize) -> Vec<[usize; 3]> {
    let base = [[0, 0], [1, 0], [1, 1], [0, 1]];
    let mut v = Vec::new();
    for kz in 0..dim - 1 {
        for b in base {
            v.push([b[0], b[1], kz]);
        }
    }
    v
}

/// K (free block, both triangles, compressed columns built directly) and
/// f = -K_fp u_p for the top motion `top` of every top node.
fn assemble(spec: &Spec, ke: &Stiffness, top: &[f64]) -> (Csc, Vec<f64>) {
    let dim = spec.dim;
    let nn = spec.nodes();
    let ne = [spec.nx, spec.ny, spec.nz.max(1)];
    let vaxis = dim - 1; // the vertical axis: y in 2D, z in 3D
    let top_index = nn[vaxis] - 1;
    let offs = local_offsets(dim);
    let nloc = offs.len();
    let nd = dim * nloc;
    let ndof = spec.n_dofs();
    let nnodes_free = ndof / dim;
    let node_id = |p: [usize; 3]| (p[2] * nn[1] + p[1]) * nn[0] + p[0];
    // Stencil of neighbour offsets (each -1, 0, 1; third is 0 in 2D), ordered by
    // increasing node index: lexicographic in (z, y, x).
    let zr: Vec<i64> = if dim == 3 { vec![-1, 0, 1] } else { vec![0] };
    let mut stencil = Vec::new();
    for &dz in &zr {
        for dy in -1i64..=1 {
            for dx in -1i64..=1 {
                stencil.push([dx, dy, dz]);
            }
        }
    }
    let sidx = |o: [i64; 3]| -> usize {
        let z = if dim == 3 { (o[2] + 1) as usize } else { 0 };
        (z * 3 + (o[1] + 1) as usize) * 3 + (o[0] + 1) as usize
    };
    let ns = stencil.len();
    let per_col = ns * dim;
    let mut col_ptr = Vec::with_capacity(ndof + 1);
    let mut row_idx = Vec::with_capacity(ndof * per_col);
    let mut values = Vec::with_capacity(ndof * per_col);
    let mut f = vec![0.0; ndof];
    col_ptr.push(0);
    // blocks[s][r * dim + c]: K(row node a + stencil s, comp c; col node a, comp r)
    let mut blocks = vec![0.0; ns * dim * dim];
    let mut present = vec![false; ns];
    for a in 0..nnodes_free {
        let pa = [a % nn[0], (a / nn[0]) % nn[1], a / (nn[0] * nn[1])];
        blocks.iter_mut().for_each(|v| *v = 0.0);
        present.iter_mut().for_each(|v| *v = false);
        for (la, oa) in offs.iter().enumerate() {
            // The element whose local node la is a (lower corner pa - oa) exists.
            if (0..dim).any(|ax| pa[ax] < oa[ax] || pa[ax] - oa[ax] >= ne[ax]) {
                continue;
            }
            let ke = ke.of_cell(dim, [pa[0] - oa[0], pa[1] - oa[1], pa[2] - oa[2]]);
            for (lb, ob) in offs.iter().enumerate() {
                let mut rel = [0i64; 3];
                for ax in 0..dim {
                    rel[ax] = ob[ax] as i64 - oa[ax] as i64;
                }
                let s = sidx(rel);
                present[s] = true;
                for r in 0..dim {
                    for c in 0..dim {
                        blocks[(s * dim + r) * dim + c] += ke[(la * dim + r) * nd + lb * dim + c];
                    }
                }
            }
        }
        for r in 0..dim {
            let col = dim * a + r;
            for (s, o) in stencil.iter().enumerate() {
                if !present[s] {
                    continue;
                }
                let mut pb = [0usize; 3];
                for ax in 0..3 {
                    pb[ax] = (pa[ax] as i64 + o[ax]) as usize;
                }
                let b = node_id(pb);
                for c in 0..dim {
                    let v = blocks[(s * dim + r) * dim + c];
                    if pb[vaxis] == top_index {
                        f[col] -= v * top[c];
                    } else {
                        row_idx.push(dim * b + c);
                        values.push(v);
                    }
                }
            }
            col_ptr.push(row_idx.len());
        }
    }
    let k = Csc {
        nrows: ndof,
        ncols: ndof,
        col_ptr,
        row_idx,
        values,
    };
    (k, f)
}

/// Element by element assembly through `Csc::from_triplets` (for the check).
fn assemble_triplets(spec: &Spec, ke: &Stiffness, top: &[f64]) -> (Csc, Vec<f64>) {
    let dim = spec.dim;
    let nn = spec.nodes();
    let ne = [spec.nx, spec.ny, spec.nz.max(1)];
    let offs = local_offsets(dim);
    let nd = dim * offs.len();
    let ndof = spec.n_dofs();
    let node_id = |p: [usize; 3]| (p[2] * nn[1] + p[1]) * nn[0] + p[0];
    let nfree_nodes = ndof / dim;
    let mut trip = Vec::new();
    let mut f = vec![0.0; ndof];
    for ez in 0..ne[2] {
        for ey in 0..ne[1] {
            for ex in 0..ne[0] {
                let ke = ke.of_cell(dim, [ex, ey, ez]);
                let nodes: Vec<usize> = offs
                    .iter()
                    .map(|o| node_id([ex + o[0], ey + o[1], ez + o[2]]))
                    .collect();
                for a in 0..nd {
                    for b in 0..nd {
                        let (na, nb) = (nodes[a / dim], nodes[b / dim]);
                        if na >= nfree_nodes {
                            continue;
                        }
                        let ga = dim * na + a % dim;
                        let v = ke[a * nd + b];
                        if nb >= nfree_nodes {
                            f[ga] -= v * top[b % dim];
                        } else {
                            trip.push((ga, dim * nb + b % dim, v));
                        }
                    }
                }
            }
        }
    }
    (Csc::from_triplets(ndof, ndof, &trip), f)
}

/// Checks the direct assembly against the triplet assembly on small grids,
/// uniform and graded, and the element matrices by the patch test (a linear
/// displacement field leaves no force on a node inside the grid, whatever the
/// cells' sizes); panics on a mismatch.
pub fn check_assembly() {
    for spec in [
        Spec {
            dim: 2,
            nx: 5,
            ny: 3,
            nz: 0,
            graded: false,
        },
        Spec {
            dim: 3,
            nx: 3,
            ny: 4,
            nz: 2,
            graded: false,
        },
        Spec {
            dim: 2,
            nx: 6,
            ny: 3,
            nz: 0,
            graded: true,
        },
        Spec {
            dim: 3,
            nx: 5,
            ny: 4,
            nz: 2,
            graded: true,
        },
    ] {
        let ke = Stiffness::of(&spec);
        check_patch(&spec, &ke);
        let top: Vec<f64> = (0..spec.dim).map(|c| 0.1 + c as f64).collect();
        let (k1, f1) = assemble(&spec, &ke, &top);
        let (k2, f2) = assemble_triplets(&spec, &ke, &top);
        assert_eq!(k1.col_ptr, k2.col_ptr, "{}: column pointers", spec.name());
        assert_eq!(k1.row_idx, k2.row_idx, "{}: row indices", spec.name());
        let scale = k2.values.iter().fold(0.0f64, |s, v| s.max(v.abs()));
        for (x, y) in k1.values.iter().zip(&k2.values) {
            assert!((x - y).abs() <= 1e-12 * scale, "{}: K values", spec.name());
        }
        for (x, y) in f1.iter().zip(&f2) {
            assert!((x - y).abs() <= 1e-12 * scale, "{}: f", spec.name());
        }
    }
}

/// The patch test of the element matrices of `spec`: the nodal forces of the
/// field u_c = sum_ax (c + 1 + ax / 2) x_ax / 10 summed over the cells vanish
/// (to rounding) at every node off the grid's boundary.
fn check_patch(spec: &Spec, ke: &Stiffness) {
    let dim = spec.dim;
    let nn = spec.nodes();
    let sizes = spec.cell_sizes();
    let pos: Vec<Vec<f64>> = sizes.iter().map(|h| positions(h)).collect();
    let ne = [spec.nx, spec.ny, spec.nz.max(1)];
    let offs = local_offsets(dim);
    let nd = dim * offs.len();
    let node_id = |p: [usize; 3]| (p[2] * nn[1] + p[1]) * nn[0] + p[0];
    let mut force = vec![0.0; dim * nn[0] * nn[1] * nn[2]];
    let mut scale = 0.0f64;
    for ez in 0..ne[2] {
        for ey in 0..ne[1] {
            for ex in 0..ne[0] {
                let ke = ke.of_cell(dim, [ex, ey, ez]);
                let corners: Vec<[usize; 3]> = offs
                    .iter()
                    .map(|o| [ex + o[0], ey + o[1], ez + o[2]])
                    .collect();
                let mut ue = vec![0.0; nd];
                for (l, p) in corners.iter().enumerate() {
                    for c in 0..dim {
                        ue[dim * l + c] = (0..dim)
                            .map(|ax| (c as f64 + 1.0 + ax as f64 / 2.0) * pos[ax][p[ax]] / 10.0)
                            .sum();
                    }
                }
                for (l, p) in corners.iter().enumerate() {
                    for c in 0..dim {
                        let row = dim * l + c;
                        let fe: f64 = (0..nd).map(|b| ke[row * nd + b] * ue[b]).sum();
                        scale = scale.max(fe.abs());
                        force[dim * node_id(*p) + c] += fe;
                    }
                }
            }
        }
    }
    for z in 0..nn[2] {
        for y in 0..nn[1] {
            for x in 0..nn[0] {
                let p = [x, y, z];
                if (0..dim).any(|ax| p[ax] == 0 || p[ax] == nn[ax] - 1) {
                    continue;
                }
                for c in 0..dim {
                    let r = force[dim * node_id(p) + c];
                    assert!(r.abs() <= 1e-12 * scale, "{}: patch test", spec.name());
                }
            }
        }
    }
}

/// Isotropic elasticity matrix (plane strain in 2D), row-major.
fn elasticity(dim: usize, e: f64, nu: f64) -> Vec<f64> {
    let lam = e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
    let mu = e / (2.0 * (1.0 + nu));
    let ns = if dim == 2 { 3 } else { 6 };
    let mut dm = vec![0.0; ns * ns];
    for a in 0..dim {
        for b in 0..dim {
            dm[a * ns + b] = lam;
        }
        dm[a * ns + a] = lam + 2.0 * mu;
    }
    for a in dim..ns {
        dm[a * ns + a] = mu;
    }
    dm
}

/// ke += w B^T D B with B ns x nd and D ns x ns, row-major.
fn accumulate_btdb(ke: &mut [f64], bm: &[f64], dm: &[f64], ns: usize, nd: usize, w: f64) {
    let mut db = vec![0.0; ns * nd];
    for r in 0..ns {
        for c in 0..nd {
            db[r * nd + c] = (0..ns).map(|s| dm[r * ns + s] * bm[s * nd + c]).sum();
        }
    }
    for a in 0..nd {
        for b in 0..nd {
            let s: f64 = (0..ns).map(|r| bm[r * nd + a] * db[r * nd + b]).sum();
            ke[a * nd + b] += w * s;
        }
    }
}

/// Stiffness of the rectangular Q4 element of sides h (plane strain, 2 x 2
/// Gauss), 8 x 8.
fn q4_stiffness(e: f64, nu: f64, h: [f64; 2]) -> Vec<f64> {
    const XI: [f64; 4] = [-1.0, 1.0, 1.0, -1.0];
    const ETA: [f64; 4] = [-1.0, -1.0, 1.0, 1.0];
    let dm = elasticity(2, e, nu);
    let gp = 1.0 / 3.0f64.sqrt();
    let mut ke = vec![0.0; 64];
    // x = h_x (1 + xi) / 2, so d/dx = (2 / h_x) d/dxi, det J = h_x h_y / 4.
    for &xi in &[-gp, gp] {
        for &eta in &[-gp, gp] {
            let mut bm = vec![0.0; 3 * 8];
            for a in 0..4 {
                let dx = 2.0 / h[0] * 0.25 * XI[a] * (1.0 + ETA[a] * eta);
                let dy = 2.0 / h[1] * 0.25 * ETA[a] * (1.0 + XI[a] * xi);
                bm[2 * a] = dx;
                bm[8 + 2 * a + 1] = dy;
                bm[16 + 2 * a] = dy;
                bm[16 + 2 * a + 1] = dx;
            }
            accumulate_btdb(&mut ke, &bm, &dm, 3, 8, h[0] * h[1] / 4.0);
        }
    }
    ke
}

/// Stiffness of the box H8 element of sides h (2 x 2 x 2 Gauss), 24 x 24.
fn h8_stiffness(e: f64, nu: f64, h: [f64; 3]) -> Vec<f64> {
    const XI: [f64; 8] = [-1.0, 1.0, 1.0, -1.0, -1.0, 1.0, 1.0, -1.0];
    const ETA: [f64; 8] = [-1.0, -1.0, 1.0, 1.0, -1.0, -1.0, 1.0, 1.0];
    const ZETA: [f64; 8] = [-1.0, -1.0, -1.0, -1.0, 1.0, 1.0, 1.0, 1.0];
    let dm = elasticity(3, e, nu);
    let gp = 1.0 / 3.0f64.sqrt();
    let mut ke = vec![0.0; 24 * 24];
    for &xi in &[-gp, gp] {
        for &eta in &[-gp, gp] {
            for &zeta in &[-gp, gp] {
                let mut bm = vec![0.0; 6 * 24];
                for a in 0..8 {
                    let g = [
                        2.0 / h[0] * 0.125 * XI[a] * (1.0 + ETA[a] * eta) * (1.0 + ZETA[a] * zeta),
                        2.0 / h[1] * 0.125 * ETA[a] * (1.0 + XI[a] * xi) * (1.0 + ZETA[a] * zeta),
                        2.0 / h[2] * 0.125 * ZETA[a] * (1.0 + XI[a] * xi) * (1.0 + ETA[a] * eta),
                    ];
                    let col = 3 * a;
                    bm[col] = g[0];
                    bm[24 + col + 1] = g[1];
                    bm[48 + col + 2] = g[2];
                    bm[72 + col] = g[1];
                    bm[72 + col + 1] = g[0];
                    bm[96 + col + 1] = g[2];
                    bm[96 + col + 2] = g[1];
                    bm[120 + col] = g[2];
                    bm[120 + col + 2] = g[0];
                }
                accumulate_btdb(&mut ke, &bm, &dm, 6, 24, h[0] * h[1] * h[2] / 8.0);
            }
        }
    }
    ke
}
