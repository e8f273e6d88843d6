//! The deviatoric half of shell bending: a per-triangle shape operator (the "midedge" operator
//! of Grinspun, Gingold, Reisman & Zorin 2006, as in Chen, Weischedel & Vouga's libshell).
//! See [`super::shell`] for why bending is split into a trace part (vertices) and this part.
//!
//! On triangle T the normal at the midpoint of edge k is the average of the two face normals,
//! tilted by θₖ/2 towards the edge's in-plane normal tₖ; the nonconforming linear interpolation
//! of the three midedge normals gives `II_T ≈ Σₖ cₖ θₖ tₖtₖᵀ`, `cₖ = |eₖ|/(2A)`. With angle
//! differences φₖ = θₖ − θ̄ₖ (rest angles of any size are kept exactly, as for hinges):
//!
//! `E_T = Ā · (1 − ν) D/2 · ‖dev ΔII‖²`, `ΔII = Σₖ cₖ φₖ tₖtₖᵀ`, `‖dev X‖² = ‖X‖² − ½(tr X)²`,
//!
//! i.e. `½ φᵀBφ` with the constant PSD matrix `Bₖₗ = Ā (1 − ν) D cₖcₗ[(tₖ·tₗ)² − ½]`. The
//! operator's error on the alternating right-triangle grid is a pure multiple of the identity
//! (a twist z = κxy gives II = κ[[−1, 1], [1, −1]]), so its deviatoric part is exact there.
//!
//! A boundary (or non-manifold) edge has no second face: its midedge normal is free and touches
//! this triangle only, so its angle is eliminated: it takes the value that minimizes the whole
//! plate energy of the triangle given the other angles (the free edge's natural condition,
//! zero moment, not a clamp), and B becomes Pᵀ B_dev P for that linear map P.
//!
//! Gradient Σₖ (Bφ)ₖ ∇θₖ; Hessian Σₖₗ Bₖₗ ∇θₖ∇θₗᵀ (PSD, the projection) + Σₖ (Bφ)ₖ ∇²θₖ.

use super::hinge::wrap_offset;
use super::{Element, Local, dihedral_angle, dihedral_angle_gradient, dihedral_gradient};
use nalgebra::{Matrix3, Vector3};
use num_dual::Dual64;

const NO_WING: u8 = u8::MAX;

/// The plate's energy ½ φᵀBφ in the edge angles φ of a rest triangle: (full, deviatoric),
/// `Bₖₗ = Ā D cₖcₗ[(1 − ν)(tₖ·tₗ)² + ν]` and `Ā (1 − ν) D cₖcₗ[(tₖ·tₗ)² − ½]`.
/// `scale[k]` multiplies cₖ: 2 on a clamped edge (see [`MidedgeBend::new`]).
fn plate_matrices(
    rest: [Vector3<f64>; 3],
    d: f64,
    nu: f64,
    scale: [f64; 3],
) -> (Matrix3<f64>, Matrix3<f64>) {
    let n = (rest[1] - rest[0]).cross(&(rest[2] - rest[0]));
    let area = 0.5 * n.norm();
    let mut t = [Vector3::zeros(); 3];
    let mut c = [0.0; 3];
    for k in 0..3 {
        let e = rest[(k + 2) % 3] - rest[(k + 1) % 3];
        t[k] = e.cross(&n).normalize();
        c[k] = scale[k] * e.norm() / (2.0 * area);
    }
    let full = Matrix3::from_fn(|k, l| {
        area * d * c[k] * c[l] * ((1.0 - nu) * t[k].dot(&t[l]).powi(2) + nu)
    });
    let dev = Matrix3::from_fn(|k, l| {
        area * (1.0 - nu) * d * c[k] * c[l] * (t[k].dot(&t[l]).powi(2) - 0.5)
    });
    (full, dev)
}

