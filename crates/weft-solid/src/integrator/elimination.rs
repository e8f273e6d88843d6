//! Nonlinear elimination of the few vertices whose Newton corrections lag the rest: after
//! each Newton step, a small Newton solve on a patch around each of them, the rest of the
//! cloth held (Lanzkron, Rose & Wilkes, "An analysis of approximate nonlinear elimination",
//! SIAM J. Sci. Comput., 1996; Cai & Li, "Inexact Newton methods with restricted additive
//! Schwarz based nonlinear elimination for problems with high local nonlinearity", SIAM J.
//! Sci. Comput., 2011).
//!
//! Why: the stopping test reads the largest vertex correction (‖Δx‖∞/h), and on a hanging
//! cloth after the first iteration that largest one sits on one to a handful of vertices —
//! next to a pinned corner, on the taut edge between the pins, or where a fold turns —
//! while the median vertex's correction is one to three orders of magnitude smaller and
//! falls faster (traced on cloth_hang; figures in docs/history/issue-71-comments.md). Their
//! local energy is the most nonlinear part of the scene, and the global Newton step, linear
//! in all vertices at once, covers only part of their way each iteration. Solving the local
//! problem (each patch's own Newton on its vertices with the inertia and every element
//! touching them) takes them the rest of the way for the cost of a few dense 57 × 57
//! solves, and the next global iteration sees a nearly linear problem again.
//!
//! The patch is the lagging vertex's two-ring (the vertices sharing a membrane with it and
//! with those; capped at [`MAX_PATCH`] vertices), chosen where a vertex's step was at least
//! [`LAG_OF_TOP`] of the largest and [`LAG_OF_MEDIAN`] times the median, at most
//! [`PATCHES`] a Newton iteration, and only while the largest step is above the tolerance.
//! Each local iteration assembles the patch's gradient and Hessian from the elements'
//! first Hessians (exact membranes, bending's Gauss–Newton term) and the inertia; where the
//! dense Cholesky fails, inertia is added as the global ladder does; an Armijo line search on
//! the patch's objective (its vertices' inertia terms and every element touching them: the
//! whole objective's change when only they move) keeps every move a descent. The loop's
//! tests still read the global Newton correction, measured before the patches move: its
//! rate's test (`rate.rs`) then reads the contraction of Newton and elimination together,
//! and a loop it ends keeps that iteration's patch moves, which its estimate does not
//! measure (traced: where the rate ends a loop, the next Newton correction is nearly always
//! below the tolerance, with the elimination as without it). Cloth only
//! ([`Integrator::eliminates`]: on hair it does not pay), not for rigid groups' or sliders'
//! nodes (their moves go through `move_members` and `retract`), nor in the contact step (a
//! local move would not see the contacts).
//!
//! On cloth_hang it cuts the Newton iterations and factorizations a step, at one substep as
//! at two; at the example's tolerance it ends a little farther from the converged run where
//! the cloth buckles, but at a tighter one that costs it no more iterations than the plain
//! loop took, nearer. The sheets of `bench/sheet_graph.py`, whose slow part is a band of tens
//! to hundreds of vertices along the edge between the pins and the folds rather than a
//! handful, gain nothing. The examples' `--stats-json` and `bench/sheet_graph.py` measure
//! it; figures in docs/history/issue-71-comments.md.

use super::{Integrator, NONE, shift_ladder};
use crate::energy::Local;
use crate::system::SolidSystem;
use nalgebra::Vector3;

/// Patches solved after one Newton step at most.
const PATCHES: usize = 8;
/// A vertex lags when its step is at least this fraction of the largest step…
const LAG_OF_TOP: f64 = 0.3;
/// …and at least this many times the median vertex's.
const LAG_OF_MEDIAN: f64 = 10.0;
/// Local Newton iterations on one patch at most.
const LOCAL_ITERATIONS: usize = 3;
/// Most vertices in a patch (a regular grid's two-ring has 19).
pub(super) const MAX_PATCH: usize = 32;
/// Line-search halvings of a local step at most.
const HALVINGS: usize = 8;

