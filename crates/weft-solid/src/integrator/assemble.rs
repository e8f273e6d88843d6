//! Assembly: the step's start (x̂ and the first iterate), the objective (the incremental
//! or static potential) and its gradient and Hessian at x into [`LinearSystem`]'s values,
//! element by element over the pool (the partition's parts write disjoint entries; every
//! sum is in element order, so the bits are the same at any thread count), and the
//! diagonal shifts and budgets the Newton loops add.

use super::linear::{Shared, block_entry};
use super::{Hessians, Integrator, LOCAL, Mode, NONE, PARALLEL_MIN};
use crate::energy::{Local, SharedHinges};
use crate::system::{SolidSystem, State};
use nalgebra::{Matrix2, Matrix3, Vector3};
use rayon::prelude::*;

impl Integrator {
    /// The start of an implicit step from `state` (x⁰): held vertices at their targets, x̂ for
    /// every vertex, and the first iterate `x` (the guess, else x⁰ + h v⁰).
    pub(super) fn predict(
        &mut self,
        sys: &SolidSystem,
        state: &State,
        x: &mut [Vector3<f64>],
        target: &dyn Fn(usize) -> Vector3<f64>,
        guess: Option<&[Vector3<f64>]>,
        h: f64,
    ) {
        let x0 = &state.x;
        for i in 0..self.lin.n {
            if self.held(i) {
                x[i] = target(i);
                self.work.x_hat[i] = x[i];
            } else {
                // x̂ = x⁰ + h v⁰ + h² (g + f/m): constant forces act like gravity.
                self.work.x_hat[i] =
                    x0[i] + h * state.v[i] + h * h * (sys.gravity + sys.force(i) / sys.mass[i]);
                x[i] = guess.map_or(x0[i] + h * state.v[i], |g| g[i]);
            }
        }
        if guess.is_none() {
            // A rigid group's first guess moves it rigidly: by its centroid's velocity.
            for g in &sys.rigid {
                let (mut p, mut w) = (Vector3::zeros(), 0.0);
                for &v in &g.vertices {
                    p += sys.mass[v as usize] * state.v[v as usize];
                    w += sys.mass[v as usize];
                }
                let vc = p / w;
                for &v in &g.vertices {
                    x[v as usize] = x0[v as usize] + h * vc;
                }
            }
        }
        self.retract(sys, x);
    }

    pub(super) fn objective(
        &self,
        sys: &SolidSystem,
        x: &[Vector3<f64>],
        x0: &[Vector3<f64>],
        mode: Mode,
    ) -> f64 {
        let mut e = 0.0;
        for i in 0..self.lin.n {
            if !self.held(i) {
                let m = sys.mass[i];
                e += match mode {
                    Mode::Dynamic { h } => self.vertex_energy(sys, x, x0, h, i),
                    // Static: the potential of gravity and the constant loads.
                    Mode::Static => -(m * sys.gravity + sys.force(i)).dot(&x[i]),
                };
            }
        }
        let mut per = self.work.per_element.borrow_mut();
        let parallel = per.len() >= PARALLEL_MIN && rayon::current_num_threads() > 1;
        if let Some(h) = &self.hinges {
            refresh_hinges(&mut h.borrow_mut(), x, false);
        }
        let hinges = self.hinges.as_ref().map(|h| h.borrow());
        let hinges = hinges.as_deref();
        let midedges = &self.midedges;
        let energy = |i: usize| match hinges.filter(|_| midedges.contains(&i)) {
            Some(h) => {
                let k = i - midedges.start;
                h.energy(k, &sys.elements.midedges[k])
            }
            None => sys.elements.get(i).energy(x),
        };
        if parallel {
            per.par_iter_mut()
                .enumerate()
                .for_each(|(i, pe)| *pe = energy(i));
        } else {
            for (i, pe) in per.iter_mut().enumerate() {
                *pe = energy(i);
            }
        }
        // Summed in element order: the same bits at any thread count.
        let e = per.iter().fold(e, |a, b| a + b);
        match mode {
            Mode::Dynamic { h } if !sys.sliders.is_empty() => {
                e + self.friction_energy(sys, x, x0, h)
            }
            _ => e,
        }
    }

    /// Vertex `i`'s own terms of a dynamic step's objective: inertia, damping and drag.
    pub(super) fn vertex_energy(
        &self,
        sys: &SolidSystem,
        x: &[Vector3<f64>],
        x0: &[Vector3<f64>],
        h: f64,
        i: usize,
    ) -> f64 {
        let m = sys.mass[i];
        let mut e = m / (2.0 * h * h) * (x[i] - self.work.x_hat[i]).norm_squared()
            + sys.damping(i) * m / (2.0 * h) * (x[i] - x0[i]).norm_squared();
        // Drag: (1/2h) rᵀDr with r = x − x⁰ − h u, whose gradient is D(v − u).
        if let Some(d) = sys.drag(i) {
            let r = x[i] - x0[i] - h * d.flow;
            e += 0.5 / h * r.dot(&(d.matrix * r));
        }
        e
    }

