//! A zero-rest-length spring from a vertex to a target point: soft attachments.

use super::{Element, Local};
use nalgebra::{Matrix3, Vector3};

/// E = ½ k ‖x − p‖², k in N/m.
#[derive(Clone, Debug)]
pub struct Spring {
    /// The vertex.
    pub v: [u32; 1],
    /// Target point (moved by the caller for animated attachments).
    pub target: Vector3<f64>,
    /// Stiffness [N/m].
    pub k: f64,
}

impl Element for Spring {
    fn vertices(&self) -> &[u32] {
        &self.v
    }
    fn energy(&self, x: &[Vector3<f64>]) -> f64 {
        0.5 * self.k * (x[self.v[0] as usize] - self.target).norm_squared()
    }
    fn eval(&self, x: &[Vector3<f64>], _project: bool, out: &mut Local) {
        let d = x[self.v[0] as usize] - self.target;
        out.set::<3>(
            0.5 * self.k * d.norm_squared(),
            &(self.k * d),
            &(self.k * Matrix3::identity()),
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finite_differences() {
        let s = Spring {
            v: [1],
            target: Vector3::new(0.3, -0.2, 0.9),
            k: 250.0,
        };
        let x = vec![Vector3::zeros(), Vector3::new(1.0, 0.5, -0.25)];
        super::super::fd::check(&s, &x, 1e-6, 1e-6);
    }
}
