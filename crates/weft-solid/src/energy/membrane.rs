//! St. Venant–Kirchhoff membrane on triangles, isotropic or orthotropic (woven cloth).
//!
//! With F the 3×2 deformation gradient from the rest triangle's 2-D material frame and
//! E = ½(FᵀF − I) the Green strain, the energy density per rest area is
//! ψ = ½(C₁₁E₁₁² + C₂₂E₂₂² + 2C₁₂E₁₁E₂₂ + 4C₃₃E₁₂²), axis 1 the warp direction, axis 2 the weft.
//! Isotropic plane stress (thickness t, Young's modulus E, Poisson's ratio ν):
//! C₁₁ = C₂₂ = Et/(1−ν²), C₁₂ = νEt/(1−ν²), C₃₃ = Et/(2(1+ν)) (so ψ = μ E:E + λ̄/2 tr²E,
//! λ̄ the plane-stress Lamé parameter). Warp, weft and shear scales multiply C₁₁, C₂₂ and C₃₃,
//! and C₁₂ by √(warp·weft), which keeps the stiffness positive definite for positive scales.

use super::{Element, Local};
use nalgebra::{Matrix2, Matrix3, Matrix3x2, SMatrix, SVector, Vector2, Vector3};

/// Material constants of a membrane, per unit rest area (thickness folded in) [N/m].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MembraneMaterial {
    /// C₁₁ (warp).
    pub c11: f64,
    /// C₂₂ (weft).
    pub c22: f64,
    /// C₁₂ (coupling).
    pub c12: f64,
    /// C₃₃ (shear).
    pub c33: f64,
}

impl MembraneMaterial {
    /// Plane-stress constants from Young's modulus [Pa], Poisson's ratio, thickness [m] and
    /// warp/weft/shear scales (1, 1, 1 for isotropic).
    pub fn orthotropic(
        youngs: f64,
        poisson: f64,
        thickness: f64,
        warp: f64,
        weft: f64,
        shear: f64,
    ) -> Self {
        let et = youngs * thickness;
        let a = et / (1.0 - poisson * poisson);
        MembraneMaterial {
            c11: warp * a,
            c22: weft * a,
            c12: (warp * weft).sqrt() * poisson * a,
            c33: shear * et / (2.0 * (1.0 + poisson)),
        }
    }
    /// ∂ψ/∂E (second Piola–Kirchhoff stress) for a symmetric strain.
    fn stress(&self, e: &Matrix2<f64>) -> Matrix2<f64> {
        let s11 = self.c11 * e[(0, 0)] + self.c12 * e[(1, 1)];
        let s22 = self.c22 * e[(1, 1)] + self.c12 * e[(0, 0)];
        let s12 = 2.0 * self.c33 * e[(0, 1)];
        Matrix2::new(s11, s12, s12, s22)
    }
    fn density(&self, e: &Matrix2<f64>) -> f64 {
        let (e11, e22, e12) = (e[(0, 0)], e[(1, 1)], e[(0, 1)]);
        0.5 * (self.c11 * e11 * e11
            + self.c22 * e22 * e22
            + 2.0 * self.c12 * e11 * e22
            + 4.0 * self.c33 * e12 * e12)
    }
}

/// A membrane triangle.
#[derive(Clone, Debug)]
pub struct Membrane {
    /// Vertices.
    pub v: [u32; 3],
    /// Rest area [m²].
    pub area: f64,
    /// F = Σₐ xₐ wₐᵀ: wₐ from the inverse rest shape matrix.
    pub w: [Vector2<f64>; 3],
    /// Material constants.
    pub material: MembraneMaterial,
}

/// Why a rest triangle cannot carry a membrane: no area, or so little for its size (below
/// 1e-12 of its longest edge squared) that its shape is lost to rounding.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("triangle {v:?} {}", self.reason())]
pub struct DegenerateTriangle {
    /// Its vertices.
    pub v: [u32; 3],
    /// Its rest area.
    pub area: f64,
    /// Its longest rest edge [m].
    pub longest: f64,
}

impl DegenerateTriangle {
    /// What is wrong, in words (without the vertices).
    pub fn reason(&self) -> String {
        let (area, longest) = (self.area, self.longest);
        if area > 0.0 && area.is_finite() {
            format!(
                "is too thin to simulate: rest area {area:e} m² for a longest edge of {longest:e} m"
            )
        } else {
            format!("has zero rest area ({area:e} m²)")
        }
    }
}