/// The adjacency and work buffers of the elimination, built once per system.
#[derive(Default)]
pub(super) struct Elimination {
    /// Vertex → the elements (in `Elements::for_each` order) whose stencils hold it
    /// (compressed rows: `elements[element_ptr[v]..element_ptr[v + 1]]`).
    element_ptr: Vec<usize>,
    elements: Vec<u32>,
    /// Vertex → the free vertices that share a membrane with it, itself excluded.
    ring_ptr: Vec<usize>,
    ring: Vec<u32>,
    /// Per free vertex: its step (largest coordinate) and index, for the choice.
    steps: Vec<(f64, u32)>,
    /// Vertex → its index in the patch being solved (NONE elsewhere).
    slot: Vec<u32>,
    /// Vertices already in a patch this iteration, and the list of them.
    covered: Vec<bool>,
    touched: Vec<u32>,
    /// Elements already listed for the patch being solved.
    listed: Vec<bool>,
    patch: Vec<u32>,
    patch_elements: Vec<u32>,
    /// Dense patch system (column-major, 3p × 3p), its factor, gradient, step, start.
    hess: Vec<f64>,
    factor: Vec<f64>,
    grad: Vec<f64>,
    step: Vec<f64>,
    start: Vec<Vector3<f64>>,
    /// Element scratch, allocated on first use.
    local: Option<Box<Local>>,
}

impl Elimination {
    fn build(&mut self, sys: &SolidSystem, free_of: &[u32]) {
        let n = free_of.len();
        let mut count = vec![0usize; n + 1];
        sys.elements.for_each(|el| {
            for &v in el.vertices() {
                count[v as usize + 1] += 1;
            }
        });
        for v in 0..n {
            count[v + 1] += count[v];
        }
        let mut fill = count.clone();
        let mut elements = vec![0u32; count[n]];
        let mut i = 0u32;
        sys.elements.for_each(|el| {
            for &v in el.vertices() {
                elements[fill[v as usize]] = i;
                fill[v as usize] += 1;
            }
            i += 1;
        });
        let membranes = sys.elements.membranes.len();
        let mut ring_ptr = vec![0usize; n + 1];
        let mut ring = Vec::new();
        let mut seen = vec![false; n];
        for v in 0..n {
            let mut near: Vec<u32> = Vec::new();
            for &e in &elements[count[v]..count[v + 1]] {
                let e = e as usize;
                if e >= membranes {
                    continue;
                }
                for &u in sys.elements.get(e).vertices() {
                    if u as usize != v && free_of[u as usize] != NONE && !seen[u as usize] {
                        seen[u as usize] = true;
                        near.push(u);
                    }
                }
            }
            for &u in &near {
                seen[u as usize] = false;
            }
            near.sort_unstable();
            ring.extend_from_slice(&near);
            ring_ptr[v + 1] = ring.len();
        }
        self.element_ptr = count;
        self.elements = elements;
        self.ring_ptr = ring_ptr;
        self.ring = ring;
        self.slot = vec![NONE; n];
        self.covered = vec![false; n];
        self.listed = vec![false; sys.elements.len()];
        let dofs = 3 * MAX_PATCH;
        self.hess = vec![0.0; dofs * dofs];
        self.factor = vec![0.0; dofs * dofs];
        self.grad = vec![0.0; dofs];
        self.step = vec![0.0; dofs];
        self.start = vec![Vector3::zeros(); MAX_PATCH];
    }

    fn ring_of(&self, v: usize) -> &[u32] {
        &self.ring[self.ring_ptr[v]..self.ring_ptr[v + 1]]
    }

    /// The patch around `v` (its two-ring, capped at MAX_PATCH, in a fixed order) and the
    /// elements touching it, each listed once.
    fn gather(&mut self, v: usize) {
        self.patch.clear();
        self.patch.push(v as u32);
        self.slot[v] = 0;
        let mut k = 0;
        while k < self.patch.len() && k < 1 + self.ring_of(v).len() {
            let u = self.patch[k] as usize;
            for j in self.ring_ptr[u]..self.ring_ptr[u + 1] {
                let w = self.ring[j] as usize;
                if self.slot[w] == NONE && self.patch.len() < MAX_PATCH {
                    self.slot[w] = self.patch.len() as u32;
                    self.patch.push(w as u32);
                }
            }
            k += 1;
        }
        self.patch_elements.clear();
        for k in 0..self.patch.len() {
            let u = self.patch[k] as usize;
            for j in self.element_ptr[u]..self.element_ptr[u + 1] {
                let e = self.elements[j];
                if !self.listed[e as usize] {
                    self.listed[e as usize] = true;
                    self.patch_elements.push(e);
                }
            }
        }
        self.patch_elements.sort_unstable();
        for &e in &self.patch_elements {
            self.listed[e as usize] = false;
        }
    }

    /// Clears the patch's slots.
    fn release(&mut self) {
        for &u in &self.patch {
            self.slot[u as usize] = NONE;
        }
    }
}

