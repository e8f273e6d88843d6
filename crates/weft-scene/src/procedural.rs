//! Procedural geometry, so examples and tests need no input files.

use crate::geometry::{Curves, Mesh};

/// The plane a grid lies in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Plane {
    /// Horizontal: width along x, height along z, at constant y.
    Xz,
    /// Vertical: width along x, height along y, at constant z.
    Xy,
}

/// A rectangular grid of `res[0] × res[1]` vertices (each ≥ 2) spanning `size` [m], centred at
/// `center`. Cell diagonals alternate in a checkerboard, which makes the discrete bending
/// response closer to isotropic than one diagonal direction everywhere. Vertex (i, j) is
/// index `j · res[0] + i`; i runs along the width.
pub fn grid(size: [f64; 2], res: [usize; 2], plane: Plane, center: [f64; 3]) -> Mesh {
    let (nx, ny) = (res[0].max(2), res[1].max(2));
    let mut positions = Vec::with_capacity(nx * ny);
    for j in 0..ny {
        for i in 0..nx {
            let u = size[0] * (i as f64 / (nx - 1) as f64 - 0.5);
            let v = size[1] * (j as f64 / (ny - 1) as f64 - 0.5);
            positions.push(match plane {
                Plane::Xz => [center[0] + u, center[1], center[2] + v],
                Plane::Xy => [center[0] + u, center[1] + v, center[2]],
            });
        }
    }
    let id = |i: usize, j: usize| (j * nx + i) as u32;
    let mut triangles = Vec::with_capacity(2 * (nx - 1) * (ny - 1));
    for j in 0..ny - 1 {
        for i in 0..nx - 1 {
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            if (i + j) % 2 == 0 {
                triangles.extend([[a, b, c], [a, c, d]]);
            } else {
                triangles.extend([[a, b, d], [b, c, d]]);
            }
        }
    }
    Mesh {
        positions,
        triangles,
    }
}

/// A closed box of extents `size` [m] (x, y, z) centred at `center`: 8 corners, 12 triangles
/// wound counter-clockwise seen from outside (normals outward).
pub fn cuboid(center: [f64; 3], size: [f64; 3]) -> Mesh {
    let corner = |k: usize| {
        let s = |bit: usize, a: usize| if k >> bit & 1 == 1 { 0.5 } else { -0.5 } * size[a];
        [
            center[0] + s(0, 0),
            center[1] + s(1, 1),
            center[2] + s(2, 2),
        ]
    };
    // Corner k has x from bit 0, y from bit 1, z from bit 2; each face as a quad (a, b, c, d)
    // counter-clockwise from outside.
    let faces: [[u32; 4]; 6] = [
        [0, 4, 6, 2], // −x
        [1, 3, 7, 5], // +x
        [0, 1, 5, 4], // −y
        [2, 6, 7, 3], // +y
        [0, 2, 3, 1], // −z
        [4, 5, 7, 6], // +z
    ];
    Mesh {
        positions: (0..8).map(corner).collect(),
        triangles: faces
            .iter()
            .flat_map(|&[a, b, c, d]| [[a, b, c], [a, c, d]])
            .collect(),
    }
}

/// A UV sphere of `rings` latitude bands and `sectors` longitude bands (for display).
pub fn sphere(center: [f64; 3], radius: f64, rings: usize, sectors: usize) -> Mesh {
    let (rings, sectors) = (rings.max(2), sectors.max(3));
    let mut positions = vec![[center[0], center[1] + radius, center[2]]];
    for r in 1..rings {
        let th = std::f64::consts::PI * r as f64 / rings as f64;
        for s in 0..sectors {
            let ph = std::f64::consts::TAU * s as f64 / sectors as f64;
            positions.push([
                center[0] + radius * th.sin() * ph.cos(),
                center[1] + radius * th.cos(),
                center[2] + radius * th.sin() * ph.sin(),
            ]);
        }
    }
    positions.push([center[0], center[1] - radius, center[2]]);
    let bottom = (positions.len() - 1) as u32;
    let ring = |r: usize, s: usize| (1 + (r - 1) * sectors + s % sectors) as u32;
    let mut triangles = Vec::new();
    for s in 0..sectors {
        triangles.push([0, ring(1, s + 1), ring(1, s)]);
        triangles.push([bottom, ring(rings - 1, s), ring(rings - 1, s + 1)]);
    }
    for r in 1..rings - 1 {
        for s in 0..sectors {
            let (a, b, c, d) = (
                ring(r, s),
                ring(r, s + 1),
                ring(r + 1, s + 1),
                ring(r + 1, s),
            );
            triangles.extend([[a, b, c], [a, c, d]]);
        }
    }
    Mesh {
        positions,
        triangles,
    }
}

