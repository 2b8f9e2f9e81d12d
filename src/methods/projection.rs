//! Projections onto the friction sets and the exact solution of the small local
//! problems met by the Gauss-Seidel sweeps.

pub(super) use crate::friction::project_disk;

/// Minimises 1/2 x^T H x - c^T x over the disk |x| <= r for a symmetric positive
/// semidefinite 2 x 2 matrix H = [h00 h01; h01 h11]. Exact up to rounding: the
/// unconstrained minimiser if it is inside, otherwise x = (H + nu I)^-1 c with nu > 0
/// chosen so that |x| = r (safeguarded Newton on the secular equation).
pub fn solve_disk_qp(h00: f64, h01: f64, h11: f64, c: [f64; 2], r: f64) -> [f64; 2] {
    if r <= 0.0 {
        return [0.0, 0.0];
    }
    // Eigen-decomposition of H: rotation by angle theta.
    let theta = 0.5 * (2.0 * h01).atan2(h00 - h11);
    let (s, co) = theta.sin_cos();
    let e0 = co * co * h00 + 2.0 * s * co * h01 + s * s * h11;
    let e1 = s * s * h00 - 2.0 * s * co * h01 + co * co * h11;
    let c0 = co * c[0] + s * c[1];
    let c1 = -s * c[0] + co * c[1];
    let back = |y0: f64, y1: f64| [co * y0 - s * y1, s * y0 + co * y1];
    let scale = h00.abs().max(h11.abs()).max(f64::MIN_POSITIVE);
    let tiny = 1e-14 * scale;
    // Unconstrained minimiser when H is (numerically) positive definite.
    if e0 > tiny && e1 > tiny {
        let (y0, y1) = (c0 / e0, c1 / e1);
        if y0 * y0 + y1 * y1 <= r * r {
            return back(y0, y1);
        }
    }
    // |x(nu)| is decreasing in nu; the root lies in (max(0, -e_min), |c|/r + |e_max|].
    let norm_at = |nu: f64| ((c0 / (e0 + nu)).powi(2) + (c1 / (e1 + nu)).powi(2)).sqrt();
    let cn = (c0 * c0 + c1 * c1).sqrt();
    if cn == 0.0 {
        return [0.0, 0.0];
    }
    let mut lo = (-e0.min(e1)).max(0.0);
    let mut hi = cn / r + e0.abs().max(e1.abs());
    let mut nu = hi;
    for _ in 0..200 {
        let n = norm_at(nu);
        if !n.is_finite() || n > r {
            lo = nu;
        } else {
            hi = nu;
        }
        // Newton step on phi(nu) = 1/r - 1/|x(nu)|, which is nearly linear.
        let d0 = c0 * c0 / (e0 + nu).powi(3);
        let d1 = c1 * c1 / (e1 + nu).powi(3);
        let dn = -(d0 + d1) / n; // d|x|/dnu
        let phi = 1.0 / r - 1.0 / n;
        let dphi = dn / (n * n);
        let mut next = nu - phi / dphi;
        if !(next > lo && next < hi && next.is_finite()) {
            next = 0.5 * (lo + hi);
        }
        if (next - nu).abs() <= 1e-15 * nu.abs().max(f64::MIN_POSITIVE) || hi - lo <= 1e-15 * hi {
            nu = next;
            break;
        }
        nu = next;
    }
    let mut y = back(c0 / (e0 + nu), c1 / (e1 + nu));
    project_disk(&mut y, r);
    y
}

#[cfg(test)]
mod tests {
    use super::*;

    fn objective(h: [f64; 3], c: [f64; 2], x: [f64; 2]) -> f64 {
        0.5 * (h[0] * x[0] * x[0] + 2.0 * h[1] * x[0] * x[1] + h[2] * x[1] * x[1])
            - c[0] * x[0]
            - c[1] * x[1]
    }

    #[test]
    fn disk_qp_interior_is_unconstrained_minimiser() {
        let x = solve_disk_qp(2.0, 0.5, 1.0, [1.0, 0.5], 10.0);
        // H x = c
        assert!((2.0 * x[0] + 0.5 * x[1] - 1.0).abs() < 1e-14);
        assert!((0.5 * x[0] + 1.0 * x[1] - 0.5).abs() < 1e-14);
    }

    #[test]
    fn disk_qp_boundary_beats_every_point_of_the_circle() {
        let h = [3.0, 1.0, 0.5];
        let c = [4.0, -2.0];
        let r = 0.3;
        let x = solve_disk_qp(h[0], h[1], h[2], c, r);
        let nx = (x[0] * x[0] + x[1] * x[1]).sqrt();
        assert!((nx - r).abs() < 1e-14 * r.max(1.0));
        let fx = objective(h, c, x);
        for k in 0..3600 {
            let a = k as f64 * std::f64::consts::TAU / 3600.0;
            let y = [r * a.cos(), r * a.sin()];
            assert!(fx <= objective(h, c, y) + 1e-12);
        }
        // KKT: H x - c = -nu x with nu >= 0.
        let g = [
            h[0] * x[0] + h[1] * x[1] - c[0],
            h[1] * x[0] + h[2] * x[1] - c[1],
        ];
        let cross = g[0] * x[1] - g[1] * x[0];
        assert!(cross.abs() < 1e-12);
        assert!(g[0] * x[0] + g[1] * x[1] <= 0.0);
    }

    #[test]
    fn disk_qp_singular_h() {
        // H = diag(1, 0): the x1 direction is only bounded by the disk.
        let x = solve_disk_qp(1.0, 0.0, 0.0, [0.0, 1.0], 2.0);
        assert!((x[0]).abs() < 1e-14 && (x[1] - 2.0).abs() < 1e-12);
        let x = solve_disk_qp(0.0, 0.0, 0.0, [3.0, 4.0], 1.0);
        assert!((x[0] - 0.6).abs() < 1e-12 && (x[1] - 0.8).abs() < 1e-12);
    }
}