impl Membrane {
    /// Builds a triangle from rest positions. The material frame's axis 1 is `warp` projected
    /// into the triangle's plane (or the first edge when `warp` is normal to it).
    pub fn new(
        v: [u32; 3],
        rest: [Vector3<f64>; 3],
        warp: Vector3<f64>,
        material: MembraneMaterial,
    ) -> Result<Self, DegenerateTriangle> {
        let (e1, e2) = (rest[1] - rest[0], rest[2] - rest[0]);
        let n = e1.cross(&e2);
        let area = 0.5 * n.norm();
        let scale = e1.norm_squared().max(e2.norm_squared());
        let longest = scale.sqrt();
        if area.is_nan() || area <= 1e-12 * scale || !area.is_finite() {
            return Err(DegenerateTriangle { v, area, longest });
        }
        let n = n.normalize();
        let mut u = warp - n * n.dot(&warp);
        if u.norm_squared() < 1e-12 * warp.norm_squared().max(1e-300)
            || !u.iter().all(|c| c.is_finite())
        {
            u = e1;
        }
        let u = u.normalize();
        let t = n.cross(&u);
        let dm = Matrix2::new(e1.dot(&u), e2.dot(&u), e1.dot(&t), e2.dot(&t));
        let b = dm
            .try_inverse()
            .ok_or(DegenerateTriangle { v, area, longest })?;
        // F = [x1 − x0, x2 − x0] B  ⇒  w₁ = row 0 of B, w₂ = row 1, w₀ = −(w₁ + w₂).
        let w1 = Vector2::new(b[(0, 0)], b[(0, 1)]);
        let w2 = Vector2::new(b[(1, 0)], b[(1, 1)]);
        Ok(Membrane {
            v,
            area,
            w: [-(w1 + w2), w1, w2],
            material,
        })
    }

    fn deformation(&self, x: &[Vector3<f64>]) -> Matrix3x2<f64> {
        let mut f = Matrix3x2::zeros();
        for a in 0..3 {
            f += x[self.v[a] as usize] * self.w[a].transpose();
        }
        f
    }

    fn strain(f: &Matrix3x2<f64>) -> Matrix2<f64> {
        0.5 * (f.transpose() * f - Matrix2::identity())
    }
}

/// The eigenvalues (larger first) of the symmetric 2×2 matrix with entries a, b (off the
/// diagonal) and d, in closed form.
fn eigenvalues2(a: f64, b: f64, d: f64) -> (f64, f64) {
    let mean = 0.5 * (a + d);
    let r = (0.25 * (a - d) * (a - d) + b * b).sqrt();
    (mean + r, mean - r)
}

/// l · v vᵀ / ‖v‖² for v an eigenvector of eigenvalue `l`: (b, l − a) or (l − d, b),
/// whichever is the longer (stable); `None` when both vanish (a multiple of the identity).
fn eigen_term(a: f64, b: f64, d: f64, eig: f64, l: f64) -> Option<Matrix2<f64>> {
    let (u, v) = if (eig - a).abs() >= (eig - d).abs() {
        (b, eig - a)
    } else {
        (eig - d, b)
    };
    let n2 = u * u + v * v;
    if n2 == 0.0 {
        return None;
    }
    let k = l / n2;
    Some(Matrix2::new(k * u * u, k * u * v, k * u * v, k * v * v))
}

/// The positive semidefinite part of a symmetric 2×2 matrix (negative eigenvalues set to 0),
/// in closed form.
fn psd_part(s: &Matrix2<f64>) -> Matrix2<f64> {
    let (a, b, d) = (s[(0, 0)], s[(0, 1)], s[(1, 1)]);
    let (l1, l2) = eigenvalues2(a, b, d);
    if l2 >= 0.0 {
        return *s;
    }
    if l1 <= 0.0 {
        return Matrix2::zeros();
    }
    // l1 v₁ v₁ᵀ alone.
    eigen_term(a, b, d, l1, l1).unwrap_or_else(|| Matrix2::new(l1.max(0.0), 0.0, 0.0, l1.max(0.0)))
}

