//! Continuous collision detection of point–triangle and edge–edge pairs moving linearly over
//! a step, conservative: additive CCD (Li et al. 2021, "Codimensional Incremental Potential
//! Contact", §4 and Alg. 1). No Rust crate provides it.
//!
//! Why this method: it only evaluates distances (the closest-point routines of
//! [`super::geometry`], exact in f64 up to rounding), never the roots of the cubic
//! coplanarity polynomial, so parallel, degenerate and grazing configurations need no special
//! case, and it never misses an impact: the distance between the pair's primitives changes
//! at most `l` per unit of time, `l` bounding their relative displacement over the step, so
//! advancing by a fraction of (distance − ξ)/l cannot step over the time the distance
//! reaches ξ. What it reports is a time `t` at which the pair is still at least ξ apart and
//! after which it may come closer than ξ: a conservative time of impact. False positives
//! (a pair that comes within ξ + 10⁻³ of its starting clearance but not within ξ) are
//! possible; false negatives are not.

use super::geometry::{closest_on_triangle, closest_segment_segment};
use nalgebra::Vector3;

type V = Vector3<f64>;

/// The two kinds of pair whose first contact starts every intersection of two triangle meshes
/// (or of segments with them).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum PairKind {
    /// Points 0 (the point) and 1, 2, 3 (the triangle).
    PointTriangle,
    /// Points 0, 1 (one edge) and 2, 3 (the other).
    EdgeEdge,
}

/// The distance between the pair's primitives at the points `x`.
pub(crate) fn distance(kind: PairKind, x: &[V; 4]) -> f64 {
    match kind {
        PairKind::PointTriangle => {
            let w = closest_on_triangle(&x[0], &x[1], &x[2], &x[3]);
            (x[0] - (w[0] * x[1] + w[1] * x[2] + w[2] * x[3])).norm()
        }
        PairKind::EdgeEdge => {
            let (s, t) = closest_segment_segment(&x[0], &x[1], &x[2], &x[3]);
            ((x[0] + s * (x[1] - x[0])) - (x[2] + t * (x[3] - x[2]))).norm()
        }
    }
}

/// The clearance left, as a fraction of the starting one, at which a pair is reported: the
/// search stops there rather than creeping towards ξ (each iteration removes about 90 % of the
/// remaining clearance of an approaching pair, so this costs three iterations more than 0.1).
const STOP_FRACTION: f64 = 1e-3;

/// Iterations before the search gives up and reports the time reached (conservative): only
/// a pair that stays within a hair of ξ while moving fast along it needs this many.
const MAX_ITERATIONS: usize = 4096;

/// The pair moving from `x` by `d` over the step (x + t d, t ∈ [0, 1]): `None` when its
/// primitives stay more than `xi` apart throughout, else `Some(t)` with the primitives at
/// least `xi` apart over [0, t] (a conservative time of impact; 0 when they start within
/// `xi`). Distances within 10⁻¹² of the points' coordinates of ξ count as ξ.
pub(crate) fn time_of_impact(kind: PairKind, x: &[V; 4], d: &[V; 4], xi: f64) -> Option<f64> {
    // The distance does not change under a common translation: remove the mean displacement
    // so that the bound below is as tight as the relative motion allows.
    let mean = (d[0] + d[1] + d[2] + d[3]) / 4.0;
    let r = d.map(|di| (di - mean).norm());
    // |d/dt distance| ≤ l: each primitive's points are convex combinations of its vertices.
    let l = match kind {
        PairKind::PointTriangle => r[0] + r[1].max(r[2]).max(r[3]),
        PairKind::EdgeEdge => r[0].max(r[1]) + r[2].max(r[3]),
    };
    // Closer than ξ by no more than rounding counts as touching (conservative).
    let scale = x.iter().fold(f64::MIN_POSITIVE, |m, p| m.max(p.amax()));
    let xi = xi + 1e-12 * scale;
    let d0 = distance(kind, x);
    if d0 <= xi || d0.is_nan() {
        return Some(0.0);
    }
    if l == 0.0 || !l.is_finite() {
        return if l == 0.0 { None } else { Some(0.0) };
    }
    let stop = STOP_FRACTION * (d0 - xi);
    let (mut t, mut gap) = (0.0, d0 - xi);
    for it in 0..MAX_ITERATIONS {
        if it > 0 && gap <= stop {
            return Some(t);
        }
        // Over [t, t + τ] the distance is at least gap + ξ − l (s − t) ≥ ξ + 0.1 gap.
        let advance = 0.9 * gap / l;
        if t + advance > 1.0 {
            return None;
        }
        let xt = positions(x, d, t + advance);
        let next = distance(kind, &xt) - xi;
        if next <= 0.0 {
            // Only rounding gets here (the advance is bounded): the last time known safe.
            return Some(t);
        }
        (t, gap) = (t + advance, next);
    }
    Some(t)
}