/// In-place Cholesky of the leading n × n block of `a` (column-major, leading dimension
/// `ld`, lower triangle read and written); false if it is not positive definite.
fn cholesky(a: &mut [f64], n: usize, ld: usize) -> bool {
    for j in 0..n {
        let mut d = a[j * ld + j];
        for k in 0..j {
            d -= a[k * ld + j] * a[k * ld + j];
        }
        if d.is_nan() || d <= 0.0 {
            return false;
        }
        let d = d.sqrt();
        a[j * ld + j] = d;
        for i in j + 1..n {
            let mut s = a[j * ld + i];
            for k in 0..j {
                s -= a[k * ld + i] * a[k * ld + j];
            }
            a[j * ld + i] = s / d;
        }
    }
    true
}

/// x ← (L Lᵀ)⁻¹ x with the factor of [`cholesky`].
fn solve(l: &[f64], n: usize, ld: usize, x: &mut [f64]) {
    for j in 0..n {
        x[j] /= l[j * ld + j];
        let xj = x[j];
        for i in j + 1..n {
            x[i] -= l[j * ld + i] * xj;
        }
    }
    for j in (0..n).rev() {
        let mut s = x[j];
        for i in j + 1..n {
            s -= l[j * ld + i] * x[i];
        }
        x[j] = s / l[j * ld + j];
    }
}

impl Integrator {
    /// Whether this system's Newton steps solve lagging patches: cloth (membranes, no rods,
    /// the scenes it was measured on: on hair it gains little or costs iterations, as
    /// `bench/ensemble.py` on hair_pile and the hair examples' counts show; figures in
    /// docs/history/issue-71-comments.md), and no rigid groups or sliders.
    pub(super) fn eliminates(&self, sys: &SolidSystem) -> bool {
        let e = &sys.elements;
        !e.membranes.is_empty()
            && e.stretches.is_empty()
            && e.bends.is_empty()
            && e.clamps.is_empty()
            && self.curvature_moves(sys)
    }

