//! Solver options: which method, tolerances and iteration limits.

/// The iterative method run on the condensed dual problem.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Method {
    /// Pop's dual splitting, Schur complement variant (design.md section 3): the
    /// tangential step on S = A22 - A21 A11^-1 A12 over the current contact set,
    /// then the normal step on A11; both sub-problems by projected Gauss-Seidel.
    Split,
    /// Plain block Gauss-Seidel on (lambda_N, lambda_T): tangential step on A22,
    /// normal step on A11, both by projected Gauss-Seidel.
    BlockGs,
    /// Projected Gauss-Seidel on the whole dual, contact by contact (Siconos NSGS).
    Pgs,
    /// Semismooth Newton (primal-dual active set) on the condensed dual with the
    /// generalised Jacobian of the friction projections, globalised by a fallback
    /// to Gauss-Seidel sweeps when a step does not lower err. One outer iteration is
    /// one Newton step (a dense LU on the free unknowns).
    Newton,
    /// Pop's splitting (Schur variant) with MPRGP / MPGP for the sub-problems instead
    /// of projected Gauss-Seidel.
    SplitMprgp,
    /// MPRGP / MPGP (Dostal) on the whole dual; for Coulomb, the fixed point
    /// p = mu lambda_N outside (one outer iteration per Tresca solve).
    Mprgp,
}

impl Method {
    /// Every method, in the order of the C enum.
    pub const ALL: [Method; 6] = [
        Method::Split,
        Method::BlockGs,
        Method::Pgs,
        Method::Newton,
        Method::SplitMprgp,
        Method::Mprgp,
    ];

    /// Short lower-case name ("split", "block-gs", "pgs", "newton",
    /// "split-mprgp", "mprgp").
    pub fn name(self) -> &'static str {
        match self {
            Method::Split => "split",
            Method::BlockGs => "block-gs",
            Method::Pgs => "pgs",
            Method::Newton => "newton",
            Method::SplitMprgp => "split-mprgp",
            Method::Mprgp => "mprgp",
        }
    }

    /// Parses a name as returned by [`Method::name`].
    pub fn from_name(s: &str) -> Option<Method> {
        Method::ALL.into_iter().find(|m| m.name() == s)
    }
}

/// Options of one solve. `Options::default()` gives the documented defaults.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Options {
    /// Method (default `Split`).
    pub method: Method,
    /// Stop when err (design.md section 5) is at most `tol` (default 1e-10).
    pub tol: f64,
    /// Maximum number of outer iterations: sweeps for `Pgs`, normal/tangential
    /// alternations for `Split` and `BlockGs` (default 10_000).
    pub max_outer: usize,
    /// Maximum number of inner iterations per sub-problem: Gauss-Seidel sweeps in
    /// `Split` and `BlockGs`, MPRGP iterations in `SplitMprgp` and `Mprgp`
    /// (default 1_000).
    pub max_inner: usize,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            method: Method::Split,
            tol: 1e-10,
            max_outer: 10_000,
            max_inner: 1_000,
        }
    }
}