/// `s` with its eigenvalues raised to at least −`floor` (`floor` ≥ 0), in closed form.
fn clamp_below(s: &Matrix2<f64>, floor: f64) -> Matrix2<f64> {
    let (a, b, d) = (s[(0, 0)], s[(0, 1)], s[(1, 1)]);
    let (l1, l2) = eigenvalues2(a, b, d);
    if l2 >= -floor {
        return *s;
    }
    if l1 <= -floor {
        return Matrix2::from_diagonal_element(-floor);
    }
    // Raise l2 alone: S + (−floor − l2) v₂ v₂ᵀ.
    match eigen_term(a, b, d, l2, -floor - l2) {
        Some(t) => s + t,
        None => Matrix2::new(a.max(-floor), 0.0, 0.0, d.max(-floor)),
    }
}

impl Membrane {
    /// λ_max(Σ_a w_a w_aᵀ): the geometric term Ā (Wᵀ S W) ⊗ I₃ has eigenvalues at least
    /// Ā λ_min(S) times this when λ_min(S) < 0.
    fn shape_norm2(&self) -> f64 {
        let mut m = Matrix2::zeros();
        for w in &self.w {
            m += w * w.transpose();
        }
        eigenvalues2(m[(0, 0)], m[(0, 1)], m[(1, 1)]).0
    }
}

/// What the Hessian's geometric term Ā (Wᵀ S W) ⊗ I₃ keeps of the second Piola–Kirchhoff
/// stress S, the one part of a membrane's Hessian that can be indefinite.
#[derive(Clone, Copy)]
enum Geo {
    /// S itself: the exact Hessian.
    Exact,
    /// S's PSD part: a PSD Hessian.
    Psd,
    /// S with its eigenvalues raised to at least −floor: a Hessian at least −floor Ā ‖W‖².
    Floor(f64),
    /// The tensile part of a stress carried by the Newton iteration instead of S's, S's
    /// compressive part kept (see [`Membrane::eval_carried`]).
    Carried(Matrix2<f64>),
    /// [`Geo::Carried`] with S's compressive part clamped as [`Geo::Floor`] does.
    CarriedFloor(Matrix2<f64>, f64),
}

impl Element for Membrane {
    fn vertices(&self) -> &[u32] {
        &self.v
    }
    fn spends_budget(&self) -> bool {
        true
    }
    fn eval_contact(&self, x: &[Vector3<f64>], budget: f64, out: &mut Local) {
        // A Hessian at least −budget: the material part is PSD and the geometric part at
        // least Ā λ_min(S) ‖W‖², so S's eigenvalues are clamped at −budget / (Ā ‖W‖²). With
        // the PSD part alone (budget 0) a compressed sheet converges linearly wherever it
        // rests on a contact (a step's largest update not shrinking for many iterations);
        // the exact Hessian there makes the contact step's model indefinite, and ADMM on it
        // diverges (`bench/ensemble.py` on hair_pile, whose sheet rests on the hair, measures
        // it; figures in docs/history/issue-71-comments.md).
        let floor = budget.max(0.0) / (self.area * self.shape_norm2());
        self.eval_geo(x, Geo::Floor(floor), out);
    }
    fn eval_first(&self, x: &[Vector3<f64>], out: &mut Local) {
        // The exact Hessian costs no more than the projected one.
        self.eval(x, false, out);
    }
    fn energy(&self, x: &[Vector3<f64>]) -> f64 {
        self.area * self.material.density(&Self::strain(&self.deformation(x)))
    }
    fn eval(&self, x: &[Vector3<f64>], project: bool, out: &mut Local) {
        self.eval_geo(x, if project { Geo::Psd } else { Geo::Exact }, out);
    }
}

/// The mixed (stress–displacement) form of Newton's method on a membrane, condensed.
///
/// With the stress σ a variable of its own, the membrane's energy is the saddle point of
/// Ā (σ:E(x) − ½ σ:C⁻¹:σ) over σ, and Newton on (x, σ) linearizes E in x. Eliminating the
/// stress's update (σ + dσ = C:(E + dE), dE = sym(Fᵀ dF)) leaves the primal system with the
/// primal gradient — so the same stationary points, tested by the same tolerance — and one
/// change: the geometric term Ā (Wᵀ σ W) ⊗ I₃ of the Hessian reads the carried σ, not
/// S(x). Where the membrane is stiff against the inertia, a step that turns an edge by d
/// lengthens it by ~d²/2L, so the tension at the new iterate (or at the first guess
/// x⁰ + h v⁰) is an overshoot the solution does not have, and primal Newton builds its next
/// model on it; the carried stress is what the last linear model predicted (it differs
/// from S by O(d²)), started at each step from the last step's converged stress.
///
/// Only the tension is taken from σ: S's compressive part stays the iterate's, so the
/// negative curvature where the sheet buckles is the exact Hessian's, as in the primal form.
/// Taking σ whole (the inertia ladder on its Hessian) also saves iterations against the
/// primal form, but can need more factorizations; the tension alone saves both on the
/// hanging cloth and the large sheets. The examples' counts
/// (`--stats-json`) and `bench/sheet_graph.py` measure it; figures in
/// docs/history/issue-71-comments.md.
impl Membrane {
    /// The second Piola–Kirchhoff stress S = C:E at `x`.
    pub fn stress_at(&self, x: &[Vector3<f64>]) -> Matrix2<f64> {
        self.material.stress(&Self::strain(&self.deformation(x)))
    }