    /// The gradient and Hessian of [`Self::vertex_energy`]: a (x − x̂) + b (x − x⁰) and
    /// (a + b) I, a = m/h², b = c m/h, plus drag's D(v − u) and D/h.
    pub(super) fn vertex_terms(
        &self,
        sys: &SolidSystem,
        x: &[Vector3<f64>],
        x0: &[Vector3<f64>],
        h: f64,
        i: usize,
    ) -> (Vector3<f64>, Matrix3<f64>) {
        let m = sys.mass[i];
        let (a, b) = (m / (h * h), sys.damping(i) * m / h);
        let mut g = a * (x[i] - self.work.x_hat[i]) + b * (x[i] - x0[i]);
        let mut hess = (a + b) * Matrix3::identity();
        if let Some(d) = sys.drag(i) {
            g += d.matrix * ((x[i] - x0[i]) / h - d.flow);
            hess += d.matrix / h;
        }
        (g, hess)
    }

    /// Fills `grad` and `values` at `x`, with every element Hessian projected to PSD.
    pub(super) fn assemble(
        &mut self,
        sys: &SolidSystem,
        x: &[Vector3<f64>],
        x0: &[Vector3<f64>],
        mode: Mode,
    ) {
        self.assemble_with(sys, x, x0, mode, Hessians::Projected);
    }

    /// Fills `grad` and `values` at `x` with the chosen element Hessians.
    pub(super) fn assemble_with(
        &mut self,
        sys: &SolidSystem,
        x: &[Vector3<f64>],
        x0: &[Vector3<f64>],
        mode: Mode,
        hessians: Hessians,
    ) {
        self.work.grad.iter_mut().for_each(|g| *g = 0.0);
        self.lin.values.iter_mut().for_each(|v| *v = 0.0);
        self.force_scale = 0.0;
        if !self.groups.is_empty() {
            self.assemble_members(sys, x, x0, mode);
        }
        for i in 0..self.lin.n {
            let f = self.lin.free_of[i];
            if f == NONE {
                continue;
            }
            let m = sys.mass[i];
            let (g, diag) = match mode {
                Mode::Dynamic { h } => {
                    let (a, b) = (m / (h * h), sys.damping(i) * m / h);
                    (a * (x[i] - self.work.x_hat[i]) + b * (x[i] - x0[i]), a + b)
                }
                Mode::Static => (-(m * sys.gravity + sys.force(i)), 0.0),
            };
            let f = f as usize;
            let mut g = g;
            if let (Mode::Dynamic { h }, Some(d)) = (mode, sys.drag(i)) {
                // Gradient D(v − u), Hessian D/h: a full 3×3 diagonal block.
                g += d.matrix * ((x[i] - x0[i]) / h - d.flow);
                let block = self.lin.block_mut(f, self.lin.diag_slot[f] as usize);
                for (v, m) in block.iter_mut().zip(d.matrix.as_slice()) {
                    *v += m / h;
                }
            }
            for c in 0..3 {
                self.work.grad[3 * f + c] += g[c];
                let k = self.lin.diagonal_entry(f, c);
                self.lin.values[k] += diag;
            }
            self.force_scale += g.abs().sum();
        }
        let parallel = rayon::current_num_threads() > 1;
        if let Some(h) = self.hinges.as_mut() {
            refresh_hinges(h.get_mut(), x, true);
        }
        let values = Shared(self.lin.values.as_mut_ptr());
        let grad = Shared(self.work.grad.as_mut_ptr());
        let mut per = self.work.per_element.borrow_mut();
        let scale = Shared(per.as_mut_ptr());
        let (free_of, col_ptr, slots, offsets) = (
            &self.lin.free_of,
            &self.lin.col_ptr,
            &self.lin.slots,
            &self.lin.slot_offset,
        );
        let hinges_ref = self.hinges.as_ref().map(|h| h.borrow());
        let hinges = hinges_ref.as_deref();
        let midedges = &self.midedges;
        let budget = &self.budget;
        let carried = &self.carried;
        let work = |&ei: &u32| {
            LOCAL.with(|l| {
                let local = &mut **l.borrow_mut();
                let ei = ei as usize;
                let el = sys.elements.get(ei);
                // Midedge bending's Hessian is its Gauss–Newton term in both modes.
                match (hinges.filter(|_| midedges.contains(&ei)), hessians) {
                    (Some(h), _) => {
                        let k = ei - midedges.start;
                        h.eval(k, &sys.elements.midedges[k], local);
                    }
                    (None, Hessians::Projected) => el.eval(x, true, local),
                    (None, Hessians::First) if ei < carried.len() => {
                        sys.elements.membranes[ei].eval_carried(x, &carried[ei], local)
                    }
                    (None, Hessians::First) => el.eval_first(x, local),
                    (None, Hessians::Contact) if ei < carried.len() => sys.elements.membranes[ei]
                        .eval_contact_carried(x, budget[ei], &carried[ei], local),
                    (None, Hessians::Contact) => el.eval_contact(x, budget[ei], local),
                }
                // SAFETY: see `Shared`: elements run concurrently write disjoint entries, and
                // `per_element[ei]` belongs to this element alone.
                unsafe {
                    scatter(
                        el.vertices(),
                        local,
                        free_of,
                        col_ptr,
                        &slots[offsets[ei]..],
                        values,
                        grad,
                        scale.at(ei),
                    )
                };
            })
        };
        self.lin.parts.run(&work, parallel);
        drop(per);
        drop(hinges_ref);
        self.lin.mirror_upper();
        if !self.groups.is_empty() {
            // Elements with a member: through the groups' Jacobians, in element order.
            // The scratch moves out by its box (a `Local` is 73 kB: moving it by value per
            // element cost more than the element).
            let mut local = self.groups.local.take().unwrap_or_default();
            for k in 0..self.groups.elements.len() {
                let ei = self.groups.elements[k] as usize;
                let el = sys.elements.get(ei);
                match hessians {
                    Hessians::Projected => el.eval(x, true, &mut local),
                    Hessians::First if ei < self.carried.len() => {
                        sys.elements.membranes[ei].eval_carried(x, &self.carried[ei], &mut local)
                    }
                    Hessians::First => el.eval_first(x, &mut local),
                    Hessians::Contact if ei < self.carried.len() => sys.elements.membranes[ei]
                        .eval_contact_carried(x, self.budget[ei], &self.carried[ei], &mut local),
                    Hessians::Contact => el.eval_contact(x, self.budget[ei], &mut local),
                }
                let k3 = 3 * el.vertices().len();
                self.work.per_element.borrow_mut()[ei] =
                    local.grad[..k3].iter().map(|g| g.abs()).sum::<f64>();
                self.add_element_through_groups(el.vertices(), &local);
            }
            self.groups.local = Some(local);
            self.finish_groups(hessians);
        }
        let per = self.work.per_element.borrow();
        self.force_scale = per.iter().fold(self.force_scale, |a, b| a + b);
        drop(per);
        self.filter_sliders(sys, x, x0, mode);
    }

