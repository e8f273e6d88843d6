//! Rod energies on polylines: stretch per segment, bending per interior vertex.

use super::{Element, Local, gather};
use nalgebra::{Matrix3, SMatrix, SVector, Vector3};
use num_dual::{Dual64, DualNum, HyperDual64};

/// A round fibre's stiffnesses from its material: what [`RodStretch`] and [`RodBend`] take.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RodSection {
    /// Axial stiffness stretch_scale · E·πr² [N].
    pub axial: f64,
    /// Bending stiffness bend_scale · EI [N m²], EI = E·πr⁴/4 (a solid circle's second
    /// moment of area) unless given.
    pub bending: f64,
}

impl RodSection {
    /// From Young's modulus, the radius, the Rod SEC's multipliers and its `bend_stiffness`
    /// (an EI that replaces E·πr⁴/4 when positive).
    pub fn round(
        youngs: f64,
        radius: f64,
        stretch_scale: f64,
        bend_stiffness: f64,
        bend_scale: f64,
    ) -> Self {
        let area = std::f64::consts::PI * radius * radius;
        let ei = if bend_stiffness > 0.0 {
            bend_stiffness
        } else {
            youngs * area * radius * radius / 4.0
        };
        RodSection {
            axial: stretch_scale * youngs * area,
            bending: bend_scale * ei,
        }
    }
}

/// Stretch of one segment: E = ½ k L̄ (‖e‖/L̄ − 1)², k = E·A [N], L̄ the rest length.
#[derive(Clone, Debug)]
pub struct RodStretch {
    /// Segment endpoints.
    pub v: [u32; 2],
    /// Rest length [m].
    pub rest_length: f64,
    /// Axial stiffness E·A [N].
    pub k: f64,
}

impl Element for RodStretch {
    fn vertices(&self) -> &[u32] {
        &self.v
    }
    fn eval_first(&self, x: &[Vector3<f64>], out: &mut Local) {
        // Exact: no dearer than the projected one.
        self.eval(x, false, out);
    }
    fn eval_contact(&self, x: &[Vector3<f64>], _budget: f64, out: &mut Local) {
        // Exact in a contact step's Newton model as well: on projected Hessians a strand
        // resting on a collider converges linearly (hair_on_head's sliding steps crawl near
        // the tolerance), and the exact ones take fewer Newton iterations on hair_on_head
        // and hair_pile. Membranes keep their exact Hessians there only down to a bound on
        // their negative curvature (`Membrane::eval_contact`): fully exact ones make
        // cloth_drape's ADMM models indefinite, retrying substeps and running several times
        // slower. `bench/ensemble.py` on those examples measures it; figures in
        // docs/history/issue-71-comments.md.
        self.eval(x, false, out);
    }
    fn energy(&self, x: &[Vector3<f64>]) -> f64 {
        let l = (x[self.v[1] as usize] - x[self.v[0] as usize]).norm();
        let s = l / self.rest_length - 1.0;
        0.5 * self.k * self.rest_length * s * s
    }
    fn eval(&self, x: &[Vector3<f64>], project: bool, out: &mut Local) {
        let e = x[self.v[1] as usize] - x[self.v[0] as usize];
        let l = e.norm();
        let lr = self.rest_length;
        let s = l / lr - 1.0;
        let u = e / l;
        // dE/de = k s u; d²E/de² = (k/L̄) u uᵀ + (k s / l)(I − u uᵀ).
        let g = self.k * s * u;
        let uu = u * u.transpose();
        let mut lat = self.k * s / l;
        if project && lat < 0.0 {
            // Compressed: the transverse term is negative; dropping it is the PSD projection
            // (the two parts act on orthogonal subspaces).
            lat = 0.0;
        }
        let he: Matrix3<f64> = self.k / lr * uu + lat * (Matrix3::identity() - uu);
        let mut grad = SVector::<f64, 6>::zeros();
        grad.fixed_rows_mut::<3>(0).copy_from(&-g);
        grad.fixed_rows_mut::<3>(3).copy_from(&g);
        let mut h = SMatrix::<f64, 6, 6>::zeros();
        h.fixed_view_mut::<3, 3>(0, 0).copy_from(&he);
        h.fixed_view_mut::<3, 3>(3, 3).copy_from(&he);
        h.fixed_view_mut::<3, 3>(0, 3).copy_from(&-he);
        h.fixed_view_mut::<3, 3>(3, 0).copy_from(&-he);
        out.set::<6>(0.5 * self.k * lr * s * s, &grad, &h);
    }
}