    /// The stress carried after a step from `from` to `to` that took the fraction `alpha` of
    /// the Newton direction: (1 − α) σ + C:(α E(from) + sym(F(from)ᵀ ΔF)), ΔF = F(to) − F(from)
    /// (= α dF on a straight step), the linear model's prediction blended as the step was.
    pub fn predict_stress(
        &self,
        from: &[Vector3<f64>],
        to: &[Vector3<f64>],
        carried: &Matrix2<f64>,
        alpha: f64,
    ) -> Matrix2<f64> {
        let f = self.deformation(from);
        let m = f.transpose() * (self.deformation(to) - f);
        let de = 0.5 * (m + m.transpose());
        carried * (1.0 - alpha) + self.material.stress(&(Self::strain(&f) * alpha + de))
    }

    /// Energy and gradient at `x`, and the Hessian whose geometric term reads `carried`
    /// instead of the stress at `x` (exact where `carried` is S(x)); it may be indefinite.
    pub fn eval_carried(&self, x: &[Vector3<f64>], carried: &Matrix2<f64>, out: &mut Local) {
        self.eval_geo(x, Geo::Carried(*carried), out);
    }

    /// [`Element::eval_contact`] with the geometric term's tension read from `carried`:
    /// still at least −`budget` (the carried tension adds a PSD term, the compression is
    /// clamped as there).
    pub fn eval_contact_carried(
        &self,
        x: &[Vector3<f64>],
        budget: f64,
        carried: &Matrix2<f64>,
        out: &mut Local,
    ) {
        let floor = budget.max(0.0) / (self.area * self.shape_norm2());
        self.eval_geo(x, Geo::CarriedFloor(*carried, floor), out);
    }