/// Deviatoric shape-operator bending on one triangle and the triangles across its edges.
#[derive(Clone, Debug)]
pub struct MidedgeBend {
    /// Stencil: the triangle's vertices, then the wing vertex across each interior edge.
    v: [u32; 6],
    /// Stencil size (3 + interior edges).
    len: u8,
    /// Stencil index of the wing across edge k (opposite vertex k), or none.
    wing: [u8; 3],
    /// Rest dihedral angle of edge k.
    rest: [f64; 3],
    /// The condensed stiffness matrix B [J] (rows and columns of free edges are zero).
    b: [[f64; 3]; 3],
    /// A square root of B (B = L Lᵀ, from its eigendecomposition; B is PSD), so the
    /// Gauss–Newton Hessian is (GL)(GL)ᵀ: symmetric by construction, half of it computed.
    l: [[f64; 3]; 3],
    /// Its energy at unit curvature in a cylinder, doubled: Ā (1 − ν) D/2 [J·m].
    unit: f64,
    /// Bend angle dropoff, if any ([`super::Dropoff`]).
    dropoff: Option<super::Dropoff>,
}

impl MidedgeBend {
    /// The element of triangle `tri` (rest positions `rest`, positive area), with `wings[k]`
    /// the vertex (index and rest position) across the edge opposite `tri[k]`, or `None` for a
    /// free edge. `d` is the bending stiffness D [J], `nu` Poisson's ratio.
    ///
    /// `clamped[k]`: edge k is clamped, its wing a fixed ghost in the clamp's plane. The fold
    /// there, θ between the triangle and the clamp, spans only the strip between the clamp
    /// line and the triangle's midline (the ghost is outside the plate and carries no
    /// energy), so it is a curvature θ/(h/2), not θ/h: cₖ is doubled, as the root clamp of a
    /// rod doubles the half-segment's bending (`RodClamp`).
    pub(crate) fn new(
        tri: [u32; 3],
        rest: [Vector3<f64>; 3],
        wings: [Option<(u32, Vector3<f64>)>; 3],
        clamped: [bool; 3],
        d: f64,
        nu: f64,
    ) -> Self {
        let scale = clamped.map(|c| if c { 2.0 } else { 1.0 });
        let (full, dev) = plate_matrices(rest, d, nu, scale);
        let mut v = [tri[0], tri[1], tri[2], 0, 0, 0];
        let mut len = 3u8;
        let mut wing = [NO_WING; 3];
        let mut rest_angle = [0.0; 3];
        for k in 0..3 {
            if let Some((w, xw)) = wings[k] {
                v[len as usize] = w;
                wing[k] = len;
                len += 1;
                let x = [rest[(k + 1) % 3], rest[(k + 2) % 3], rest[k], xw];
                let s: Vec<f64> = x.iter().flat_map(|p| [p.x, p.y, p.z]).collect();
                rest_angle[k] = dihedral_angle(&s);
            }
        }
        // Free edges take the angle that minimizes the whole plate energy given the others
        // (zero moment across a free edge): φ_F = −B_FF⁻¹ B_FI φ_I with the full plate matrix,
        // a linear map P: φ_I ↦ φ. Condensing with the deviatoric matrix alone would let the
        // free edge cancel the deviator (κ⊥ = κ∥) and halve a boundary row's stiffness.
        let free: Vec<usize> = (0..3).filter(|&k| wing[k] == NO_WING).collect();
        let mut p = Matrix3::<f64>::identity();
        if !free.is_empty() {
            let mut s_emb = Matrix3::<f64>::identity();
            let mut c = Matrix3::<f64>::zeros();
            for &i in &free {
                for j in 0..3 {
                    if free.contains(&j) {
                        s_emb[(i, j)] = full[(i, j)];
                    } else {
                        c[(i, j)] = full[(i, j)];
                    }
                }
            }
            let x = -s_emb.try_inverse().unwrap_or_else(Matrix3::zeros) * c;
            for &i in &free {
                p.set_row(i, &x.row(i));
            }
        }
        let bm = p.transpose() * dev * p;
        let mut b = [[0.0; 3]; 3];
        for k in 0..3 {
            for l in 0..3 {
                b[k][l] = 0.5 * (bm[(k, l)] + bm[(l, k)]);
            }
        }
        let eig = nalgebra::SymmetricEigen::new(Matrix3::from_fn(|k, l| b[k][l]));
        let root =
            eig.eigenvectors * Matrix3::from_diagonal(&eig.eigenvalues.map(|e| e.max(0.0).sqrt()));
        let l = std::array::from_fn(|k| std::array::from_fn(|m| root[(k, m)]));
        MidedgeBend {
            v,
            len,
            wing,
            rest: rest_angle,
            b,
            l,
            // A cylinder of curvature κ has ‖dev II‖² = κ²/2: E = ½ κ² · Ā (1 − ν) D/2.
            unit: 0.5 * (rest[1] - rest[0]).cross(&(rest[2] - rest[0])).norm() * (1.0 - nu) * d
                / 2.0,
            dropoff: None,
        }
    }

