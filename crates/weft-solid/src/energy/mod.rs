//! Energy terms. Each acts on a fixed stencil of at most 32 vertices and gives its energy,
//! gradient and Hessian (optionally projected to PSD) into a [`Local`] buffer, so assembly
//! never allocates.

mod dropoff;
mod hinge;
mod membrane;
mod midedge;
mod rod;
mod shell;
mod shell_clamp;
mod spring;

pub use dropoff::Dropoff;
pub use hinge::{Hinge, dihedral_angle, dihedral_angle_gradient, dihedral_gradient};
pub use membrane::{Membrane, MembraneMaterial};
pub use midedge::{MidedgeBend, SharedHinges};
pub use rod::{RodBend, RodClamp, RodSection, RodStretch};
pub use shell::{
    ClampedEdge, MAX_STENCIL, ShellBend, ShellBending, ShellError, plate_bending_stiffness,
    shell_bending, shell_bending_clamped,
};
pub use shell_clamp::ShellClamp;
pub use spring::Spring;

use nalgebra::{SMatrix, SVector, Vector3};

/// Largest stencil: a shell-bending vertex and up to 31 ring neighbours.
pub const MAX_DOFS: usize = 96;

/// One element's energy, gradient and Hessian over its own DOFs (3 per stencil vertex).
#[derive(Clone, Debug)]
pub struct Local {
    /// DOFs in use (3 × stencil vertices).
    pub dofs: usize,
    /// Energy.
    pub energy: f64,
    /// Gradient (first `dofs` entries).
    pub grad: [f64; MAX_DOFS],
    /// Hessian, `hess[col][row]` (first `dofs` × `dofs`).
    pub hess: [[f64; MAX_DOFS]; MAX_DOFS],
}

impl Default for Local {
    fn default() -> Self {
        Local {
            dofs: 0,
            energy: 0.0,
            grad: [0.0; MAX_DOFS],
            hess: [[0.0; MAX_DOFS]; MAX_DOFS],
        }
    }
}

impl Local {
    /// Makes the used Hessian block exactly symmetric (the mean of the two triangles).
    pub(crate) fn symmetrize(&mut self) {
        for c in 0..self.dofs {
            for r in 0..c {
                let s = 0.5 * (self.hess[c][r] + self.hess[r][c]);
                self.hess[c][r] = s;
                self.hess[r][c] = s;
            }
        }
    }

    pub(crate) fn set<const D: usize>(
        &mut self,
        e: f64,
        g: &SVector<f64, D>,
        h: &SMatrix<f64, D, D>,
    ) {
        self.dofs = D;
        self.energy = e;
        for i in 0..D {
            self.grad[i] = g[i];
            for j in 0..D {
                // Exactly symmetric (a + b == b + a in floating point), whatever rounding
                // the element's own computation left.
                self.hess[j][i] = 0.5 * (h[(i, j)] + h[(j, i)]);
            }
        }
    }
}

/// An energy on a stencil of vertices.
pub trait Element: Sync {
    /// The stencil's vertex indices.
    fn vertices(&self) -> &[u32];
    /// Energy at positions `x` (the whole system's positions).
    fn energy(&self, x: &[Vector3<f64>]) -> f64;
    /// Energy, gradient and Hessian; the Hessian is projected to PSD when `project`.
    fn eval(&self, x: &[Vector3<f64>], project: bool, out: &mut Local);
    /// Energy, gradient and the Hessian Newton tries first: the exact one where it costs no
    /// more than its PSD surrogate (membranes, rods), else the surrogate (bending's
    /// Gauss–Newton term, whose curvature part would cost several times the rest). It may be
    /// indefinite: the integrator checks the assembled matrix by factorizing it and falls
    /// back to the projected Hessians when it is not positive definite.
    fn eval_first(&self, x: &[Vector3<f64>], out: &mut Local) {
        self.eval(x, true, out);
    }
    /// Energy, gradient and the Hessian of a contact step's Newton model (ADMM solves on it;
    /// a factorization that fails is regularized by a diagonal shift, not retried with other
    /// Hessians). `budget` ≥ 0 is the negative curvature the element may keep: an element that
    /// [`Self::spends_budget`] returns a Hessian whose smallest eigenvalue is at least
    /// −`budget` (membranes: the exact Hessian, compression's negative curvature clamped
    /// there); the others ignore it and return the projected Hessian, except rods, whose
    /// exact Hessian is kept (see the rod elements).
    fn eval_contact(&self, x: &[Vector3<f64>], budget: f64, out: &mut Local) {
        let _ = budget;
        self.eval(x, true, out);
    }
    /// Whether [`Self::eval_contact`] spends its budget (the integrator divides each vertex's
    /// inertia among the elements that do).
    fn spends_budget(&self) -> bool {
        false
    }
}