    /// Energy, gradient and the Hessian with the geometric term as `geo_mode` says.
    fn eval_geo(&self, x: &[Vector3<f64>], geo_mode: Geo, out: &mut Local) {
        let f = self.deformation(x);
        let e = Self::strain(&f);
        let s = self.material.stress(&e);
        let p = f * s; // first Piola–Kirchhoff stress
        let mut g = SVector::<f64, 9>::zeros();
        for a in 0..3 {
            g.fixed_rows_mut::<3>(3 * a)
                .copy_from(&(self.area * p * self.w[a]));
        }
        // Hessian block of vertices (a, b): perturbing x_b by δ gives dF = δ w_bᵀ,
        // dE = sym(Fᵀ dF) = sym(u w_bᵀ) with u = Fᵀδ, and dP w_a = δ (w_bᵀ S w_a) + F dS w_a
        // with dS = C:dE linear in u, dS w_a = L_ab u. So
        //   H_ab = Ā [(w_aᵀ S w_b) I₃ + F L_ab Fᵀ],
        // (L_ab)ᵢⱼ = [C:sym(eⱼ w_bᵀ) w_a]ᵢ. The second term is Bᵀ(G C Gᵀ)B over the element
        // (G maps symmetric strains to F-space), PSD for a positive definite material; the
        // first, S ⊗ I, is indefinite when S has a negative eigenvalue (compression).
        // Replacing S by its PSD part S₊ makes the whole PSD in closed form (a 2×2
        // eigenproblem instead of projecting the 6×6 ∂P/∂F; Teran et al. 2005 project the
        // same quantity): the same Newton iterations as the nearest-PSD projection of the
        // 6×6 matrix, for a cheaper assembly (`weft bench solid` measures it; figures in
        // docs/history/issue-71-comments.md).
        let s_geo = match geo_mode {
            Geo::Exact => s,
            Geo::Psd => psd_part(&s),
            Geo::Floor(floor) => clamp_below(&s, floor),
            // The carried stress's tension, the iterate's compression.
            Geo::Carried(carried) => psd_part(&carried) + (s - psd_part(&s)),
            Geo::CarriedFloor(carried, floor) => {
                psd_part(&carried) + (clamp_below(&s, floor) - psd_part(&s))
            }
        };
        // dS for the unit strains sym(eⱼ w_bᵀ), per b and j.
        let mut ds = [[Matrix2::<f64>::zeros(); 2]; 3];
        for (b, dsb) in ds.iter_mut().enumerate() {
            for (j, dsbj) in dsb.iter_mut().enumerate() {
                let mut de = Matrix2::zeros();
                de[(j, 0)] += 0.5 * self.w[b][0];
                de[(j, 1)] += 0.5 * self.w[b][1];
                de[(0, j)] += 0.5 * self.w[b][0];
                de[(1, j)] += 0.5 * self.w[b][1];
                *dsbj = self.material.stress(&de);
            }
        }
        let mut h = SMatrix::<f64, 9, 9>::zeros();
        for a in 0..3 {
            for (b, dsb) in ds.iter().enumerate().skip(a) {
                let geo = self.area * self.w[a].dot(&(s_geo * self.w[b]));
                let l = Matrix2::from_columns(&[dsb[0] * self.w[a], dsb[1] * self.w[a]]);
                let block =
                    (f * l * f.transpose()) * self.area + Matrix3::from_diagonal_element(geo);
                h.fixed_view_mut::<3, 3>(3 * a, 3 * b).copy_from(&block);
                if a != b {
                    h.fixed_view_mut::<3, 3>(3 * b, 3 * a)
                        .copy_from(&block.transpose());
                }
            }
        }
        out.set::<9>(self.area * self.material.density(&e), &g, &h);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::energy::fd::check;

    /// `tri()` stretched (and moved out of its plane).
    fn stretched() -> Vec<Vector3<f64>> {
        vec![
            Vector3::new(0.0, 0.0, 0.01),
            Vector3::new(0.12, 0.01, 0.0),
            Vector3::new(0.02, 0.09, 0.02),
        ]
    }

    /// `tri()` compressed (and moved out of its plane).
    fn compressed() -> Vec<Vector3<f64>> {
        vec![
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(0.07, 0.01, 0.01),
            Vector3::new(0.03, 0.05, -0.01),
        ]
    }

    fn tri() -> [Vector3<f64>; 3] {
        [
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(0.1, 0.0, 0.0),
            Vector3::new(0.03, 0.08, 0.0),
        ]
    }

    #[test]
    fn finite_differences_isotropic_and_orthotropic_stretched_and_compressed() {
        for mat in [
            MembraneMaterial::orthotropic(1e5, 0.3, 1e-3, 1.0, 1.0, 1.0),
            MembraneMaterial::orthotropic(1e5, 0.3, 1e-3, 3.0, 0.5, 0.2),
        ] {
            let m = Membrane::new([0, 1, 2], tri(), Vector3::new(1.0, 1.0, 0.0), mat).unwrap();
            let stretched = vec![
                Vector3::new(0.0, 0.0, 0.01),
                Vector3::new(0.12, 0.01, 0.0),
                Vector3::new(0.02, 0.09, 0.02),
            ];
            let compressed = vec![
                Vector3::new(0.0, 0.0, 0.0),
                Vector3::new(0.07, 0.01, 0.01),
                Vector3::new(0.03, 0.05, -0.01),
            ];
            check(&m, &stretched, 1e-8, 1e-5);
            check(&m, &compressed, 1e-8, 1e-5);
        }
    }

    #[test]
    fn rest_state_has_zero_energy_and_rigid_motion_costs_nothing() {
        let m = Membrane::new(
            [0, 1, 2],
            tri(),
            Vector3::x(),
            MembraneMaterial::orthotropic(1e5, 0.3, 1e-3, 2.0, 1.0, 1.0),
        )
        .unwrap();
        let r = nalgebra::Rotation3::from_euler_angles(0.4, 0.2, -0.9);
        let moved: Vec<_> = tri()
            .iter()
            .map(|p| r * p + Vector3::new(1.0, 2.0, 3.0))
            .collect();
        assert!(m.energy(&tri()) == 0.0);
        assert!(m.energy(&moved) < 1e-18, "{}", m.energy(&moved));
    }

    #[test]
    fn uniaxial_strain_energy_matches_plane_stress_constants() {
        // Stretch along the warp (x) by a small ε with the weft held: E₁₁ = ε + ε²/2.
        let mat = MembraneMaterial::orthotropic(2e5, 0.25, 1e-3, 1.0, 1.0, 1.0);
        let m = Membrane::new([0, 1, 2], tri(), Vector3::x(), mat).unwrap();
        let eps = 1e-3;
        let x: Vec<_> = tri()
            .iter()
            .map(|p| Vector3::new(p.x * (1.0 + eps), p.y, p.z))
            .collect();
        let e11 = eps + 0.5 * eps * eps;
        let want = m.area * 0.5 * mat.c11 * e11 * e11;
        assert!(
            (m.energy(&x) - want).abs() < 1e-12 * want,
            "{} vs {want}",
            m.energy(&x)
        );
        assert!((mat.c11 - 2e2 / (1.0 - 0.0625)).abs() < 1e-9);
    }

    /// Symmetric 2×2 cases: definite, indefinite, diagonal, negative definite, large,
    /// zero diagonal, a negative multiple of the identity plus a coupling.
    const SYMMETRIC_2X2: [(f64, f64, f64); 8] = [
        (2.0, 0.5, 1.0),
        (-1.0, 0.3, 2.0),
        (1.0, 0.0, -3.0),
        (-3.0, 0.0, 1.0),
        (-1.0, -0.2, -2.0),
        (1e3, 2e3, -5e2),
        (0.0, 1.0, 0.0),
        (-4.0, 1.0, -4.0),
    ];

    /// Checks `f` against nalgebra's symmetric eigensolver with the eigenvalues raised to
    /// −floor, to 1e-14 relative (both are a few rounding errors from the exact answer).
    fn matches_eigendecomposition(floor: f64, f: impl Fn(&Matrix2<f64>) -> Matrix2<f64>) {
        for (a, b, d) in SYMMETRIC_2X2 {
            let m = Matrix2::new(a, b, b, d);
            let eig = m.symmetric_eigen();
            let mut want = Matrix2::<f64>::zeros();
            for k in 0..2 {
                let q = eig.eigenvectors.column(k);
                let l: f64 = eig.eigenvalues[k];
                want += l.max(-floor) * q * q.transpose();
            }
            let got = f(&m);
            assert!(
                (got - want).amax() <= 1e-14 * m.amax().max(floor),
                "{m}, floor {floor} → {got}, want {want}"
            );
            assert_eq!(got[(0, 1)], got[(1, 0)]);
        }
    }

    #[test]
    fn psd_part_matches_the_eigendecomposition() {
        matches_eigendecomposition(0.0, psd_part);
    }

    #[test]
    fn clamp_below_matches_the_eigendecomposition() {
        for floor in [0.0, 0.5, 2.5] {
            matches_eigendecomposition(floor, |m| clamp_below(m, floor));
        }
    }

    /// The contact step's Hessian of a compressed triangle: its smallest eigenvalue is at
    /// least −budget (the bound the integrator's inertia budget relies on), it is the exact
    /// Hessian when the budget is large, the projected one at a budget of 0 (to rounding:
    /// clamp_below and psd_part build S₊ from different eigenvectors), and the gradient and
    /// energy are the exact ones whatever the budget.
    #[test]
    fn the_contact_hessian_keeps_negative_curvature_down_to_its_budget() {
        let mat = MembraneMaterial::orthotropic(1e5, 0.3, 1e-3, 1.0, 1.0, 1.0);
        let m = Membrane::new([0, 1, 2], tri(), Vector3::x(), mat).unwrap();
        let compressed = compressed();
        let hessian = |l: &Local| SMatrix::<f64, 9, 9>::from_fn(|r, c| l.hess[c][r]);
        let (mut exact, mut projected, mut bounded) =
            (Local::default(), Local::default(), Local::default());
        m.eval(&compressed, false, &mut exact);
        m.eval(&compressed, true, &mut projected);
        let lowest = |h: SMatrix<f64, 9, 9>| h.symmetric_eigenvalues().min();
        let most_negative = lowest(hessian(&exact));
        assert!(
            most_negative < 0.0,
            "the case must be indefinite: {most_negative}"
        );
        for budget in [0.25 * -most_negative, 0.75 * -most_negative] {
            m.eval_contact(&compressed, budget, &mut bounded);
            let l = lowest(hessian(&bounded));
            // 1e-9 relative to the Hessian's size: the eigensolver's rounding.
            let tol = 1e-9 * hessian(&exact).amax();
            assert!(
                l >= -budget - tol,
                "budget {budget}: smallest eigenvalue {l}"
            );
            assert!(l <= 0.0, "budget {budget}: negative curvature kept, {l}");
            assert_eq!(bounded.energy, exact.energy);
            assert_eq!(bounded.grad[..9], exact.grad[..9]);
        }
        m.eval_contact(&compressed, 1e30, &mut bounded);
        assert_eq!(hessian(&bounded), hessian(&exact));
        m.eval_contact(&compressed, 0.0, &mut bounded);
        let gap = (hessian(&bounded) - hessian(&projected)).amax();
        assert!(gap <= 1e-12 * hessian(&exact).amax(), "{gap}");
    }

    #[test]
    fn degenerate_triangles_are_refused() {
        let flat = [Vector3::zeros(), Vector3::x(), Vector3::x() * 2.0];
        let err = Membrane::new(
            [4, 5, 6],
            flat,
            Vector3::x(),
            MembraneMaterial::orthotropic(1.0, 0.3, 1.0, 1.0, 1.0, 1.0),
        )
        .unwrap_err();
        assert_eq!(
            err.to_string(),
            "triangle [4, 5, 6] has zero rest area (0e0 m²)"
        );
    }

    /// The carried stress after a step is the linear model's: S at the end of the step
    /// minus C:(½ ΔFᵀΔF), the one term of the Green strain the model leaves out (exact,
    /// since E is quadratic in x); a partial step blends it with the stress carried before.
    #[test]
    fn the_carried_stress_is_the_linear_models_prediction() {
        let mat = MembraneMaterial::orthotropic(1e5, 0.3, 1e-3, 3.0, 0.5, 0.2);
        let m = Membrane::new([0, 1, 2], tri(), Vector3::new(1.0, 1.0, 0.0), mat).unwrap();
        let from = stretched();
        let step = [
            Vector3::new(0.004, -0.01, 0.02),
            Vector3::new(-0.01, 0.003, 0.015),
            Vector3::new(0.0, 0.008, -0.03),
        ];
        let to: Vec<_> = from.iter().zip(&step).map(|(p, d)| p + d).collect();
        let df = m.deformation(&to) - m.deformation(&from);
        let left_out = mat.stress(&(0.5 * df.transpose() * df));
        let carried = Matrix2::new(7.0, -2.0, -2.0, 3.0);
        let whole = m.predict_stress(&from, &to, &carried, 1.0);
        let expected = m.stress_at(&to) - left_out;
        // Rounding of stresses of ~1e2 N/m: 1e-10 relative.
        assert!(
            (whole - expected).amax() <= 1e-10 * expected.amax(),
            "{whole} {expected}"
        );
        // A half step (to the midpoint) is half the way from the carried stress to the whole
        // step's prediction (Newton's update of (x, σ) together, scaled by the line search).
        let mid: Vec<_> = from.iter().zip(&step).map(|(p, d)| p + 0.5 * d).collect();
        let half = m.predict_stress(&from, &mid, &carried, 0.5);
        let expected = 0.5 * carried + 0.5 * (m.stress_at(&to) - left_out);
        assert!(
            (half - expected).amax() <= 1e-10 * expected.amax(),
            "{half} {expected}"
        );
    }

    /// Carrying the stress at the iterate gives the exact Hessian (stretched or compressed);
    /// carrying another changes only the geometric term's tension: a compressed triangle
    /// keeps its exact negative curvature, a relaxed one's Hessian gains the carried
    /// tension's (Wᵀ σ₊ W) ⊗ I₃.
    #[test]
    fn carrying_the_iterates_stress_gives_the_exact_hessian() {
        let mat = MembraneMaterial::orthotropic(1e5, 0.3, 1e-3, 1.0, 1.0, 1.0);
        let m = Membrane::new([0, 1, 2], tri(), Vector3::new(1.0, 0.0, 0.0), mat).unwrap();
        let stretched = stretched();
        let compressed = compressed();
        let (mut exact, mut carried) = (Local::default(), Local::default());
        for x in [&stretched, &compressed] {
            m.eval(x, false, &mut exact);
            m.eval_carried(x, &m.stress_at(x), &mut carried);
            let scale = (0..9).map(|i| exact.hess[i][i].abs()).fold(0.0, f64::max);
            for c in 0..9 {
                assert_eq!(carried.grad[c], exact.grad[c]);
                for r in 0..9 {
                    // psd(S) + (S − psd(S)) is S up to rounding.
                    assert!((carried.hess[c][r] - exact.hess[c][r]).abs() <= 1e-12 * scale);
                }
            }
        }
        // At rest S = 0: carrying a tension σ adds Ā (w_aᵀ σ w_b) I₃ to each block.
        let rest = tri().to_vec();
        let sigma = Matrix2::new(40.0, 5.0, 5.0, 10.0);
        m.eval(&rest, false, &mut exact);
        m.eval_carried(&rest, &sigma, &mut carried);
        assert_adds_carried_tension(&m, &sigma, &exact, &carried);
        // Carried compression adds nothing: the compressive part is the iterate's.
        m.eval_carried(&rest, &(-sigma), &mut carried);
        for c in 0..9 {
            for r in 0..9 {
                assert!((carried.hess[c][r] - exact.hess[c][r]).abs() <= 1e-12);
            }
        }
    }

    /// `carried`'s Hessian is `base`'s plus a carried tension σ's geometric term at rest,
    /// Ā (w_aᵀ σ w_b) I₃ on each block (a, b).
    fn assert_adds_carried_tension(
        m: &Membrane,
        sigma: &Matrix2<f64>,
        base: &Local,
        carried: &Local,
    ) {
        for a in 0..3 {
            for b in 0..3 {
                let geo = m.area * m.w[a].dot(&(sigma * m.w[b]));
                for k in 0..3 {
                    let d = carried.hess[3 * b + k][3 * a + k] - base.hess[3 * b + k][3 * a + k];
                    assert!((d - geo).abs() <= 1e-9 * geo.abs().max(1.0), "{d} {geo}");
                }
            }
        }
    }

    /// The contact step's model with a carried stress: carrying S(x) gives the contact
    /// step's own Hessian (its compression bounded by the budget either way), and a carried
    /// tension at rest adds Ā (w_aᵀ σ w_b) I₃ to it, as in the contact-free step.
    #[test]
    fn the_contact_models_carried_tension_keeps_its_compression_bound() {
        let mat = MembraneMaterial::orthotropic(1e5, 0.3, 1e-3, 1.0, 1.0, 1.0);
        let m = Membrane::new([0, 1, 2], tri(), Vector3::new(1.0, 0.0, 0.0), mat).unwrap();
        let (mut bounded, mut carried) = (Local::default(), Local::default());
        // A budget small enough that the compressed triangle's floor binds.
        let budget = 1.0;
        let mut exact = Local::default();
        m.eval(&compressed(), false, &mut exact);
        m.eval_contact(&compressed(), budget, &mut bounded);
        let clamped = (0..9).any(|c| (0..9).any(|r| bounded.hess[c][r] != exact.hess[c][r]));
        assert!(clamped, "the budget binds on the compressed triangle");
        m.eval_contact(&compressed(), 1e12, &mut bounded);
        let scale = (0..9).map(|i| exact.hess[i][i].abs()).fold(0.0, f64::max);
        let unbounded = (0..9).all(|c| {
            (0..9).all(|r| (bounded.hess[c][r] - exact.hess[c][r]).abs() <= 1e-12 * scale)
        });
        assert!(
            unbounded,
            "a budget that does not bind leaves the exact Hessian"
        );
        for x in [&stretched(), &compressed()] {
            m.eval_contact(x, budget, &mut bounded);
            m.eval_contact_carried(x, budget, &m.stress_at(x), &mut carried);
            let scale = (0..9).map(|i| bounded.hess[i][i].abs()).fold(0.0, f64::max);
            for c in 0..9 {
                assert_eq!(carried.grad[c], bounded.grad[c]);
                for r in 0..9 {
                    assert!((carried.hess[c][r] - bounded.hess[c][r]).abs() <= 1e-12 * scale);
                }
            }
        }
        let rest = tri().to_vec();
        let sigma = Matrix2::new(40.0, 5.0, 5.0, 10.0);
        m.eval_contact(&rest, budget, &mut bounded);
        m.eval_contact_carried(&rest, budget, &sigma, &mut carried);
        assert_adds_carried_tension(&m, &sigma, &bounded, &carried);
    }
}