/// Bending at an interior vertex: E = EI/(2 l) (|κb| − |κb̄|)², with the discrete curvature
/// binormal κb = 2 e₀×e₁ / (|e₀||e₁| + e₀·e₁) (|κb| = 2 tan(φ/2), φ the turning angle) and l
/// the Voronoi length (|ē₀| + |ē₁|)/2. For small φ, |κb|/l is the curvature, so the sum is
/// ½ EI ∫ κ² ds. The rest curvature is kept in magnitude: rods without material frames have
/// no twist, so the plane of a rest curl is free (a known limit until frames are added).
#[derive(Clone, Debug)]
pub struct RodBend {
    /// Previous, middle and next vertex.
    pub v: [u32; 3],
    /// EI / (2 l) [N·m].
    pub k: f64,
    /// |κb̄| at rest.
    pub rest: f64,
    /// Bend angle dropoff, if any ([`RodBend::set_dropoff`]).
    pub dropoff: Option<super::Dropoff>,
}

/// |κb|² = 4|e₀ × e₁|² / (|e₀||e₁| + e₀·e₁)² of two edge vectors.
fn kb_squared_of<S: DualNum<Primitive = f64> + Clone>(e0: &[S], e1: &[S]) -> S {
    let c = [
        e0[1].clone() * e1[2].clone() - e0[2].clone() * e1[1].clone(),
        e0[2].clone() * e1[0].clone() - e0[0].clone() * e1[2].clone(),
        e0[0].clone() * e1[1].clone() - e0[1].clone() * e1[0].clone(),
    ];
    let c2 = c.iter().map(|a| a.clone() * a.clone()).sum::<S>();
    let n0 = e0.iter().map(|a| a.clone() * a.clone()).sum::<S>().sqrt();
    let n1 = e1.iter().map(|a| a.clone() * a.clone()).sum::<S>().sqrt();
    let dot = (0..3).map(|i| e0[i].clone() * e1[i].clone()).sum::<S>();
    let den = n0 * n1 + dot;
    c2 * 4.0 / (den.clone() * den)
}

impl RodBend {
    /// Sets the bend angle dropoff d ∈ [0, 1] at reference curvature κ₀ (d = 0: none), for a
    /// bend whose Voronoi length is `length`: its curvature is |κb|/l, so E = ½ κ² · 2k l².
    pub fn set_dropoff(&mut self, d: f64, kappa0: f64, length: f64) {
        self.dropoff = super::Dropoff::new(d, kappa0, 2.0 * self.k * length * length);
    }

    fn is_straight(&self, x: &[Vector3<f64>]) -> bool {
        let e0 = x[self.v[1] as usize] - x[self.v[0] as usize];
        let e1 = x[self.v[2] as usize] - x[self.v[1] as usize];
        e0.cross(&e1).norm_squared() <= 1e-24 * e0.norm_squared() * e1.norm_squared()
    }
}

