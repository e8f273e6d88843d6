//! Discrete-shell bending on the hinge of two triangles (Grinspun et al. 2003):
//! E = k (θ − θ̄)² with k = κ_b · 3|ē|²/Ā, θ the dihedral angle across the shared edge, |ē| its
//! rest length and Ā the two triangles' rest area. The gradient and Hessian are exact, from
//! second-order dual numbers (`num-dual`), and checked against finite differences.

use super::{Element, Local, gather};
use nalgebra::{Const, SVector, Vector3};
use num_dual::{Dual2Vec, DualNum, hessian};

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

impl Hinge {
    fn value<S: DualNum<Primitive = f64> + Clone>(&self, x: &[S]) -> S {
        let d = dihedral_angle(x) - self.rest;
        d.clone() * d * self.k
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
        let (e, g, mut h) = hessian(
            |v: SVector<Dual2Vec<f64, Const<12>>, 12>| self.value(v.as_slice()),
            &s,
        );
        if project {
            crate::spd::project_psd(&mut h);
        }
        out.set::<12>(e, &g, &h);
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
