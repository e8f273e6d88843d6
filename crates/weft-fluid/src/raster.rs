//! Rasterization of hair and cloth onto the grid's faces: solid fraction φ_s (so α = 1 − φ_s),
//! drag coefficient K per unit volume, and solid velocity, per face and per axis.
//!
//! Each solid element is sampled by points no farther apart than half a cell (rod segments
//! along their length, triangles on a barycentric lattice); each sample carries its share of
//! the element's volume V, velocity v and drag coefficient per unit solid volume k (a 3×3
//! tensor from [`crate::drag`]: f = −V k Δv). A sample spreads to the faces of each axis with
//! trilinear weights w, and face f of axis a collects
//!
//! `φ_s = Σ w V / Δx³`, `K = Σ w V k_aa / Δx³`, `v = Σ w V k_aa v_a / Σ w V k_aa`
//!
//! (v weighted by drag where there is drag, by volume otherwise), so the total drag the grid
//! applies equals the total on the samples for a uniform flow: the coupling's momentum
//! balance. Only the tensor's diagonal along each face's axis reaches the grid (a scalar per
//! face, as the porous pressure system needs); the solid side keeps the full tensor.
//! φ_s is capped at `max_solid_fraction` so every face keeps some fluid. Faces already marked
//! as obstacle faces (α = 0, [`crate::obstacle`]) are left as they are.

use crate::grid::MacGrid;

/// One solid sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// Position [m].
    pub position: [f64; 3],
    /// Velocity [m/s].
    pub velocity: [f64; 3],
    /// Solid volume [m³].
    pub volume: f64,
    /// Drag per unit solid volume, the diagonal of k (f = −V k Δv) [kg/(m³·s)].
    pub drag: [f64; 3],
}

/// What rasterization did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RasterStats {
    /// Samples that fell outside the domain and were dropped (clipped).
    pub outside: usize,
    /// Faces whose solid fraction reached the cap.
    pub capped: usize,
    /// Samples rasterized.
    pub samples: usize,
}

/// The sample lattice along a segment of length `len`: the midpoints of n = ⌈2 len/dx⌉
/// equal parts (spacing at most dx/2), as interpolation weights of its two ends. Returns n
/// (each sample carries 1/n of the segment) and the weights.
pub fn segment_lattice(len: f64, dx: f64) -> (usize, impl Iterator<Item = [f64; 2]>) {
    let n = segment_samples(len, dx);
    let weights = (0..n).map(move |s| {
        let t = (s as f64 + 0.5) / n as f64;
        [1.0 - t, t]
    });
    (n, weights)
}

/// The sample lattice over a triangle whose longest edge is `longest`: the centroids of its
/// n² equal sub-triangles, n = ⌈2 longest/dx⌉ (spacing at most dx/2 along every edge), as
/// barycentric weights. Returns the sample count n² (each carries 1/n² of the triangle) and
/// the weights.
pub fn triangle_lattice(longest: f64, dx: f64) -> (usize, impl Iterator<Item = [f64; 3]>) {
    let n = lattice_side(longest, dx);
    let nf = n as f64;
    let weights = (0..n).flat_map(move |i| {
        (0..n - i).flat_map(move |j| {
            // The upward sub-triangle (i, j), and the downward one beside it when it exists.
            let up = Some([(i as f64 + 1.0 / 3.0) / nf, (j as f64 + 1.0 / 3.0) / nf]);
            let down =
                (i + j + 1 < n).then(|| [(i as f64 + 2.0 / 3.0) / nf, (j as f64 + 2.0 / 3.0) / nf]);
            up.into_iter().chain(down).map(|[s, t]| [1.0 - s - t, s, t])
        })
    });
    (n * n, weights)
}

/// Samples along a segment of length `len` at cell size `dx` (⌈2 len/dx⌉, at least 1;
/// saturating, so a length of 10¹⁰⁰ cells counts as usize::MAX rather than overflowing).
pub fn segment_samples(len: f64, dx: f64) -> usize {
    let n = (2.0 * len / dx).ceil();
    if n.is_nan() { 1 } else { (n as usize).max(1) }
}