    /// Sets the bend angle dropoff d ∈ [0, 1] at reference curvature κ₀ (d = 0: none).
    pub fn set_dropoff(&mut self, d: f64, kappa0: f64) {
        self.dropoff = super::Dropoff::new(d, kappa0, self.unit);
    }

    /// The condensed stiffness matrix B (energy ½ φᵀBφ) [J].
    pub fn stiffness(&self) -> [[f64; 3]; 3] {
        self.b
    }

    /// Adds `offset` to every vertex index.
    pub fn offset_vertices(&mut self, offset: u32) {
        self.map_vertices(|v| v + offset);
    }

    /// Replaces every vertex index v by `f(v)` (to place a mesh and its clamps' ghosts in a
    /// larger system).
    pub fn map_vertices(&mut self, f: impl Fn(u32) -> u32) {
        let n = self.len as usize;
        self.v[..n].iter_mut().for_each(|v| *v = f(*v));
    }

    /// Stencil indices of edge k's hinge (edge, edge, own vertex, wing).
    fn hinge(&self, k: usize) -> Option<[usize; 4]> {
        (self.wing[k] != NO_WING).then(|| [(k + 1) % 3, (k + 2) % 3, k, self.wing[k] as usize])
    }

    fn gather12(&self, x: &[Vector3<f64>], h: [usize; 4]) -> [f64; 12] {
        gather4(x, h.map(|i| self.v[i]))
    }

    /// φₖ = θₖ − θ̄ₖ wrapped into (−π, π] (0 for free edges).
    fn angles(&self, x: &[Vector3<f64>]) -> [f64; 3] {
        let mut phi = [0.0; 3];
        for (k, p) in phi.iter_mut().enumerate() {
            if let Some(h) = self.hinge(k) {
                let d = dihedral_angle(&self.gather12(x, h)) - self.rest[k];
                *p = d - wrap_offset(d);
            }
        }
        phi
    }

    fn quad(&self, phi: &[f64; 3]) -> ([f64; 3], f64) {
        let mut f = [0.0; 3];
        for (k, fk) in f.iter_mut().enumerate() {
            *fk = (0..3).map(|l| self.b[k][l] * phi[l]).sum();
        }
        (f, 0.5 * (0..3).map(|k| phi[k] * f[k]).sum::<f64>())
    }
}

impl Element for MidedgeBend {
    fn vertices(&self) -> &[u32] {
        &self.v[..self.len as usize]
    }
    fn energy(&self, x: &[Vector3<f64>]) -> f64 {
        let e = self.quad(&self.angles(x)).1;
        self.dropoff.map_or(e, |dr| dr.energy(e))
    }
    #[allow(clippy::needless_range_loop)] // stencil index arithmetic
    fn eval(&self, x: &[Vector3<f64>], project: bool, out: &mut Local) {
        // φₖ and ∇θₖ (spread over the stencil's DOFs) from one pass over each hinge.
        let mut phi = [0.0; 3];
        let mut g = [[0.0; 18]; 3];
        let mut xs12 = [[0.0; 12]; 3];
        for k in 0..3 {
            if let Some(h) = self.hinge(k) {
                xs12[k] = self.gather12(x, h);
                let (theta, gk) = dihedral_angle_gradient(&xs12[k]);
                let d = theta - self.rest[k];
                phi[k] = d - wrap_offset(d);
                for (a, &i) in h.iter().enumerate() {
                    for r in 0..3 {
                        g[k][3 * i + r] = gk[3 * a + r];
                    }
                }
            }
        }
        let f = self.gauss_newton(&phi, &g, out);
        if !project {
            // Curvature part Σₖ (Bφ)ₖ ∇²θₖ, ∇²θₖ column by column by dual numbers.
            for k in 0..3 {
                let Some(h) = self.hinge(k) else { continue };
                if f[k] == 0.0 {
                    continue;
                }
                for (a, &ia) in h.iter().enumerate() {
                    for cc in 0..3 {
                        let mut xd = xs12[k].map(Dual64::from_re);
                        xd[3 * a + cc].eps = 1.0;
                        let gd = dihedral_gradient(&xd);
                        for (b, &ib) in h.iter().enumerate() {
                            for rr in 0..3 {
                                out.hess[3 * ia + cc][3 * ib + rr] += f[k] * gd[3 * b + rr].eps;
                            }
                        }
                    }
                }
            }
            out.symmetrize();
        }
        if let Some(dr) = self.dropoff {
            dr.apply(out);
        }
    }
}

