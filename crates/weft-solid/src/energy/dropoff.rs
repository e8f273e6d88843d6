//! Bend angle dropoff (Maya Nucleus's control): bending that is soft for small bends and
//! stiffens as the bend grows, as a documented function of the bend's curvature.
//!
//! With the dropoff d ∈ [0, 1] and the reference curvature κ₀ [1/m], the bending stiffness
//! at curvature κ (the bend angle per unit length) is the plain one times
//!
//! `s(κ) = 1 − d + d (κ/κ₀)²`,
//!
//! so a bend's moment is `M(κ) = B [(1 − d) κ + d κ³/(3κ₀²)]` and its energy per unit area
//! (or length) `B [(1 − d) κ²/2 + d κ⁴/(12κ₀²)]`: d = 0 is the plain element; d = 1 has no
//! stiffness at the flat state and the full one at κ₀, stiffer beyond. Measured in curvature,
//! not per element angle, the curve is the same on a fine or a coarse mesh (Nucleus's acts on
//! edge angles, so refining its mesh changes it).
//!
//! Each bending element's plain energy is quadratic: E₀ = ½ b κₑ², b [J·m] its energy at unit
//! curvature in a uniform bend (a rod's EI·l over its Voronoi length l; the shell's trace term
//! (1 + ν) D Aᵥ/2, its deviatoric term (1 − ν) D A/2: a cylinder's two halves), κₑ the
//! element's own curvature measure. In u = κₑ² = 2E₀/b the energy is b G(u),
//! G(u) = (1 − d) u/2 + d u²/(12κ₀²), so the element's own gradient and Hessian map exactly:
//! ∇E = 2G′ ∇E₀ and ∇²E = 2G′ ∇²E₀ + (4G″/b) ∇E₀∇E₀ᵀ, with G′ > 0 (d < 1 or u > 0) and
//! G″ ≥ 0: a PSD projection of ∇²E₀ stays a PSD approximation of ∇²E.

use super::Local;

/// The dropoff of one element.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Dropoff {
    /// Dropoff d ∈ [0, 1].
    pub d: f64,
    /// The reference curvature κ₀ > 0 [1/m].
    pub kappa0: f64,
    /// The element's plain energy at unit curvature, doubled: E₀ = ½ b κ² [J·m].
    pub b: f64,
}

impl Dropoff {
    /// A dropoff `d` at reference curvature `kappa0` for an element whose plain energy is
    /// ½ `b` κ²; None when d is 0 (the plain element) or the element has no stiffness.
    pub fn new(d: f64, kappa0: f64, b: f64) -> Option<Self> {
        (d > 0.0 && kappa0 > 0.0 && b > 0.0).then_some(Dropoff { d, kappa0, b })
    }

    /// G(u), G′(u), G″(u).
    fn g(&self, u: f64) -> (f64, f64, f64) {
        let c = self.d / (12.0 * self.kappa0 * self.kappa0);
        (
            0.5 * (1.0 - self.d) * u + c * u * u,
            0.5 * (1.0 - self.d) + 2.0 * c * u,
            2.0 * c,
        )
    }

    /// The element's energy from its plain energy `e0`.
    pub fn energy(&self, e0: f64) -> f64 {
        self.b * self.g(2.0 * e0 / self.b).0
    }

    /// Maps an element's plain energy, gradient and Hessian in `out` to the dropoff's.
    pub fn apply(&self, out: &mut Local) {
        let n = out.dofs;
        let (g, g1, g2) = self.g(2.0 * out.energy / self.b);
        out.energy = self.b * g;
        let rank1 = 4.0 * g2 / self.b;
        for c in 0..n {
            for r in 0..n {
                // g_r g_c, not (rank1 g_r) g_c: exactly symmetric.
                out.hess[c][r] = 2.0 * g1 * out.hess[c][r] + rank1 * (out.grad[r] * out.grad[c]);
            }
        }
        for v in &mut out.grad[..n] {
            *v *= 2.0 * g1;
        }
    }

    /// The moment at curvature κ per unit plain stiffness B: (1 − d) κ + d κ³/(3κ₀²).
    pub fn moment(d: f64, kappa0: f64, kappa: f64) -> f64 {
        (1.0 - d) * kappa + d * kappa.powi(3) / (3.0 * kappa0 * kappa0)
    }
}

/// Test helper: asserts that the moment dE/dκ of `energy(d, κ)` (a bend of curvature κ with
/// dropoff d), over the plain one's, is the stated M(κ)/(Bκ) = (1 − d) + dκ²/(3κ₀²) within 1 %
/// for d = 0.5 and 1 and κ from κ₀/4 to 3κ₀ (κ₀ = 20/m).
#[cfg(test)]
pub(crate) fn assert_moment_curve(energy: impl Fn(f64, f64) -> f64) {
    let kappa0 = 20.0;
    for d in [0.5, 1.0] {
        for kappa in [5.0f64, 20.0, 40.0, 60.0] {
            let h = 1e-4 * kappa;
            let moment = |d: f64| (energy(d, kappa + h) - energy(d, kappa - h)) / (2.0 * h);
            let ratio = moment(d) / moment(0.0);
            let want = Dropoff::moment(d, kappa0, kappa) / kappa;
            assert!(
                (ratio / want - 1.0).abs() < 0.01,
                "d {d}, κ {kappa}/m: moment ratio {ratio}, stated {want}"
            );
        }
    }
}