    /// After a Newton step of `alpha` × `self.work.dir` that ended at `x` (time step `h`): local
    /// Newton on the patches around the vertices that lag (see the module's doc). Returns the
    /// patches moved. `scale` turns a displacement into the residual the tolerance reads.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn eliminate(
        &mut self,
        sys: &SolidSystem,
        x: &mut [Vector3<f64>],
        x0: &[Vector3<f64>],
        h: f64,
        alpha: f64,
        scale: f64,
        tolerance: f64,
    ) -> usize {
        let mut el = std::mem::take(&mut self.elimination);
        // Built once per system (an integrator serves one system; the element count is
        // checked as well as the vertex count).
        if el.slot.len() != self.lin.n || el.listed.len() != sys.elements.len() {
            el.build(sys, &self.lin.free_of);
        }
        el.steps.clear();
        for (v, &f) in self.lin.free_of.iter().enumerate() {
            if f != NONE {
                let f = 3 * f as usize;
                let d = &self.work.dir[f..f + 3];
                let s = alpha * d[0].abs().max(d[1].abs()).max(d[2].abs());
                el.steps.push((s, v as u32));
            }
        }
        let count = el.steps.len();
        if count == 0 {
            self.elimination = el;
            return 0;
        }
        // The largest step and the median (the ⌈count/2⌉-th largest) without sorting every
        // vertex: the k-th value is the same whichever order selection leaves.
        let top = el.steps.iter().fold(0.0f64, |m, s| m.max(s.0));
        let nth = count - 1 - count / 2;
        let median = el
            .steps
            .select_nth_unstable_by(nth, |a, b| a.0.total_cmp(&b.0))
            .1
            .0;
        let bar = (LAG_OF_TOP * top).max(LAG_OF_MEDIAN * median);
        let mut moved = 0;
        if top * scale > tolerance && top.is_finite() {
            // The lagging vertices, largest first, ties by index: a fixed order.
            el.steps.retain(|s| s.0 >= bar);
            el.steps
                .sort_unstable_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
            // The element scratch lives in `Elimination` (a Local is 74 KB: not rebuilt per call).
            let mut local = el.local.take().unwrap_or_default();
            let mut patches = 0;
            for k in 0..el.steps.len() {
                if patches == PATCHES {
                    break;
                }
                let v = el.steps[k].1 as usize;
                if el.covered[v] {
                    continue;
                }
                el.gather(v);
                for &u in &el.patch {
                    el.covered[u as usize] = true;
                }
                el.touched.extend_from_slice(&el.patch);
                patches += 1;
                if self.solve_patch(sys, &mut el, x, x0, h, tolerance, &mut local) {
                    moved += 1;
                }
                el.release();
            }
            for k in 0..el.touched.len() {
                el.covered[el.touched[k] as usize] = false;
            }
            el.touched.clear();
            el.local = Some(local);
        }
        self.elimination = el;
        moved
    }

    /// The patch's objective: its vertices' inertia, damping and drag terms and the energy
    /// of every element touching it.
    fn patch_objective(
        &self,
        sys: &SolidSystem,
        el: &Elimination,
        x: &[Vector3<f64>],
        x0: &[Vector3<f64>],
        h: f64,
    ) -> f64 {
        let mut e = 0.0;
        for &v in &el.patch {
            e += self.vertex_energy(sys, x, x0, h, v as usize);
        }
        for &k in &el.patch_elements {
            e += sys.elements.get(k as usize).energy(x);
        }
        e
    }

    /// Local Newton on `el`'s patch, the other vertices held; whether it moved.
    #[allow(clippy::too_many_arguments)]
    fn solve_patch(
        &self,
        sys: &SolidSystem,
        el: &mut Elimination,
        x: &mut [Vector3<f64>],
        x0: &[Vector3<f64>],
        h: f64,
        tolerance: f64,
        local: &mut Local,
    ) -> bool {
        let p = el.patch.len();
        let n3 = 3 * p;
        let ld = 3 * MAX_PATCH;
        let mut moved = false;
        // The patch's objective at `x`, once known (the last accepted trial's).
        let mut e_now = None;
        for _ in 0..LOCAL_ITERATIONS {
            el.grad[..n3].fill(0.0);
            for j in 0..n3 {
                el.hess[j * ld..j * ld + n3].fill(0.0);
            }
            for (a, &v) in el.patch.iter().enumerate() {
                let (g, hv) = self.vertex_terms(sys, x, x0, h, v as usize);
                for r in 0..3 {
                    el.grad[3 * a + r] += g[r];
                    for q in 0..3 {
                        el.hess[(3 * a + q) * ld + 3 * a + r] += hv[(r, q)];
                    }
                }
            }
            for k in 0..el.patch_elements.len() {
                let e = sys.elements.get(el.patch_elements[k] as usize);
                e.eval_first(x, local);
                let vs = e.vertices();
                for (ka, &va) in vs.iter().enumerate() {
                    let ia = el.slot[va as usize];
                    if ia == NONE {
                        continue;
                    }
                    let ia = 3 * ia as usize;
                    for r in 0..3 {
                        el.grad[ia + r] += local.grad[3 * ka + r];
                    }
                    for (kb, &vb) in vs.iter().enumerate() {
                        let ib = el.slot[vb as usize];
                        if ib == NONE {
                            continue;
                        }
                        let ib = 3 * ib as usize;
                        for q in 0..3 {
                            let col = &local.hess[3 * kb + q];
                            for r in 0..3 {
                                el.hess[(ib + q) * ld + ia + r] += col[3 * ka + r];
                            }
                        }
                    }
                }
            }
            // The exact Hessian where positive definite, else with inertia added as the
            // global ladder adds it (relative to each vertex's m/h²).
            let mut factored = false;
            let mut added = 0.0;
            for kappa in std::iter::once(0.0).chain(shift_ladder(0.0)) {
                added += kappa;
                for j in 0..n3 {
                    let col = j * ld;
                    el.factor[col..col + n3].copy_from_slice(&el.hess[col..col + n3]);
                    el.factor[col + j] += added * sys.mass[el.patch[j / 3] as usize] / (h * h);
                }
                if cholesky(&mut el.factor, n3, ld) {
                    factored = true;
                    break;
                }
            }
            if !factored {
                break;
            }
            for j in 0..n3 {
                el.step[j] = -el.grad[j];
            }
            solve(&el.factor, n3, ld, &mut el.step[..n3]);
            let slope: f64 = (0..n3).map(|j| el.grad[j] * el.step[j]).sum();
            let size = el.step[..n3].iter().fold(0.0f64, |m, s| m.max(s.abs()));
            // Converged locally (a tenth of what the tolerance reads), or no descent.
            if slope.is_nan() || slope >= 0.0 || !size.is_finite() || size < 0.1 * tolerance * h {
                break;
            }
            let e0 = e_now.unwrap_or_else(|| self.patch_objective(sys, el, x, x0, h));
            for (a, &v) in el.patch.iter().enumerate() {
                el.start[a] = x[v as usize];
            }
            let mut alpha = 1.0;
            let mut accepted = false;
            for _ in 0..=HALVINGS {
                for (a, &v) in el.patch.iter().enumerate() {
                    let d = Vector3::new(el.step[3 * a], el.step[3 * a + 1], el.step[3 * a + 2]);
                    x[v as usize] = el.start[a] + alpha * d;
                }
                let e1 = self.patch_objective(sys, el, x, x0, h);
                if e1 <= e0 + 1e-4 * alpha * slope {
                    e_now = Some(e1);
                    accepted = true;
                    break;
                }
                alpha *= 0.5;
            }
            if !accepted {
                for (a, &v) in el.patch.iter().enumerate() {
                    x[v as usize] = el.start[a];
                }
                break;
            }
            moved = true;
        }
        moved
    }
}