/// Sub-triangles along each edge of a triangle whose longest edge is `longest`.
fn lattice_side(longest: f64, dx: f64) -> usize {
    segment_samples(longest, dx)
}

/// Samples over a triangle whose longest edge is `longest` (n², saturating), without making
/// them: what a caller checks against its memory budget first.
pub fn triangle_samples(longest: f64, dx: f64) -> usize {
    let n = lattice_side(longest, dx);
    n.saturating_mul(n)
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2) + (b[2] - a[2]).powi(2)).sqrt()
}

/// Samples along a rod segment between `ends` (each a position and a velocity) of
/// cross-section `area` [m²], with drag tensor diagonal `drag` ([`segment_lattice`]).
pub fn sample_segment(
    ends: [([f64; 3], [f64; 3]); 2],
    area: f64,
    drag: [f64; 3],
    dx: f64,
    out: &mut Vec<Sample>,
) {
    let [(a, va), (b, vb)] = ends;
    let len = dist(a, b);
    let (n, lattice) = segment_lattice(len, dx);
    for [wa, wb] in lattice {
        out.push(Sample {
            position: [0, 1, 2].map(|i| wa * a[i] + wb * b[i]),
            velocity: [0, 1, 2].map(|i| wa * va[i] + wb * vb[i]),
            volume: area * len / n as f64,
            drag,
        });
    }
}

/// Samples over a triangle (vertices `p`, velocities `v`) of thickness `thickness` [m]
/// ([`triangle_lattice`]).
pub fn sample_triangle(
    p: [[f64; 3]; 3],
    v: [[f64; 3]; 3],
    thickness: f64,
    drag: [f64; 3],
    dx: f64,
    out: &mut Vec<Sample>,
) {
    let longest = dist(p[0], p[1]).max(dist(p[1], p[2])).max(dist(p[2], p[0]));
    let e1 = [0, 1, 2].map(|i| p[1][i] - p[0][i]);
    let e2 = [0, 1, 2].map(|i| p[2][i] - p[0][i]);
    let cr = [
        e1[1] * e2[2] - e1[2] * e2[1],
        e1[2] * e2[0] - e1[0] * e2[2],
        e1[0] * e2[1] - e1[1] * e2[0],
    ];
    let area = 0.5 * (cr[0] * cr[0] + cr[1] * cr[1] + cr[2] * cr[2]).sqrt();
    let (count, lattice) = triangle_lattice(longest, dx);
    for w in lattice {
        out.push(Sample {
            position: [0, 1, 2].map(|c| w[0] * p[0][c] + w[1] * p[1][c] + w[2] * p[2][c]),
            velocity: [0, 1, 2].map(|c| w[0] * v[0][c] + w[1] * v[1][c] + w[2] * v[2][c]),
            volume: area * thickness / count as f64,
            drag,
        });
    }
}

