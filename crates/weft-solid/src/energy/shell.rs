//! Discrete-shell bending by the squared mean curvature at vertices, with cotangent weights.
//!
//! Why not the classic hinge energy Σₑ k(θₑ − θ̄ₑ)², k ∝ |ē|²/Ā (Grinspun et al. 2003): it
//! weighs each edge's normal curvature on its own, so a uniform bend costs an amount that
//! depends on how the edges are laid out. Measured on the alternating right-triangle grid cloth
//! is usually made of (test below): a cylinder costs 2.0× the plate energy when its axis is a
//! grid axis and 3.0× at 45°, so a shell cantilever deflected 0.59× beam theory. The "midedge"
//! shape operator (face-normal averages on edges, no extra unknowns) was tried too: exact on
//! the grid axes but 1.65× at 45°.
//!
//! The Kirchhoff plate energy density D/2[(1 − ν)‖II‖² + ν(tr II)²] splits into two PSD parts,
//! `D/2 · (1 + ν)/2 · (tr II)²  +  D/2 · (1 − ν) · ‖dev II‖²`, `dev II = II − ½ tr II · I`,
//! and each gets the discretization that is consistent for it:
//!
//! * the trace, 2H, at vertices by the cotangent Laplacian (this module). Cloth bending is
//!   nearly isometric, and under isometry this is the whole energy (Bergou, Wardetzky, Harmon,
//!   Zorin & Grinspun 2006), so folds cost the same in every direction on any mesh;
//! * the deviatoric part per triangle by the midedge shape operator ([`super::MidedgeBend`]),
//!   whose error on the usual grids is a pure trace. Without it, twist and saddle modes cost
//!   nothing but membrane stretch: a ν = 0 strip then bends as if ν were 1 (measured: a
//!   cantilever 11 % too soft, and 250 Newton iterations to reach static equilibrium).
//!
//! The mean-curvature normal has a consistent discretization on any mesh, the cotangent
//! Laplacian (Meyer, Desbrun, Schröder & Barr 2003):
//!
//! `y_v = Σⱼ wᵥⱼ (xⱼ − xᵥ)`, `wᵥⱼ = ½(cot αᵥⱼ + cot βᵥⱼ)` (rest angles) `≈ Aᵥ · 2H n`,
//!
//! with Aᵥ the mixed Voronoi area. Its signed normal component `r = y·n` (n the area-weighted
//! vertex normal) is rotation invariant, so a curved rest shape keeps its rest value r̄, and
//!
//! `E_v = ½ k (r − r̄)²`, `k = (1 + ν)/2 · D/Aᵥ`  `≈ ∫ D/2 (1 + ν)/2 (2H − 2H̄)² dA` over the cell.
//!
//! Unlike Bergou's quadratic model (E = ½ xᵀ LᵀM⁻¹L x, flat rest only) this keeps rest
//! curvature; the price is a non-constant Hessian. Gradient (exact):
//! `∇r = Σⱼ wⱼ (∂xⱼ − ∂xᵥ)ᵀ n + (∂N/∂x)ᵀ ỹ`, `ỹ = (I − nnᵀ) y / |N|`, N the area-weighted normal
//! (for a face (a, b, c): ∂(ỹ·N)/∂x_a = ½ (x_b − x_c) × ỹ, cyclically). Hessian:
//! `k (∇r∇rᵀ + (r − r̄)∇²r)`; the first (Gauss–Newton) term is the PSD projection, for the
//! same reason as the hinge's (the curvature term is indefinite and vanishes at rest).
//!
//! Boundary vertices use the same formula over their partial ring: a first-order estimate in
//! the boundary row whose error vanishes under refinement (the shell cantilever converges).
//! Held vertices on a clamped edge measure their partial ring against the clamp's normal
//! instead of their own, so the edge holds the cloth's tangent plane ([`shell_bending_clamped`]).

use super::{Element, Local, MidedgeBend, ShellClamp};
use nalgebra::Vector3;
use num_dual::{Dual64, DualNum};

/// Most vertices in one stencil (a vertex and its ring): valence up to 31.
pub const MAX_STENCIL: usize = super::MAX_DOFS / 3;

/// Mean-curvature (trace) bending at one vertex of a triangle mesh.
#[derive(Clone, Debug)]
pub struct ShellBend {
    /// The vertex, then its ring neighbours (ascending).
    v: Box<[u32]>,
    /// Cotangent weight of the edge to each neighbour (`v[1..]`).
    w: Box<[f64]>,
    /// The ring's triangles as stencil indices, in the mesh's orientation.
    faces: Box<[[u8; 3]]>,
    /// (1 + ν)/2 · D / Aᵥ [J/m²].
    k: f64,
    /// Rest value of r = y·n [m²].
    rest: f64,
    /// Mixed Voronoi area Aᵥ [m²].
    area: f64,
    /// Bend angle dropoff, if any ([`super::Dropoff`]).
    dropoff: Option<super::Dropoff>,
}