impl MidedgeBend {
    /// Energy ½ φᵀBφ, its gradient Σₖ (Bφ)ₖ ∇θₖ and the Gauss–Newton Hessian
    /// Σₖₗ Bₖₗ ∇θₖ∇θₗᵀ from the angle differences `phi` and the gradients `g` of the edge
    /// angles (spread over the stencil's DOFs); returns Bφ.
    #[allow(clippy::needless_range_loop)] // stencil index arithmetic
    fn gauss_newton(&self, phi: &[f64; 3], g: &[[f64; 18]; 3], out: &mut Local) -> [f64; 3] {
        let dofs = 3 * self.len as usize;
        let (f, e) = self.quad(phi);
        out.dofs = dofs;
        out.energy = e;
        for i in 0..dofs {
            out.grad[i] = (0..3).map(|k| f[k] * g[k][i]).sum();
        }
        // Σₖₗ Bₖₗ ∇θₖ∇θₗᵀ = V Vᵀ with V = G L (G's columns the ∇θₖ), V stored by columns
        // (vt[m] is V's m-th column) so that each column of the Hessian is three contiguous
        // multiply-adds (vectorized), and exactly symmetric (products commute).
        let mut vt = [[0.0; 18]; 3];
        for (m, vm) in vt.iter_mut().enumerate() {
            for (i, vim) in vm.iter_mut().enumerate().take(dofs) {
                *vim = (0..3).map(|k| g[k][i] * self.l[k][m]).sum();
            }
        }
        let [v0, v1, v2] = &vt;
        for c in 0..dofs {
            let (a0, a1, a2) = (v0[c], v1[c], v2[c]);
            for (r, h) in out.hess[c][..dofs].iter_mut().enumerate() {
                *h = a0 * v0[r] + a1 * v1[r] + a2 * v2[r];
            }
        }
        f
    }
}

/// The positions of four vertices, stacked.
fn gather4(x: &[Vector3<f64>], v: [u32; 4]) -> [f64; 12] {
    let mut s = [0.0; 12];
    for (a, &i) in v.iter().enumerate() {
        let p = x[i as usize];
        s[3 * a..3 * a + 3].copy_from_slice(&[p.x, p.y, p.z]);
    }
    s
}

/// Where a triangle's hinge finds its angle in [`SharedHinges`]: the table's hinge
/// (`index`) seen in the element's vertex order (`orient`, see [`ORIENT`]).
#[derive(Clone, Copy, Debug)]
struct HingeRef {
    index: u32,
    orient: u8,
}

/// For each orientation of a hinge [e₀, e₁, w₀, w₁] (edge, then the wing on each side) as
/// an element lists it against the table's: which of the table's four vertices is the
/// element's j-th, and the sign of the angle. The angle is the same with edge and wings
/// both reversed (the other side's element, where the two triangles are oriented alike) and
/// changes sign with either alone (wings alone: the other side's, oriented unlike; the edge
/// alone does not arise from two triangles, each listing its own vertex before the wing).
const ORIENT: [([usize; 4], f64); 4] = [
    ([0, 1, 2, 3], 1.0),
    ([1, 0, 3, 2], 1.0),
    ([0, 1, 3, 2], -1.0),
    ([1, 0, 2, 3], -1.0),
];