impl Element for RodBend {
    fn vertices(&self) -> &[u32] {
        &self.v
    }
    fn eval_first(&self, x: &[Vector3<f64>], out: &mut Local) {
        // Exact: no dearer than the projected one.
        self.eval(x, false, out);
    }
    fn eval_contact(&self, x: &[Vector3<f64>], _budget: f64, out: &mut Local) {
        // Exact in contact steps too: see `RodStretch`.
        self.eval(x, false, out);
    }
    fn energy(&self, x: &[Vector3<f64>]) -> f64 {
        let e0 = x[self.v[1] as usize] - x[self.v[0] as usize];
        let e1 = x[self.v[2] as usize] - x[self.v[1] as usize];
        let e = kb_value(self, e0.as_slice(), e1.as_slice(), self.is_straight(x));
        self.dropoff.map_or(e, |d| d.energy(e))
    }
    fn eval(&self, x: &[Vector3<f64>], project: bool, out: &mut Local) {
        // Exact gradient in closed form, and the exact Hessian as its derivative by one
        // forward dual pass per edge coordinate ([`bend_derivatives`]): fewer passes than
        // hyper-dual passes of the energy or one second-order vector-dual pass, so a cheaper
        // assembly. Projected to PSD for the solve. (A Gauss–Newton surrogate 2c JᵀJ is
        // cheaper still but needs many more Newton iterations on drooping hair, where
        // κb·∇²κb is large; `weft bench solid`'s strands measure both, figures in
        // docs/history/issue-71-comments.md.)
        // The energy depends on the edges e₀ = x₁ − x₀, e₁ = x₂ − x₁ alone, so it is
        // differentiated over those 6 numbers and mapped back by B (x ↦ (e₀, e₁)):
        // ∇ₓE = Bᵀ∇ₑE, ∇²ₓE = Bᵀ∇²ₑE B. The projection is the 9×9 Hessian's (below):
        // Bᵀ(∇²ₑE)₊B is PSD too but a different (not the nearest) surrogate, with which the
        // contact solve lets strands of hair_on_head reach inside the distance kept.
        let straight = self.is_straight(x);
        let (p0, p1, p2) = (
            x[self.v[0] as usize],
            x[self.v[1] as usize],
            x[self.v[2] as usize],
        );
        let mut edges = SVector::<f64, 6>::zeros();
        edges.fixed_rows_mut::<3>(0).copy_from(&(p1 - p0));
        edges.fixed_rows_mut::<3>(3).copy_from(&(p2 - p1));
        let (e, ge, he) = bend_derivatives(self, edges, straight);
        // B = [[−I, I, 0], [0, −I, I]] per coordinate: vertex a's rows of Bᵀ.
        const B: [[f64; 2]; 3] = [[-1.0, 0.0], [1.0, -1.0], [0.0, 1.0]];
        let mut g = SVector::<f64, 9>::zeros();
        for a in 0..3 {
            for r in 0..3 {
                g[3 * a + r] = B[a][0] * ge[r] + B[a][1] * ge[3 + r];
            }
        }
        // ∇²ₓE = Bᵀ∇²ₑE B has the translations as null space. Written Bᵀ = V C, with V
        // (9×6) an orthonormal basis of the translation-free motions, it is V (C ∇²ₑE Cᵀ) Vᵀ,
        // and its nearest PSD matrix is V (C ∇²ₑE Cᵀ)₊ Vᵀ: the 9×9 projection done on a 6×6
        // matrix (about a third of the eigendecomposition's cost; the same result to
        // rounding). Per coordinate, V's columns are (−1, 1, 0)/√2 and (−1, −1, 2)/√6 over
        // the three vertices, and C = Vᵀ Bᵀ = [[√2, −1/√2], [0, 3/√6]].
        let (map, inner) = if project {
            let (r2, r6) = (std::f64::consts::SQRT_2, 6f64.sqrt());
            let basis = [
                [-1.0 / r2, -1.0 / r6],
                [1.0 / r2, -1.0 / r6],
                [0.0, 2.0 / r6],
            ];
            let c = [[r2, -1.0 / r2], [0.0, 3.0 / r6]];
            let mut m: SMatrix<f64, 6, 6> = per_coordinate(&c, &he);
            crate::spd::project_psd(&mut m);
            (basis, m)
        } else {
            (B, he)
        };
        let h: SMatrix<f64, 9, 9> = per_coordinate(&map, &inner);
        out.set::<9>(e, &g, &h);
        if let Some(d) = self.dropoff {
            d.apply(out);
        }
    }
}

/// M Ĥ Mᵀ for M = `map` ⊗ I₃ (`map` is A × 2, N = 3A): a 6×6 matrix over two edges (or
/// two basis motions) mapped to N×N, each coordinate alike.
fn per_coordinate<const A: usize, const N: usize>(
    map: &[[f64; 2]; A],
    inner: &SMatrix<f64, 6, 6>,
) -> SMatrix<f64, N, N> {
    let mut out = SMatrix::<f64, N, N>::zeros();
    for a in 0..A {
        for b in 0..A {
            for r in 0..3 {
                for c in 0..3 {
                    let mut v = 0.0;
                    for p in 0..2 {
                        for q in 0..2 {
                            v += map[a][p] * map[b][q] * inner[(3 * p + r, 3 * q + c)];
                        }
                    }
                    out[(3 * a + r, 3 * b + c)] = v;
                }
            }
        }
    }
    out
}

/// [`RodBend`]'s energy as a function of its two edges.
fn kb_value<S: DualNum<Primitive = f64> + Clone>(
    bend: &RodBend,
    e0: &[S],
    e1: &[S],
    straight: bool,
) -> S {
    let k2 = kb_squared_of(e0, e1);
    if straight || bend.rest == 0.0 {
        // (|κb| − r)² without its |κb| term, which is not differentiable at κb = 0: the
        // subgradient there is zero, and the value is the same.
        (k2 + bend.rest * bend.rest) * bend.k
    } else {
        let d = k2.sqrt() - bend.rest;
        d.clone() * d * bend.k
    }
}

