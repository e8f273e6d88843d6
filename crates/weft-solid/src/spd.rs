//! Projection of small symmetric matrices onto the positive semidefinite cone.
//!
//! Projected Newton (Teran et al. 2005; IPC) clamps each element Hessian's negative
//! eigenvalues to zero before assembly, so the global system is SPD and every Newton direction
//! is a descent direction, whatever the deformation.

use nalgebra::{SMatrix, SymmetricEigen};

/// Projection onto the PSD cone, for the stencil sizes the energies use.
pub trait ProjectPsd {
    /// Replaces the (symmetric) matrix by its nearest PSD matrix in the Frobenius norm:
    /// negative eigenvalues are set to zero. A PSD input is left untouched, bit for bit.
    fn project_psd(&mut self);
}

macro_rules! impl_project {
    ($($d:literal),*) => {$(
        impl ProjectPsd for SMatrix<f64, $d, $d> {
            fn project_psd(&mut self) {
                // Fast path: a Cholesky factorization (~d³/6 flops) proves positive
                // definiteness, and most element Hessians are (stretched membranes, rods at
                // rest); the eigendecomposition costs ~30× more, so the membranes' share of
                // assembly falls with it (`weft bench solid`'s hanging cloth measures it).
                if self.cholesky().is_some() {
                    return;
                }
                let eig = SymmetricEigen::new(*self);
                if eig.eigenvalues.iter().all(|&l| l >= 0.0) {
                    return;
                }
                let mut out = SMatrix::<f64, $d, $d>::zeros();
                for (k, &l) in eig.eigenvalues.iter().enumerate() {
                    if l > 0.0 {
                        let q = eig.eigenvectors.column(k);
                        out += l * q * q.transpose();
                    }
                }
                // Symmetric by construction up to rounding; make it exact.
                *self = 0.5 * (out + out.transpose());
            }
        }
    )*};
}
impl_project!(3, 6, 9, 12);

/// Free-function form of [`ProjectPsd::project_psd`].
pub fn project_psd<M: ProjectPsd>(m: &mut M) {
    m.project_psd();
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Matrix3;

    #[test]
    fn clamps_negative_eigenvalues_and_keeps_psd_matrices() {
        let mut m = Matrix3::new(2.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 3.0);
        project_psd(&mut m);
        assert_eq!(m, Matrix3::new(2.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 3.0));
        let psd = Matrix3::new(2.0, 1.0, 0.0, 1.0, 2.0, 0.0, 0.0, 0.0, 1.0);
        let mut p = psd;
        project_psd(&mut p);
        assert_eq!(p, psd, "already PSD: untouched, bit for bit");
    }
}
