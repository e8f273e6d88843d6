//! Independent checks for Weft's tests: whether a segment meets a triangle, how many pairs
//! of triangles intersect, exact point–triangle and point–segment distances ([`distance`]),
//! whether two runs' positions are bit-identical (and a pool of a chosen size to run them on), and the graph-file text of vertex probes,
//! on plain coordinates. Written apart from the solver's
//! geometry (`weft-sim`'s detection, `weft-solid`'s contacts) so that a test's verdict of
//! "no intersection" owes nothing to the code it checks; the graph-level tests (`tests/`)
//! and the solver's own (`weft-sim/tests`) use the same one.
//!
//! Tolerances: a segment's ends must lie on opposite sides of (or on) the triangle's plane
//! by more than rounding (1e-12 of the largest coordinate, at least 1e-12), and the crossing
//! point inside the triangle to rounding. Both ends on the plane (coplanar pieces, as flat
//! cloth is): it meets when an end or its midpoint is inside by more than 1e-9 (an overlap
//! of flat pieces; touching edges are not an intersection).

use nalgebra::Vector3;

pub mod distance;

pub use distance::{distance_to_segment, distance_to_triangle, least_along};

type V = Vector3<f64>;

/// True when segment p→q meets triangle `t` (see the crate's tolerances). A degenerate
/// triangle (no normal) meets nothing.
pub fn segment_meets_triangle(p: [f64; 3], q: [f64; 3], t: [[f64; 3]; 3]) -> bool {
    let (p, q, t) = (V::from(p), V::from(q), t.map(V::from));
    let Some(n) = (t[1] - t[0]).cross(&(t[2] - t[0])).try_normalize(0.0) else {
        return false;
    };
    let scale = [p, q, t[0], t[1], t[2]]
        .iter()
        .fold(1.0f64, |m, x| m.max(x.amax()));
    let tol = 1e-12 * scale;
    let (dp, dq) = ((p - t[0]).dot(&n), (q - t[0]).dot(&n));
    let inside = |x: V, margin: f64| {
        (0..3).all(|k| {
            let e = t[(k + 1) % 3] - t[k];
            e.cross(&(x - t[k])).dot(&n) / e.norm() >= margin
        })
    };
    if (dp > tol && dq > tol) || (dp < -tol && dq < -tol) {
        return false;
    }
    if dp.abs() <= tol && dq.abs() <= tol {
        return [p, q, 0.5 * (p + q)].iter().any(|&x| inside(x, 1e-9));
    }
    inside(p + dp / (dp - dq) * (q - p), -tol)
}

/// Pairs of triangles (`tris`, each its corners' coordinates) that intersect, an edge of
/// one meeting the other, skipping pairs that share a vertex (`ids`: each corner's vertex
/// identity, one entry per triangle). Every pair whose bounding boxes overlap is tested.
pub fn intersecting_pairs<I: PartialEq>(tris: &[[[f64; 3]; 3]], ids: &[[I; 3]]) -> usize {
    assert_eq!(tris.len(), ids.len(), "one identity triple per triangle");
    let bound = |t: &[[f64; 3]; 3], a: usize| {
        let v = [t[0][a], t[1][a], t[2][a]];
        (
            v.iter().copied().fold(f64::INFINITY, f64::min),
            v.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        )
    };
    let mut count = 0;
    for i in 0..tris.len() {
        for j in i + 1..tris.len() {
            if ids[i].iter().any(|v| ids[j].contains(v)) {
                continue;
            }
            let apart = (0..3).any(|a| {
                let ((li, hi), (lj, hj)) = (bound(&tris[i], a), bound(&tris[j], a));
                li > hj || lj > hi
            });
            if apart {
                continue;
            }
            let (ti, tj) = (tris[i], tris[j]);
            if (0..3).any(|k| segment_meets_triangle(ti[k], ti[(k + 1) % 3], tj))
                || (0..3).any(|k| segment_meets_triangle(tj[k], tj[(k + 1) % 3], ti))
            {
                count += 1;
            }
        }
    }
    count
}

/// Graph-file text for `scene.vertex` probes `v0` … `v{count-1}` of element `element` in the
/// scene `scene` ("node.port"): (their node declarations, their output declarations).
pub fn vertex_probes(scene: &str, element: &str, count: usize) -> (String, String) {
    let nodes: Vec<String> = (0..count)
        .map(|i| {
            format!(
                r#""v{i}": {{"type": "scene.vertex", "inputs": {{"scene": "{scene}"}}, "params": {{"element": "{element}", "index": {i}}}}}"#
            )
        })
        .collect();
    let outputs: Vec<String> = (0..count)
        .map(|i| format!(r#""v{i}": "v{i}.position""#))
        .collect();
    (nodes.join(",\n"), outputs.join(", "))
}

/// True when two runs' positions are the same to the bit (determinism across thread counts:
/// not close, identical).
pub fn bit_identical(a: &[Vector3<f64>], b: &[Vector3<f64>]) -> bool {
    a.len() == b.len()
        && a.iter().zip(b).all(|(p, q)| {
            p.iter()
                .zip(q.iter())
                .all(|(x, y)| x.to_bits() == y.to_bits())
        })
}

/// Runs `f` on a fresh rayon pool of `threads` threads: a determinism test compares what
/// the same work gives at 1 and at 2 (or more) threads.
pub fn on_threads<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("a thread pool")
        .install(f)
}

#[cfg(test)]
mod tests {
    use super::*;

    const T: [[f64; 3]; 3] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];

    #[test]
    fn a_segment_through_the_triangle_meets_it_and_one_beside_it_does_not() {
        assert!(segment_meets_triangle([0.2, 0.2, -1.0], [0.2, 0.2, 1.0], T));
        assert!(!segment_meets_triangle(
            [0.8, 0.8, -1.0],
            [0.8, 0.8, 1.0],
            T
        ));
        // Ending 1e-6 above the plane: apart by far more than rounding.
        assert!(!segment_meets_triangle(
            [0.2, 0.2, 1e-6],
            [0.2, 0.2, 1.0],
            T
        ));
    }

    #[test]
    fn coplanar_pieces_meet_when_they_overlap_not_when_they_touch() {
        assert!(segment_meets_triangle([0.1, 0.1, 0.0], [0.3, 0.1, 0.0], T));
        // Along the edge y = 0: touching, not overlapping.
        assert!(!segment_meets_triangle([0.2, 0.0, 0.0], [0.6, 0.0, 0.0], T));
    }

    #[test]
    fn crossing_triangles_are_one_pair_and_neighbours_none() {
        let crossing = [[0.2, 0.2, -1.0], [0.2, 0.2, 1.0], [0.3, 0.9, 0.0]];
        let apart = [[5.0, 5.0, 5.0], [6.0, 5.0, 5.0], [5.0, 6.0, 5.0]];
        assert_eq!(
            intersecting_pairs(&[T, crossing, apart], &[[0, 1, 2], [3, 4, 5], [6, 7, 8]]),
            1
        );
        // Sharing vertex 0 with T, the crossing triangle is not counted.
        assert_eq!(
            intersecting_pairs(&[T, crossing], &[[0, 1, 2], [0, 4, 5]]),
            0
        );
    }
}