fn positions(x: &[V; 4], d: &[V; 4], t: f64) -> [V; 4] {
    [
        x[0] + t * d[0],
        x[1] + t * d[1],
        x[2] + t * d[2],
        x[3] + t * d[3],
    ]
}

#[cfg(test)]
mod tests {
    use super::PairKind::{EdgeEdge, PointTriangle};
    use super::*;

    fn v(x: f64, y: f64, z: f64) -> V {
        V::new(x, y, z)
    }

    /// The unit right triangle in z = 0 and a point or edge above it.
    fn tri() -> [V; 3] {
        [v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(0.0, 1.0, 0.0)]
    }

    fn pt(p: V, dp: V, dt: [V; 3]) -> ([V; 4], [V; 4]) {
        let t = tri();
        ([p, t[0], t[1], t[2]], [dp, dt[0], dt[1], dt[2]])
    }

    const STILL: [V; 3] = [V::new(0.0, 0.0, 0.0); 3];

    /// A reported time is safe: the pair is at least ξ apart at it (to rounding), and it is
    /// no later than the true first time of impact `t_star` (when there is one) and within
    /// `slack` of it.
    fn check_reported(kind: PairKind, x: &[V; 4], d: &[V; 4], xi: f64, t_star: f64, slack: f64) {
        let t = time_of_impact(kind, x, d, xi).expect("an impact must be reported");
        assert!(
            t <= t_star && t >= t_star - slack,
            "t = {t}, impact at {t_star}"
        );
        let at = positions(x, d, t);
        assert!(distance(kind, &at) >= xi - 1e-15, "not safe at {t}");
    }