/// `count` straight strands of `segments` segments and length `length` [m], rooted on a
/// sphere and pointing along its normal. Roots follow a Fibonacci spiral over the cap within
/// `cap_degrees` of the +y pole (180 covers the sphere): even coverage, no randomness.
pub fn strands_on_sphere(
    center: [f64; 3],
    radius: f64,
    count: usize,
    segments: usize,
    length: f64,
    cap_degrees: f64,
) -> Curves {
    let segments = segments.max(1);
    let cap = cap_degrees.clamp(0.0, 180.0).to_radians();
    let ymin = cap.cos();
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let mut positions = Vec::with_capacity(count * (segments + 1));
    let mut offsets = vec![0u32];
    for k in 0..count {
        // Uniform in y over [ymin, 1] gives uniform area density on the cap.
        let y = 1.0 - (1.0 - ymin) * (k as f64 + 0.5) / count as f64;
        let r = (1.0 - y * y).max(0.0).sqrt();
        let ph = golden * k as f64;
        let n = [r * ph.cos(), y, r * ph.sin()];
        for s in 0..=segments {
            let d = radius + length * s as f64 / segments as f64;
            positions.push([
                center[0] + d * n[0],
                center[1] + d * n[1],
                center[2] + d * n[2],
            ]);
        }
        offsets.push(positions.len() as u32);
    }
    Curves { positions, offsets }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The box is closed and outward: every directed edge appears once and its reverse once,
    /// and the signed volume (divergence theorem, Σ a·(b×c)/6) is the box's, positive.
    #[test]
    fn cuboid_is_closed_outward_and_of_its_volume() {
        let m = cuboid([1.0, 2.0, 3.0], [0.5, 2.0, 4.0]);
        assert_eq!((m.positions.len(), m.triangles.len()), (8, 12));
        let mut edges = std::collections::BTreeSet::new();
        for t in &m.triangles {
            for k in 0..3 {
                assert!(edges.insert((t[k], t[(k + 1) % 3])), "edge repeated");
            }
        }
        assert!(edges.iter().all(|&(a, b)| edges.contains(&(b, a))));
        let volume: f64 = m
            .triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| m.positions[i as usize]);
                let bc = [
                    b[1] * c[2] - b[2] * c[1],
                    b[2] * c[0] - b[0] * c[2],
                    b[0] * c[1] - b[1] * c[0],
                ];
                (a[0] * bc[0] + a[1] * bc[1] + a[2] * bc[2]) / 6.0
            })
            .sum();
        assert!((volume - 4.0).abs() < 1e-12, "{volume}");
    }

    #[test]
    fn grid_counts_and_extent() {
        let m = grid([2.0, 1.0], [5, 3], Plane::Xy, [0.0, 1.0, 0.0]);
        assert_eq!((m.positions.len(), m.triangles.len()), (15, 16));
        assert_eq!(m.positions[0], [-1.0, 0.5, 0.0]);
        assert_eq!(m.positions[14], [1.0, 1.5, 0.0]);
        // Every triangle has positive area and the total is the rectangle's.
        let area: f64 = m
            .triangles
            .iter()
            .map(|t| {
                let p = |k: usize| m.positions[t[k] as usize];
                let (a, b, c) = (p(0), p(1), p(2));
                0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])).abs()
            })
            .sum();
        assert!((area - 2.0).abs() < 1e-14);
    }

    #[test]
    fn strands_start_on_the_sphere_within_the_cap() {
        let c = strands_on_sphere([0.0, 1.0, 0.0], 0.1, 50, 8, 0.2, 60.0);
        assert_eq!((c.len(), c.positions.len()), (50, 450));
        for k in 0..c.len() {
            let r = c.range(k);
            let root = c.positions[r.start];
            let tip = c.positions[r.end - 1];
            let d = |p: [f64; 3]| (p[0].powi(2) + (p[1] - 1.0).powi(2) + p[2].powi(2)).sqrt();
            assert!((d(root) - 0.1).abs() < 1e-14 && (d(tip) - 0.3).abs() < 1e-14);
            assert!((root[1] - 1.0) / 0.1 >= 60f64.to_radians().cos() - 1e-12);
        }
    }

    #[test]
    fn sphere_is_closed() {
        let m = sphere([0.0; 3], 1.0, 8, 12);
        // Closed surface: every edge is shared by exactly two triangles.
        let mut edges = std::collections::HashMap::new();
        for t in &m.triangles {
            for k in 0..3 {
                let (a, b) = (t[k].min(t[(k + 1) % 3]), t[k].max(t[(k + 1) % 3]));
                *edges.entry((a, b)).or_insert(0) += 1;
            }
        }
        assert!(edges.values().all(|&n| n == 2));
        assert_eq!(
            m.positions.len() as i64 - edges.len() as i64 + m.triangles.len() as i64,
            2,
            "Euler characteristic"
        );
    }
}
