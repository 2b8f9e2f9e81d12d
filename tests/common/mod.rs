//! Shared helpers of the integration tests `closed_form`, `patch_test` and
//! `methods_agree`:
//!
//! - an optimality (KKT) checker of docs/design.md section 1 that works on K, N, T, f, g
//!   and the returned u and multipliers only, independently of the solver's report;
//! - small dense/sparse helpers and norms;
//! - finite element builders: a plane-strain Q4 block and a trilinear H8 block on a
//!   rigid foundation, with Dirichlet conditions eliminated into the load vector and
//!   the contact rows on the bottom nodes.
//!
//! Each test binary uses only part of this module.
#![allow(dead_code)]
// Element and small dense kernels read best with explicit indices.
#![allow(clippy::needless_range_loop)]

use dualsplit::internals::ffi::{DsFormat, DsIndexType, DsMatrix, DsStorage};
use dualsplit::{ContactProblem, Csc, Friction, Method, Options, Solution, SolveStatus};

// ---------------------------------------------------------------------------------
// Small vector helpers
// ---------------------------------------------------------------------------------

/// Euclidean norm.
pub fn norm2(x: &[f64]) -> f64 {
    x.iter().map(|v| v * v).sum::<f64>().sqrt()
}

/// Maximum norm (0 for an empty slice).
pub fn norm_inf(x: &[f64]) -> f64 {
    x.iter().fold(0.0f64, |a, v| a.max(v.abs()))
}

/// max_i |a_i - b_i|.
pub fn max_diff(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len(), "max_diff: lengths differ");
    a.iter()
        .zip(b)
        .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()))
}

/// y = A x for a `Csc`.
pub fn mul(a: &Csc, x: &[f64]) -> Vec<f64> {
    let mut y = vec![0.0; a.nrows];
    a.mul_vec(x, &mut y);
    y
}

/// y = A^T x for a `Csc`.
pub fn mul_t(a: &Csc, x: &[f64]) -> Vec<f64> {
    let mut y = vec![0.0; a.ncols];
    a.mul_t_vec(x, &mut y);
    y
}

/// Asserts |got - want|_inf <= rel * scale, with a message naming the quantity.
pub fn assert_close(what: &str, got: &[f64], want: &[f64], rel: f64, scale: f64) {
    assert_eq!(got.len(), want.len(), "{what}: length");
    let d = max_diff(got, want);
    assert!(
        d <= rel * scale,
        "{what}: max |got - want| = {d:.3e} > {rel:.1e} * {scale:.3e}\n  got  = {got:?}\n  want = {want:?}"
    );
}

/// Options of a method with the default tolerance (1e-10) and limits.
pub fn opts(method: Method) -> Options {
    Options {
        method,
        ..Options::default()
    }
}

/// Asserts that a solve reports Converged with finite outputs. (That its err is at
/// most the tolerance is how the status is defined; the callers check the answer
/// against an independent truth: KKT, a closed form or a second method.)
pub fn assert_converged(what: &str, sol: &Solution) {
    let r = &sol.report;
    assert_eq!(
        r.status,
        SolveStatus::Converged,
        "{what}: not converged: {r:?}"
    );
    assert!(
        sol.u
            .iter()
            .chain(&sol.lambda_n)
            .chain(&sol.lambda_t)
            .all(|v| v.is_finite()),
        "{what}: non-finite output"
    );
}

// ---------------------------------------------------------------------------------
// The KKT checker
// ---------------------------------------------------------------------------------

