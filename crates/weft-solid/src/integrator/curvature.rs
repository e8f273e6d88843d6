//! Steps along a direction of negative curvature, where the inertia ladder's shifted
//! Hessian hides one (Moré & Sorensen 1979, "On the use of directions of negative curvature
//! in a modified Newton method", Math. Programming 16).
//!
//! Where the first Hessian H (exact but for the membranes' tension read from the carried
//! stress and midedge bending's Gauss–Newton term) is indefinite, the ladder adds inertia
//! κ D (D = diag(mᵢ/h²)) until H + κD factors, and the step follows −(H + κD)⁻¹ g. Along
//! an eigenvector v of H's most negative eigenvalue λ (relative to D) that step multiplies
//! the distance from the saddle by κ / (κ + λ) an iteration. Where a sheet is about to
//! buckle λ is tiny, even against κ at the ladder's floor, so that factor is barely above
//! 1: the residuals grow slowly for tens of iterations until the step runs out of
//! iterations and is halved (`bench/sheet_graph.py`'s sheets show it; figures in
//! docs/history/issue-71-comments.md). Every other mode converges as
//! κ / (μ + κ) for its eigenvalue μ, so a shift large enough for the negative mode also
//! slows the soft positive ones.
//!
//! So after a shifted step the same factor gives v by inverse iteration,
//! v ← (H + κD)⁻¹ D v, whose Rayleigh quotient vᵀHv / vᵀDv bounds λ from above: where it
//! is negative, v is a direction of negative curvature of H whatever the iteration's
//! accuracy (with the one-ring preconditioner the factor is of a sparser matrix M₋ ⪯ H + κD:
//! the iteration then finds M₋'s soft mode, and the quotient, taken on H itself, still
//! decides). The iterate then moves along ±v to the lowest objective found: the better
//! sign at a first length (the step just taken), the vertex of the parabola through the
//! three values where it is convex, and doublings while the objective falls. Every move
//! lowers the objective, so the loop's descent and its convergence test are unchanged.
//!
//! Limits: a move needs a shifted iteration that does not end the step, so a saddle reached
//! exactly (a zero gradient) or within the tolerance is not left; and a move is taken on
//! any decrease of the objective, even one below the line search's threshold (its
//! `unresolvable` test, far coarser than the objective's own rounding): at tolerances far
//! below the default, on large sheets, such moves and the whole Newton steps after them
//! cycle along a mode flatter than that threshold, and tightening it costs more iterations
//! at the default tolerance than it saves (`bench/sheet_graph.py` measures it; figures in
//! docs/history/issue-71-comments.md). Not for rigid
//! groups' or sliders' nodes (their moves go through `move_members` and `retract`; their
//! steps keep the ladder alone), nor for the contact step (its model is kept convex by its
//! budget, `fill_budget`).

use super::{Integrator, Mode, NONE, one_ring};
use crate::system::SolidSystem;
use nalgebra::Vector3;

/// Inverse iterations. Summed over cloth_hang at several substeps and the sheets of
/// `bench/sheet_graph.py`, the Newton iterations and factorizations gain little from two
/// sweeps over the ladder alone, and from 3 sweeps on they differ by less than single sizes
/// move with the sweeps (buckling is chaotic in these counts); 4 keep a sweep of margin for
/// a mode less well separated. Stopping once the Rayleigh quotient settles, without the
/// start's perturbation, gains nothing (figures in docs/history/issue-71-comments.md). Each
/// sweep is one solve with the factor at hand (at 24², an eighth of a factorization).
const SWEEPS: usize = 4;

/// The start's deterministic perturbation, relative to the shifted direction (in D's
/// norm): at an exactly symmetric saddle the direction has no component along v, and
/// inverse iteration could never find it.
const PERTURBATION: f64 = 1e-2;

/// Doublings of the move at most (2³⁰ times the first length).
const DOUBLINGS: usize = 30;

