//! Exact f64 narrow-phase geometry: closest points on triangles and segments crossing them.

use nalgebra::Vector3;

type V = Vector3<f64>;

/// The point of triangle (a, b, c) closest to p, as barycentric weights (Ericson, *Real-Time
/// Collision Detection* §5.1.5: by Voronoi region, vertex, edge or face).
pub(crate) fn closest_on_triangle(p: &V, a: &V, b: &V, c: &V) -> [f64; 3] {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(&ap), ac.dot(&ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return [1.0, 0.0, 0.0];
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(&bp), ac.dot(&bp));
    if d3 >= 0.0 && d4 <= d3 {
        return [0.0, 1.0, 0.0];
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return [1.0 - v, v, 0.0];
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(&cp), ac.dot(&cp));
    if d6 >= 0.0 && d5 <= d6 {
        return [0.0, 0.0, 1.0];
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return [1.0 - w, 0.0, w];
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return [0.0, 1.0 - w, w];
    }
    let denom = va + vb + vc;
    if denom.abs() < f64::MIN_POSITIVE {
        // A degenerate (zero-area) triangle whose regions all failed: its nearest corner.
        let d = [(p - a).norm(), (p - b).norm(), (p - c).norm()];
        let k = (0..3).min_by(|&i, &j| d[i].total_cmp(&d[j])).unwrap_or(0);
        let mut w = [0.0; 3];
        w[k] = 1.0;
        return w;
    }
    let (v, w) = (vb / denom, vc / denom);
    [1.0 - v - w, v, w]
}

/// True when the segment p → q meets triangle (a, b, c) (its closed surface): the segment's
/// end points lie on opposite sides of (or on) the triangle's plane and the crossing point is
/// inside the triangle (signed volumes, no division before the tests).
pub(crate) fn segment_crosses_triangle(p: &V, q: &V, a: &V, b: &V, c: &V) -> bool {
    let n = (b - a).cross(&(c - a));
    let (sp, sq) = (n.dot(&(p - a)), n.dot(&(q - a)));
    if (sp > 0.0 && sq > 0.0) || (sp < 0.0 && sq < 0.0) || (sp == 0.0 && sq == 0.0) {
        return false;
    }
    let d = q - p;
    // The crossing is inside when the three edge volumes have one sign.
    let s1 = d.dot(&(a - p).cross(&(b - p)));
    let s2 = d.dot(&(b - p).cross(&(c - p)));
    let s3 = d.dot(&(c - p).cross(&(a - p)));
    (s1 >= 0.0 && s2 >= 0.0 && s3 >= 0.0) || (s1 <= 0.0 && s2 <= 0.0 && s3 <= 0.0)
}

