//! Discrete-shell bending on the hinge of two triangles (Grinspun et al. 2003):
//! E = k (θ − θ̄)² with k = κ_b · 3|ē|²/Ā, θ the dihedral angle across the shared edge, |ē| its
//! rest length and Ā the two triangles' rest area. The gradient of θ is the closed form of
//! Bridson et al. 2003; the Hessian of θ is that gradient's exact derivative, taken by
//! forward-mode dual numbers (one cheap pass per DOF), so it is exact and costs a few µs.
//! Both are checked against finite differences.

use super::{Element, Local, gather};
use nalgebra::{SMatrix, SVector, Vector3};
use num_dual::{Dual64, DualNum};

/// A hinge: `v[0]`–`v[1]` the shared edge, `v[2]` and `v[3]` the opposite vertices.
#[derive(Clone, Debug)]
pub struct Hinge {
    /// Vertices (edge, edge, wing, wing).
    pub v: [u32; 4],
    /// Stiffness k [J] (bend stiffness × 3|ē|²/Ā).
    pub k: f64,
    /// Rest dihedral angle θ̄ [rad].
    pub rest: f64,
}

fn sub<S: Clone + std::ops::Sub<Output = S>>(x: &[S], a: usize, b: usize) -> [S; 3] {
    [
        x[3 * a].clone() - x[3 * b].clone(),
        x[3 * a + 1].clone() - x[3 * b + 1].clone(),
        x[3 * a + 2].clone() - x[3 * b + 2].clone(),
    ]
}
fn cross<S: Clone + std::ops::Sub<Output = S> + std::ops::Mul<Output = S>>(
    a: &[S; 3],
    b: &[S; 3],
) -> [S; 3] {
    [
        a[1].clone() * b[2].clone() - a[2].clone() * b[1].clone(),
        a[2].clone() * b[0].clone() - a[0].clone() * b[2].clone(),
        a[0].clone() * b[1].clone() - a[1].clone() * b[0].clone(),
    ]
}
fn dot<S: DualNum<Primitive = f64> + Clone>(a: &[S; 3], b: &[S; 3]) -> S {
    a[0].clone() * b[0].clone() + a[1].clone() * b[1].clone() + a[2].clone() * b[2].clone()
}

/// Signed dihedral angle (0 when flat), generic over dual numbers:
/// n₁ = e × (x₂ − x₀), n₂ = (x₃ − x₀) × e, θ = atan2((n₁ × n₂)·ê, n₁·n₂).
pub fn dihedral_angle<S: DualNum<Primitive = f64> + Clone>(x: &[S]) -> S {
    let e = sub(x, 1, 0);
    let n1 = cross(&e, &sub(x, 2, 0));
    let n2 = cross(&sub(x, 3, 0), &e);
    let en = dot(&e, &e).sqrt();
    let sin = dot(&cross(&n1, &n2), &e) / en;
    sin.atan2(dot(&n1, &n2))
}

/// ∂θ/∂x for the angle of [`dihedral_angle`] (Bridson, Marino & Fedkiw 2003): with
/// n₁ = (x₀−x₂)×(x₁−x₂), n₂ = (x₁−x₃)×(x₀−x₃), e = x₁ − x₀,
/// ∂θ/∂x₂ = −|e| n₁/|n₁|², ∂θ/∂x₃ = −|e| n₂/|n₂|²,
/// ∂θ/∂x₁ = −((x₀−x₂)·ê n₁/|n₁|² + (x₀−x₃)·ê n₂/|n₂|²),
/// ∂θ/∂x₀ = (x₁−x₂)·ê n₁/|n₁|² + (x₁−x₃)·ê n₂/|n₂|².
/// Generic over the scalar so its derivative (the Hessian) can be taken by dual numbers.
pub fn dihedral_gradient<S: DualNum<Primitive = f64> + Copy>(x: &[S; 12]) -> [S; 12] {
    gradient_parts(x).0
}

/// [`dihedral_angle`] and [`dihedral_gradient`] at once, from one computation of the two
/// normals: the elements that need both take them here.
pub fn dihedral_angle_gradient(x: &[f64; 12]) -> (f64, [f64; 12]) {
    let (g, n1, n2, e, el) = gradient_parts(x);
    let theta = (dot(&cross(&n1, &n2), &e) / el).atan2(dot(&n1, &n2));
    (theta, g)
}