/// Clears the grid's solid fields (all but obstacle faces, α = 0) and rasterizes `samples`
/// into them, with the weights of [`MacGrid::face_stencil`].
pub fn rasterize(grid: &mut MacGrid, samples: &[Sample], max_solid_fraction: f64) -> RasterStats {
    let dom = grid.domain.clone();
    let mut stats = RasterStats::default();
    // Accumulators per axis and face: Σ wV, Σ wVk, Σ wVk·v, Σ wV·v.
    let zeros = || [0, 1, 2].map(|a| vec![0.0; dom.face_count(a)]);
    let (mut vol, mut kk, mut mk, mut mv) = (zeros(), zeros(), zeros(), zeros());
    for s in samples {
        if !dom.contains(s.position) {
            stats.outside += 1;
            continue;
        }
        stats.samples += 1;
        for a in 0..3 {
            for (f, w) in grid.face_stencil(a, s.position) {
                if w == 0.0 {
                    continue;
                }
                let wv = w * s.volume;
                vol[a][f] += wv;
                kk[a][f] += wv * s.drag[a];
                mk[a][f] += wv * s.drag[a] * s.velocity[a];
                mv[a][f] += wv * s.velocity[a];
            }
        }
    }
    // Periodic axes: the stencil only addresses faces 0..n−1; face n is face 0's copy.
    for a in 0..3 {
        if dom.boundaries.is_periodic(a) {
            for (lo, hi) in dom.boundary_face_pairs(a) {
                for acc in [&mut vol, &mut kk, &mut mk, &mut mv] {
                    acc[a][hi] = acc[a][lo];
                }
            }
        }
    }
    let cell = dom.dx.powi(3);
    for a in 0..3 {
        for f in 0..dom.face_count(a) {
            if grid.alpha[a][f] == 0.0 {
                // An obstacle face (see [`crate::obstacle`]): the obstacle takes what the
                // solids put there.
                continue;
            }
            let mut phi = vol[a][f] / cell;
            if phi > max_solid_fraction {
                phi = max_solid_fraction;
                stats.capped += 1;
            }
            grid.alpha[a][f] = 1.0 - phi;
            grid.drag[a][f] = kk[a][f] / cell;
            // Drag-weighted where there is drag (momentum exchange), else volume-weighted
            // (the displacement flux (1 − α) v).
            grid.solid_vel[a][f] = if kk[a][f] > 0.0 {
                mk[a][f] / kk[a][f]
            } else if vol[a][f] > 0.0 {
                mv[a][f] / vol[a][f]
            } else {
                0.0
            };
        }
    }
    stats
}