/// The violations of the conditions of docs/design.md section 1, each made
/// dimensionless: forces by `lam_scale` = max(|lambda|_inf, |f|_inf), lengths by
/// `u_scale` = max(|u|_inf, |g|_inf).
#[derive(Clone, Debug, Default)]
pub struct Kkt {
    /// |K u - f + N^T lambda_N + T^T lambda_T|_2 / max(|f|_2, |K u|_2).
    pub equilibrium: f64,
    /// max_i max(0, (N u)_i - g_i) / u_scale.
    pub feasibility: f64,
    /// max_i max(0, -lambda_N,i) / lam_scale.
    pub sign: f64,
    /// max_i min(lambda_N,i^+ / lam_scale, |g_i - (N u)_i| / u_scale).
    pub complementarity: f64,
    /// max_i max(0, |lambda_T,i| - p_i) / lam_scale.
    pub bound: f64,
    /// Stick: max_i min((p_i - |lambda_T,i|)^+ / lam_scale, |(T u)_i| / u_scale), i.e.
    /// a contact strictly inside the friction disk must not slip.
    pub stick: f64,
    /// Slip direction: max_i |(T u)_i - alpha_i lambda_T,i| / u_scale with
    /// alpha_i = max(0, (T u)_i . lambda_T,i) / |lambda_T,i|^2, over contacts with
    /// p_i > 0 (a frictionless contact may slip in any direction). Zero exactly when
    /// the slip is a non-negative multiple of lambda_T,i: the friction force
    /// -T^T lambda_T opposes the slip.
    pub slip_direction: f64,
    /// The scales used.
    pub u_scale: f64,
    pub lam_scale: f64,
}

impl Kkt {
    /// The largest violation.
    pub fn max(&self) -> f64 {
        [
            self.equilibrium,
            self.feasibility,
            self.sign,
            self.complementarity,
            self.bound,
            self.stick,
            self.slip_direction,
        ]
        .into_iter()
        .fold(0.0, f64::max)
    }

    /// Panics with the full record when a violation exceeds `tol`.
    pub fn assert_ok(&self, what: &str, tol: f64) {
        assert!(
            self.max() <= tol,
            "{what}: KKT conditions violated beyond {tol:.1e}: {self:#?}"
        );
    }
}

/// Slip bound per contact: p itself (Tresca) or mu_i max(lambda_N,i, 0) (Coulomb).
pub fn slip_bounds(friction: Friction<'_>, lambda_n: &[f64]) -> Vec<f64> {
    match friction {
        Friction::Tresca(p) => p.to_vec(),
        Friction::Coulomb(mu) => mu
            .iter()
            .zip(lambda_n)
            .map(|(m, l)| m * l.max(0.0))
            .collect(),
    }
}

/// The KKT violations of (u, lambda_N, lambda_T) for the problem (K, N, T, f, g,
/// friction) in dimension d, computed from the data alone.
#[allow(clippy::too_many_arguments)]
pub fn kkt(
    d: usize,
    k: &Csc,
    n: &Csc,
    t: &Csc,
    f: &[f64],
    g: &[f64],
    friction: Friction<'_>,
    u: &[f64],
    lambda_n: &[f64],
    lambda_t: &[f64],
) -> Kkt {
    let m = n.nrows;
    let dt = d - 1;
    assert_eq!(lambda_n.len(), m);
    assert_eq!(lambda_t.len(), dt * m);
    assert_eq!(u.len(), k.ncols);
    let ku = mul(k, u);
    let ntl = mul_t(n, lambda_n);
    let ttl = mul_t(t, lambda_t);
    let res: Vec<f64> = (0..u.len())
        .map(|i| ku[i] - f[i] + ntl[i] + ttl[i])
        .collect();
    let eq_den = norm2(f).max(norm2(&ku)).max(f64::MIN_POSITIVE);
    let nu = mul(n, u);
    let tu = mul(t, u);
    let p = slip_bounds(friction, lambda_n);
    let u_scale = norm_inf(u).max(norm_inf(g)).max(f64::MIN_POSITIVE);
    let lam_scale = norm_inf(lambda_n)
        .max(norm_inf(lambda_t))
        .max(norm_inf(f))
        .max(f64::MIN_POSITIVE);
    let mut out = Kkt {
        equilibrium: norm2(&res) / eq_den,
        u_scale,
        lam_scale,
        ..Kkt::default()
    };
    for i in 0..m {
        let slack = g[i] - nu[i];
        out.feasibility = out.feasibility.max((-slack).max(0.0) / u_scale);
        out.sign = out.sign.max((-lambda_n[i]).max(0.0) / lam_scale);
        out.complementarity = out
            .complementarity
            .max((lambda_n[i].max(0.0) / lam_scale).min(slack.abs() / u_scale));
        let lt = &lambda_t[dt * i..dt * (i + 1)];
        let s = &tu[dt * i..dt * (i + 1)];
        let lt_norm = norm2(lt);
        let s_norm = norm2(s);
        out.bound = out.bound.max((lt_norm - p[i]).max(0.0) / lam_scale);
        out.stick = out
            .stick
            .max(((p[i] - lt_norm).max(0.0) / lam_scale).min(s_norm / u_scale));
        if p[i] > 0.0 {
            let dir = if lt_norm > 0.0 {
                let dot: f64 = s.iter().zip(lt).map(|(a, b)| a * b).sum();
                let alpha = dot.max(0.0) / (lt_norm * lt_norm);
                let r: Vec<f64> = s.iter().zip(lt).map(|(a, b)| a - alpha * b).collect();
                norm2(&r)
            } else {
                s_norm
            };
            out.slip_direction = out.slip_direction.max(dir / u_scale);
        }
    }
    out
}