/// [`RodBend`]'s energy and its gradient over the two edges (e₀, e₁), in closed form:
/// with c = e₀ × e₁ and d = |e₀||e₁| + e₀·e₁, |κb|² = 4|c|²/d² and
/// ∇|κb|² = 4 (∇|c|²/d² − 2|c|²∇d/d³), ∇_{e₀}|c|² = 2 e₁ × c, ∇_{e₁}|c|² = 2 c × e₀,
/// ∇_{e₀}d = (|e₁|/|e₀|) e₀ + e₁, ∇_{e₁}d = (|e₀|/|e₁|) e₁ + e₀. The energy is k(|κb|² + r²)
/// where straight or r = 0 (see [`kb_value`]), else k(|κb| − r)², whose gradient is
/// k (1 − r/|κb|) ∇|κb|².
fn bend_gradient<S: DualNum<Primitive = f64> + Copy>(
    bend: &RodBend,
    e: &[S; 6],
    straight: bool,
) -> (S, [S; 6]) {
    let (a, b) = ([e[0], e[1], e[2]], [e[3], e[4], e[5]]);
    let cross = |u: [S; 3], v: [S; 3]| {
        [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ]
    };
    let dot = |u: [S; 3], v: [S; 3]| u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
    let c = cross(a, b);
    let c2 = dot(c, c);
    let (na, nb) = (dot(a, a).sqrt(), dot(b, b).sqrt());
    let d = na * nb + dot(a, b);
    let k2 = c2 * 4.0 / (d * d);
    let (ga, gb) = (cross(b, c), cross(c, a));
    let (ra, rb) = (nb / na, na / nb);
    let (p, q) = (S::from(8.0) / (d * d), c2 * 8.0 / (d * d * d));
    let mut g = [S::zero(); 6];
    for i in 0..3 {
        // ∇|κb|²: 4 (2 (e₁ × c) / d² − 2|c|² ∇d / d³), and likewise for e₁.
        g[i] = p * ga[i] - q * (ra * a[i] + b[i]);
        g[3 + i] = p * gb[i] - q * (rb * b[i] + a[i]);
    }
    let r = bend.rest;
    if straight || r == 0.0 {
        ((k2 + r * r) * bend.k, g.map(|x| x * bend.k))
    } else {
        let kb = k2.sqrt();
        let f = (S::one() - S::from(r) / kb) * bend.k;
        let dk = kb - r;
        (dk * dk * bend.k, g.map(|x| x * f))
    }
}

/// [`RodBend`]'s energy, gradient and exact Hessian over its two edges: the closed-form
/// gradient ([`bend_gradient`]), differentiated by one forward dual pass per edge coordinate
/// (6 passes, against 21 hyper-dual passes of the energy, which made rod bending a large
/// share of a hair run; `weft bench solid`'s strands measure it, figures in
/// docs/history/issue-71-comments.md).
fn bend_derivatives(
    bend: &RodBend,
    edges: SVector<f64, 6>,
    straight: bool,
) -> (f64, SVector<f64, 6>, SMatrix<f64, 6, 6>) {
    let xs: [f64; 6] = edges.into();
    let (e, g) = bend_gradient(bend, &xs, straight);
    let mut h = SMatrix::<f64, 6, 6>::zeros();
    for j in 0..6 {
        let mut xd = xs.map(Dual64::from_re);
        xd[j].eps = 1.0;
        let (_, gd) = bend_gradient(bend, &xd, straight);
        for i in 0..6 {
            h[(i, j)] = gd[i].eps;
        }
    }
    // Exactly symmetric (the two triangles differ by rounding).
    let h = 0.5 * (h + h.transpose());
    (e, SVector::from(g), h)
}

/// Energy, exact gradient and Hessian of `value` at `s` into `out` (Hessian projected to PSD
/// when `project`): one forward-over-forward hyper-dual pass per DOF pair i ≤ j.
fn local<const D: usize>(
    s: SVector<f64, D>,
    project: bool,
    out: &mut Local,
    value: impl Fn(&[HyperDual64]) -> HyperDual64,
) where
    SMatrix<f64, D, D>: crate::spd::ProjectPsd,
{
    let (e, g, h) = derivatives(s, project, value);
    out.set::<D>(e, &g, &h);
}