    /// Point–triangle cases with known answers (ξ = 0: intersection itself).
    #[test]
    fn point_triangle_known_answers() {
        // Head-on through the face: impact at t = 0.5.
        let (x, d) = pt(v(0.2, 0.2, 1.0), v(0.0, 0.0, -2.0), STILL);
        check_reported(PointTriangle, &x, &d, 0.0, 0.5, 1e-3);
        // The same with a thickness of 0.1: impact when 0.1 away, at t = 0.45.
        check_reported(PointTriangle, &x, &d, 0.1, 0.45, 1e-3);
        // Passing beside the triangle (0.1 outside its hypotenuse): no impact.
        let (x, d) = pt(v(0.6, 0.6, 1.0), v(0.0, 0.0, -2.0), STILL);
        assert_eq!(time_of_impact(PointTriangle, &x, &d, 0.0), None);
        // Moving parallel to the plane, 0.01 above it, across the whole triangle: none.
        let (x, d) = pt(v(-1.0, 0.2, 0.01), v(3.0, 0.0, 0.0), STILL);
        assert_eq!(time_of_impact(PointTriangle, &x, &d, 0.0), None);
        // ... but with ξ = 0.02 it is within reach from the moment it is over the face.
        let t = time_of_impact(PointTriangle, &x, &d, 0.02).unwrap();
        assert!(t <= 1.0 / 3.0 + 1e-12 && t > 0.3, "{t}");
        // Touching at t = 0 (on the face): reported at 0.
        let (x, d) = pt(v(0.2, 0.2, 0.0), v(0.0, 0.0, 1.0), STILL);
        assert_eq!(time_of_impact(PointTriangle, &x, &d, 0.0), Some(0.0));
        // Touching at t = 1 exactly (arrives on the face at the step's end): reported.
        let (x, d) = pt(v(0.2, 0.2, 1.0), v(0.0, 0.0, -1.0), STILL);
        check_reported(PointTriangle, &x, &d, 0.0, 1.0, 1e-2);
        // Stopping 0.01 short of the face at t = 1: no impact. (Stopping within a thousandth
        // of the starting clearance is reported: the documented false positive.)
        let (x, d) = pt(v(0.2, 0.2, 1.0), v(0.0, 0.0, -0.99), STILL);
        assert_eq!(time_of_impact(PointTriangle, &x, &d, 0.0), None);
        // Grazing a vertex exactly (the path passes through the corner (1, 0, 0)): reported.
        let (x, d) = pt(v(1.0, -1.0, 0.0), v(0.0, 2.0, 0.0), STILL);
        check_reported(PointTriangle, &x, &d, 0.0, 0.5, 1e-3);
        // Grazing an edge exactly, in the plane, from outside the hypotenuse: reported.
        let (x, d) = pt(v(1.0, 1.0, 0.0), v(-1.0, -1.0, 0.0), STILL);
        check_reported(PointTriangle, &x, &d, 0.0, 0.5, 1e-3);
        // The triangle moves onto a still point: the same impact.
        let down = v(0.0, 0.0, 2.0);
        let (x, d) = pt(v(0.2, 0.2, 1.0), V::zeros(), [down; 3]);
        check_reported(PointTriangle, &x, &d, 0.0, 0.5, 1e-3);
        // Both move the same way: no relative motion, no impact.
        let (x, d) = pt(v(0.2, 0.2, 1.0), v(5.0, 1.0, -3.0), [v(5.0, 1.0, -3.0); 3]);
        assert_eq!(time_of_impact(PointTriangle, &x, &d, 0.0), None);
        // A degenerate (zero-area) triangle, a segment along x: the point crossing it at
        // x = 0.5 is reported; one passing beyond its end is not.
        let line = [v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(0.5, 0.0, 0.0)];
        let x = [v(0.5, -1.0, 0.0), line[0], line[1], line[2]];
        let d = [v(0.0, 2.0, 0.0), V::zeros(), V::zeros(), V::zeros()];
        check_reported(PointTriangle, &x, &d, 0.0, 0.5, 1e-3);
        let x = [v(1.5, -1.0, 0.0), line[0], line[1], line[2]];
        assert_eq!(time_of_impact(PointTriangle, &x, &d, 0.0), None);
        // A vertex of the triangle sweeps through the point (the triangle tilts up).
        let (x, d) = pt(
            v(0.9, 0.02, 0.05),
            V::zeros(),
            [V::zeros(), v(0.0, 0.0, 0.1), V::zeros()],
        );
        let t = time_of_impact(PointTriangle, &x, &d, 0.0).expect("the tilting face hits it");
        assert!(t < 1.0);
    }