    /// The rigid groups' members' own terms (inertia, damping, drag, or the static loads),
    /// through their groups' Jacobians at `x` (`rigid.rs`).
    pub(super) fn assemble_members(
        &mut self,
        sys: &SolidSystem,
        x: &[Vector3<f64>],
        x0: &[Vector3<f64>],
        mode: Mode,
    ) {
        self.groups.centers(sys, x);
        for g in 0..self.groups.members.len() {
            for k in 0..self.groups.members[g].len() {
                let i = self.groups.members[g][k] as usize;
                let m = sys.mass[i];
                let (g, hess) = match mode {
                    Mode::Dynamic { h } => self.vertex_terms(sys, x, x0, h, i),
                    Mode::Static => (-(m * sys.gravity + sys.force(i)), Matrix3::zeros()),
                };
                self.force_scale += g.abs().sum();
                self.add_member_terms(i, &g, &hess);
            }
        }
    }

    pub(super) fn shift_diagonal(&mut self, mu: f64) {
        // Adding zero changes no entry: skip the pass (every factorization asks for it).
        if mu != 0.0 {
            self.add_to_diagonal(|_| mu);
        }
    }

    /// Adds `mu(i)` to the three diagonal entries of every free vertex i (and through J to
    /// the rigid groups' nodes).
    pub(super) fn add_to_diagonal(&mut self, mu: impl Fn(usize) -> f64) {
        if !self.groups.is_empty() {
            self.add_to_group_diagonals(&mu);
        }
        for i in 0..self.lin.n {
            let f = self.lin.free_of[i];
            if f == NONE {
                continue;
            }
            let mu = mu(i);
            for c in 0..3 {
                let k = self.lin.diagonal_entry(f as usize, c);
                self.lin.values[k] += mu;
            }
        }
    }