/// Energy, gradient and Hessian (projected to PSD when `project`) of `value` at `s`.
fn derivatives<const D: usize>(
    s: SVector<f64, D>,
    project: bool,
    value: impl Fn(&[HyperDual64]) -> HyperDual64,
) -> (f64, SVector<f64, D>, SMatrix<f64, D, D>)
where
    SMatrix<f64, D, D>: crate::spd::ProjectPsd,
{
    let xs: [f64; D] = s.into();
    let mut g = SVector::<f64, D>::zeros();
    let mut h = SMatrix::<f64, D, D>::zeros();
    let mut e = 0.0;
    for i in 0..D {
        for j in i..D {
            let mut xd = xs.map(HyperDual64::from_re);
            xd[i].eps1 = 1.0;
            xd[j].eps2 = 1.0;
            let v = value(&xd);
            h[(i, j)] = v.eps1eps2;
            h[(j, i)] = v.eps1eps2;
            if j == i {
                g[i] = v.eps1;
                e = v.re;
            }
        }
    }
    if project {
        crate::spd::project_psd(&mut h);
    }
    (e, g, h)
}

/// A clamped root: the strand leaves vertex `v[0]` along the direction `tangent`. Energy
/// E = k |κb(t, e)|², the bending of [`RodBend`] between a ghost edge along t that ends at
/// the root (it follows the attachment's transform) and the first free edge e = x₁ − x₀.
///
/// Why this stiffness: a rod clamped at s = 0 has bending energy ½EI∫₀ᴸκ² ds, and the root
/// vertex's Voronoi region is the half edge [0, l/2]. The turning angle θ between the clamp's
/// tangent (at s = 0) and the edge's (at s = l/2) spans l/2, so κ ≈ θ/(l/2) and the region's
/// energy is ½EI(2θ/l)²(l/2) = (EI/l)θ²: k = EI/l, i.e. [`RodBend`]'s EI/(2 l_v) with
/// l_v = l/2. Pinning the first two vertices instead clamps the tangent at the first edge's
/// midpoint, so the beam that bends is l/2 shorter than the strand: a first-order error
/// (−5 % in tip deflection at 40 segments). With this term the cantilever converges at
/// second order. The rest state is the clamp's own direction (|κb| = 0), so a curved strand
/// is held as it starts, with no cone of equally good directions around t.
#[derive(Clone, Debug)]
pub struct RodClamp {
    /// The root (normally pinned) and the next vertex.
    pub v: [u32; 2],
    /// The clamp's direction in world space (unit), moved with the attachment's rotation.
    pub tangent: Vector3<f64>,
    /// EI / l [N·m], l the first edge's rest length.
    pub k: f64,
}

impl RodClamp {
    fn value<S: DualNum<Primitive = f64> + Clone>(&self, x: &[S]) -> S {
        let t: Vec<S> = self.tangent.iter().map(|&c| S::from(c)).collect();
        let e: Vec<S> = (0..3).map(|i| x[3 + i].clone() - x[i].clone()).collect();
        kb_squared_of(&t, &e) * self.k
    }
}