/// A pseudo-random number in [−½, ½) from `i` (SplitMix64's finalizer): the same at any
/// thread count and on any machine.
fn jitter(i: usize) -> f64 {
    let mut z = (i as u64)
        .wrapping_add(1)
        .wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    (z >> 11) as f64 / (1u64 << 53) as f64 - 0.5
}

/// Σ aᵢ bᵢ dᵢ in index order.
fn weighted(a: &[f64], b: &[f64], d: &[f64]) -> f64 {
    a.iter().zip(b).zip(d).map(|((a, b), d)| a * b * d).sum()
}

impl Integrator {
    /// Whether a shifted step of this system may move along negative curvature.
    pub(super) fn curvature_moves(&self, sys: &SolidSystem) -> bool {
        self.groups.is_empty() && sys.sliders.is_empty()
    }

    /// After a direction found with `kappa` · mᵢ/h² of inertia added (`values` still hold
    /// H + κD and the factor is theirs): an upper bound on H's most negative eigenvalue
    /// relative to D, in units of mᵢ/h², with its vector in `curv_v`.
    pub(super) fn negative_curvature(&mut self, sys: &SolidSystem, h: f64, kappa: f64) -> f64 {
        let n = self.work.dir.len();
        self.work.curv_d.resize(n, 0.0);
        self.work.curv_d.fill(0.0);
        for (v, &f) in self.lin.free_of.iter().enumerate() {
            if f != NONE {
                let f = 3 * f as usize;
                self.work.curv_d[f..f + 3].fill(sys.mass[v] / (h * h));
            }
        }
        self.work.curv_v.resize(n, 0.0);
        self.work.curv_w.resize(n, 0.0);
        // Start: the direction and a small deterministic perturbation, each of unit D-norm.
        let dn = weighted(&self.work.dir, &self.work.dir, &self.work.curv_d).sqrt();
        for (i, w) in self.work.curv_w.iter_mut().enumerate() {
            *w = jitter(i);
        }
        let wn = weighted(&self.work.curv_w, &self.work.curv_w, &self.work.curv_d).sqrt();
        if !(dn > 0.0 && dn.is_finite() && wn > 0.0) {
            return f64::INFINITY;
        }
        for ((v, d), w) in self
            .work
            .curv_v
            .iter_mut()
            .zip(&self.work.dir)
            .zip(&self.work.curv_w)
        {
            *v = d / dn + PERTURBATION * w / wn;
        }
        for _ in 0..SWEEPS {
            // v ← (H + κD)⁻¹ D v with the factor at hand, then normalized in D's norm.
            for ((w, v), d) in self
                .work
                .curv_w
                .iter_mut()
                .zip(&self.work.curv_v)
                .zip(&self.work.curv_d)
            {
                *w = d * v;
            }
            let mut w = std::mem::take(&mut self.work.curv_w);
            self.solve_with_last(&mut w);
            std::mem::swap(&mut self.work.curv_v, &mut w);
            self.work.curv_w = w;
            let vn = weighted(&self.work.curv_v, &self.work.curv_v, &self.work.curv_d).sqrt();
            if !(vn > 0.0 && vn.is_finite()) {
                return f64::INFINITY;
            }
            self.work.curv_v.iter_mut().for_each(|v| *v /= vn);
        }
        // The Rayleigh quotient vᵀ(H + κD)v / vᵀDv (= 1), less the shift.
        one_ring::product(
            &self.lin.values,
            &self.lin.col_ptr,
            &self.lin.row_idx,
            &self.work.curv_v,
            &mut self.work.curv_w,
        );
        let rho: f64 = self
            .work
            .curv_v
            .iter()
            .zip(&self.work.curv_w)
            .map(|(a, b)| a * b)
            .sum();
        if rho.is_finite() {
            rho - kappa
        } else {
            f64::INFINITY
        }
    }