/// The gradient of [`dihedral_gradient`] with what it is made of: the normals n₁, n₂ (the
/// ones of [`dihedral_angle`]: n₁ = e × (x₂ − x₀) = (x₀ − x₂) × (x₁ − x₂), likewise n₂), e and
/// |e|.
#[allow(clippy::type_complexity)]
fn gradient_parts<S: DualNum<Primitive = f64> + Copy>(
    x: &[S; 12],
) -> ([S; 12], [S; 3], [S; 3], [S; 3], S) {
    let p = |i: usize| [x[3 * i], x[3 * i + 1], x[3 * i + 2]];
    let (x0, x1, x2, x3) = (p(0), p(1), p(2), p(3));
    let d = |a: [S; 3], b: [S; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let e = d(x1, x0);
    let n1 = cross(&e, &d(x2, x0));
    let n2 = cross(&d(x3, x0), &e);
    let el = dot(&e, &e).sqrt();
    let (q1, q2) = (dot(&n1, &n1), dot(&n2, &n2));
    let m1 = n1.map(|c| c / q1);
    let m2 = n2.map(|c| c / q2);
    let proj = |a: [S; 3]| dot(&a, &e) / el;
    let (a0, a1) = (proj(d(x0, x2)), proj(d(x0, x3)));
    let (b0, b1) = (proj(d(x1, x2)), proj(d(x1, x3)));
    let mut g = [x[0] * 0.0; 12];
    for k in 0..3 {
        g[k] = b0 * m1[k] + b1 * m2[k];
        g[3 + k] = -(a0 * m1[k] + a1 * m2[k]);
        g[6 + k] = -(el * m1[k]);
        g[9 + k] = -(el * m2[k]);
    }
    (g, n1, n2, e, el)
}

impl Hinge {
    fn value<S: DualNum<Primitive = f64> + Clone>(&self, x: &[S]) -> S {
        let th = dihedral_angle(x);
        let d = th.clone() - self.rest - wrap_offset(th.re() - self.rest);
        d.clone() * d * self.k
    }
}

/// The multiple of 2π that brings θ − θ̄ into (−π, π]: θ jumps by 2π when a hinge folds past
/// ±π, and the energy must not (subtracting a constant leaves every derivative unchanged).
pub(crate) fn wrap_offset(d: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    if d > PI || d <= -PI {
        TAU * ((d + PI) / TAU).floor()
    } else {
        0.0
    }
}

impl Element for Hinge {
    fn vertices(&self) -> &[u32] {
        &self.v
    }
    fn energy(&self, x: &[Vector3<f64>]) -> f64 {
        let s: SVector<f64, 12> = gather(x, &self.v);
        self.value(s.as_slice())
    }
    fn eval(&self, x: &[Vector3<f64>], project: bool, out: &mut Local) {
        let s: SVector<f64, 12> = gather(x, &self.v);
        let xs: [f64; 12] = s.into();
        let (theta, gt) = dihedral_angle_gradient(&xs);
        let d0 = theta - self.rest;
        let d = d0 - wrap_offset(d0);
        // E = k d², ∇E = 2k d ∇θ, ∇²E = 2k ∇θ∇θᵀ + 2k d ∇²θ; ∇²θ column by column as the
        // derivative of ∇θ along each DOF.
        let mut h = SMatrix::<f64, 12, 12>::zeros();
        if project {
            // The PSD surrogate is the Gauss–Newton term 2k ∇θ∇θᵀ: the curvature term
            // 2k d ∇²θ is indefinite for any d ≠ 0 (∇²θ has both signs), so its eigenvalue
            // projection costs a 12×12 eigendecomposition per hinge for a term that vanishes
            // at rest. Without it Newton takes the same iterations on the hanging cloth and
            // assembly is much cheaper (`weft bench solid` measures it; figures in
            // docs/history/issue-71-comments.md).
            for c in 0..12 {
                for r in 0..12 {
                    h[(r, c)] = 2.0 * self.k * gt[r] * gt[c];
                }
            }
        } else {
            for c in 0..12 {
                let mut xd = xs.map(Dual64::from_re);
                xd[c].eps = 1.0;
                let gd = dihedral_gradient(&xd);
                for r in 0..12 {
                    h[(r, c)] = 2.0 * self.k * (gt[r] * gt[c] + d * gd[r].eps);
                }
            }
        }
        let g = SVector::<f64, 12>::from_fn(|r, _| 2.0 * self.k * d * gt[r]);
        out.set::<12>(self.k * d * d, &g, &h);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::energy::fd::check;

    fn wing(angle: f64) -> Vec<Vector3<f64>> {
        // Edge along x; wing 2 in the xy-plane (y > 0); wing 3 folded by `angle` about x.
        vec![
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(1.0, 0.0, 0.0),
            Vector3::new(0.4, 0.8, 0.0),
            Vector3::new(0.6, -0.9 * angle.cos(), -0.9 * angle.sin()),
        ]
    }

    #[test]
    fn the_fused_angle_is_the_angle() {
        // Its gradient is dihedral_gradient's own (checked against dual numbers below); its
        // angle comes from those normals instead of dihedral_angle's: equal to a few
        // roundings (1e-13).
        let x = [
            0.1, 0.0, 0.02, 0.9, 0.1, -0.03, 0.4, 0.7, 0.2, 0.5, -0.6, 0.35,
        ];
        let (theta, g) = dihedral_angle_gradient(&x);
        assert!((theta - dihedral_angle(&x)).abs() < 1e-13);
        assert_eq!(g, dihedral_gradient(&x));
    }

    #[test]
    fn dihedral_angle_is_the_fold_angle() {
        for a in [-1.2, -0.3, 0.0, 0.5, 2.0] {
            let x = wing(a);
            let s: SVector<f64, 12> = gather(&x, &[0, 1, 2, 3]);
            let th = dihedral_angle(s.as_slice());
            assert!((th.abs() - a.abs()).abs() < 1e-12, "fold {a}: θ = {th}");
            assert!(
                th.signum() == a.signum() || a == 0.0,
                "sign follows the fold"
            );
        }
    }

    #[test]
    fn the_energy_is_continuous_when_the_fold_passes_pi() {
        // Rest folded to 3.0 rad; folding on past π to −3.0 (same as 3.28) costs (0.28)².
        let h = Hinge {
            v: [0, 1, 2, 3],
            k: 1.0,
            rest: 3.0,
        };
        let e = h.energy(&wing(-3.0));
        let want = (2.0 * std::f64::consts::PI - 6.0).powi(2);
        assert!((e - want).abs() < 1e-12, "{e} vs {want}");
        assert_eq!(wrap_offset(0.5), 0.0);
        assert!((wrap_offset(4.0) - std::f64::consts::TAU).abs() < 1e-15);
        assert!((wrap_offset(-4.0) + std::f64::consts::TAU).abs() < 1e-15);
    }

    #[test]
    fn closed_form_gradient_matches_the_angle_derivative() {
        for a in [-1.0, 0.2, 1.4] {
            let x = wing(a);
            let s: SVector<f64, 12> = gather(&x, &[0, 1, 2, 3]);
            let xs: [f64; 12] = s.into();
            let g = dihedral_gradient(&xs);
            let (_, gad) = num_dual::gradient(
                |v: SVector<num_dual::DualSVec64<12>, 12>| dihedral_angle(v.as_slice()),
                &s,
            );
            for k in 0..12 {
                assert!(
                    (g[k] - gad[k]).abs() < 1e-12,
                    "fold {a}, dof {k}: {} vs {}",
                    g[k],
                    gad[k]
                );
            }
        }
    }

    #[test]
    fn finite_differences_flat_and_folded_with_rest_angle() {
        check(
            &Hinge {
                v: [0, 1, 2, 3],
                k: 0.7,
                rest: 0.0,
            },
            &wing(0.4),
            1e-7,
            1e-5,
        );
        check(
            &Hinge {
                v: [0, 1, 2, 3],
                k: 0.7,
                rest: 0.3,
            },
            &wing(-0.8),
            1e-7,
            1e-5,
        );
        check(
            &Hinge {
                v: [0, 1, 2, 3],
                k: 0.7,
                rest: 0.2,
            },
            &wing(0.0),
            1e-7,
            1e-5,
        );
    }
}
