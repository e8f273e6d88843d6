//! Sliding attachments: vertices held on a rail (a polyline) or a surface (a triangle mesh),
//! either possibly moving from step to step, and free to slide along it, exactly; with
//! optional Coulomb friction along it.
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
//! (P = 0 for that iteration); pulled back inwards, it slides again. A surface's open border
//! is a rail for a vertex pushed across it (P = e eᵀ along the border edge).
//!
//! **Friction** (coefficient μ) is IPC's lagged, mollified Coulomb law (Li et al. 2020, §5):
//! the potential μ N f₀(|u|) of the step's tangential displacement u = P (x − x⁰), with
//! f₀(y) = y beyond ε = ε_v h and a cubic blend below it, so a sliding vertex feels μN
//! against its motion and a sticking one creeps below ε_v ([`FRICTION_EPS_V`]). N, the normal
//! force the target supplies, is taken from the previous Newton iterate (the normal part of
//! the unconstrained gradient), so at convergence the law is Coulomb's with the step's own
//! normal force.

use nalgebra::{Matrix3, Vector3};
use std::sync::Arc;

/// ε_v of the friction's mollifier [m/s]: a sticking vertex creeps below it. Small enough not
/// to show over a shot (≤ 1 mm in 10 s), large enough that the sticking stiffness μN/(ε_v h)
/// stays within a few hundred m/h² at film steps.
pub const FRICTION_EPS_V: f64 = 1e-4;

/// A surface that vertices slide on: the closest point and the normal there.
pub trait Surface: Send + Sync + std::fmt::Debug {
    /// The surface's closest point to `p`, or None when it has none (no triangles).
    fn closest(&self, p: &Vector3<f64>) -> Option<OnSurface>;
}

/// Where a point is on a surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OnSurface {
    /// The closest point [m].
    pub point: Vector3<f64>,
    /// The unit normal of the triangle it is on.
    pub normal: Vector3<f64>,
    /// On an open border: the border edge's unit direction and the unit direction out of the
    /// surface across it (in the triangle's plane).
    pub border: Option<(Vector3<f64>, Vector3<f64>)>,
}

/// What a sliding vertex slides on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SlideOn {
    /// Rail k of [`crate::SolidSystem::rails`].
    Rail(u32),
    /// Surface k of [`crate::SolidSystem::surfaces`].
    Surface(u32),
    /// A point [m]: the vertex is held there exactly (P = 0, retracted onto it), without the
    /// pattern change that pinning it would need; the caller moves the point between steps
    /// (frozen vertices following an animated input).
    Point(Vector3<f64>),
}

/// Where a sliding vertex's target holds a point, as the filter needs it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Place {
    /// The target's closest point.
    pub point: Vector3<f64>,
    /// The projector onto the directions it may move in.
    pub free: Matrix3<f64>,
    /// At a stop (a rail's end, a surface's border): the projector when pushed past it and
    /// the outward direction.
    pub stop: Option<(Matrix3<f64>, Vector3<f64>)>,
}

/// A rail: a polyline (at least two points) the sliding vertices stay on.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Rail {
    /// The polyline's points [m], in order.
    pub points: Vec<Vector3<f64>>,
}

/// A vertex that slides on a rail or a surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Slider {
    /// The vertex (global index).
    pub vertex: u32,
    /// What it slides on.
    pub on: SlideOn,
    /// Coulomb friction coefficient μ ≥ 0 along it.
    pub friction: f64,
}

/// The place of `p` on what `on` names; None when that target does not exist or has no
/// closest point (`SolidSystem::check` refuses both).
pub fn place(
    rails: &[Rail],
    surfaces: &[Arc<dyn Surface>],
    on: SlideOn,
    p: &Vector3<f64>,
) -> Option<Place> {
    match on {
        SlideOn::Rail(k) => {
            let o = rails.get(k as usize)?.closest(p)?;
            let t = o.tangent;
            Some(Place {
                point: o.point,
                free: t * t.transpose(),
                stop: (o.end != 0).then(|| (Matrix3::zeros(), f64::from(o.end) * t)),
            })
        }
        SlideOn::Surface(k) => {
            let o = surfaces.get(k as usize)?.closest(p)?;
            let n = o.normal;
            Some(Place {
                point: o.point,
                free: Matrix3::identity() - n * n.transpose(),
                stop: o.border.map(|(e, out)| (e * e.transpose(), out)),
            })
        }
        SlideOn::Point(point) => Some(Place {
            point,
            free: Matrix3::zeros(),
            stop: None,
        }),
    }
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

/// The projector a sliding vertex's rows and columns are filtered with at its place, given
/// the force −`grad` on it: the free one, or the stop's when the force pushes past a stop.
pub fn projector(place: &Place, grad: &Vector3<f64>) -> Matrix3<f64> {
    match place.stop {
        Some((stopped, out)) if -grad.dot(&out) > 0.0 => stopped,
        _ => place.free,
    }
}

/// The friction's mollified magnitude f₀(y) and its derivative f₁(y) (IPC's eq. 17: C¹,
/// f₀(y) = y and f₁ = 1 from ε on).
pub fn friction_f0_f1(y: f64, eps: f64) -> (f64, f64) {
    if y >= eps {
        (y, 1.0)
    } else {
        let r = y / eps;
        (
            eps * (-r * r * r / 3.0 + r * r + 1.0 / 3.0),
            2.0 * r - r * r,
        )
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
        let rails = [rail()];
        let p = place(&rails, &[], SlideOn::Rail(0), &Vector3::new(-1.0, 0.0, 0.0)).unwrap();
        // Force towards −x (gradient +x): pushed past the first point, held.
        assert_eq!(projector(&p, &Vector3::x()), Matrix3::zeros());
        // Force towards +x: slides back along the rail.
        assert_eq!(
            projector(&p, &-Vector3::x()),
            Vector3::x() * Vector3::x().transpose()
        );
        assert!(place(&rails, &[], SlideOn::Rail(1), &Vector3::zeros()).is_none());
    }

    #[test]
    fn the_friction_mollifier_is_c1_and_coulomb_beyond_eps() {
        let eps = 1e-3;
        assert_eq!(friction_f0_f1(2e-3, eps), (2e-3, 1.0));
        let (a, da) = friction_f0_f1(eps * (1.0 - 1e-9), eps);
        assert!((a - eps).abs() < 1e-12 && (da - 1.0).abs() < 1e-8);
        // f₁ = f₀′ (central differences; one-sided at 0).
        for y in [0.0, 1e-4, 5e-4, 9e-4] {
            let d = 1e-9;
            let fd = if y == 0.0 {
                (friction_f0_f1(d, eps).0 - friction_f0_f1(0.0, eps).0) / d
            } else {
                (friction_f0_f1(y + d, eps).0 - friction_f0_f1(y - d, eps).0) / (2.0 * d)
            };
            let want = friction_f0_f1(y, eps).1;
            assert!((fd - want).abs() < 1e-5, "y {y}: {fd} vs {want}");
        }
    }
}