    /// Moves `x` along ±`curv_v` to the lowest objective found (see the module's doc); `base`
    /// is the first move's largest vertex displacement, `e_at_x` the objective at `x` (known
    /// after the line search; updated to the new one). Whether it moved.
    pub(super) fn curvature_search(
        &mut self,
        sys: &SolidSystem,
        x: &mut Vec<Vector3<f64>>,
        x0: &[Vector3<f64>],
        mode: Mode,
        base: f64,
        e_at_x: &mut Option<f64>,
    ) -> bool {
        let vmax = self.work.curv_v.iter().fold(0.0f64, |m, a| m.max(a.abs()));
        if !(vmax > 0.0 && vmax.is_finite() && base > 0.0 && base.is_finite()) {
            return false;
        }
        let e_x = e_at_x.unwrap_or_else(|| self.objective(sys, x, x0, mode));
        let t0 = base / vmax;
        let ep = self.objective_along(sys, x, x0, mode, t0);
        let em = self.objective_along(sys, x, x0, mode, -t0);
        let (mut best_t, mut best_e) = if ep <= em { (t0, ep) } else { (-t0, em) };
        // Neither side lower (or a value not finite): no move.
        if best_e.partial_cmp(&e_x) != Some(std::cmp::Ordering::Less) {
            return false;
        }
        // The parabola through (−t0, em), (0, e_x), (t0, ep): its vertex where convex.
        let curvature = ep + em - 2.0 * e_x;
        if curvature > 0.0 {
            let t = t0 * (em - ep) / (2.0 * curvature);
            let e = self.objective_along(sys, x, x0, mode, t);
            if e < best_e {
                (best_t, best_e) = (t, e);
            }
        }
        for _ in 0..DOUBLINGS {
            let e = self.objective_along(sys, x, x0, mode, 2.0 * best_t);
            if e.partial_cmp(&best_e) != Some(std::cmp::Ordering::Less) {
                break;
            }
            (best_t, best_e) = (2.0 * best_t, e);
        }
        self.objective_along(sys, x, x0, mode, best_t);
        std::mem::swap(x, &mut self.work.x_trial);
        if !self.carried.is_empty() {
            // The membranes' carried stress moves by the move's linearized strain (a step
            // that took none of the Newton direction: `Membrane::predict_stress`, α = 0).
            let from = std::mem::take(&mut self.work.x_trial);
            self.carry_stress(sys, &from, x, 0.0);
            self.work.x_trial = from;
        }
        *e_at_x = Some(best_e);
        true
    }

    /// The objective at `x` + `t` · `curv_v`, left in `x_trial` (held vertices stay).
    fn objective_along(
        &mut self,
        sys: &SolidSystem,
        x: &[Vector3<f64>],
        x0: &[Vector3<f64>],
        mode: Mode,
        t: f64,
    ) -> f64 {
        let mut trial = std::mem::take(&mut self.work.x_trial);
        self.place(sys, x, &self.work.curv_v, t, &mut trial);
        let e = self.objective(sys, &trial, x0, mode);
        self.work.x_trial = trial;
        e
    }
}

#[cfg(test)]
mod tests {
    use super::jitter;
    use crate::energy::{MembraneMaterial, shell_bending};
    use crate::integrator::{Integrator, Settings};
    use nalgebra::Vector3;