/// Stacks the stencil's positions into one vector.
pub(crate) fn gather<const D: usize>(x: &[Vector3<f64>], v: &[u32]) -> SVector<f64, D> {
    let mut s = SVector::<f64, D>::zeros();
    for (a, &i) in v.iter().enumerate() {
        s.fixed_rows_mut::<3>(3 * a).copy_from(&x[i as usize]);
    }
    s
}

/// Finite-difference checks shared by every energy's tests.
#[cfg(test)]
#[allow(clippy::needless_range_loop)] // matrix index arithmetic reads clearer than iterators here
pub(crate) mod fd {
    use super::{Element, Local};
    use nalgebra::Vector3;

    /// Central differences of energy (→ gradient) and gradient (→ Hessian), compared with the
    /// analytic ones: relative error below `tol` with a step of `step` (VERIFY.md: < 1e-5 at a
    /// step of about 1e-6 × scale).
    pub fn check(e: &dyn Element, x: &[Vector3<f64>], step: f64, tol: f64) {
        let mut l = Local::default();
        e.eval(x, false, &mut l);
        assert!(
            (l.energy - e.energy(x)).abs() <= 1e-12 * l.energy.abs().max(1e-300),
            "eval and energy disagree"
        );
        let n = l.dofs;
        let vs = e.vertices().to_vec();
        let mut xp = x.to_vec();
        let mut gnum = vec![0.0; n];
        let mut hnum = vec![vec![0.0; n]; n];
        for k in 0..n {
            let (vi, c) = (vs[k / 3] as usize, k % 3);
            let orig = xp[vi][c];
            xp[vi][c] = orig + step;
            let ep = e.energy(&xp);
            let mut lp = Local::default();
            e.eval(&xp, false, &mut lp);
            xp[vi][c] = orig - step;
            let em = e.energy(&xp);
            let mut lm = Local::default();
            e.eval(&xp, false, &mut lm);
            xp[vi][c] = orig;
            gnum[k] = (ep - em) / (2.0 * step);
            for r in 0..n {
                hnum[k][r] = (lp.grad[r] - lm.grad[r]) / (2.0 * step);
            }
        }
        let gscale = (0..n)
            .map(|i| l.grad[i].abs())
            .fold(0.0, f64::max)
            .max(1e-300);
        for i in 0..n {
            let err = (gnum[i] - l.grad[i]).abs() / gscale;
            assert!(
                err < tol,
                "gradient[{i}]: analytic {} vs FD {} (rel {err:e})",
                l.grad[i],
                gnum[i]
            );
        }
        let hscale = (0..n)
            .flat_map(|i| (0..n).map(move |j| (i, j)))
            .map(|(i, j)| l.hess[j][i].abs())
            .fold(0.0, f64::max)
            .max(1e-300);
        for i in 0..n {
            for j in 0..n {
                let err = (hnum[j][i] - l.hess[j][i]).abs() / hscale;
                assert!(
                    err < tol,
                    "hessian[{i},{j}]: analytic {} vs FD {} (rel {err:e})",
                    l.hess[j][i],
                    hnum[j][i]
                );
                assert_eq!(
                    l.hess[j][i], l.hess[i][j],
                    "Hessian must be exactly symmetric"
                );
            }
        }
        // The projected Hessian is PSD (smallest eigenvalue ≥ −1e-9 of the largest).
        let mut lproj = Local::default();
        e.eval(x, true, &mut lproj);
        // The solver uses the projected mode: its energy and gradient must be the exact ones
        // (only the Hessian may be a PSD surrogate).
        assert!(
            (lproj.energy - l.energy).abs() <= 1e-12 * l.energy.abs().max(1e-300),
            "projected energy differs"
        );
        for i in 0..n {
            assert!(
                (lproj.grad[i] - l.grad[i]).abs() <= 1e-10 * gscale,
                "projected gradient[{i}] {} vs exact {}",
                lproj.grad[i],
                l.grad[i]
            );
        }
        let m = nalgebra::DMatrix::from_fn(n, n, |i, j| lproj.hess[j][i]);
        let eig = m.symmetric_eigen();
        let max = eig.eigenvalues.iter().fold(0.0f64, |a, b| a.max(b.abs()));
        assert!(
            eig.eigenvalues.iter().all(|&l| l >= -1e-9 * max),
            "projected Hessian is not PSD"
        );
    }
}