/// The closest points of segments p₁q₁ and p₂q₂ as parameters (s, t) in [0, 1] (Ericson,
/// *Real-Time Collision Detection* §5.1.9: the unclamped solution clamped to the square,
/// degenerate segments as points; parallel segments take s = 0).
pub(crate) fn closest_segment_segment(p1: &V, q1: &V, p2: &V, q2: &V) -> (f64, f64) {
    let (d1, d2, r) = (q1 - p1, q2 - p2, p1 - p2);
    let (a, e, f) = (d1.norm_squared(), d2.norm_squared(), d2.dot(&r));
    let tiny = f64::MIN_POSITIVE;
    if a <= tiny && e <= tiny {
        return (0.0, 0.0);
    }
    if a <= tiny {
        return (0.0, (f / e).clamp(0.0, 1.0));
    }
    let c = d1.dot(&r);
    if e <= tiny {
        return ((-c / a).clamp(0.0, 1.0), 0.0);
    }
    let b = d1.dot(&d2);
    let denom = a * e - b * b;
    let mut s = if denom > 1e-14 * a * e {
        ((b * f - c * e) / denom).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let mut t = (b * s + f) / e;
    if t < 0.0 {
        t = 0.0;
        s = (-c / a).clamp(0.0, 1.0);
    } else if t > 1.0 {
        t = 1.0;
        s = ((b - c) / a).clamp(0.0, 1.0);
    }
    (s, t)
}

/// The closest points of segment p → q and triangle (a, b, c): (s along the segment,
/// barycentric weights on the triangle, distance). A segment through the triangle is at
/// distance 0 where it crosses; otherwise the closest pair has an end of the segment or an
/// edge of the triangle in it (the distance to the plane is linear along the segment), so
/// those five candidates decide it (the lowest distance, the first of equals).
pub(crate) fn closest_segment_triangle(p: &V, q: &V, a: &V, b: &V, c: &V) -> (f64, [f64; 3], f64) {
    if segment_crosses_triangle(p, q, a, b, c) {
        let n = (b - a).cross(&(c - a));
        let (sp, sq) = (n.dot(&(p - a)), n.dot(&(q - a)));
        let s = if sp == sq {
            0.0
        } else {
            (sp / (sp - sq)).clamp(0.0, 1.0)
        };
        let x = p + s * (q - p);
        let w = closest_on_triangle(&x, a, b, c);
        let d = (x - (w[0] * a + w[1] * b + w[2] * c)).norm();
        return (s, w, d);
    }
    let tri = [a, b, c];
    let mut best = (0.0, [1.0, 0.0, 0.0], f64::INFINITY);
    for k in 0..3 {
        let (e0, e1) = (tri[k], tri[(k + 1) % 3]);
        let (s, t) = closest_segment_segment(p, q, e0, e1);
        let d = ((p + s * (q - p)) - (e0 + t * (e1 - e0))).norm();
        if d < best.2 {
            let mut w = [0.0; 3];
            w[k] = 1.0 - t;
            w[(k + 1) % 3] = t;
            best = (s, w, d);
        }
    }
    for (s, x) in [(0.0, p), (1.0, q)] {
        let w = closest_on_triangle(x, a, b, c);
        let d = (x - (w[0] * a + w[1] * b + w[2] * c)).norm();
        if d < best.2 {
            best = (s, w, d);
        }
    }
    best
}

/// The unit normal of a triangle by its winding (zero for a degenerate one).
pub(crate) fn face_normal(tri: &[V; 3]) -> V {
    (tri[1] - tri[0])
        .cross(&(tri[2] - tri[0]))
        .try_normalize(0.0)
        .unwrap_or_else(V::zeros)
}

/// An orthonormal frame with first row `n` (unit): rows n, t₁, t₂.
pub(crate) fn frame(n: &V) -> nalgebra::Matrix3<f64> {
    // Branch-free basis (Duff et al. 2017, "Building an orthonormal basis, revisited").
    let s = 1f64.copysign(n.z);
    let a = -1.0 / (s + n.z);
    let b = n.x * n.y * a;
    let t1 = V::new(1.0 + s * n.x * n.x * a, s * b, -s * n.x);
    let t2 = V::new(b, s + n.y * n.y * a, -n.y);
    nalgebra::Matrix3::from_rows(&[n.transpose(), t1.transpose(), t2.transpose()])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The closest point is checked against a dense sampling of the triangle: no sample is
    /// closer (to 1e-12), on points in every Voronoi region.
    #[test]
    fn closest_point_beats_every_sample() {
        let (a, b, c) = (
            V::new(0.0, 0.0, 0.0),
            V::new(1.0, 0.2, 0.0),
            V::new(0.3, 0.9, 0.1),
        );
        let mut seed = 7u64;
        let mut rnd = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 * 3.0 - 1.0
        };
        for _ in 0..200 {
            let p = V::new(rnd(), rnd(), rnd());
            let w = closest_on_triangle(&p, &a, &b, &c);
            assert!(w.iter().all(|&x| (-1e-12..=1.0 + 1e-12).contains(&x)));
            assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
            let q = w[0] * a + w[1] * b + w[2] * c;
            let d = (p - q).norm();
            let n = 60;
            for i in 0..=n {
                for j in 0..=n - i {
                    let (u, v) = (i as f64 / n as f64, j as f64 / n as f64);
                    let s = (1.0 - u - v) * a + u * b + v * c;
                    assert!((p - s).norm() >= d - 1e-12);
                }
            }
        }
    }

    #[test]
    fn segments_cross_triangles_only_through_them() {
        let (a, b, c) = (
            V::new(0.0, 0.0, 0.0),
            V::new(1.0, 0.0, 0.0),
            V::new(0.0, 1.0, 0.0),
        );
        let up = V::new(0.2, 0.2, 1.0);
        assert!(segment_crosses_triangle(
            &up,
            &V::new(0.2, 0.2, -1.0),
            &a,
            &b,
            &c
        ));
        assert!(!segment_crosses_triangle(
            &up,
            &V::new(0.2, 0.2, 0.5),
            &a,
            &b,
            &c
        ));
        assert!(!segment_crosses_triangle(
            &V::new(0.9, 0.9, 1.0),
            &V::new(0.9, 0.9, -1.0),
            &a,
            &b,
            &c
        ));
        // Ending on the surface counts.
        assert!(segment_crosses_triangle(
            &up,
            &V::new(0.2, 0.2, 0.0),
            &a,
            &b,
            &c
        ));
    }

    /// Segment–segment and segment–triangle closest points against dense sampling of both
    /// shapes: no sampled pair is closer (to 1e-12), over random segments (some crossing the
    /// triangle, some parallel to it); and the hand-built cases' known answers.
    #[test]
    fn segment_closest_points_beat_every_sample() {
        let (a, b, c) = (
            V::new(0.0, 0.0, 0.0),
            V::new(1.0, 0.2, 0.0),
            V::new(0.3, 0.9, 0.1),
        );
        let mut seed = 11u64;
        let mut rnd = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 * 3.0 - 1.0
        };
        let n = 40;
        for k in 0..150 {
            let p = V::new(rnd(), rnd(), rnd());
            let mut q = V::new(rnd(), rnd(), rnd());
            if k % 5 == 0 {
                q = p + 0.7 * (b - a); // parallel to an edge and the plane
            }
            let (s, w, d) = closest_segment_triangle(&p, &q, &a, &b, &c);
            let x = p + s * (q - p);
            let y = w[0] * a + w[1] * b + w[2] * c;
            assert!(((x - y).norm() - d).abs() < 1e-12);
            let (s2, t2) = closest_segment_segment(&p, &q, &b, &c);
            let d2 = ((p + s2 * (q - p)) - (b + t2 * (c - b))).norm();
            for i in 0..=n {
                let xs = p + (i as f64 / n as f64) * (q - p);
                for u in 0..=n {
                    let ys = b + (u as f64 / n as f64) * (c - b);
                    assert!((xs - ys).norm() >= d2 - 1e-12, "segments {k}");
                    for v in 0..=n - u {
                        let (bu, bv) = (u as f64 / n as f64, v as f64 / n as f64);
                        let ys = (1.0 - bu - bv) * a + bu * b + bv * c;
                        assert!((xs - ys).norm() >= d - 1e-12, "triangle {k}");
                    }
                }
            }
        }
        let (a, b, c) = (V::zeros(), V::x(), V::y());
        // Through the face: distance 0 where it crosses, s at the crossing.
        let (s, w, d) =
            closest_segment_triangle(&V::new(0.2, 0.2, 1.0), &V::new(0.2, 0.2, -3.0), &a, &b, &c);
        assert!(d < 1e-15 && (s - 0.25).abs() < 1e-15, "{s} {d}");
        assert!((w[1] - 0.2).abs() < 1e-15 && (w[2] - 0.2).abs() < 1e-15);
        // Across an edge, above it: the middle of the segment, the edge's middle.
        let (s, w, d) =
            closest_segment_triangle(&V::new(0.5, -1.0, 0.1), &V::new(0.5, 1.0, -0.1), &a, &b, &c);
        assert!((s - 0.5).abs() < 1e-15 && d < 1e-15, "{s} {d}");
        assert!((w[0] - 0.5).abs() < 1e-15 && (w[1] - 0.5).abs() < 1e-15);
        // Degenerate segment: the point's answer.
        let p = V::new(0.3, 0.3, 0.5);
        let (s, _, d) = closest_segment_triangle(&p, &p, &a, &b, &c);
        assert!(s == 0.0 && (d - 0.5).abs() < 1e-15);
    }

    #[test]
    fn frames_are_orthonormal_with_n_first() {
        for n in [V::z(), -V::z(), V::x(), V::new(1.0, -2.0, 0.5).normalize()] {
            let f = frame(&n);
            assert!((f * f.transpose() - nalgebra::Matrix3::identity()).amax() < 1e-14);
            assert!((f.row(0).transpose() - n).amax() < 1e-15);
            assert!(f.determinant() > 0.0);
        }
    }
}