    /// Edge–edge cases with known answers.
    #[test]
    fn edge_edge_known_answers() {
        let a = [v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0)];
        // A perpendicular edge above the first falls through it: impact at t = 0.25.
        let x = [a[0], a[1], v(0.5, -0.5, 1.0), v(0.5, 0.5, 1.0)];
        let d = [V::zeros(), V::zeros(), v(0.0, 0.0, -4.0), v(0.0, 0.0, -4.0)];
        check_reported(EdgeEdge, &x, &d, 0.0, 0.25, 1e-3);
        check_reported(EdgeEdge, &x, &d, 0.2, 0.2, 1e-3);
        // The same edge falling beside the first's end (x = 1.5): none.
        let x2 = [a[0], a[1], v(1.5, -0.5, 1.0), v(1.5, 0.5, 1.0)];
        assert_eq!(time_of_impact(EdgeEdge, &x2, &d, 0.0), None);
        // Parallel edges, one falling onto the other, overlapping by half: impact at 0.5.
        let x = [a[0], a[1], v(0.5, 0.0, 1.0), v(1.5, 0.0, 1.0)];
        let d = [V::zeros(), V::zeros(), v(0.0, 0.0, -2.0), v(0.0, 0.0, -2.0)];
        check_reported(EdgeEdge, &x, &d, 0.0, 0.5, 1e-3);
        // Parallel and collinear, sliding end to end: they meet at t = 0.5.
        let x = [a[0], a[1], v(2.0, 0.0, 0.0), v(3.0, 0.0, 0.0)];
        let d = [V::zeros(), V::zeros(), v(-2.0, 0.0, 0.0), v(-2.0, 0.0, 0.0)];
        check_reported(EdgeEdge, &x, &d, 0.0, 0.5, 1e-3);
        // Parallel, sliding past each other 0.01 apart: none.
        let x = [a[0], a[1], v(2.0, 0.01, 0.0), v(3.0, 0.01, 0.0)];
        let d = [V::zeros(), V::zeros(), v(-4.0, 0.0, 0.0), v(-4.0, 0.0, 0.0)];
        assert_eq!(time_of_impact(EdgeEdge, &x, &d, 0.0), None);
        // Touching at t = 0 (end on edge) and at t = 1 (they cross at the step's end).
        let x = [a[0], a[1], v(0.5, 0.0, 0.0), v(0.5, 1.0, 0.0)];
        let d = [V::zeros(), V::zeros(), v(0.0, 0.0, 1.0), v(0.0, 0.0, 1.0)];
        assert_eq!(time_of_impact(EdgeEdge, &x, &d, 0.0), Some(0.0));
        let x = [a[0], a[1], v(0.5, -0.5, 1.0), v(0.5, 0.5, 1.0)];
        let d = [V::zeros(), V::zeros(), v(0.0, 0.0, -1.0), v(0.0, 0.0, -1.0)];
        check_reported(EdgeEdge, &x, &d, 0.0, 1.0, 1e-2);
        // A degenerate (zero-length) edge is a point: it hits the other edge's middle.
        let x = [a[0], a[1], v(0.5, 0.0, 1.0), v(0.5, 0.0, 1.0)];
        let d = [V::zeros(), V::zeros(), v(0.0, 0.0, -2.0), v(0.0, 0.0, -2.0)];
        check_reported(EdgeEdge, &x, &d, 0.0, 0.5, 1e-3);
        // Rotating through: an edge spinning about its middle above the x axis, 0.1 high,
        // and dropping 0.2: meets the axis when crossing it.
        let x = [a[0], a[1], v(0.5, -0.5, 0.1), v(0.5, 0.5, 0.1)];
        let d = [
            V::zeros(),
            V::zeros(),
            v(0.5, 0.5, -0.2),
            v(-0.5, -0.5, -0.2),
        ];
        check_reported(EdgeEdge, &x, &d, 0.0, 0.5, 1e-3);
    }

    /// Random linear motions against a dense sampling of the path: whenever a sample comes
    /// within ξ, an impact is reported no later than that sample (no false negatives), and
    /// every reported time is safe.
    #[test]
    fn no_false_negatives_on_random_paths() {
        let mut seed = 3u64;
        let mut rnd = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        let mut hits = 0;
        for k in 0..4000 {
            let kind = if k % 2 == 0 { PointTriangle } else { EdgeEdge };
            let x = [(); 4].map(|_| V::new(rnd(), rnd(), rnd()) * 0.5);
            let d = [(); 4].map(|_| V::new(rnd(), rnd(), rnd()) * 1.5);
            let xi = if k % 3 == 0 {
                0.0
            } else {
                0.05 * (rnd() + 1.0)
            };
            let toi = time_of_impact(kind, &x, &d, xi);
            let n = 2000;
            let first = (0..=n)
                .map(|i| i as f64 / n as f64)
                .find(|&t| distance(kind, &positions(&x, &d, t)) < xi);
            if let Some(ts) = first {
                hits += 1;
                let t = toi.unwrap_or_else(|| panic!("case {k}: missed an impact at {ts}"));
                assert!(t <= ts, "case {k}: reported {t} after the sample at {ts}");
            }
            if let Some(t) = toi {
                let at = distance(kind, &positions(&x, &d, t));
                assert!(at >= xi - 1e-14 || t == 0.0, "case {k}: unsafe at {t}");
            }
        }
        assert!(hits > 500, "the set exercises impacts ({hits})");
    }
}