    /// Fills `budget` for [`Hessians::Contact`]: element e may keep negative curvature down
    /// to −α minᵢ (mᵢ/h²)/nᵢ over its vertices i, nᵢ the number of elements at i that
    /// spend a budget. Their sum is then at least −α M/h² and, every other element's
    /// Hessian being PSD (rods aside: their exact Hessians are not bounded), the contact
    /// step's matrix at least (1 − α) M/h² plus the contacts' terms: positive definite
    /// without a factorization to prove it, and the step's elastic model convex, which
    /// ADMM needs (on the exact, indefinite one it diverged). Filled again only when h or α
    /// changes.
    pub(super) fn fill_budget(&mut self, sys: &SolidSystem, h: f64, alpha: f64) {
        let n = sys.elements.len();
        if self.budget_for == (h, alpha) && self.budget.len() == n {
            return;
        }
        let mut count = vec![0u32; sys.mass.len()];
        for ei in 0..n {
            let el = sys.elements.get(ei);
            if el.spends_budget() {
                for &v in el.vertices() {
                    count[v as usize] += 1;
                }
            }
        }
        self.budget.clear();
        self.budget.resize(n, 0.0);
        for (ei, b) in self.budget.iter_mut().enumerate() {
            let el = sys.elements.get(ei);
            if el.spends_budget() {
                *b = el
                    .vertices()
                    .iter()
                    .map(|&v| alpha * sys.mass[v as usize] / (h * h * count[v as usize] as f64))
                    .fold(f64::INFINITY, f64::min);
            }
        }
        self.budget_for = (h, alpha);
    }

    /// Adds `kappa` · mᵢ/h² to every free vertex's diagonal block.
    pub(super) fn shift_inertia(&mut self, sys: &SolidSystem, h: f64, kappa: f64) {
        self.add_to_diagonal(|i| kappa * sys.mass[i] / (h * h));
    }

    /// Starts the membranes' carried stresses at the stresses at `x0` (the last step's
    /// converged state: its stress is the mixed form's warm start, where the first guess's
    /// is an overshoot), or clears them where the step does not carry any.
    pub(super) fn start_carried(&mut self, sys: &SolidSystem, x0: &[Vector3<f64>], carry: bool) {
        self.carried.clear();
        if carry {
            let ms = &sys.elements.membranes;
            self.carried.extend(ms.iter().map(|m| m.stress_at(x0)));
        }
    }

    /// Moves the carried stresses by the step just taken from `from` to `to` at the fraction
    /// `alpha` of its direction (`Membrane::predict_stress`).
    pub(super) fn carry_stress(
        &mut self,
        sys: &SolidSystem,
        from: &[Vector3<f64>],
        to: &[Vector3<f64>],
        alpha: f64,
    ) {
        let ms = &sys.elements.membranes;
        let update = |(s, m): (&mut Matrix2<f64>, &crate::energy::Membrane)| {
            *s = m.predict_stress(from, to, s, alpha);
        };
        // Each stress on its own: the same bits at any thread count.
        if ms.len() >= PARALLEL_MIN && rayon::current_num_threads() > 1 {
            self.carried
                .par_iter_mut()
                .zip(ms.par_iter())
                .for_each(update);
        } else {
            self.carried.iter_mut().zip(ms.iter()).for_each(update);
        }
    }
}

/// The hinge table's angles (and gradients where `with_grad`) at `x`, over the pool from
/// [`PARALLEL_MIN`] hinges.
fn refresh_hinges(h: &mut SharedHinges, x: &[Vector3<f64>], with_grad: bool) {
    let parallel = rayon::current_num_threads() > 1 && h.len() >= PARALLEL_MIN;
    h.update(x, with_grad, parallel);
}

/// Adds one element's gradient and Hessian, evaluated into `local` on the stencil `v`, into
/// the shared arrays; `scale` receives Σ|gradient entries|.
///
/// # Safety
/// No other thread may write the entries this element touches while it runs (the assembly
/// tree guarantees it), and the pointers must cover the integrator's arrays.
#[allow(clippy::too_many_arguments)]
unsafe fn scatter(
    v: &[u32],
    local: &Local,
    free_of: &[u32],
    col_ptr: &[usize],
    slots: &[u32],
    values: Shared,
    grad: Shared,
    scale: *mut f64,
) {
    let k = v.len();
    unsafe {
        *scale = local.grad[..3 * k].iter().map(|g| g.abs()).sum::<f64>();
        for (a, &va) in v.iter().enumerate() {
            let fa = free_of[va as usize];
            if fa != NONE {
                for r in 0..3 {
                    *grad.at(3 * fa as usize + r) += local.grad[3 * a + r];
                }
            }
        }
        for (b, &vb) in v.iter().enumerate() {
            let fb = free_of[vb as usize];
            for a in 0..k {
                let s = slots[b * k + a];
                if s == NONE {
                    continue;
                }
                let base = block_entry(col_ptr, fb as usize, s as usize, 0, 0);
                for cc in 0..3 {
                    for rr in 0..3 {
                        *values.at(base + 3 * cc + rr) += local.hess[3 * b + cc][3 * a + rr];
                    }
                }
            }
        }
    }
}