/// Adds an impulse `impulse` [N·s] at `position` to the fluid, spread over the faces with
/// the weights of [`MacGrid::face_stencil`]: face f gains w·J/(ρ α_f Δx³), so the fluid's
/// momentum Σ ρ α u Δx³ changes by exactly J (the reaction of an explicit force on a solid,
/// such as lift). Returns false, changing nothing, when `position` is outside the domain.
pub fn add_impulse(
    grid: &mut MacGrid,
    position: [f64; 3],
    impulse: [f64; 3],
    density: f64,
) -> bool {
    if !grid.domain.contains(position) {
        return false;
    }
    let cell = grid.domain.dx.powi(3);
    for (a, j) in impulse.iter().enumerate() {
        for (f, w) in grid.face_stencil(a, position) {
            // Obstacle faces (α = 0) hold no fluid: their share goes to the obstacle.
            if w != 0.0 && grid.alpha[a][f] > 0.0 {
                grid.vel[a][f] += w * j / (density * grid.alpha[a][f] * cell);
            }
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::{Boundaries, Domain};

    fn grid() -> MacGrid {
        MacGrid::new(Domain::new([0.0; 3], [1.0; 3], 0.1, Boundaries::closed(), None).unwrap())
    }

    #[test]
    fn samples_carry_the_whole_volume() {
        let mut s = Vec::new();
        sample_segment(
            [([0.1; 3], [0.0; 3]), ([0.7, 0.2, 0.3], [1.0; 3])],
            1e-6,
            [1.0; 3],
            0.1,
            &mut s,
        );
        let len = (0.36f64 + 0.01 + 0.04).sqrt();
        let v: f64 = s.iter().map(|x| x.volume).sum();
        assert!((v - 1e-6 * len).abs() < 1e-18);
        let mut t = Vec::new();
        sample_triangle(
            [[0.0, 0.0, 0.5], [0.8, 0.0, 0.5], [0.0, 0.6, 0.5]],
            [[0.0; 3]; 3],
            1e-3,
            [1.0; 3],
            0.1,
            &mut t,
        );
        let v: f64 = t.iter().map(|x| x.volume).sum();
        assert!((v - 0.24 * 1e-3).abs() < 1e-15, "{v}");
        // The sample centroid is the triangle's centroid (the lattice is symmetric).
        let cx = t.iter().map(|x| x.position[0]).sum::<f64>() / t.len() as f64;
        assert!((cx - 0.8 / 3.0).abs() < 1e-12, "{cx}");
    }

    #[test]
    fn rasterized_volume_drag_and_momentum_are_conserved() {
        // Interior samples: trilinear weights sum to one, so each axis' faces hold the total
        // solid volume, the total drag, and the drag-weighted velocity.
        let mut g = grid();
        let mut s = Vec::new();
        sample_segment(
            [
                ([0.22, 0.31, 0.44], [0.1, 0.0, -0.2]),
                ([0.71, 0.52, 0.63], [0.3, 0.1, 0.0]),
            ],
            2e-5,
            [4.0, 5.0, 6.0],
            0.1,
            &mut s,
        );
        let st = rasterize(&mut g, &s, 0.9);
        assert_eq!((st.outside, st.capped), (0, 0));
        let vol: f64 = s.iter().map(|x| x.volume).sum();
        let cell = 1e-3;
        for a in 0..3 {
            let phi: f64 = g.alpha[a].iter().map(|x| 1.0 - x).sum::<f64>() * cell;
            assert!((phi - vol).abs() < 1e-12 * vol, "axis {a}: {phi} vs {vol}");
            let k: f64 = g.drag[a].iter().sum::<f64>() * cell;
            let kw = vol * [4.0, 5.0, 6.0][a];
            assert!((k - kw).abs() < 1e-12 * kw);
            let mom: f64 = (0..g.drag[a].len())
                .map(|f| g.drag[a][f] * g.solid_vel[a][f])
                .sum::<f64>()
                * cell;
            let want: f64 = s.iter().map(|x| x.volume * x.drag[a] * x.velocity[a]).sum();
            assert!(
                (mom - want).abs() < 1e-12 * want.abs().max(1e-30),
                "axis {a}"
            );
        }
    }

    #[test]
    fn outside_samples_are_clipped_and_counted_and_fractions_capped() {
        let mut g = grid();
        let mut s = vec![Sample {
            position: [1.5, 0.5, 0.5],
            velocity: [0.0; 3],
            volume: 1.0,
            drag: [1.0; 3],
        }];
        s.push(Sample {
            position: [0.5, 0.55, 0.55],
            velocity: [0.0; 3],
            volume: 1.0, // a whole cubic metre in a 1-litre cell
            drag: [1.0; 3],
        });
        let st = rasterize(&mut g, &s, 0.9);
        assert_eq!(st.outside, 1);
        assert!(st.capped > 0);
        assert!(
            g.alpha
                .iter()
                .flatten()
                .all(|&a| (0.1 - 1e-15..=1.0).contains(&a))
        );
    }

    #[test]
    fn an_impulse_changes_fluid_momentum_by_exactly_itself() {
        // Over a rasterized (partly solid) grid: Σ ρ α Δu Δx³ = J per axis, to rounding.
        let mut g = grid();
        let mut s = Vec::new();
        sample_segment(
            [([0.2, 0.3, 0.4], [0.0; 3]), ([0.7, 0.5, 0.6], [0.0; 3])],
            2e-4,
            [1.0; 3],
            0.1,
            &mut s,
        );
        rasterize(&mut g, &s, 0.9);
        let before = g.vel.clone();
        let j = [3e-3, -2e-3, 1e-3];
        assert!(add_impulse(&mut g, [0.43, 0.41, 0.52], j, 1000.0));
        assert!(!add_impulse(&mut g, [1.5, 0.5, 0.5], j, 1000.0));
        for a in 0..3 {
            let p: f64 = (0..g.vel[a].len())
                .map(|f| 1000.0 * g.alpha[a][f] * (g.vel[a][f] - before[a][f]) * 1e-3)
                .sum();
            assert!((p - j[a]).abs() < 1e-15, "axis {a}: {p} vs {}", j[a]);
        }
    }
}