    /// A strip 1 m × 5 cm (41 × 3 vertices, 1 g each, D = 0.01 J, E t = 1000 N/m, ν = 0)
    /// hinged at both ends (each end's column held, free to turn about it), shortened by
    /// three times Euler's critical strain ε_c = π² D / (L² E t) and relaxed by damped
    /// implicit steps from flat. Nothing pushes it out of its plane: flat, every
    /// out-of-plane entry of gradient and direction is exactly zero, and the flat state is
    /// an equilibrium, a saddle past the load. Its buckled equilibrium (Euler's elastica
    /// near the load, the membrane keeping ε_c): the first mode w = A sin(πx/L) with
    /// A = (2/π) √(L (Δ − ε_c L)) = (2/π) √(2 ε_c) L = 8.94 mm. Along the first mode the
    /// elastic curvature D π⁴/L⁴ − N π²/L² = −1.95 N/m³ outweighs each step's inertia and
    /// damping (h = 2 s, c = 1/s: (1 + c h) ρ/h² ≈ 1.8 N/m³ per unit area), so the steps'
    /// objectives are indefinite there, by about 0.2 mᵢ/h², which the ladder's shifts cover
    /// (its 0.31): while the strip relaxes in its plane, only a move along that curvature
    /// leaves the flat state. Tolerance 1 %: the discrete shell at 40 cells and the sinusoid
    /// for the elastica (O(A²/L²) ≈ 1e-4); measured 8.955 mm, 0.12 % above (at 3.4 ε_c:
    /// 0.10 %).
    #[test]
    fn a_strip_compressed_past_eulers_load_buckles_into_its_elastica() {
        let (nx, ny, len, width) = (41, 3, 1.0, 0.05);
        let (e, t, d) = (2e6, 5e-4, 1e-2);
        let mat = MembraneMaterial::orthotropic(e, 0.0, t, 1.0, 1.0, 1.0);
        let (mut sys, mut state) =
            crate::verify::membrane_sheet(nx, ny, len, width, mat, Vector3::x()).unwrap();
        let tris: Vec<[u32; 3]> = sys.elements.membranes.iter().map(|m| m.v).collect();
        let bending = shell_bending(&state.x, &tris, d, 0.0).unwrap();
        sys.elements.shells = bending.vertices;
        sys.elements.midedges = bending.triangles;
        sys.damping = vec![1.0; nx * ny];
        let eps_c = std::f64::consts::PI.powi(2) * d / (len * len * e * t);
        let shortening = 3.0 * eps_c * len;
        let mut target = state.x.clone();
        for j in 0..ny {
            for i in [0, nx - 1] {
                sys.pinned[j * nx + i] = true;
            }
            target[j * nx + nx - 1].x -= shortening;
        }
        sys.layout = state.x.clone();
        let settings = Settings {
            tolerance: 1e-6,
            max_iterations: 100,
            ..Settings::default()
        };
        let mut integrator = Integrator::new(&sys).unwrap();
        let h = 2.0;
        let mut moves = 0;
        for _ in 0..200 {
            moves += integrator
                .step(&sys, &mut state, Some(&target), h, &settings)
                .unwrap()
                .curvature_moves;
            if state.v.iter().all(|v| v.norm() < 1e-7) && moves > 0 {
                break;
            }
        }
        let amplitude = 2.0 / std::f64::consts::PI * (2.0 * eps_c).sqrt() * len;
        let z = |i: usize| state.x[nx + i].z;
        let mid = z(nx / 2).abs();
        assert!(moves > 0, "no move along negative curvature");
        assert!(
            (mid / amplitude - 1.0).abs() < 0.01,
            "mid-span {mid:e} m against {amplitude:e} m"
        );
        // The first mode: one sign, a quarter of the way at sin(π/4) of the middle.
        let quarter = z(nx / 4).abs();
        assert!((1..nx - 1).all(|i| z(i) * z(nx / 2) > 0.0));
        assert!(
            (quarter / mid - std::f64::consts::FRAC_1_SQRT_2).abs() < 0.02,
            "quarter {quarter:e} m, middle {mid:e} m"
        );
    }

    #[test]
    fn the_jitter_is_centred_and_bounded() {
        let n = 10_000;
        let mean = (0..n).map(jitter).sum::<f64>() / n as f64;
        assert!(mean.abs() < 0.01, "mean {mean}");
        assert!((0..n).all(|i| (-0.5..0.5).contains(&jitter(i))));
    }
}