/// The KKT violations of a solution of a scene.
pub fn kkt_of(scene: &Scene, friction: Friction<'_>, sol: &Solution) -> Kkt {
    kkt(
        scene.d,
        &scene.k,
        &scene.n,
        &scene.t,
        &scene.f,
        &scene.g,
        friction,
        &sol.u,
        &sol.lambda_n,
        &sol.lambda_t,
    )
}

// ---------------------------------------------------------------------------------
// Finite element builders
// ---------------------------------------------------------------------------------

/// A structured mesh of quadrilaterals (2D) or hexahedra (3D) with node (i, j[, k])
/// at index `(k * (ny + 1) + j) * (nx + 1) + i`. The "vertical" direction is y in 2D
/// and z in 3D; the bottom (contact) face is the first layer of nodes, the top face
/// the last.
#[derive(Clone, Debug)]
pub struct Mesh {
    /// 2 or 3.
    pub dim: usize,
    pub nx: usize,
    pub ny: usize,
    /// 0 in 2D.
    pub nz: usize,
    /// Node coordinates (the third is 0 in 2D).
    pub coords: Vec<[f64; 3]>,
    /// Element connectivity: 4 nodes counter-clockwise (2D) or 8 nodes, bottom face
    /// counter-clockwise seen from above then the top face (3D).
    pub elems: Vec<Vec<usize>>,
}