impl Element for RodClamp {
    fn vertices(&self) -> &[u32] {
        &self.v
    }
    fn eval_first(&self, x: &[Vector3<f64>], out: &mut Local) {
        // Exact: no dearer than the projected one.
        self.eval(x, false, out);
    }
    fn eval_contact(&self, x: &[Vector3<f64>], _budget: f64, out: &mut Local) {
        // Exact in contact steps too: see `RodStretch`.
        self.eval(x, false, out);
    }
    fn energy(&self, x: &[Vector3<f64>]) -> f64 {
        let s: SVector<f64, 6> = gather(x, &self.v);
        self.value(s.as_slice())
    }
    fn eval(&self, x: &[Vector3<f64>], project: bool, out: &mut Local) {
        // As RodBend: exact derivatives by hyper-dual numbers (21 passes over 6 DOFs). |κb|²
        // is smooth everywhere but at e = −t (a strand folded back into its root).
        local::<6>(gather(x, &self.v), project, out, |xd| self.value(xd));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::energy::fd::check;

    fn pts(p: &[[f64; 3]]) -> Vec<Vector3<f64>> {
        p.iter().map(|a| Vector3::new(a[0], a[1], a[2])).collect()
    }

    #[test]
    fn stretch_finite_differences_stretched_and_compressed() {
        let s = RodStretch {
            v: [0, 1],
            rest_length: 0.5,
            k: 1e3,
        };
        check(&s, &pts(&[[0.0, 0.0, 0.0], [0.6, 0.1, -0.05]]), 1e-7, 1e-6);
        check(&s, &pts(&[[0.0, 0.0, 0.0], [0.3, 0.1, -0.05]]), 1e-7, 1e-6);
    }

    #[test]
    fn bend_finite_differences_with_and_without_rest_curvature() {
        let x = pts(&[[0.0, 0.0, 0.0], [0.1, 0.01, 0.0], [0.19, 0.05, 0.02]]);
        check(
            &RodBend {
                v: [0, 1, 2],
                k: 0.02,
                rest: 0.0,
                dropoff: None,
            },
            &x,
            1e-8,
            1e-5,
        );
        check(
            &RodBend {
                v: [0, 1, 2],
                k: 0.02,
                rest: 0.3,
                dropoff: None,
            },
            &x,
            1e-8,
            1e-5,
        );
    }

    /// The closed-form gradient differentiated by dual numbers gives the hyper-dual
    /// derivatives of the energy itself, to rounding: bent, nearly straight and sharply
    /// folded edges, with and without rest curvature, and the straight branch.
    #[test]
    fn bend_closed_form_gradient_matches_the_hyper_dual_derivatives() {
        let shapes = [
            [0.1, 0.01, 0.0, 0.09, 0.04, 0.02],
            [0.1, 0.0, 0.0, 0.1, 1e-5, -2e-6],
            [0.1, 0.02, -0.01, -0.07, 0.05, 0.03],
            [0.02, -0.3, 0.1, 0.5, 0.2, -0.1],
        ];
        for e in shapes {
            let edges = SVector::<f64, 6>::from(e);
            for rest in [0.0, 0.3, 1.5] {
                for straight in [false, true] {
                    let bend = RodBend {
                        v: [0, 1, 2],
                        k: 0.02,
                        rest,
                        dropoff: None,
                    };
                    let (e0, g0, h0) = derivatives::<6>(edges, false, |ed| {
                        kb_value(&bend, &ed[..3], &ed[3..], straight)
                    });
                    let (e1, g1, h1) = bend_derivatives(&bend, edges, straight);
                    assert!((e1 - e0).abs() <= 1e-13 * e0.abs().max(1e-300), "{e1} {e0}");
                    let (gs, hs) = (g0.amax().max(1e-300), h0.amax().max(1e-300));
                    assert!((g1 - g0).amax() <= 1e-11 * gs, "{e:?} {rest}: {g1} {g0}");
                    assert!((h1 - h0).amax() <= 1e-9 * hs, "{e:?} {rest}: {h1} {h0}");
                    assert_eq!(h1, h1.transpose());
                }
            }
        }
    }

    #[test]
    fn bend_dropoff_finite_differences_and_its_moment_curvature_curve() {
        let x = pts(&[[0.0, 0.0, 0.0], [0.1, 0.01, 0.0], [0.19, 0.05, 0.02]]);
        for rest in [0.0, 0.3] {
            let mut b = RodBend {
                v: [0, 1, 2],
                k: 0.02,
                rest,
                dropoff: None,
            };
            b.set_dropoff(0.8, 5.0, 0.1);
            check(&b, &x, 1e-8, 1e-5);
        }
        // Three vertices on a circle of curvature κ, chords a = 2 mm (Voronoi length a): the
        // moment dE/dκ over the plain one is the stated (1 − d) + dκ²/(3κ₀²) to 1 % up to
        // κ = 3κ₀ (|κb|/a reads the circle's κ high by (κa)²/8, 0.2 % at 60/m: 1.1 % at 5 mm).
        let (a, kappa0) = (0.002, 20.0);
        let energy = |d: f64, kappa: f64| {
            let r = 1.0 / kappa;
            let half = (a / (2.0 * r)).asin();
            let p: Vec<_> = [-2.0 * half, 0.0, 2.0 * half]
                .iter()
                .map(|t| Vector3::new(r * t.sin(), r * (1.0 - t.cos()), 0.0))
                .collect();
            let mut b = RodBend {
                v: [0, 1, 2],
                k: 1e-4 / (2.0 * a),
                rest: 0.0,
                dropoff: None,
            };
            b.set_dropoff(d, kappa0, a);
            b.energy(&p)
        };
        super::super::dropoff::assert_moment_curve(energy);
    }

    /// The projection done on the translation-free 6×6 matrix is the 9×9 Hessian's nearest
    /// PSD matrix (the same to rounding), bent and nearly straight, with and without rest
    /// curvature.
    #[test]
    fn bend_projection_is_the_nine_by_nine_one() {
        let shapes = [
            pts(&[[0.0, 0.0, 0.0], [0.1, 0.01, 0.0], [0.19, 0.05, 0.02]]),
            pts(&[[0.0, 0.0, 0.0], [0.01, 0.0, 0.0], [0.0, 0.009, 0.001]]),
            pts(&[[0.0, 0.0, 0.0], [0.02, 1e-4, 0.0], [0.04, 0.0, 2e-4]]),
        ];
        let mut indefinite = 0;
        for x in &shapes {
            for rest in [0.0, 0.3, 1.5] {
                let bend = RodBend {
                    v: [0, 1, 2],
                    k: 0.02,
                    rest,
                    dropoff: None,
                };
                let (mut exact, mut projected) = (Local::default(), Local::default());
                bend.eval(x, false, &mut exact);
                bend.eval(x, true, &mut projected);
                let mut h = SMatrix::<f64, 9, 9>::from_fn(|r, c| exact.hess[c][r]);
                let before = h;
                crate::spd::project_psd(&mut h);
                indefinite += usize::from((h - before).amax() > 1e-9 * before.amax());
                let scale = h.amax().max(1e-300);
                for c in 0..9 {
                    for r in 0..9 {
                        let d = (projected.hess[c][r] - h[(r, c)]).abs();
                        assert!(d <= 1e-12 * scale, "rest {rest}: ({r}, {c}) off by {d:e}");
                    }
                }
                assert_eq!(exact.grad, projected.grad);
            }
        }
        assert!(
            indefinite >= 6,
            "{indefinite} of 9 cases needed a projection"
        );
    }

    #[test]
    fn clamp_finite_differences_and_turning_angle() {
        let t = Vector3::new(0.6, 0.8, 0.0);
        let c = RodClamp {
            v: [0, 1],
            tangent: t,
            k: 0.05,
        };
        check(&c, &pts(&[[0.1, 0.0, 0.0], [0.15, 0.11, 0.02]]), 1e-8, 1e-5);
        // Along the clamp: no energy, no force; a right angle: |κb| = 2, E = 4k.
        let along = vec![Vector3::zeros(), 0.3 * t];
        assert!(c.energy(&along).abs() < 1e-28);
        let side = vec![Vector3::zeros(), Vector3::new(0.0, 0.0, 0.2)];
        assert!((c.energy(&side) - 4.0 * 0.05).abs() < 1e-14);
        // The energy is RodBend's with a ghost vertex one tangent behind the root.
        let x = pts(&[[0.1, 0.0, 0.0], [0.15, 0.11, 0.02]]);
        let ghost = vec![x[0] - t, x[0], x[1]];
        let bend = RodBend {
            v: [0, 1, 2],
            k: 0.05,
            rest: 0.0,
            dropoff: None,
        };
        assert!((c.energy(&x) - bend.energy(&ghost)).abs() < 1e-15);
    }

    #[test]
    fn bend_energy_matches_the_turning_angle() {
        // A right-angle turn: |κb| = 2 tan(45°) = 2.
        let x = pts(&[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0]]);
        let b = RodBend {
            v: [0, 1, 2],
            k: 1.0,
            rest: 0.0,
            dropoff: None,
        };
        assert!((b.energy(&x) - 4.0).abs() < 1e-14);
        // Rigid rotation leaves the energy unchanged (rotation invariance).
        let r = nalgebra::Rotation3::from_euler_angles(0.3, -1.1, 2.0);
        let xr: Vec<_> = x.iter().map(|p| r * p).collect();
        assert!((b.energy(&xr) - 4.0).abs() < 1e-13);
        // Straight: zero energy and zero gradient (no NaN from the kink of |κb|).
        let straight = pts(&[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]]);
        let mut l = Local::default();
        b.eval(&straight, true, &mut l);
        assert_eq!(l.energy, 0.0);
        assert!(
            l.grad[..9].iter().all(|g| *g == 0.0) && l.hess.iter().flatten().all(|h| h.is_finite())
        );
    }
}