/// The hinges (interior edges) of a set of [`MidedgeBend`] elements, each once, and their
/// angles and angle gradients at the positions last given to [`Self::update`]. A mesh's
/// interior edge belongs to the triangles on both its sides, so evaluating each element on
/// its own computes every angle twice; the assembly and the objective compute them here
/// once, then evaluate the elements from the table ([`Self::eval`], [`Self::energy`]): the
/// same function, rounded differently on one of the two sides.
pub struct SharedHinges {
    /// Per hinge: its vertices [e₀, e₁, w₀, w₁] in the order the first element listed them.
    hinges: Vec<[u32; 4]>,
    /// Per element, per edge k: its hinge (`index` u32::MAX on a free edge).
    refs: Vec<[HingeRef; 3]>,
    /// Per hinge: θ and ∂θ/∂x at the last update.
    theta: Vec<f64>,
    grad: Vec<[f64; 12]>,
}

impl SharedHinges {
    /// The table of `elements`' hinges.
    pub fn new(elements: &[MidedgeBend]) -> Self {
        let mut hinges: Vec<[u32; 4]> = Vec::new();
        let mut by_key: std::collections::HashMap<[u32; 4], u32> = Default::default();
        let none = HingeRef {
            index: u32::MAX,
            orient: 0,
        };
        let refs = elements
            .iter()
            .map(|el| {
                let mut r = [none; 3];
                for (k, rk) in r.iter_mut().enumerate() {
                    let Some(h) = el.hinge(k) else { continue };
                    let v = h.map(|i| el.v[i]);
                    let key = [
                        v[0].min(v[1]),
                        v[0].max(v[1]),
                        v[2].min(v[3]),
                        v[2].max(v[3]),
                    ];
                    let index = *by_key.entry(key).or_insert_with(|| {
                        hinges.push(v);
                        hinges.len() as u32 - 1
                    });
                    let t = hinges[index as usize];
                    let orient = ORIENT
                        .iter()
                        .position(|(p, _)| (0..4).all(|j| v[j] == t[p[j]]))
                        .expect("a hinge with the same edge and wings is one of four orders");
                    *rk = HingeRef {
                        index,
                        orient: orient as u8,
                    };
                }
                r
            })
            .collect();
        let n = hinges.len();
        SharedHinges {
            hinges,
            refs,
            theta: vec![0.0; n],
            grad: vec![[0.0; 12]; n],
        }
    }

    /// Number of distinct hinges.
    pub fn len(&self) -> usize {
        self.hinges.len()
    }

    /// Whether there is none.
    pub fn is_empty(&self) -> bool {
        self.hinges.is_empty()
    }

    /// Every hinge's angle at `x`, and its gradient where `with_grad`; over the thread pool
    /// where `parallel` (each hinge writes its own entries: the same bits either way).
    pub fn update(&mut self, x: &[Vector3<f64>], with_grad: bool, parallel: bool) {
        use rayon::prelude::*;
        let gather = |h: &[u32; 4]| gather4(x, *h);
        let hinges = &self.hinges;
        if with_grad {
            let one = |(i, (t, g)): (usize, (&mut f64, &mut [f64; 12]))| {
                (*t, *g) = dihedral_angle_gradient(&gather(&hinges[i]));
            };
            if parallel {
                (self.theta.par_iter_mut().zip(self.grad.par_iter_mut()))
                    .enumerate()
                    .for_each(one);
            } else {
                self.theta
                    .iter_mut()
                    .zip(self.grad.iter_mut())
                    .enumerate()
                    .for_each(one);
            }
        } else {
            let one = |(i, t): (usize, &mut f64)| *t = dihedral_angle(&gather(&hinges[i]));
            if parallel {
                self.theta.par_iter_mut().enumerate().for_each(one);
            } else {
                self.theta.iter_mut().enumerate().for_each(one);
            }
        }
    }

    /// φₖ = θₖ − θ̄ₖ of element `i` (`el`) from the table's angles.
    fn phi(&self, i: usize, el: &MidedgeBend) -> [f64; 3] {
        let mut phi = [0.0; 3];
        for (k, r) in self.refs[i].iter().enumerate() {
            if r.index != u32::MAX {
                let d = ORIENT[r.orient as usize].1 * self.theta[r.index as usize] - el.rest[k];
                phi[k] = d - wrap_offset(d);
            }
        }
        phi
    }

