//! Exact distances on plain coordinates, for tests that check how close the solver let two
//! things come: point to triangle, point to segment, and the least of a convex function along
//! a segment (which turns either into a segment's distance).

/// The exact distance from p to triangle `t`, computed without the solver's code: the
/// projection onto the plane when it falls inside (by edge half-planes), else the nearest of
/// the three edges as clamped segments.
pub fn distance_to_triangle(p: [f64; 3], t: [[f64; 3]; 3]) -> f64 {
    let n = cross(sub(t[1], t[0]), sub(t[2], t[0]));
    let nn = dot(n, n).sqrt();
    let n = [n[0] / nn, n[1] / nn, n[2] / nn];
    let h = dot(sub(p, t[0]), n);
    let q = [p[0] - h * n[0], p[1] - h * n[1], p[2] - h * n[2]];
    let inside = (0..3).all(|k| dot(cross(sub(t[(k + 1) % 3], t[k]), sub(q, t[k])), n) >= 0.0);
    if inside {
        return h.abs();
    }
    (0..3)
        .map(|k| {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            let ab = sub(b, a);
            let s = (dot(sub(p, a), ab) / dot(ab, ab)).clamp(0.0, 1.0);
            let c = [a[0] + s * ab[0], a[1] + s * ab[1], a[2] + s * ab[2]];
            dot(sub(p, c), sub(p, c)).sqrt()
        })
        .fold(f64::INFINITY, f64::min)
}

/// The exact distance from p to segment a→b (the clamped projection).
pub fn distance_to_segment(p: [f64; 3], a: [f64; 3], b: [f64; 3]) -> f64 {
    let (ab, ap) = (sub(b, a), sub(p, a));
    let l2 = ab.iter().map(|x| x * x).sum::<f64>();
    let s = if l2 > 0.0 {
        (ab.iter().zip(&ap).map(|(x, y)| x * y).sum::<f64>() / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    norm(sub(p, along(a, b, s)))
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

/// b − a's length.
pub fn length(a: [f64; 3], b: [f64; 3]) -> f64 {
    norm(sub(b, a))
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn norm(a: [f64; 3]) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
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