/// Why a mesh cannot carry shell bending.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ShellError {
    /// A vertex has more neighbours than a stencil holds.
    #[error("vertex {vertex} has {valence} neighbours; shell bending supports at most {max}")]
    Valence {
        /// The vertex.
        vertex: u32,
        /// Its neighbour count.
        valence: usize,
        /// The limit.
        max: usize,
    },
    /// A triangle has no area, or a vertex's Voronoi area is not positive.
    #[error("triangle {triangle} has zero rest area")]
    Degenerate {
        /// The triangle.
        triangle: usize,
    },
}

pub(super) fn sub<S: DualNum<Primitive = f64> + Copy>(a: [S; 3], b: [S; 3]) -> [S; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
pub(super) fn cross<S: DualNum<Primitive = f64> + Copy>(a: [S; 3], b: [S; 3]) -> [S; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
pub(super) fn dot<S: DualNum<Primitive = f64> + Copy>(a: [S; 3], b: [S; 3]) -> S {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// A plate's bending stiffness D = scale · E t³/(12(1 − ν²)) [J] (Kirchhoff–Love: the
/// moment per unit width per unit curvature of a plate of Young's modulus `youngs`, Poisson's
/// ratio `poisson` and thickness `thickness`); `scale` is the Discrete Shell SEC's
/// `bend_scale`.
pub fn plate_bending_stiffness(youngs: f64, poisson: f64, thickness: f64, scale: f64) -> f64 {
    scale * youngs * thickness.powi(3) / (12.0 * (1.0 - poisson.powi(2)))
}

/// Shell bending of a mesh: both halves of the plate energy.
#[derive(Clone, Debug, Default)]
pub struct ShellBending {
    /// Trace part: one element per vertex that lies in a triangle and on no non-manifold edge,
    /// in vertex order (determinism).
    pub vertices: Vec<ShellBend>,
    /// Deviatoric part: one element per triangle, in triangle order.
    pub triangles: Vec<MidedgeBend>,
    /// Trace part of held vertices on clamped edges (in their place in `vertices`), in vertex
    /// order.
    pub clamped_vertices: Vec<ShellClamp>,
    /// Edges shared by more than two triangles. There a curvature has no meaning (three sheets
    /// meet): their vertices get no trace term and the edge is free for the triangles on it.
    pub non_manifold_edges: usize,
}

/// Bending elements for a mesh. `rest` are the rest positions (indexed like the triangles),
/// `d` the bending stiffness D = E t³/(12(1 − ν²)) [J], `nu` Poisson's ratio.
pub fn shell_bending(
    rest: &[Vector3<f64>],
    tris: &[[u32; 3]],
    d: f64,
    nu: f64,
) -> Result<ShellBending, ShellError> {
    shell_bending_clamped(rest, tris, d, nu, &[])
}

/// A clamped boundary edge: its two vertices are held, and so is the cloth's tangent plane
/// along it, represented by a ghost vertex (held, outside the plate, no energy of its own)
/// that mirrors the edge's triangle across the edge, so the ghost triangle continues the
/// cloth flat as it starts.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClampedEdge {
    /// The edge's vertices (either order).
    pub edge: [u32; 2],
    /// The ghost's index in the rest positions passed with it.
    pub ghost: u32,
}

/// [`shell_bending`] with clamped boundary edges (the rule of a rod's root clamp, `RodClamp`:
/// count the half cell between the clamp line and the first free vertices, against the
/// clamp's direction):
/// - the deviator: a triangle on a clamped edge takes the ghost as that edge's wing, with the
///   edge's weight doubled (see `MidedgeBend::new`);
/// - the trace: a held vertex on a clamped edge keeps its weights and (half) Voronoi area
///   from the real triangles, but measures its Laplacian's turn against the clamp's frame
///   (from its ghost triangles) instead of its own ring's normal (which turns with the cloth
///   and would make the held row a hinge): a [`ShellClamp`].
///
/// `rest` holds the mesh's vertices and then the ghosts; `tris` uses only the former.
pub fn shell_bending_clamped(
    rest: &[Vector3<f64>],
    tris: &[[u32; 3]],
    d: f64,
    nu: f64,
    clamps: &[ClampedEdge],
) -> Result<ShellBending, ShellError> {
    let key = |a: u32, b: u32| (a.min(b), a.max(b));
    let clamp_of: std::collections::HashMap<(u32, u32), u32> = clamps
        .iter()
        .map(|c| (key(c.edge[0], c.edge[1]), c.ghost))
        .collect();
    let n = rest.len();
    let (ring, edges) = rings_and_edges(rest, tris)?;
    let mut triangles = Vec::with_capacity(tris.len());
    // Ghost triangles, in each held vertex's ring: (b, a, ghost) for a clamped edge that
    // its triangle runs a → b, so the ghost's normal continues the triangle's.
    let mut ghost_faces: Vec<Vec<[u32; 3]>> = vec![Vec::new(); n];
    for (ti, t) in tris.iter().enumerate() {
        let mut clamped = [false; 3];
        let wings = [0, 1, 2].map(|k| {
            let (p, q) = (t[(k + 1) % 3], t[(k + 2) % 3]);
            match edges[&key(p, q)].as_slice() {
                [a, b] => {
                    let other = tris[if *a == ti { *b } else { *a }];
                    let w = other.into_iter().find(|&u| u != p && u != q)?;
                    Some((w, rest[w as usize]))
                }
                [_] => {
                    let &g = clamp_of.get(&key(p, q))?;
                    clamped[k] = true;
                    for v in [p, q] {
                        ghost_faces[v as usize].push([q, p, g]);
                    }
                    Some((g, *rest.get(g as usize)?))
                }
                _ => None,
            }
        });
        triangles.push(MidedgeBend::new(
            *t,
            t.map(|v| rest[v as usize]),
            wings,
            clamped,
            d,
            nu,
        ));
    }
    let mut skip = vec![false; n];
    let mut non_manifold_edges = 0;
    for (&(a, b), count) in &edges {
        if count.len() > 2 {
            non_manifold_edges += 1;
            skip[a as usize] = true;
            skip[b as usize] = true;
        }
    }
    let mut out = Vec::new();
    let mut clamped_vertices = Vec::new();
    for (v, faces) in ring.iter().enumerate() {
        if faces.is_empty() || skip[v] {
            continue;
        }
        let mut nb: Vec<u32> = faces
            .iter()
            .flat_map(|&ti| tris[ti])
            .chain(ghost_faces[v].iter().flatten().copied())
            .filter(|&u| u as usize != v)
            .collect();
        nb.sort_unstable();
        nb.dedup();
        if nb.len() + 1 > MAX_STENCIL {
            return Err(ShellError::Valence {
                vertex: v as u32,
                valence: nb.len(),
                max: MAX_STENCIL - 1,
            });
        }
        let mut stencil = vec![v as u32];
        stencil.extend(&nb);
        let local = |u: u32| stencil.iter().position(|&s| s == u).expect("in ring") as u8;
        let (w, area, local_faces) = cotan_weights(rest, tris, faces, v, &stencil);
        if area.is_nan() || area <= 0.0 {
            return Err(ShellError::Degenerate { triangle: faces[0] });
        }
        if !ghost_faces[v].is_empty() {
            // Held on a clamped edge: measured against the clamp (ghost weights stay zero).
            let ghosts = ghost_faces[v].iter().map(|f| f.map(local)).collect();
            let p: Vec<[f64; 3]> = stencil.iter().map(|&u| rest[u as usize].into()).collect();
            let k = 0.5 * (1.0 + nu) * d / area;
            match ShellClamp::new(stencil, w, ghosts, &p, k, area) {
                Some(c) => clamped_vertices.push(c),
                None => return Err(ShellError::Degenerate { triangle: faces[0] }),
            }
            continue;
        }
        let mut e = ShellBend {
            v: stencil.into(),
            w: w.into(),
            faces: local_faces.into(),
            k: 0.5 * (1.0 + nu) * d / area,
            rest: 0.0,
            area,
            dropoff: None,
        };
        let p: Vec<[f64; 3]> = e.v.iter().map(|&u| rest[u as usize].into()).collect();
        e.rest = e.r(&p, None);
        out.push(e);
    }
    Ok(ShellBending {
        vertices: out,
        triangles,
        clamped_vertices,
        non_manifold_edges,
    })
}

/// Each vertex's ring of triangles and each edge's triangles (key: the sorted pair),
/// refusing a degenerate triangle.
#[allow(clippy::type_complexity)]
fn rings_and_edges(
    rest: &[Vector3<f64>],
    tris: &[[u32; 3]],
) -> Result<
    (
        Vec<Vec<usize>>,
        std::collections::HashMap<(u32, u32), Vec<usize>>,
    ),
    ShellError,
> {
    let mut ring: Vec<Vec<usize>> = vec![Vec::new(); rest.len()];
    let mut edges: std::collections::HashMap<(u32, u32), Vec<usize>> = Default::default();
    for (ti, t) in tris.iter().enumerate() {
        let p = t.map(|v| rest[v as usize]);
        let twice_area = (p[1] - p[0]).cross(&(p[2] - p[0])).norm();
        if twice_area.is_nan() || twice_area <= 0.0 {
            return Err(ShellError::Degenerate { triangle: ti });
        }
        for k in 0..3 {
            ring[t[k] as usize].push(ti);
            let (a, b) = (t[k], t[(k + 1) % 3]);
            edges.entry((a.min(b), a.max(b))).or_default().push(ti);
        }
    }
    Ok((ring, edges))
}

/// Vertex `v`'s cotangent weights to its ring (`stencil[1..]`, in that order), its mixed
/// Voronoi area (Meyer et al. 2003), and its faces in stencil-local indices.
fn cotan_weights(
    rest: &[Vector3<f64>],
    tris: &[[u32; 3]],
    faces: &[usize],
    v: usize,
    stencil: &[u32],
) -> (Vec<f64>, f64, Vec<[u8; 3]>) {
    let local = |u: u32| stencil.iter().position(|&s| s == u).expect("in ring") as u8;
    let mut w = vec![0.0; stencil.len() - 1];
    let mut area = 0.0;
    let mut local_faces = Vec::with_capacity(faces.len());
    for &ti in faces {
        let t = tris[ti];
        local_faces.push(t.map(local));
        // Rotate so t = (v, b, c).
        let k = t
            .iter()
            .position(|&u| u as usize == v)
            .expect("vertex in its face");
        let (b, c) = (t[(k + 1) % 3], t[(k + 2) % 3]);
        let (pv, pb, pc) = (rest[v], rest[b as usize], rest[c as usize]);
        let cot = |o: Vector3<f64>, p: Vector3<f64>, q: Vector3<f64>| {
            let (a, b) = (p - o, q - o);
            a.dot(&b) / a.cross(&b).norm()
        };
        let (cot_v, cot_b, cot_c) = (cot(pv, pb, pc), cot(pb, pc, pv), cot(pc, pv, pb));
        // Edge v–b is opposite c; edge v–c is opposite b.
        w[local(b) as usize - 1] += 0.5 * cot_c;
        w[local(c) as usize - 1] += 0.5 * cot_b;
        // Mixed Voronoi area (Meyer et al. 2003): the Voronoi part of a non-obtuse
        // triangle, else half (obtuse at v) or a quarter of its area.
        let ta = 0.5 * (pb - pv).cross(&(pc - pv)).norm();
        area += if cot_v >= 0.0 && cot_b >= 0.0 && cot_c >= 0.0 {
            0.125 * ((pb - pv).norm_squared() * cot_c + (pc - pv).norm_squared() * cot_b)
        } else if cot_v < 0.0 {
            0.5 * ta
        } else {
            0.25 * ta
        };
    }
    (w, area, local_faces)
}

impl ShellBend {
    /// Sets the bend angle dropoff d ∈ [0, 1] at reference curvature κ₀ (d = 0: none).
    pub fn set_dropoff(&mut self, d: f64, kappa0: f64) {
        // A cylinder of curvature κ has r − r̄ = κ Aᵥ: E = ½ κ² · k Aᵥ².
        self.dropoff = super::Dropoff::new(d, kappa0, self.k * self.area * self.area);
    }

    /// r = y·n at stencil positions `p`; with `grad`, also ∇r (3 entries per stencil vertex).
    fn r<S: DualNum<Primitive = f64> + Copy>(&self, p: &[[S; 3]], grad: Option<&mut [S]>) -> S {
        let zero = p[0][0] * 0.0;
        let mut y = [zero; 3];
        let mut wsum = 0.0;
        for (j, &wj) in self.w.iter().enumerate() {
            let e = sub(p[j + 1], p[0]);
            for c in 0..3 {
                y[c] += e[c] * wj;
            }
            wsum += wj;
        }
        let mut big_n = [zero; 3];
        for f in self.faces.iter() {
            let [a, b, c] = f.map(|i| p[i as usize]);
            let fn_ = cross(sub(b, a), sub(c, a));
            for k in 0..3 {
                big_n[k] += fn_[k] * 0.5;
            }
        }
        let len = dot(big_n, big_n).sqrt();
        let n = big_n.map(|c| c / len);
        let r = dot(y, n);
        if let Some(g) = grad {
            let yt = [0, 1, 2].map(|c| (y[c] - r * n[c]) / len);
            for c in 0..3 {
                g[c] = n[c] * (-wsum);
            }
            for (j, &wj) in self.w.iter().enumerate() {
                for c in 0..3 {
                    g[3 * (j + 1) + c] = n[c] * wj;
                }
            }
            for f in self.faces.iter() {
                let [ia, ib, ic] = f.map(|i| i as usize);
                for (i, q, s) in [(ia, ib, ic), (ib, ic, ia), (ic, ia, ib)] {
                    let t = cross(sub(p[q], p[s]), yt);
                    for c in 0..3 {
                        g[3 * i + c] += t[c] * 0.5;
                    }
                }
            }
        }
        r
    }

    /// (1 + ν)/2 · D/Aᵥ [J/m²].
    pub fn stiffness(&self) -> f64 {
        self.k
    }

    /// Adds `offset` to every vertex index (to place a mesh's elements in a larger system).
    pub fn offset_vertices(&mut self, offset: u32) {
        self.map_vertices(|v| v + offset);
    }

    /// Replaces every vertex index v by `f(v)` (to place a mesh and its clamps' ghosts in a
    /// larger system).
    pub fn map_vertices(&mut self, f: impl Fn(u32) -> u32) {
        self.v.iter_mut().for_each(|v| *v = f(*v));
    }

    fn positions(&self, x: &[Vector3<f64>], p: &mut [[f64; 3]; MAX_STENCIL]) {
        for (a, &i) in self.v.iter().enumerate() {
            p[a] = x[i as usize].into();
        }
    }
}

impl Element for ShellBend {
    fn vertices(&self) -> &[u32] {
        &self.v
    }
    fn energy(&self, x: &[Vector3<f64>]) -> f64 {
        let mut p = [[0.0; 3]; MAX_STENCIL];
        self.positions(x, &mut p);
        let d = self.r(&p[..self.v.len()], None) - self.rest;
        let e = 0.5 * self.k * d * d;
        self.dropoff.map_or(e, |dr| dr.energy(e))
    }
    #[allow(clippy::needless_range_loop)] // stencil index arithmetic
    fn eval(&self, x: &[Vector3<f64>], project: bool, out: &mut Local) {
        let m = self.v.len();
        let dofs = 3 * m;
        let mut p = [[0.0; 3]; MAX_STENCIL];
        self.positions(x, &mut p);
        let mut g = [0.0; super::MAX_DOFS];
        let d = self.r(&p[..m], Some(&mut g[..dofs])) - self.rest;
        out.dofs = dofs;
        out.energy = 0.5 * self.k * d * d;
        for i in 0..dofs {
            out.grad[i] = self.k * d * g[i];
        }
        for c in 0..dofs {
            for r in 0..dofs {
                out.hess[c][r] = self.k * g[r] * g[c];
            }
        }
        if !project && d != 0.0 {
            // k d ∇²r, column by column: the derivative of ∇r along each DOF (dual numbers).
            let mut pd = [[Dual64::from_re(0.0); 3]; MAX_STENCIL];
            let mut gd = [Dual64::from_re(0.0); super::MAX_DOFS];
            for c in 0..dofs {
                for a in 0..m {
                    pd[a] = p[a].map(Dual64::from_re);
                }
                pd[c / 3][c % 3].eps = 1.0;
                self.r(&pd[..m], Some(&mut gd[..dofs]));
                for r in 0..dofs {
                    out.hess[c][r] += self.k * d * gd[r].eps;
                }
            }
            out.symmetrize();
        }
        if let Some(dr) = self.dropoff {
            dr.apply(out);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::energy::fd::check;

    /// A grid of `n`×`n` vertices with spacing `a`, each cell split along alternating
    /// diagonals (or, with `jitter`, interior vertices displaced pseudo-randomly in the plane).
    fn grid(n: usize, a: f64, jitter: f64) -> (Vec<Vector3<f64>>, Vec<[u32; 3]>) {
        let mut x = Vec::new();
        let mut seed = 12345u64;
        for j in 0..n {
            for i in 0..n {
                seed = seed
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let r1 = ((seed >> 33) as f64 / (1u64 << 31) as f64) - 0.5;
                seed = seed
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let r2 = ((seed >> 33) as f64 / (1u64 << 31) as f64) - 0.5;
                x.push(Vector3::new(
                    i as f64 * a + jitter * a * r1,
                    j as f64 * a + jitter * a * r2,
                    0.0,
                ));
            }
        }
        let id = |i: usize, j: usize| (j * n + i) as u32;
        let mut t = Vec::new();
        for j in 0..n - 1 {
            for i in 0..n - 1 {
                let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
                if (i + j) % 2 == 0 {
                    t.push([a, b, c]);
                    t.push([a, c, d]);
                } else {
                    t.push([a, b, d]);
                    t.push([b, c, d]);
                }
            }
        }
        (x, t)
    }

    fn bent(x: &[Vector3<f64>], kxx: f64, kyy: f64, kxy: f64) -> Vec<Vector3<f64>> {
        x.iter()
            .map(|p| {
                let z = 0.5 * (kxx * p.x * p.x + 2.0 * kxy * p.x * p.y + kyy * p.y * p.y);
                Vector3::new(p.x, p.y, z)
            })
            .collect()
    }

    #[test]
    fn finite_differences_interior_and_boundary_vertices() {
        let (x, t) = grid(4, 0.3, 0.25);
        let els = shell_bending(&x, &t, 0.7, 0.3).unwrap().vertices;
        let mut y = bent(&x, 1.1, -0.4, 0.7);
        y[5].z += 0.05;
        y[10].x -= 0.04;
        // An interior vertex of valence 8 and 4, and a corner and an edge vertex.
        for v in [5usize, 6, 0, 1] {
            check(&els[v], &y, 1e-7, 1e-5);
        }
    }

    #[test]
    fn dropoff_finite_differences_trace_midedge_and_clamped() {
        let (x, t) = grid(4, 0.3, 0.25);
        let mut els = shell_bending(&x, &t, 0.7, 0.3).unwrap();
        let mut y = bent(&x, 1.1, -0.4, 0.7);
        y[5].z += 0.05;
        y[10].x -= 0.04;
        for d in [0.5, 1.0] {
            // κ₀ = 3/m: the bent patch's curvatures (~1/m) are in the curve's nonlinear part.
            for v in [5usize, 6, 0, 1] {
                els.vertices[v].set_dropoff(d, 3.0);
                check(&els.vertices[v], &y, 1e-7, 1e-5);
            }
            for e in els.triangles.iter_mut().take(6) {
                e.set_dropoff(d, 3.0);
                check(e, &y, 1e-7, 1e-5);
            }
        }
    }

    /// Issue 17's check of bend angle dropoff, per element: a strip (30 × 6 grid, spacing
    /// a = 3 mm) bent isometrically into a cylinder of curvature κ about the y axis. The
    /// moment dE/dκ of its interior elements' bending (trace and deviatoric), by central
    /// differences, over the same without dropoff, is the stated ratio
    /// M(κ)/(Bκ) = (1 − d) + dκ²/(3κ₀²) within 1 % for κ₀ = 20/m and κ from 5 to 60/m (up
    /// to 10° a grid cell: the elements' own curvature measures read a bend's low by
    /// ~(κa)²/12, which the ratio sees only in its nonlinear part: at 17° a cell, 1.1 %).
    #[test]
    fn dropoff_follows_the_stated_moment_curvature_curve_in_a_uniform_bend() {
        let a = 0.003;
        let (nx, ny) = (30usize, 6usize);
        let mut x = Vec::new();
        for j in 0..ny {
            for i in 0..nx {
                x.push(Vector3::new(i as f64 * a, j as f64 * a, 0.0));
            }
        }
        let id = |i: usize, j: usize| (j * nx + i) as u32;
        let mut t = Vec::new();
        for j in 0..ny - 1 {
            for i in 0..nx - 1 {
                let (p, q, r, s) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
                if (i + j) % 2 == 0 {
                    t.extend([[p, q, r], [p, r, s]]);
                } else {
                    t.extend([[p, q, s], [q, r, s]]);
                }
            }
        }
        let interior = |v: usize| {
            let (i, j) = (v % nx, v / nx);
            i > 0 && i < nx - 1 && j > 0 && j < ny - 1
        };
        let kappa0 = 20.0;
        let energy = |d: f64, kappa: f64| -> f64 {
            let y: Vec<_> = x
                .iter()
                .map(|p| {
                    let r = 1.0 / kappa;
                    let phi = p.x * kappa;
                    Vector3::new(r * phi.sin(), p.y, r * (1.0 - phi.cos()))
                })
                .collect();
            let mut els = shell_bending(&x, &t, 1e-3, 0.3).unwrap();
            let mut e = 0.0;
            for el in &mut els.vertices {
                if interior(el.vertices()[0] as usize) {
                    el.set_dropoff(d, kappa0);
                    e += el.energy(&y);
                }
            }
            for el in &mut els.triangles {
                if el.vertices()[..3].iter().all(|&v| interior(v as usize)) {
                    el.set_dropoff(d, kappa0);
                    e += el.energy(&y);
                }
            }
            e
        };
        super::super::dropoff::assert_moment_curve(energy);
    }

    /// A 4 × 4 patch clamped along its first row (y = 0), ghosts appended: finite
    /// differences of the clamped trace and midedge terms with the ghosts moved too; the rest
    /// shape (curved) and a rigid motion of everything, ghosts included, cost nothing; turning
    /// the cloth about the clamp line costs, and more past 90° than at it (the half-angle
    /// tangent does not go slack).
    #[test]
    fn clamped_edges_finite_differences_rest_and_rigid_motion() {
        let (x, t) = grid(4, 0.3, 0.2);
        // Ghosts mirror each first-row edge's triangle across the edge.
        let with_ghosts = |pos: &[Vector3<f64>]| {
            let mut rest = pos.to_vec();
            let mut clamps = Vec::new();
            for i in 0..3u32 {
                let tri = t
                    .iter()
                    .find(|f| f.contains(&i) && f.contains(&(i + 1)))
                    .unwrap();
                let apex = *tri.iter().find(|&&v| v != i && v != i + 1).unwrap();
                let (a, b, c) = (pos[i as usize], pos[i as usize + 1], pos[apex as usize]);
                let d = b - a;
                let foot = a + d * ((c - a).dot(&d) / d.norm_squared());
                clamps.push(ClampedEdge {
                    edge: [i, i + 1],
                    ghost: rest.len() as u32,
                });
                rest.push(2.0 * foot - c);
            }
            (rest, clamps)
        };
        let (rest, clamps) = with_ghosts(&bent(&x, 0.8, 0.3, -0.2));
        let els = shell_bending_clamped(&rest, &t, 0.7, 0.3, &clamps).unwrap();
        assert_eq!(els.clamped_vertices.len(), 4);
        assert_eq!(els.vertices.len(), 16 - 4);
        let mut y = bent(&rest, 0.5, -0.9, 0.4);
        y[5].z += 0.05;
        y[17].y -= 0.03;
        for e in &els.clamped_vertices {
            check(e, &y, 1e-7, 1e-5);
        }
        for e in els.triangles.iter().take(6) {
            check(e, &y, 1e-7, 1e-5);
        }
        // With bend angle dropoff too.
        let mut dropped = els.clone();
        for e in &mut dropped.clamped_vertices {
            e.set_dropoff(0.7, 2.0);
            check(e, &y, 1e-7, 1e-5);
        }
        let r = nalgebra::Rotation3::from_euler_angles(0.3, -0.7, 1.1);
        let moved: Vec<_> = rest
            .iter()
            .map(|p| r * p + Vector3::new(1.0, 2.0, 3.0))
            .collect();
        let all: Vec<&dyn Element> = els
            .clamped_vertices
            .iter()
            .map(|e| e as &dyn Element)
            .chain(els.triangles.iter().map(|e| e as &dyn Element))
            .collect();
        for e in &all {
            assert!(e.energy(&rest).abs() < 1e-28, "{}", e.energy(&rest));
            assert!(e.energy(&moved) < 1e-26, "{}", e.energy(&moved));
        }
        // Turn the flat cloth (not the ghosts) about the clamp line (the x axis) by θ.
        let (flat_rest, clamps) = with_ghosts(&x);
        let flat = shell_bending_clamped(&flat_rest, &t, 0.7, 0.0, &clamps).unwrap();
        let turned = |th: f64| -> f64 {
            let r = nalgebra::Rotation3::from_axis_angle(&Vector3::x_axis(), th);
            let mut p = flat_rest.clone();
            for q in p.iter_mut().take(16) {
                *q = r * *q;
            }
            flat.clamped_vertices.iter().map(|e| e.energy(&p)).sum()
        };
        let pi = std::f64::consts::PI;
        let (e45, e90, e135) = (turned(0.25 * pi), turned(0.5 * pi), turned(0.75 * pi));
        assert!(0.0 < e45 && e45 < e90 && e90 < e135, "{e45} {e90} {e135}");
    }

    #[test]
    fn rest_shape_has_zero_energy_and_rigid_motion_costs_nothing() {
        let (x, t) = grid(5, 0.25, 0.2);
        let curved = bent(&x, 2.0, 0.5, -0.3);
        let els = shell_bending(&curved, &t, 1.0, 0.3).unwrap();
        let r = nalgebra::Rotation3::from_euler_angles(0.3, -0.7, 1.1);
        let moved: Vec<_> = curved
            .iter()
            .map(|p| r * p + Vector3::new(1.0, 2.0, 3.0))
            .collect();
        let all: Vec<&dyn Element> = els
            .vertices
            .iter()
            .map(|e| e as &dyn Element)
            .chain(els.triangles.iter().map(|e| e as &dyn Element))
            .collect();
        for e in &all {
            assert!(e.energy(&curved).abs() < 1e-30);
            assert!(e.energy(&moved) < 1e-26, "{}", e.energy(&moved));
        }
        // Flattening the rest curvature does cost energy, in both parts.
        assert!(els.vertices.iter().map(|e| e.energy(&x)).sum::<f64>() > 1e-3);
        assert!(els.triangles.iter().map(|e| e.energy(&x)).sum::<f64>() > 1e-4);
    }

    #[test]
    fn bad_meshes_are_reported() {
        let p = Vector3::new(1.0, 1.0, 0.0);
        assert_eq!(
            shell_bending(&[p, p, p], &[[0, 1, 2]], 1.0, 0.3).unwrap_err(),
            ShellError::Degenerate { triangle: 0 }
        );
        // A fan of 40 triangles around vertex 0.
        let mut x = vec![Vector3::zeros()];
        let mut t = Vec::new();
        for i in 0..40u32 {
            let a = i as f64 * std::f64::consts::TAU / 40.0;
            x.push(Vector3::new(a.cos(), a.sin(), 0.0));
            t.push([0, 1 + i, 1 + (i + 1) % 40]);
        }
        assert!(matches!(
            shell_bending(&x, &t, 1.0, 0.3).unwrap_err(),
            ShellError::Valence {
                vertex: 0,
                valence: 40,
                ..
            }
        ));
    }

    /// Energy per area over the interior of a flat mesh bent into z = ½ pᵀKp, against the
    /// plate's D/2[(1 − ν)‖K‖² + ν(tr K)²], for cylinders at several angles (isometric bending:
    /// what cloth does), a twist, a saddle and a dome. Tolerances: the right-triangle grid is
    /// exact up to round-off and the geometric nonlinearity of the small bend (κL ≈ 1e-3), so
    /// 1e-3; on the jittered mesh (vertices moved by up to ±15 % of the spacing) cylinders
    /// measure 1.7–3.3 % and the non-developable modes 1.9–6.0 % too stiff, asserted at 5 %
    /// and 10 %.
    /// For comparison (measured on the same meshes): classic hinges give 2.0× on the axes and
    /// 3.0× at 45°; the midedge operator alone 1.0× and 1.65×.
    #[test]
    fn bending_costs_the_plate_energy_in_every_direction_on_any_mesh() {
        let (d, nu, kappa) = (1.0, 0.3, 1e-3);
        for jitter in [0.0, 0.3] {
            let n = 24;
            let a = 1.0 / (n - 1) as f64;
            let (x, tris) = grid(n, a, jitter);
            let els = shell_bending(&x, &tris, d, nu).unwrap();
            let inside = |p: Vector3<f64>| {
                p.x > 3.0 * a && p.x < 1.0 - 3.0 * a && p.y > 3.0 * a && p.y < 1.0 - 3.0 * a
            };
            let mut cases: Vec<(String, [f64; 3], bool)> = [0.0f64, 20.0, 45.0, 90.0, 120.0, 135.0]
                .iter()
                .map(|alpha| {
                    let (c, s) = (alpha.to_radians().cos(), alpha.to_radians().sin());
                    (format!("cylinder at {alpha}°"), [c * c, s * s, c * s], true)
                })
                .collect();
            cases.push(("twist".into(), [0.0, 0.0, 1.0], false));
            cases.push(("saddle".into(), [1.0, -1.0, 0.0], false));
            cases.push(("dome".into(), [1.0, 0.6, 0.2], false));
            for (name, k, developable) in cases {
                let (kxx, kyy, kxy) = (kappa * k[0], kappa * k[1], kappa * k[2]);
                let y = bent(&x, kxx, kyy, kxy);
                let (mut ev, mut av) = (0.0, 0.0);
                for el in &els.vertices {
                    if inside(x[el.v[0] as usize]) {
                        ev += el.energy(&y);
                        av += 0.5 * (1.0 + nu) * d / el.k;
                    }
                }
                let (mut et, mut at) = (0.0, 0.0);
                for (t, el) in tris.iter().zip(&els.triangles) {
                    let p = t.map(|v| x[v as usize]);
                    if inside((p[0] + p[1] + p[2]) / 3.0) {
                        et += el.energy(&y);
                        at += 0.5 * (p[1] - p[0]).cross(&(p[2] - p[0])).norm();
                    }
                }
                let norm2 = kxx * kxx + kyy * kyy + 2.0 * kxy * kxy;
                let want = 0.5 * d * ((1.0 - nu) * norm2 + nu * (kxx + kyy).powi(2));
                let ratio = (ev / av + et / at) / want;
                eprintln!("jitter {jitter}, {name}: energy / plate = {ratio}");
                let tol = match (jitter > 0.0, developable) {
                    (false, _) => 1e-3,
                    (true, true) => 0.05,
                    (true, false) => 0.1,
                };
                assert!(
                    (ratio - 1.0).abs() < tol,
                    "jitter {jitter}, {name}: {ratio}"
                );
            }
        }
    }
}