    /// [`Element::eval`] of element `i` (`el`) with the projected (Gauss–Newton) Hessian,
    /// from the angles and gradients of the last [`Self::update`] with gradients.
    pub fn eval(&self, i: usize, el: &MidedgeBend, out: &mut Local) {
        let phi = self.phi(i, el);
        let mut g = [[0.0; 18]; 3];
        for (k, r) in self.refs[i].iter().enumerate() {
            if r.index == u32::MAX {
                continue;
            }
            let (perm, sign) = ORIENT[r.orient as usize];
            let gt = &self.grad[r.index as usize];
            let h = el.hinge(k).expect("a shared hinge is an interior edge");
            for (j, &a) in h.iter().enumerate() {
                for c in 0..3 {
                    g[k][3 * a + c] = sign * gt[3 * perm[j] + c];
                }
            }
        }
        el.gauss_newton(&phi, &g, out);
        if let Some(dr) = el.dropoff {
            dr.apply(out);
        }
    }

    /// [`Element::energy`] of element `i` (`el`) from the angles of the last update.
    pub fn energy(&self, i: usize, el: &MidedgeBend) -> f64 {
        let e = el.quad(&self.phi(i, el)).1;
        el.dropoff.map_or(e, |dr| dr.energy(e))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::energy::fd::check;

    fn patch() -> Vec<Vector3<f64>> {
        vec![
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(1.0, 0.0, 0.0),
            Vector3::new(0.3, 0.9, 0.0),
            Vector3::new(0.8, 0.9, 0.0),  // across edge 1–2 (opposite 0)
            Vector3::new(-0.6, 0.5, 0.0), // across edge 2–0 (opposite 1)
            Vector3::new(0.5, -0.8, 0.0), // across edge 0–1 (opposite 2)
        ]
    }

    fn element(x: &[Vector3<f64>], free: Option<usize>) -> MidedgeBend {
        let wings = [0, 1, 2].map(|k| (Some(k) != free).then(|| (3 + k as u32, x[3 + k])));
        MidedgeBend::new([0, 1, 2], [x[0], x[1], x[2]], wings, [false; 3], 0.3, 0.3)
    }

    #[test]
    fn finite_differences_with_and_without_a_free_edge() {
        let x = patch();
        let mut y = x.clone();
        y[3].z += 0.2;
        y[4].z -= 0.1;
        y[5].z += 0.3;
        y[1].y += 0.05;
        check(&element(&x, None), &y, 1e-7, 1e-5);
        check(&element(&x, Some(1)), &y, 1e-7, 1e-5);
    }

    #[test]
    fn a_free_edge_takes_its_zero_moment_angle() {
        let x = patch();
        let (d, nu) = (0.3, 0.3);
        let (full, dev) = plate_matrices([x[0], x[1], x[2]], d, nu, [1.0; 3]);
        let cond = element(&x, Some(1)).stiffness();
        assert_eq!(cond[1], [0.0; 3]);
        assert_eq!([cond[0][1], cond[2][1]], [0.0; 2]);
        // Energy with φ₁ eliminated = deviatoric energy at φ₁ = −(B₁₀φ₀ + B₁₂φ₂)/B₁₁.
        let (p0, p2) = (0.3, -0.7);
        let p1 = -(full[(1, 0)] * p0 + full[(1, 2)] * p2) / full[(1, 1)];
        let phi = Vector3::new(p0, p1, p2);
        let want = 0.5 * phi.dot(&(dev * phi));
        let got = 0.5 * (cond[0][0] * p0 * p0 + 2.0 * cond[0][2] * p0 * p2 + cond[2][2] * p2 * p2);
        assert!((got - want).abs() < 1e-12 * want.abs(), "{got} vs {want}");
        // Rest angles of any size are kept: a folded rest shape has zero energy.
        let mut r = x.clone();
        r[3].z += 0.7;
        r[5].z -= 0.4;
        let e = MidedgeBend::new(
            [0, 1, 2],
            [r[0], r[1], r[2]],
            [0, 1, 2].map(|k| Some((3 + k as u32, r[3 + k]))),
            [false; 3],
            1.0,
            0.3,
        );
        assert!(e.energy(&r).abs() < 1e-30);
        assert!(e.energy(&x) > 1e-3);
    }

    /// The hinge table gives every element the energy, gradient and Gauss–Newton Hessian its
    /// own evaluation gives (to rounding: one side's angle is computed in the other side's
    /// vertex order), serially and over the pool, on a bent, jittered grid with dropoff and
    /// with four triangles listed in the opposite orientation (so some hinges are seen with
    /// their angle's sign flipped).
    #[test]
    fn shared_hinges_evaluate_as_the_elements_do() {
        let n = 7;
        let mut rest = Vec::new();
        for j in 0..n {
            for i in 0..n {
                let jitter = 0.02 * (((i * 7 + j * 3) % 5) as f64 - 2.0);
                rest.push(Vector3::new(0.1 * i as f64 + jitter, 0.1 * j as f64, 0.0));
            }
        }
        let mut tris = Vec::new();
        for j in 0..n - 1 {
            for i in 0..n - 1 {
                let v = (j * n + i) as u32;
                let n = n as u32;
                tris.push([v, v + 1, v + n]);
                tris.push([v + 1, v + n + 1, v + n]);
            }
        }
        tris[0].swap(1, 2);
        tris[9].swap(1, 2);
        tris[20].swap(0, 2);
        tris[41].swap(0, 1);
        let mut els = crate::energy::shell_bending(&rest, &tris, 0.7, 0.3)
            .unwrap()
            .triangles;
        els[5].set_dropoff(0.5, 2.0);
        let x: Vec<_> = rest
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let z = 0.3 * (3.0 * p.x).sin() * (2.0 * p.y).cos() + 0.01 * ((i * 7) % 5) as f64;
                Vector3::new(p.x, p.y + 0.05 * p.x * p.x, z)
            })
            .collect();
        let mut shared = SharedHinges::new(&els);
        let mut seen = [0usize; 4];
        for r in shared.refs.iter().flatten().filter(|r| r.index != u32::MAX) {
            seen[r.orient as usize] += 1;
        }
        // The second side lists the wings swapped (each side's own vertex is the other's
        // wing): the edge reversed too where the two triangles are oriented alike.
        assert!(seen[..3].iter().all(|&k| k > 0), "orders seen: {seen:?}");
        // Each interior edge once: a grid of 7 × 7 vertices has 42 + 42 + 36 edges, 24 of
        // them on its boundary.
        assert_eq!(shared.len(), 42 + 42 + 36 - 24);
        let (mut own, mut from) = (Box::<Local>::default(), Box::<Local>::default());
        for parallel in [false, true] {
            shared.update(&x, true, parallel);
            for (i, el) in els.iter().enumerate() {
                el.eval(&x, true, &mut own);
                shared.eval(i, el, &mut from);
                let dofs = own.dofs;
                assert_eq!(from.dofs, dofs);
                let close = |a: f64, b: f64, scale: f64| (a - b).abs() <= 1e-12 * scale.max(1e-30);
                assert!(
                    close(own.energy, from.energy, own.energy),
                    "element {i} energy"
                );
                let gs = own.grad[..dofs].iter().fold(0.0f64, |m, g| m.max(g.abs()));
                let hs = (0..dofs)
                    .flat_map(|c| (0..dofs).map(move |r| (c, r)))
                    .fold(0.0f64, |m, (c, r)| m.max(own.hess[c][r].abs()));
                for a in 0..dofs {
                    assert!(close(own.grad[a], from.grad[a], gs), "element {i} grad {a}");
                    for b in 0..dofs {
                        assert!(
                            close(own.hess[a][b], from.hess[a][b], hs),
                            "element {i} hessian {a} {b}"
                        );
                    }
                }
            }
            shared.update(&x, false, parallel);
            for (i, el) in els.iter().enumerate() {
                let (a, b) = (el.energy(&x), shared.energy(i, el));
                assert!(
                    (a - b).abs() <= 1e-12 * a.abs().max(1e-30),
                    "element {i}: {a} vs {b}"
                );
            }
        }
    }
}