impl Mesh {
    /// The nx x ny grid of Q4 elements on [0, lx] x [0, ly].
    pub fn grid2d(nx: usize, ny: usize, lx: f64, ly: f64) -> Mesh {
        let mut coords = Vec::new();
        for j in 0..=ny {
            for i in 0..=nx {
                coords.push([lx * i as f64 / nx as f64, ly * j as f64 / ny as f64, 0.0]);
            }
        }
        let id = |i: usize, j: usize| j * (nx + 1) + i;
        let mut elems = Vec::new();
        for j in 0..ny {
            for i in 0..nx {
                elems.push(vec![id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
        Mesh {
            dim: 2,
            nx,
            ny,
            nz: 0,
            coords,
            elems,
        }
    }

    /// The nx x ny x nz grid of H8 elements on [0, lx] x [0, ly] x [0, lz].
    pub fn grid3d(nx: usize, ny: usize, nz: usize, lx: f64, ly: f64, lz: f64) -> Mesh {
        let mut coords = Vec::new();
        for k in 0..=nz {
            for j in 0..=ny {
                for i in 0..=nx {
                    coords.push([
                        lx * i as f64 / nx as f64,
                        ly * j as f64 / ny as f64,
                        lz * k as f64 / nz as f64,
                    ]);
                }
            }
        }
        let id = |i: usize, j: usize, k: usize| (k * (ny + 1) + j) * (nx + 1) + i;
        let mut elems = Vec::new();
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    elems.push(vec![
                        id(i, j, k),
                        id(i + 1, j, k),
                        id(i + 1, j + 1, k),
                        id(i, j + 1, k),
                        id(i, j, k + 1),
                        id(i + 1, j, k + 1),
                        id(i + 1, j + 1, k + 1),
                        id(i, j + 1, k + 1),
                    ]);
                }
            }
        }
        Mesh {
            dim: 3,
            nx,
            ny,
            nz,
            coords,
            elems,
        }
    }

    /// Number of nodes.
    pub fn n_nodes(&self) -> usize {
        self.coords.len()
    }

    /// Number of DOFs (dim per node).
    pub fn n_dofs(&self) -> usize {
        self.dim * self.n_nodes()
    }

    /// Nodes per layer (bottom or top face).
    fn layer(&self) -> usize {
        if self.dim == 2 {
            self.nx + 1
        } else {
            (self.nx + 1) * (self.ny + 1)
        }
    }

    /// Nodes of the bottom face (the contact face), in index order.
    pub fn bottom_nodes(&self) -> Vec<usize> {
        (0..self.layer()).collect()
    }

    /// Nodes of the top face, in index order.
    pub fn top_nodes(&self) -> Vec<usize> {
        let l = self.layer();
        (self.n_nodes() - l..self.n_nodes()).collect()
    }

    /// The full (unconstrained) stiffness matrix as triplets, for an isotropic
    /// material (plane strain in 2D).
    pub fn stiffness_triplets(&self, e: f64, nu: f64) -> Vec<(usize, usize, f64)> {
        let dim = self.dim;
        let mut trip = Vec::new();
        for el in &self.elems {
            let xe: Vec<[f64; 3]> = el.iter().map(|&a| self.coords[a]).collect();
            let ke = if dim == 2 {
                q4_stiffness(&xe, e, nu)
            } else {
                h8_stiffness(&xe, e, nu)
            };
            let nd = dim * el.len();
            for a in 0..nd {
                for b in 0..nd {
                    let ga = dim * el[a / dim] + a % dim;
                    let gb = dim * el[b / dim] + b % dim;
                    trip.push((ga, gb, ke[a * nd + b]));
                }
            }
        }
        trip
    }
}

/// Isotropic elasticity matrix: plane strain (3 x 3, strains [exx, eyy, gxy]) or 3D
/// (6 x 6, strains [exx, eyy, ezz, gxy, gyz, gzx]), row-major.
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

/// Element stiffness of a bilinear quadrilateral (plane strain, 2 x 2 Gauss),
/// 8 x 8 row-major, DOFs [u_x1, u_y1, u_x2, ...].
pub fn q4_stiffness(xe: &[[f64; 3]], e: f64, nu: f64) -> Vec<f64> {
    const XI: [f64; 4] = [-1.0, 1.0, 1.0, -1.0];
    const ETA: [f64; 4] = [-1.0, -1.0, 1.0, 1.0];
    let dm = elasticity(2, e, nu);
    let gp = 1.0 / 3.0f64.sqrt();
    let mut ke = vec![0.0; 64];
    for &xi in &[-gp, gp] {
        for &eta in &[-gp, gp] {
            let mut dn = [[0.0; 2]; 4]; // dN_a / d(xi, eta)
            for a in 0..4 {
                dn[a][0] = 0.25 * XI[a] * (1.0 + ETA[a] * eta);
                dn[a][1] = 0.25 * ETA[a] * (1.0 + XI[a] * xi);
            }
            // J[r][c] = d x_c / d xi_r
            let mut j = [[0.0; 2]; 2];
            for a in 0..4 {
                for r in 0..2 {
                    for c in 0..2 {
                        j[r][c] += dn[a][r] * xe[a][c];
                    }
                }
            }
            let det = j[0][0] * j[1][1] - j[0][1] * j[1][0];
            assert!(det > 0.0, "q4_stiffness: inverted element (det J = {det})");
            let inv = [
                [j[1][1] / det, -j[0][1] / det],
                [-j[1][0] / det, j[0][0] / det],
            ];
            // dN_a/dx_c = sum_r invJ[c][r] dN_a/dxi_r
            let mut bm = vec![0.0; 3 * 8];
            for a in 0..4 {
                let dx = inv[0][0] * dn[a][0] + inv[0][1] * dn[a][1];
                let dy = inv[1][0] * dn[a][0] + inv[1][1] * dn[a][1];
                bm[2 * a] = dx;
                bm[8 + 2 * a + 1] = dy;
                bm[16 + 2 * a] = dy;
                bm[16 + 2 * a + 1] = dx;
            }
            accumulate_btdb(&mut ke, &bm, &dm, 3, 8, det);
        }
    }
    ke
}

/// Element stiffness of a trilinear hexahedron (2 x 2 x 2 Gauss), 24 x 24 row-major.
pub fn h8_stiffness(xe: &[[f64; 3]], e: f64, nu: f64) -> Vec<f64> {
    const XI: [f64; 8] = [-1.0, 1.0, 1.0, -1.0, -1.0, 1.0, 1.0, -1.0];
    const ETA: [f64; 8] = [-1.0, -1.0, 1.0, 1.0, -1.0, -1.0, 1.0, 1.0];
    const ZETA: [f64; 8] = [-1.0, -1.0, -1.0, -1.0, 1.0, 1.0, 1.0, 1.0];
    let dm = elasticity(3, e, nu);
    let gp = 1.0 / 3.0f64.sqrt();
    let mut ke = vec![0.0; 24 * 24];
    for &xi in &[-gp, gp] {
        for &eta in &[-gp, gp] {
            for &zeta in &[-gp, gp] {
                let mut dn = [[0.0; 3]; 8];
                for a in 0..8 {
                    dn[a][0] = 0.125 * XI[a] * (1.0 + ETA[a] * eta) * (1.0 + ZETA[a] * zeta);
                    dn[a][1] = 0.125 * ETA[a] * (1.0 + XI[a] * xi) * (1.0 + ZETA[a] * zeta);
                    dn[a][2] = 0.125 * ZETA[a] * (1.0 + XI[a] * xi) * (1.0 + ETA[a] * eta);
                }
                let mut j = [[0.0; 3]; 3];
                for a in 0..8 {
                    for r in 0..3 {
                        for c in 0..3 {
                            j[r][c] += dn[a][r] * xe[a][c];
                        }
                    }
                }
                let det = j[0][0] * (j[1][1] * j[2][2] - j[1][2] * j[2][1])
                    - j[0][1] * (j[1][0] * j[2][2] - j[1][2] * j[2][0])
                    + j[0][2] * (j[1][0] * j[2][1] - j[1][1] * j[2][0]);
                assert!(det > 0.0, "h8_stiffness: inverted element (det J = {det})");
                // inverse by cofactors
                let mut inv = [[0.0; 3]; 3];
                for r in 0..3 {
                    for c in 0..3 {
                        let (r1, r2) = ((c + 1) % 3, (c + 2) % 3);
                        let (c1, c2) = ((r + 1) % 3, (r + 2) % 3);
                        inv[r][c] = (j[r1][c1] * j[r2][c2] - j[r1][c2] * j[r2][c1]) / det;
                    }
                }
                let mut bm = vec![0.0; 6 * 24];
                for a in 0..8 {
                    let mut g = [0.0; 3];
                    for (c, gc) in g.iter_mut().enumerate() {
                        *gc = (0..3).map(|r| inv[c][r] * dn[a][r]).sum();
                    }
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
                accumulate_btdb(&mut ke, &bm, &dm, 6, 24, det);
            }
        }
    }
    ke
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

/// A contact scene with the Dirichlet DOFs eliminated: K (free DOFs, both
/// triangles), N, T, f (external loads minus K_fc u_c), g, and the maps back to the
/// mesh.
#[derive(Clone, Debug)]
pub struct Scene {
    pub d: usize,
    pub k: Csc,
    pub n: Csc,
    pub t: Csc,
    pub f: Vec<f64>,
    pub g: Vec<f64>,
    /// Mesh DOF -> free DOF index (None for a prescribed DOF).
    pub free: Vec<Option<usize>>,
    /// Mesh DOF -> prescribed value (None for a free DOF).
    pub prescribed: Vec<Option<f64>>,
    /// Contact i sits on mesh node `contact_nodes[i]`.
    pub contact_nodes: Vec<usize>,
    pub mesh: Mesh,
}

impl Scene {
    /// Builds the scene: `prescribed` lists (mesh DOF, value) pairs, with the mesh
    /// DOF `dim * node + component`; `f_ext` holds the external nodal loads on all
    /// mesh DOFs; the contacts sit on `contact_nodes` with the outward normal
    /// -e_vertical (N row = -1 on the vertical DOF; T rows +1 on u_x, and on u_y in
    /// 3D); gap(x) is the initial gap of the node at x.
    pub fn build(
        mesh: Mesh,
        e: f64,
        nu: f64,
        prescribed: &[(usize, f64)],
        f_ext: &[f64],
        contact_nodes: &[usize],
        gap: impl Fn(&[f64; 3]) -> f64,
    ) -> Scene {
        let dim = mesh.dim;
        let ndof = mesh.n_dofs();
        assert_eq!(f_ext.len(), ndof);
        let mut pres = vec![None; ndof];
        for &(dof, v) in prescribed {
            pres[dof] = Some(v);
        }
        let mut free = vec![None; ndof];
        let mut nfree = 0;
        for dof in 0..ndof {
            if pres[dof].is_none() {
                free[dof] = Some(nfree);
                nfree += 1;
            }
        }
        let mut f: Vec<f64> = (0..ndof)
            .filter(|&dof| free[dof].is_some())
            .map(|dof| f_ext[dof])
            .collect();
        let mut kff = Vec::new();
        for (a, b, v) in mesh.stiffness_triplets(e, nu) {
            match (free[a], free[b]) {
                (Some(fa), Some(fb)) => kff.push((fa, fb, v)),
                (Some(fa), None) => f[fa] -= v * pres[b].unwrap(),
                _ => {}
            }
        }
        let k = Csc::from_triplets(nfree, nfree, &kff);
        let m = contact_nodes.len();
        let vert = dim - 1;
        let mut nt = Vec::new();
        let mut tt = Vec::new();
        let mut g = Vec::new();
        for (i, &node) in contact_nodes.iter().enumerate() {
            let dv = free[dim * node + vert].expect("contact DOF must be free");
            nt.push((i, dv, -1.0));
            for s in 0..dim - 1 {
                let ds = free[dim * node + s].expect("contact DOF must be free");
                tt.push(((dim - 1) * i + s, ds, 1.0));
            }
            g.push(gap(&mesh.coords[node]));
        }
        let n = Csc::from_triplets(m, nfree, &nt);
        let t = Csc::from_triplets((dim - 1) * m, nfree, &tt);
        Scene {
            d: dim,
            k,
            n,
            t,
            f,
            g,
            free,
            prescribed: pres,
            contact_nodes: contact_nodes.to_vec(),
            mesh,
        }
    }

    /// A block of `mesh` (E = 100, nu = 0.3, no loads) whose top face is moved by
    /// `top` (one value per component: the horizontal ones, then the vertical),
    /// every bottom node a contact over the gap kappa |x_h - centre|^2, x_h the
    /// node's horizontal coordinates.
    pub fn pressed_block(mesh: Mesh, top: &[f64], kappa: f64, centre: &[f64]) -> Scene {
        let dim = mesh.dim;
        assert_eq!((top.len(), centre.len()), (dim, dim - 1));
        let mut prescribed = Vec::new();
        for &a in &mesh.top_nodes() {
            for (s, &v) in top.iter().enumerate() {
                prescribed.push((dim * a + s, v));
            }
        }
        let f_ext = vec![0.0; mesh.n_dofs()];
        let bottom = mesh.bottom_nodes();
        let centre = centre.to_vec();
        Scene::build(mesh, 100.0, 0.3, &prescribed, &f_ext, &bottom, move |x| {
            kappa
                * (0..dim - 1)
                    .map(|s| (x[s] - centre[s]).powi(2))
                    .sum::<f64>()
        })
    }

    /// The contact problem (K factored, dual condensed).
    pub fn problem(&self) -> ContactProblem {
        ContactProblem::from_csc(self.d, self.k.clone(), self.n.clone(), self.t.clone())
            .expect("the scene is a valid contact problem")
    }

    /// The displacement of every mesh DOF (prescribed values included).
    pub fn expand(&self, u: &[f64]) -> Vec<f64> {
        (0..self.free.len())
            .map(|dof| match self.free[dof] {
                Some(i) => u[i],
                None => self.prescribed[dof].unwrap(),
            })
            .collect()
    }

    /// Number of contacts.
    pub fn m(&self) -> usize {
        self.contact_nodes.len()
    }
}

// ---------------------------------------------------------------------------------
// Helpers added for the hard-case tests (hard_scenes, property, threads, bad_input)
// ---------------------------------------------------------------------------------

impl Mesh {
    /// As [`Mesh::stiffness_triplets`], with the material (E, nu) of each element
    /// given by `material(element index)` (elements in the order of `elems`).
    pub fn stiffness_triplets_by(
        &self,
        material: impl Fn(usize) -> (f64, f64),
    ) -> Vec<(usize, usize, f64)> {
        let dim = self.dim;
        let mut trip = Vec::new();
        for (ie, el) in self.elems.iter().enumerate() {
            let (e, nu) = material(ie);
            let xe: Vec<[f64; 3]> = el.iter().map(|&a| self.coords[a]).collect();
            let ke = if dim == 2 {
                q4_stiffness(&xe, e, nu)
            } else {
                h8_stiffness(&xe, e, nu)
            };
            let nd = dim * el.len();
            for a in 0..nd {
                for b in 0..nd {
                    let ga = dim * el[a / dim] + a % dim;
                    let gb = dim * el[b / dim] + b % dim;
                    trip.push((ga, gb, ke[a * nd + b]));
                }
            }
        }
        trip
    }
}

impl Scene {
    /// As [`Scene::build`], with a material per element (see
    /// [`Mesh::stiffness_triplets_by`]).
    pub fn build_by(
        mesh: Mesh,
        material: impl Fn(usize) -> (f64, f64),
        prescribed: &[(usize, f64)],
        f_ext: &[f64],
        contact_nodes: &[usize],
        gap: impl Fn(&[f64; 3]) -> f64,
    ) -> Scene {
        // Build with a unit material for the maps and the contact rows, then
        // replace K and f by the per-element assembly.
        let mut s = Scene::build(
            mesh.clone(),
            1.0,
            0.3,
            prescribed,
            f_ext,
            contact_nodes,
            gap,
        );
        let ndof = mesh.n_dofs();
        let mut f: Vec<f64> = (0..ndof)
            .filter(|&dof| s.free[dof].is_some())
            .map(|dof| f_ext[dof])
            .collect();
        let mut kff = Vec::new();
        for (a, b, v) in mesh.stiffness_triplets_by(material) {
            match (s.free[a], s.free[b]) {
                (Some(fa), Some(fb)) => kff.push((fa, fb, v)),
                (Some(fa), None) => f[fa] -= v * s.prescribed[b].unwrap(),
                _ => {}
            }
        }
        s.k = Csc::from_triplets(s.k.nrows, s.k.ncols, &kff);
        s.f = f;
        s
    }
}

/// The dense form of a `Csc` (faer, column-major).
pub fn dense(a: &Csc) -> faer::Mat<f64> {
    let mut m = faer::Mat::<f64>::zeros(a.nrows, a.ncols);
    for j in 0..a.ncols {
        for k in a.col_ptr[j]..a.col_ptr[j + 1] {
            m[(a.row_idx[k], j)] += a.values[k];
        }
    }
    m
}

/// x = K^-1 f by a dense LU with partial pivoting (an independent linear solve).
pub fn dense_solve(k: &Csc, f: &[f64]) -> Vec<f64> {
    use faer::linalg::solvers::Solve;
    let kd = dense(k);
    let lu = kd.partial_piv_lu();
    let rhs = faer::Mat::<f64>::from_fn(f.len(), 1, |i, _| f[i]);
    let x = lu.solve(&rhs);
    (0..f.len()).map(|i| x[(i, 0)]).collect()
}

/// Spectral condition number of a symmetric positive semi-definite matrix: the
/// ratio of its largest to its smallest eigenvalue; infinity when the smallest is
/// not positive (or below 1e-300), NaN for an empty matrix.
pub fn sym_cond(a: faer::MatRef<'_, f64>) -> f64 {
    if a.nrows() == 0 {
        return f64::NAN;
    }
    let ev = a
        .self_adjoint_eigenvalues(faer::Side::Lower)
        .expect("symmetric eigenvalues");
    let lo = ev[0];
    let hi = ev[ev.len() - 1];
    if lo <= 1e-300 * hi.abs().max(1.0) || lo <= 0.0 {
        f64::INFINITY
    } else {
        hi / lo
    }
}

/// A small deterministic PRNG (SplitMix64), for property tests without
/// dependencies.
#[derive(Clone, Debug)]
pub struct Rng(pub u64);

impl Rng {
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in [lo, hi).
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.uniform()
    }

    /// Uniform integer in [0, n) (n > 0).
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }

    /// True with probability `p`.
    pub fn chance(&mut self, p: f64) -> bool {
        self.uniform() < p
    }
}

/// CSC int64 arrays of a Csc, which a `DsMatrix` borrows (0-based, full storage).
pub struct Owned {
    pub nrows: i64,
    pub ncols: i64,
    pub p: Vec<i64>,
    pub i: Vec<i64>,
    pub x: Vec<f64>,
}

impl Owned {
    pub fn of(a: &dualsplit::Csc) -> Owned {
        Owned {
            nrows: a.nrows as i64,
            ncols: a.ncols as i64,
            p: a.col_ptr.iter().map(|&v| v as i64).collect(),
            i: a.row_idx.iter().map(|&v| v as i64).collect(),
            x: a.values.clone(),
        }
    }

    /// The Rust API's view of the arrays.
    pub fn view(&self) -> dualsplit::MatrixView<'_> {
        dualsplit::MatrixView {
            format: dualsplit::Format::Csc,
            storage: dualsplit::Storage::Full,
            base: 0,
            nrows: self.nrows as usize,
            ncols: self.ncols as usize,
            p: dualsplit::Indices::I64(&self.p),
            i: dualsplit::Indices::I64(&self.i),
            x: &self.x,
        }
    }

    pub fn ds(&self) -> DsMatrix {
        DsMatrix {
            format: DsFormat::Csc as i32,
            index_type: DsIndexType::I64 as i32,
            base: 0,
            storage: DsStorage::Full as i32,
            nrows: self.nrows,
            ncols: self.ncols,
            nnz: 0,
            p: self.p.as_ptr().cast(),
            i: self.i.as_ptr().cast(),
            x: self.x.as_ptr(),
        }
    }
}
