//! Exact distances on plain coordinates, for tests that check how close the solver let two
//! things come: point to triangle, point to segment, and the least of a convex function along
//! a segment (which turns either into a segment's distance).

use nalgebra::Vector3;

type V = Vector3<f64>;

/// The exact distance from p to triangle `t`, computed without the solver's code: the
/// projection onto the plane when it falls inside (by edge half-planes), else the nearest of
/// the three edges as clamped segments.
pub fn distance_to_triangle(p: [f64; 3], t: [[f64; 3]; 3]) -> f64 {
    let (p, t) = (V::from(p), t.map(V::from));
    let n = (t[1] - t[0]).cross(&(t[2] - t[0])).normalize();
    let h = (p - t[0]).dot(&n);
    let q = p - h * n;
    let inside = (0..3).all(|k| (t[(k + 1) % 3] - t[k]).cross(&(q - t[k])).dot(&n) >= 0.0);
    if inside {
        return h.abs();
    }
    (0..3)
        .map(|k| distance_to_segment(p.into(), t[k].into(), t[(k + 1) % 3].into()))
        .fold(f64::INFINITY, f64::min)
}

/// The exact distance from p to segment a→b (the clamped projection).
pub fn distance_to_segment(p: [f64; 3], a: [f64; 3], b: [f64; 3]) -> f64 {
    let (p, a, b) = (V::from(p), V::from(a), V::from(b));
    let ab = b - a;
    let l2 = ab.norm_squared();
    let s = if l2 > 0.0 {
        ((p - a).dot(&ab) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p - (a + s * ab)).norm()
}

/// The least of `f` over segment a→b, for `f` convex along it (the distance to a convex
/// set is): golden-section search (60 rounds: 3e-13 of the segment), and the ends.
pub fn least_along(a: [f64; 3], b: [f64; 3], f: impl Fn([f64; 3]) -> f64) -> f64 {
    let f = |s: f64| f(along(a, b, s));
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let (mut lo, mut hi) = (0.0, 1.0);
    for _ in 0..60 {
        let (l, r) = (hi - g * (hi - lo), lo + g * (hi - lo));
        if f(l) <= f(r) {
            hi = r;
        } else {
            lo = l;
        }
    }
    f(0.5 * (lo + hi)).min(f(0.0)).min(f(1.0))
}

/// The point a fraction `s` of the way from `a` to `b`.
pub fn along(a: [f64; 3], b: [f64; 3], s: f64) -> [f64; 3] {
    [0, 1, 2].map(|k| a[k] + s * (b[k] - a[k]))
}

/// The distance from a to b.
pub fn length(a: [f64; 3], b: [f64; 3]) -> f64 {
    (V::from(b) - V::from(a)).norm()
}

#[cfg(test)]
mod tests {
    use super::*;

    const T: [[f64; 3]; 3] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];

    /// Above the face: the height; beside an edge: the distance to it; beyond a corner: to
    /// the corner (exact to rounding, 1e-15).
    #[test]
    fn a_point_is_as_far_from_a_triangle_as_its_nearest_feature() {
        assert!((distance_to_triangle([0.2, 0.2, 0.5], T) - 0.5).abs() < 1e-15);
        assert!((distance_to_triangle([0.5, -0.3, 0.4], T) - 0.5).abs() < 1e-15);
        let corner = distance_to_triangle([-0.3, -0.4, 0.0], T);
        assert!((corner - 0.5).abs() < 1e-15, "{corner}");
    }

    /// A segment's distance to a triangle as the least of the distance along it: 0 for one
    /// through the face, 0.25 for one 0.25 over it, to 1e-12 (the search's 3e-13 of the
    /// segment); a point's distance to a segment beside it.
    #[test]
    fn the_least_along_a_segment_finds_its_closest_point() {
        let d = least_along([0.2, 0.2, -1.0], [0.2, 0.2, 1.0], |x| {
            distance_to_triangle(x, T)
        });
        assert!(d.abs() < 1e-12, "{d}");
        let d = least_along([0.2, 0.2, 0.25], [0.3, 0.1, 0.25], |x| {
            distance_to_triangle(x, T)
        });
        assert!((d - 0.25).abs() < 1e-12, "{d}");
        assert!(
            (distance_to_segment([0.5, 1.0, 0.0], [0.0; 3], [1.0, 0.0, 0.0]) - 1.0).abs() < 1e-15
        );
    }
}