#[cfg(test)]
mod tests {
    use super::{MAX_PATCH, cholesky, solve};
    use crate::integrator::{Integrator, Mode, order};

    /// A resting 8 × 8 sheet (1 m, held at two corners, no gravity so rest is the answer)
    /// with one interior vertex pushed 1 mm out of its plane and reported as the one
    /// lagging vertex of a Newton step: its patch alone is solved. The patch's minimum with
    /// the rest held is the rest state (every element and the inertia are at their minimum
    /// there), so the vertex returns to rest within the local loop's own stopping size
    /// (measured 1.2e-10 m; from 5 mm three local iterations leave 7e-5 m, the membrane's
    /// stretch d²/2L making the first ones linear), the objective falls, and every vertex
    /// outside the patch keeps its bits.
    #[test]
    fn a_lagging_vertex_is_solved_back_to_rest_by_its_patch_alone() {
        let k = 8;
        let (mut sys, state) = order::tests::shell_sheet(k, 1e-3);
        sys.gravity = nalgebra::Vector3::zeros();
        let mut it = Integrator::new(&sys).unwrap();
        let h = 1.0 / 48.0;
        it.work.x_hat = state.x.clone();
        let v = 3 * k + 4;
        let mut x = state.x.clone();
        x[v].z += 1e-3;
        let mode = Mode::Dynamic { h };
        let before = it.objective(&sys, &x, &state.x, mode);
        it.work.dir.fill(0.0);
        let f = 3 * it.lin.free_of[v] as usize;
        it.work.dir[f + 2] = 1e-2;
        let moved = it.eliminate(&sys, &mut x, &state.x, h, 1.0, 1.0 / h, 1e-6);
        assert_eq!(moved, 1);
        // The local loop stops once its next step is below a tenth of the tolerance's
        // displacement (0.1 · 1e-6 m/s · h = 2.1e-9 m), near enough its converged answer.
        let left = (x[v] - state.x[v]).norm();
        assert!(left < 0.1 * 1e-6 * h, "{left:e} m");
        assert!(it.objective(&sys, &x, &state.x, mode) < before);
        let patch = &it.elimination.patch;
        assert!(
            patch.len() >= 13 && patch.len() <= MAX_PATCH,
            "{}",
            patch.len()
        );
        for (u, (p, q)) in x.iter().zip(&state.x).enumerate() {
            if !patch.contains(&(u as u32)) {
                assert_eq!(p, q, "vertex {u} outside the patch moved");
            }
        }
    }

    /// The dense kernels solve an SPD system to rounding and refuse an indefinite one.
    #[test]
    fn the_patch_kernels_solve_spd_systems_and_refuse_indefinite_ones() {
        let (n, ld) = (3, 4);
        // A = [[4, 2, 0], [2, 5, 1], [0, 1, 3]], x = [1, -2, 3], b = A x = [0, -5, 7].
        let mut a = vec![0.0; ld * ld];
        let rows = [[4.0, 2.0, 0.0], [2.0, 5.0, 1.0], [0.0, 1.0, 3.0]];
        for (i, row) in rows.iter().enumerate() {
            for (j, &v) in row.iter().enumerate() {
                a[j * ld + i] = v;
            }
        }
        assert!(cholesky(&mut a, n, ld));
        let mut b = [0.0, -5.0, 7.0];
        solve(&a, n, ld, &mut b);
        for (got, want) in b.iter().zip([1.0, -2.0, 3.0]) {
            assert!((got - want).abs() < 1e-14, "{got} against {want}");
        }
        let mut indefinite = vec![1.0, 2.0, 0.0, 0.0, 2.0, 1.0, 0.0, 0.0];
        assert!(!cholesky(&mut indefinite, 2, 4));
    }
}
