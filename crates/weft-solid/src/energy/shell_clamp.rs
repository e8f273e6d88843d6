//! The trace half of shell bending at a held vertex on a clamped border edge
//! ([`super::shell_bending_clamped`]).
//!
//! A free vertex's trace term measures r = y·n, y = Σⱼ wⱼ (xⱼ − xᵥ) its cotangent Laplacian and
//! n its ring's normal. At a held border vertex the ring's own normal turns with the cloth, so
//! r cannot see the cloth turning about the border: the held row would be a hinge. Against
//! the clamp's frame instead (n the normal of the ghost triangles that continue the cloth
//! beyond the border, a along the border, m = ±n × a pointing into the cloth), tilting the
//! cloth by θ about the border turns y in the (m, n) plane, and
//!
//! `r = s · 2 tan(θ/2) = 2 s (y·n) / (√((y·n)² + (y·m)²) + y·m)`, s = |y⊥| at rest,
//!
//! is s θ for small θ: with the weights and Voronoi area of the real (half) ring, the energy
//! ½ k (r − r̄)², k = (1 + ν)/2 · D/Aᵥ, is the plate's trace energy over the half cell between
//! the clamp line and the first free vertices (the rule of a rod's `RodClamp`). The half-angle
//! tangent keeps the clamp stiffening up to a fold back onto itself (θ → π), where y·n alone
//! (sin θ) would go slack past 90°.
//!
//! The frame comes from the held vertex, its border neighbours and the ghosts, all held, so it
//! is constant within a solve; derivatives are still taken through it (exactly, by
//! hyper-dual numbers over the stencil), so the element passes the finite-difference checks.

use super::shell::{cross, dot, sub};
use super::{Element, Local, MAX_DOFS, MAX_STENCIL};
use nalgebra::Vector3;
use num_dual::{DualNum, HyperDual64};

fn unit<S: DualNum<Primitive = f64> + Copy>(a: [S; 3]) -> [S; 3] {
    let l = dot(a, a).sqrt();
    [a[0] / l, a[1] / l, a[2] / l]
}

/// Trace bending of a held vertex on a clamped border edge.
#[derive(Clone, Debug)]
pub struct ShellClamp {
    /// The held vertex, its real ring neighbours, then the ghosts of its clamped edges.
    v: Box<[u32]>,
    /// Cotangent weight per real neighbour (from the real triangles only).
    w: Box<[f64]>,
    /// Ghost triangles (stencil indices), oriented like the cloth: their normal is n, and
    /// each one's first two vertices run along the border (their sum gives a).
    faces: Box<[[u8; 3]]>,
    /// ±1: the sign that makes m = σ n × a point into the cloth at rest.
    sign: f64,
    /// |y⊥| at rest [m].
    s: f64,
    /// (1 + ν)/2 · D/Aᵥ with the real (half) Voronoi area [J/m²].
    k: f64,
    /// r at rest.
    rest: f64,
    /// The real (half) Voronoi area [m²].
    area: f64,
    /// Bend angle dropoff, if any ([`super::Dropoff`]).
    dropoff: Option<super::Dropoff>,
}

impl ShellClamp {
    /// Sets the bend angle dropoff d ∈ [0, 1] at reference curvature κ₀, as
    /// [`super::ShellBend::set_dropoff`].
    pub fn set_dropoff(&mut self, d: f64, kappa0: f64) {
        // A cylinder of curvature κ has r − r̄ = κ Aᵥ: E = ½ κ² · k Aᵥ².
        self.dropoff = super::Dropoff::new(d, kappa0, self.k * self.area * self.area);
    }

    /// The element for stencil `v` (held vertex, real neighbours with weights `w`, then
    /// ghosts) with ghost `faces` in stencil indices, rest positions `p` (stencil order) and
    /// stiffness `k`. None when the rest ring gives no direction into the cloth.
    pub(crate) fn new(
        v: Vec<u32>,
        w: Vec<f64>,
        faces: Vec<[u8; 3]>,
        p: &[[f64; 3]],
        k: f64,
        area: f64,
    ) -> Option<Self> {
        let mut e = ShellClamp {
            v: v.into(),
            w: w.into(),
            faces: faces.into(),
            sign: 1.0,
            s: 1.0,
            k,
            rest: 0.0,
            area,
            dropoff: None,
        };
        let (_, n, m) = e.frame(p);
        let y = e.laplacian(p);
        let (yn, ym) = (dot(y, n), dot(y, m));
        let s = (yn * yn + ym * ym).sqrt();
        if !(s > 0.0 && s.is_finite()) {
            return None;
        }
        e.sign = if ym < 0.0 { -1.0 } else { 1.0 };
        e.s = s;
        e.rest = e.r(p);
        e.rest.is_finite().then_some(e)
    }

