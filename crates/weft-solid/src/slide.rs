//! Sliding attachments: vertices held on a rail (a polyline, possibly moving from step to
//! step) and free to slide along it, exactly.
//!
//! The constraint is kept by the Newton solve itself, not by a penalty (Baraff & Witkin 1998's
//! filtered constraints; Nocedal & Wright §12 for the manifold view):
//! - **filter**: at an iterate on the rail, each sliding vertex's gradient and Hessian rows and
//!   columns are multiplied by the projector P = t tᵀ onto the rail's tangent t there, and
//!   s (I − P) is added to its diagonal block (s its diagonal's mean, so the matrix stays SPD and
//!   as well scaled as before). The Newton direction then moves the vertex along t only;
//! - **retraction**: every trial point of the line search puts the vertex back on the rail at
//!   its closest point (the direction is tangent, so this moves it by O(|d|²·curvature)).
//!
//! The converged position is a point of a rail segment (rounding aside: distances ~1e-16 m),
//! and the step is implicit Euler on the constrained system: the normal force is whatever the
//! rail must supply. The filtered Hessian leaves out the rail's curvature term (the normal
//! force times the curvature, a second-order effect per step), so on a curved rail the last
//! iterations converge linearly at a rate ~ |force·κ| / (m/h²).
//!
//! A rail's ends are stops: a vertex at an end that the forces push outwards is held there
//! (P = 0 for that iteration); pulled back inwards, it slides again.

use nalgebra::{Matrix3, Vector3};

/// A rail: a polyline (at least two points) the sliding vertices stay on.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Rail {
    /// The polyline's points [m], in order.
    pub points: Vec<Vector3<f64>>,
}

/// A vertex that slides on a rail.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Slider {
    /// The vertex (global index).
    pub vertex: u32,
    /// Index of its rail in [`crate::SolidSystem::rails`].
    pub rail: u32,
}

/// Where a point is on a rail.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OnRail {
    /// The closest point of the rail [m].
    pub point: Vector3<f64>,
    /// The unit tangent of the segment it is on (along increasing point index).
    pub tangent: Vector3<f64>,
    /// At the rail's first (−1) or last (+1) point, else 0.
    pub end: i8,
}

impl Rail {
    /// The rail's closest point to `p` and its tangent there; the first segment wins a tie,
    /// so the answer is the same on every run. `None` when the rail has fewer than two points
    /// or only zero-length segments.
    pub fn closest(&self, p: &Vector3<f64>) -> Option<OnRail> {
        let mut best: Option<(f64, OnRail)> = None;
        let last = self.points.len().checked_sub(2)?;
        for (k, w) in self.points.windows(2).enumerate() {
            let e = w[1] - w[0];
            let l2 = e.norm_squared();
            if l2 == 0.0 || !l2.is_finite() {
                continue;
            }
            let s = ((p - w[0]).dot(&e) / l2).clamp(0.0, 1.0);
            let q = if s == 1.0 { w[1] } else { w[0] + s * e };
            let d = (p - q).norm_squared();
            if best.as_ref().is_none_or(|(bd, _)| d < *bd) {
                let end = if k == 0 && s == 0.0 {
                    -1
                } else if k == last && s == 1.0 {
                    1
                } else {
                    0
                };
                best = Some((
                    d,
                    OnRail {
                        point: q,
                        tangent: e / l2.sqrt(),
                        end,
                    },
                ));
            }
        }
        best.map(|(_, o)| o)
    }

    /// Whether the rail can hold a vertex: two or more finite points and a segment of
    /// positive length.
    pub fn is_usable(&self) -> bool {
        self.points.iter().all(|p| p.iter().all(|c| c.is_finite()))
            && self
                .points
                .first()
                .is_some_and(|p| self.closest(p).is_some())
    }
}

/// The projector a sliding vertex's rows and columns are filtered with at a point of its
/// rail, given the force −`grad` on it: t tᵀ, or zero at an end the force pushes past.
pub fn projector(on: &OnRail, grad: &Vector3<f64>) -> Matrix3<f64> {
    let outwards = -grad.dot(&on.tangent) * f64::from(on.end);
    if on.end != 0 && outwards > 0.0 {
        Matrix3::zeros()
    } else {
        on.tangent * on.tangent.transpose()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rail() -> Rail {
        Rail {
            points: vec![
                Vector3::new(0.0, 0.0, 0.0),
                Vector3::new(1.0, 0.0, 0.0),
                Vector3::new(1.0, 1.0, 0.0),
            ],
        }
    }

    #[test]
    fn closest_points_tangents_and_ends() {
        let r = rail();
        let o = r.closest(&Vector3::new(0.25, 0.5, 0.0)).unwrap();
        assert_eq!(o.point, Vector3::new(0.25, 0.0, 0.0));
        assert_eq!(o.tangent, Vector3::x());
        assert_eq!(o.end, 0);
        let o = r.closest(&Vector3::new(0.75, 0.5, 3.0)).unwrap();
        assert_eq!(o.point, Vector3::new(1.0, 0.5, 0.0));
        assert_eq!(o.tangent, Vector3::y());
        let o = r.closest(&Vector3::new(-2.0, 0.1, 0.0)).unwrap();
        assert_eq!((o.point, o.end), (Vector3::zeros(), -1));
        let o = r.closest(&Vector3::new(1.5, 4.0, 0.0)).unwrap();
        assert_eq!((o.point, o.end), (Vector3::new(1.0, 1.0, 0.0), 1));
    }

    #[test]
    fn degenerate_rails_are_refused() {
        let one = Rail {
            points: vec![Vector3::zeros()],
        };
        assert!(one.closest(&Vector3::x()).is_none());
        let dup = Rail {
            points: vec![Vector3::zeros(), Vector3::zeros()],
        };
        assert!(!dup.is_usable());
        let nan = Rail {
            points: vec![Vector3::zeros(), Vector3::new(f64::NAN, 0.0, 0.0)],
        };
        assert!(!nan.is_usable());
        assert!(rail().is_usable());
    }

    #[test]
    fn an_end_holds_only_what_is_pushed_past_it() {
        let r = rail();
        let o = r.closest(&Vector3::new(-1.0, 0.0, 0.0)).unwrap();
        // Force towards −x (gradient +x): pushed past the first point, held.
        assert_eq!(projector(&o, &Vector3::x()), Matrix3::zeros());
        // Force towards +x: slides back along the rail.
        assert_eq!(
            projector(&o, &-Vector3::x()),
            Vector3::x() * Vector3::x().transpose()
        );
    }
}