    fn laplacian<S: DualNum<Primitive = f64> + Copy>(&self, p: &[[S; 3]]) -> [S; 3] {
        let zero = p[0][0] * 0.0;
        let mut y = [zero; 3];
        for (j, &wj) in self.w.iter().enumerate() {
            let e = sub(p[j + 1], p[0]);
            for c in 0..3 {
                y[c] += e[c] * wj;
            }
        }
        y
    }

    /// (a, n, σ n × a normalized) from the ghost triangles.
    fn frame<S: DualNum<Primitive = f64> + Copy>(&self, p: &[[S; 3]]) -> ([S; 3], [S; 3], [S; 3]) {
        let zero = p[0][0] * 0.0;
        let (mut big_n, mut along) = ([zero; 3], [zero; 3]);
        for f in self.faces.iter() {
            let [a, b, c] = f.map(|i| p[i as usize]);
            let fnm = cross(sub(b, a), sub(c, a));
            let e = sub(b, a);
            for k in 0..3 {
                big_n[k] += fnm[k];
                along[k] += e[k];
            }
        }
        let n = unit(big_n);
        let a = unit(along);
        let m = unit(cross(n, a));
        (a, n, m.map(|c| c * self.sign))
    }

    /// r = 2 s (y·n) / (|(y·n, y·m)| + y·m).
    fn r<S: DualNum<Primitive = f64> + Copy>(&self, p: &[[S; 3]]) -> S {
        let (_, n, m) = self.frame(p);
        let y = self.laplacian(p);
        let (yn, ym) = (dot(y, n), dot(y, m));
        yn * (2.0 * self.s) / ((yn * yn + ym * ym).sqrt() + ym)
    }

    /// Replaces every vertex index v by `f(v)`.
    pub fn map_vertices(&mut self, f: impl Fn(u32) -> u32) {
        self.v.iter_mut().for_each(|v| *v = f(*v));
    }

    /// (1 + ν)/2 · D/Aᵥ [J/m²].
    pub fn stiffness(&self) -> f64 {
        self.k
    }

    fn positions(&self, x: &[Vector3<f64>], p: &mut [[f64; 3]; MAX_STENCIL]) {
        for (a, &i) in self.v.iter().enumerate() {
            p[a] = x[i as usize].into();
        }
    }
}

impl Element for ShellClamp {
    fn vertices(&self) -> &[u32] {
        &self.v
    }
    fn energy(&self, x: &[Vector3<f64>]) -> f64 {
        let mut p = [[0.0; 3]; MAX_STENCIL];
        self.positions(x, &mut p);
        let d = self.r(&p[..self.v.len()]) - self.rest;
        let e = 0.5 * self.k * d * d;
        self.dropoff.map_or(e, |dr| dr.energy(e))
    }
    #[allow(clippy::needless_range_loop)] // DOF index arithmetic
    fn eval(&self, x: &[Vector3<f64>], project: bool, out: &mut Local) {
        // ∇r and ∇²r by one hyper-dual pass per DOF pair (a held vertex has a small stencil,
        // and there are few of them); E = ½k d², d = r − r̄: ∇E = k d ∇r, ∇²E = k ∇r∇rᵀ
        // (the projection: Gauss–Newton, PSD) + k d ∇²r.
        let m = self.v.len();
        let dofs = 3 * m;
        let mut p = [[0.0; 3]; MAX_STENCIL];
        self.positions(x, &mut p);
        let mut pd = [[HyperDual64::from_re(0.0); 3]; MAX_STENCIL];
        let mut g = [0.0; MAX_DOFS];
        let mut r = 0.0;
        for i in 0..dofs {
            for j in i..dofs {
                if project && j != i {
                    continue;
                }
                for a in 0..m {
                    pd[a] = p[a].map(HyperDual64::from_re);
                }
                pd[i / 3][i % 3].eps1 = 1.0;
                pd[j / 3][j % 3].eps2 = 1.0;
                let v = self.r(&pd[..m]);
                if j == i {
                    g[i] = v.eps1;
                    r = v.re;
                }
                // The second derivatives, for the unprojected Hessian (scaled below).
                out.hess[j][i] = v.eps1eps2;
                out.hess[i][j] = v.eps1eps2;
            }
        }
        let d = r - self.rest;
        out.dofs = dofs;
        out.energy = 0.5 * self.k * d * d;
        for i in 0..dofs {
            out.grad[i] = self.k * d * g[i];
        }
        for c in 0..dofs {
            for rr in 0..dofs {
                let curvature = if project { 0.0 } else { out.hess[c][rr] };
                out.hess[c][rr] = self.k * (g[rr] * g[c] + d * curvature);
            }
        }
        out.symmetrize();
        if let Some(dr) = self.dropoff {
            dr.apply(out);
        }
    }
}
