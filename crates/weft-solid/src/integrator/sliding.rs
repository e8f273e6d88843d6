//! The Newton solve's side of sliding attachments ([`crate::slide`]): the filter that keeps
//! each sliding vertex's direction along its rail, and the retraction that puts its trial
//! positions back on the rail.

use nalgebra::{Matrix3, Vector3};

use super::rate::RateStop;
use super::{Integrator, Mode, NONE, block_entry};
use crate::settings::Settings;
use crate::slide::{FRICTION_EPS_V, friction_f0_f1, place, projector};
use crate::system::SolidSystem;

/// What sliders' friction reads its normal force from: the force each target supplies as
/// the Newton model predicts it at the iterate, not as the iterate's gradient reads it.
///
/// The target's force is the part of the gradient on the sliding node its filter removes:
/// at a converged step, the constraint's reaction. Read at an iterate it is the reaction
/// plus whatever the stiffest element next to the node is out of balance: a strand's
/// stretch (EA/L = 1.8e5 N/m against its root's m/h² of 0.61 N/m) turns a position error of
/// tol·h = 2e-6 m into 0.35 N on a strand weighing 0.04 N, so friction read from it holds a
/// root that should slide and stalls Newton (`graphs/curtain_rail.json` and a strand whose
/// root slides show it). After a step α·d the model predicts g + αH·d on the node: for a
/// full step the free rows' imbalance is met and only the model's error, second order in
/// the step, is left (the multiplier estimate of sequential quadratic programming); a
/// shortened step leaves (1 − α) of the iterate's. H is the matrix before the filter,
/// friction and inertia shifts: friction and the filter act along the target (P) and the
/// shifts are isotropic on a node whose step is along it, so none has a normal part; d is
/// taken along each slider's target (P d), as the retraction leaves it (a contact step's
/// direction has a normal part there: its contact terms act after the filter).
/// Each step starts from the gradient at its first iterate, or, in a step iterated to its
/// tolerance, without friction for a stiffly held node (`STIFF_NODE`; that iteration never
/// ends the step): nothing is carried from one step to the next, so a step still depends
/// on its inputs alone (resuming from any checkpoint gives the same bits). Kept only for
/// sliders with friction in dynamic steps (frictionless sliders' stops read the gradient).
/// In a contact step the contact force on the node is not in the prediction (nor was it in
/// the gradient read before), and an extrapolated step (α up to 20) extrapolates the
/// force with it.
#[derive(Default)]
pub(super) struct SlideForces {
    /// Per slider: its node at the last assembly, or NONE (no friction to read it, a static
    /// step, or no node: its vertex held).
    node: Vec<u32>,
    /// Per slider: the gradient on its node at the last assembly, before the filter and
    /// friction.
    grad: Vec<Vector3<f64>>,
    /// Per slider: its node's column of the matrix at the last assembly, before the filter
    /// and friction, as (row node, block) from `start[k]` to `start[k + 1]`.
    column: Vec<(u32, Matrix3<f64>)>,
    start: Vec<usize>,
    /// Per slider: the gradient on its node the model predicts at the iterate (None: read
    /// the gradient).
    predicted: Vec<Option<Vector3<f64>>>,
    /// Whether a stiffly held node's first iteration may run without friction (not in a
    /// linearized step, whose one iteration is its answer).
    free_first: bool,
    /// Whether the last assembly left a frictional slider's friction out (its first
    /// iteration): its step may not end there, below the tolerance or not — a strand at
    /// rest on a rail tilted by less than tol/(h g) would otherwise take every step
    /// without friction and slide where it should stick.
    pub(super) frictionless: bool,
    /// Per slider: the normal force its friction read in the last iteration (NaN: none yet
    /// in this step).
    used: Vec<f64>,
    /// The largest change of a frictional slider's normal force from the last iteration's
    /// to this one's, as the velocity μ ΔN h / m it makes on its node (NaN in a step's first
    /// iteration and after one that left friction out; zero with no frictional slider).
    pub(super) change: f64,
}

impl SlideForces {
    /// Sized for `n` sliders at an assembly's start: no column kept, no node, nothing left
    /// out and no change yet (what the last iteration used and the model predicted stay).
    fn reset(&mut self, n: usize) {
        self.frictionless = false;
        self.change = 0.0;
        self.used.resize(n, f64::NAN);
        self.node.clear();
        self.node.resize(n, NONE);
        self.grad.resize(n, Vector3::zeros());
        self.column.clear();
        self.start.clear();
        self.start.resize(n + 1, 0);
        self.predicted.resize(n, None);
    }
}

/// How much stiffer than its inertia m/h² a sliding node may be (its diagonal's mean, its
/// neighbours' stiffness included) and still have the normal force of a step's first
/// iteration read from the gradient at the first guess, whose error is the position
/// error times that stiffness. The bound lies between curtain_rail's rings (about 1e2),
/// which take fewer Newton iterations with friction from the gradient than without it in
/// the first iteration, and a stiffly held strand root (about 1e5), which takes several
/// times the iterations so (figures in docs/history/issue-71-comments.md).
const STIFF_NODE: f64 = 1e3;

/// The mass-weighted centroid of `members` at `x`.
fn centroid(sys: &SolidSystem, members: &[u32], x: &[Vector3<f64>]) -> Vector3<f64> {
    let (mut s, mut w) = (Vector3::zeros(), 0.0);
    for &v in members {
        s += sys.mass[v as usize] * x[v as usize];
        w += sys.mass[v as usize];
    }
    s / w
}

impl Integrator {
    /// What slider `v` moves, and the point that slides: a free vertex's node and position,
    /// or, for a member of a rigid group, its group's translation node and centroid (a ring
    /// on a rail: the group slides, its rotation free); None for a held vertex.
    fn slider_node(
        &self,
        sys: &SolidSystem,
        x: &[Vector3<f64>],
        v: usize,
    ) -> Option<(usize, Vector3<f64>)> {
        let f = self.lin.free_of[v];
        if f != NONE {
            return Some((f as usize, x[v]));
        }
        let g = *self.groups.of.get(v)?;
        (g != NONE).then(|| {
            let g = g as usize;
            (
                self.groups.node[g] as usize,
                centroid(sys, &self.groups.members[g], x),
            )
        })
    }

    /// The mass that slider vertex `v`'s node moves: the vertex's, or its rigid group's.
    fn node_mass(&self, sys: &SolidSystem, v: usize) -> f64 {
        match self.groups.of.get(v).copied() {
            Some(g) if self.lin.free_of[v] == NONE && g != NONE => self.groups.members[g as usize]
                .iter()
                .map(|&u| sys.mass[u as usize])
                .sum(),
            _ => sys.mass[v],
        }
    }

    /// Maps free vertices (and groups' translation nodes) to their sliders (the system's
    /// sliders may change between calls).
    fn map_sliders(&mut self, sys: &SolidSystem, x: &[Vector3<f64>]) {
        let k = sys.sliders.len();
        self.sliders.slide_of.clear();
        self.sliders.slide_of.resize(self.lin.n_free, NONE);
        self.sliders.slide_proj.resize(k, Matrix3::zeros());
        self.sliders.slide_scale.resize(k, 0.0);
        self.sliders.slide_normal.resize(k, 0.0);
        for (k, sl) in sys.sliders.iter().enumerate() {
            if let Some((f, _)) = self.slider_node(sys, x, sl.vertex as usize) {
                self.sliders.slide_of[f] = k as u32;
            }
        }
    }

    /// Moves every sliding vertex of `x` to its target's closest point (a sliding rigid
    /// group: all its members by the step that takes its centroid there).
    pub(super) fn retract(&self, sys: &SolidSystem, x: &mut [Vector3<f64>]) {
        for sl in &sys.sliders {
            let v = sl.vertex as usize;
            let group = self.groups.of.get(v).copied().unwrap_or(NONE);
            if self.lin.free_of[v] == NONE && group != NONE {
                let members = &self.groups.members[group as usize];
                let c = centroid(sys, members, x);
                if let Some(p) = place(&sys.rails, &sys.surfaces, sl.on, &c) {
                    let shift = p.point - c;
                    for &m in members {
                        x[m as usize] += shift;
                    }
                }
                continue;
            }
            // `SolidSystem::check` refused targets without a closest point.
            if let Some(p) = place(&sys.rails, &sys.surfaces, sl.on, &x[v]) {
                x[v] = p.point;
            }
        }
    }

    /// Starts a step with no predicted target force (`SlideForces`: nothing carried);
    /// `iterated`: the step runs Newton to its tolerance (not one linearized iteration).
    pub(super) fn start_slide_forces(&mut self, sys: &SolidSystem, iterated: bool) {
        let sf = &mut self.sliders.slide_forces;
        sf.free_first = iterated;
        sf.frictionless = false;
        sf.predicted.clear();
        sf.predicted.resize(sys.sliders.len(), None);
        sf.node.clear();
        sf.used.clear();
        sf.used.resize(sys.sliders.len(), f64::NAN);
        sf.change = f64::NAN;
    }

    /// Moves the predicted target forces by the step `alpha`·`dir` just taken: g + αH·(P d)
    /// on each slider's node, with the gradient and the matrix kept at the assembly `dir`
    /// was solved from (`SlideForces`), each sliding node's part of `dir` along its target.
    pub(super) fn predict_slide_forces(&mut self, dir: &[f64], alpha: f64) {
        let sf = &mut self.sliders.slide_forces;
        sf.used.clear();
        if sf.frictionless {
            // An iteration that left friction out is no term of the fixed-point iteration on
            // the normal forces: the next change is measured from none.
            sf.used.resize(self.sliders.slide_normal.len(), f64::NAN);
        } else {
            sf.used.extend_from_slice(&self.sliders.slide_normal);
        }
        for (k, &f) in sf.node.iter().enumerate() {
            if f == NONE {
                sf.predicted[k] = None;
                continue;
            }
            // (H d)_f = Σₐ H_fa dₐ = Σₐ (H_af)ᵀ dₐ: the stored column's blocks, transposed.
            let mut g = sf.grad[k];
            for (a, b) in &sf.column[sf.start[k]..sf.start[k + 1]] {
                let a = *a as usize;
                let mut d = Vector3::new(dir[3 * a], dir[3 * a + 1], dir[3 * a + 2]);
                let slider = self.sliders.slide_of[a];
                if slider != NONE {
                    d = self.sliders.slide_proj[slider as usize] * d;
                }
                g += alpha * b.tr_mul(&d);
            }
            sf.predicted[k] = Some(g);
        }
    }

    /// Keeps slider `k`'s node `f`, its gradient and its column of the matrix, before the
    /// filter and friction change them (`SlideForces`).
    fn keep_column(&mut self, k: usize, f: usize, g: Vector3<f64>) {
        let sf = &mut self.sliders.slide_forces;
        sf.node[k] = f as u32;
        sf.grad[k] = g;
        let start = self.lin.col_ptr[3 * f];
        let slots = (self.lin.col_ptr[3 * f + 1] - start) / 3;
        for s in 0..slots {
            let a = self.lin.row_idx[start + 3 * s] / 3;
            let at = block_entry(&self.lin.col_ptr, f, s, 0, 0);
            let b = Matrix3::from_column_slice(&self.lin.values[at..at + 9]);
            sf.column.push((a as u32, b));
        }
        sf.start[k + 1] = sf.column.len();
    }

    /// The tolerance the sliders' lagged friction leaves the rate stop's estimate of the
    /// Newton steps' tail, or None while it has not settled: with no friction, all of it; else its
    /// normal forces' changes from iteration to iteration (as the velocity μ ΔN h / m each
    /// makes on its node: `SlideForces::change`) must contract by the same test as the
    /// Newton steps' (`rate.rs`: two full steps, ratio < ½), and the two geometric tails
    /// together stay below the tolerance. Friction reads the normal force the last step
    /// predicted, so the loop is also a fixed-point iteration on N, whose contraction the
    /// Newton steps' ratio does not show: on a strand whose stiffly held root slides with
    /// friction (μ = 0.05, 1e-4 m/s), the Newton steps' test alone ends far from the
    /// converged run, and this one about as near as the measured test, in about its
    /// iterations (the sequence starts after a first iteration without friction, whose
    /// normal force of zero is no term of it); curtain_rail's rings take fewer iterations a
    /// step with it, as near their run at 1e-8 m/s (figures in
    /// docs/history/issue-71-comments.md).
    pub(super) fn friction_budget(
        &self,
        sys: &SolidSystem,
        friction_rate: &mut RateStop,
        full: bool,
        settings: &Settings,
    ) -> Option<f64> {
        if !Self::slide_friction(sys) {
            return Some(settings.tolerance);
        }
        let change = self.sliders.slide_forces.change;
        let tail = friction_rate.done(change, full, settings.tolerance);
        // No change at all (every frictional slider held at a stop, or its force unchanged):
        // nothing lags, though the ratio of two zeros is no contraction.
        if change == 0.0 {
            return Some(settings.tolerance);
        }
        tail.map(|e| settings.tolerance - e)
    }

    /// The fraction (at most `max`) of the step `dir` from `x` at which it stops for a
    /// frictional slider's stick point, or `max`: for each slider with friction, sliding
    /// (its displacement this step, u = P (x − x⁰), beyond the mollifier's ε), the ray
    /// u + α P d (d the step on its node) is followed to its closest approach to zero, and
    /// where that passes within ε/2 of it the step stops there (the smallest such α over
    /// the sliders). Friction's potential μN f₀(|u|) has its kink at zero: beyond ε its model
    /// has no stiffness along the motion, so a step that reverses the motion overshoots the
    /// stick point and the line search halves it across the kink (a strand hanging still from
    /// a stiff root on a tilted wire, its first iteration run without friction: 6, 7, 9 and
    /// 10 halvings in one step's iterations). Stopped there, the next iteration starts in the
    /// mollified zone (within ε/2, where its model's stiffness along the motion is at least
    /// μN/ε), whose model holds it. Both Newton loops use it, once a step (`newton`,
    /// `step_contacts_here`).
    pub(super) fn stick_cap(
        &self,
        sys: &SolidSystem,
        x: &[Vector3<f64>],
        x0: &[Vector3<f64>],
        dir: &[f64],
        h: f64,
        max: f64,
    ) -> f64 {
        let eps = FRICTION_EPS_V * h;
        let mut cap = max;
        for (k, sl) in sys.sliders.iter().enumerate() {
            let n = self.sliders.slide_normal.get(k).copied().unwrap_or(0.0);
            if sl.friction <= 0.0 || n.is_nan() || n <= 0.0 {
                continue;
            }
            let v = sl.vertex as usize;
            let (Some((f, at)), Some((_, at0))) =
                (self.slider_node(sys, x, v), self.slider_node(sys, x0, v))
            else {
                continue;
            };
            let p = self.sliders.slide_proj[k];
            let u = p * (at - at0);
            let d = p * Vector3::new(dir[3 * f], dir[3 * f + 1], dir[3 * f + 2]);
            let dd = d.norm_squared();
            if u.norm() <= eps || dd == 0.0 {
                continue;
            }
            let a = -u.dot(&d) / dd;
            if a > 0.0 && a < cap && (u + a * d).norm() <= 0.5 * eps {
                cap = a;
            }
        }
        cap
    }

    /// Whether any slider has friction (its potential then changes with the iterate's normal
    /// force, so an objective value is not carried from one iteration to the next).
    pub(super) fn slide_friction(sys: &SolidSystem) -> bool {
        sys.sliders.iter().any(|s| s.friction > 0.0)
    }

    /// The sliders' friction potential Σ μ N f₀(|P (x − x⁰)|) at `x` (dynamic steps), with
    /// the projectors and normal forces of the last assembly.
    pub(super) fn friction_energy(
        &self,
        sys: &SolidSystem,
        x: &[Vector3<f64>],
        x0: &[Vector3<f64>],
        h: f64,
    ) -> f64 {
        let mut e = 0.0;
        for (k, sl) in sys.sliders.iter().enumerate() {
            let n = self.sliders.slide_normal.get(k).copied().unwrap_or(0.0);
            if sl.friction > 0.0 && n > 0.0 {
                let v = sl.vertex as usize;
                let (Some((_, p)), Some((_, p0))) =
                    (self.slider_node(sys, x, v), self.slider_node(sys, x0, v))
                else {
                    continue;
                };
                let u = self.sliders.slide_proj[k] * (p - p0);
                e += sl.friction * n * friction_f0_f1(u.norm(), FRICTION_EPS_V * h).0;
            }
        }
        e
    }

    /// Filters the assembled gradient and matrix at `x` (on the targets): each sliding
    /// vertex's rows and columns are multiplied by its projector P, its gradient by P, and
    /// s (I − P) is added to its diagonal block, s the mean of its diagonal before (positive:
    /// the block of an SPD matrix). The matrix stays SPD when it was, and its solution moves
    /// sliding vertices along their targets only. In dynamic steps, friction's gradient and
    /// Hessian are added first, with N the normal part of the gradient the Newton model
    /// predicts at `x` (`SlideForces`; where it has no prediction, the gradient itself, or
    /// zero for a stiffly held node in an iterated step's first iteration).
    pub(super) fn filter_sliders(
        &mut self,
        sys: &SolidSystem,
        x: &[Vector3<f64>],
        x0: &[Vector3<f64>],
        mode: Mode,
    ) {
        if sys.sliders.is_empty() {
            return;
        }
        self.map_sliders(sys, x);
        self.sliders.slide_forces.reset(sys.sliders.len());
        for k in 0..sys.sliders.len() {
            self.slider_terms(sys, x, x0, mode, k);
        }
        self.project_slider_blocks();
        self.project_slider_gradients(sys, x);
    }

    /// Slider `k`'s projector P and diagonal scale at `x`, the normal force its friction
    /// reads, and in dynamic steps friction's gradient and Hessian added to its node's.
    fn slider_terms(
        &mut self,
        sys: &SolidSystem,
        x: &[Vector3<f64>],
        x0: &[Vector3<f64>],
        mode: Mode,
        k: usize,
    ) {
        let sl = &sys.sliders[k];
        let dynamic = matches!(mode, Mode::Dynamic { .. });
        let v = sl.vertex as usize;
        let from = self.sliders.slide_forces.column.len();
        self.sliders.slide_forces.start[k + 1] = from;
        let Some((f, at)) = self.slider_node(sys, x, v) else {
            return;
        };
        let g = Vector3::new(
            self.work.grad[3 * f],
            self.work.grad[3 * f + 1],
            self.work.grad[3 * f + 2],
        );
        if dynamic && sl.friction > 0.0 {
            self.keep_column(k, f, g);
        }
        // The force on the node (the model's where it has one): whether it pushes past a
        // stop is the sign of the constraint's multiplier.
        let force = self.sliders.slide_forces.predicted[k].unwrap_or(g);
        let p = match place(&sys.rails, &sys.surfaces, sl.on, &at) {
            Some(pl) => projector(&pl, &force),
            None => Matrix3::zeros(),
        };
        self.sliders.slide_proj[k] = p;
        self.sliders.slide_scale[k] = (0..3)
            .map(|c| self.lin.values[self.lin.diagonal_entry(f, c)])
            .sum::<f64>()
            / 3.0;
        // The normal force the target supplies: the part of the (predicted) gradient it
        // takes. Held at a stop (P = 0), the vertex does not slide: no friction.
        let held = p == Matrix3::zeros();
        let predicted = self.sliders.slide_forces.predicted[k];
        // With no prediction yet (a step's first iteration), the gradient, unless the
        // node is stiffly held by its neighbours: then its normal part is mostly their
        // imbalance at the first guess (a swinging strand's root: 1.84 N where the strand
        // weighs 0.04 N) and the first iteration of an iterated step runs without
        // friction.
        let stiff = |s: &Self| match mode {
            Mode::Dynamic { h } => {
                s.sliders.slide_scale[k] > STIFF_NODE * s.node_mass(sys, v) / (h * h)
            }
            Mode::Static => false,
        };
        self.sliders.slide_normal[k] = match predicted {
            _ if held => 0.0,
            Some(f) => (f - p * f).norm(),
            None if sl.friction > 0.0 && self.sliders.slide_forces.free_first && stiff(self) => {
                self.sliders.slide_forces.frictionless = true;
                0.0
            }
            None => (g - p * g).norm(),
        };
        // Friction's change from the last iteration's normal force, held sliders included
        // (their friction switching off is a change too).
        if let (Mode::Dynamic { h }, true) = (mode, sl.friction > 0.0) {
            let d = sl.friction
                * (self.sliders.slide_normal[k] - self.sliders.slide_forces.used[k]).abs()
                * h
                / self.node_mass(sys, v);
            let c = &mut self.sliders.slide_forces.change;
            *c = if d.is_nan() || c.is_nan() {
                f64::NAN
            } else {
                c.max(d)
            };
        }
        if let (Mode::Dynamic { h }, true) = (mode, sl.friction > 0.0 && !held) {
            let at0 = self.slider_node(sys, x0, v).map_or(at, |(_, q)| q);
            let mu_n = sl.friction * self.sliders.slide_normal[k];
            self.add_slide_friction(f, mu_n, p * (at - at0), p, FRICTION_EPS_V * h);
        }
    }

    /// μ N f₀(|u|), u = P (x − x⁰) the slide since x⁰ (`mu_n` = μ N): gradient μN f₁/y u;
    /// Hessian μN [f₁/y (P − û ûᵀ) + f₁′ û ûᵀ], both terms PSD (f₁′ = 0 beyond ε), added
    /// to node `f`'s.
    fn add_slide_friction(
        &mut self,
        f: usize,
        mu_n: f64,
        u: Vector3<f64>,
        p: Matrix3<f64>,
        eps: f64,
    ) {
        let y = u.norm();
        let (grad, hess) = if y == 0.0 {
            (Vector3::zeros(), 2.0 / eps * p)
        } else {
            let (_, f1) = friction_f0_f1(y, eps);
            let df1 = if y < eps {
                2.0 / eps * (1.0 - y / eps)
            } else {
                0.0
            };
            let uh = u / y;
            let uu = uh * uh.transpose();
            (f1 / y * u, f1 / y * (p - uu) + df1 * uu)
        };
        for c in 0..3 {
            self.work.grad[3 * f + c] += mu_n * grad[c];
        }
        let block = self.lin.block_mut(f, self.lin.diag_slot[f] as usize);
        for (v, h) in block.iter_mut().zip(hess.as_slice()) {
            *v += mu_n * h;
        }
    }

    /// Every block in a sliding node's row or column multiplied by its projector
    /// (Pₐ B P_b).
    fn project_slider_blocks(&mut self) {
        let proj = |s: &Self, f: usize| {
            let k = s.sliders.slide_of[f];
            (k != NONE).then(|| s.sliders.slide_proj[k as usize])
        };
        for fb in 0..self.lin.n_free {
            let pb = proj(self, fb);
            let start = self.lin.col_ptr[3 * fb];
            let slots = (self.lin.col_ptr[3 * fb + 1] - start) / 3;
            for s in 0..slots {
                let fa = self.lin.row_idx[start + 3 * s] / 3;
                let pa = proj(self, fa);
                if pa.is_none() && pb.is_none() {
                    continue;
                }
                let block = self.lin.block_mut(fb, s);
                let mut b = Matrix3::from_column_slice(block);
                if let Some(pa) = pa {
                    b = pa * b;
                }
                if let Some(pb) = pb {
                    b *= pb;
                }
                block.copy_from_slice(b.as_slice());
            }
        }
    }

    /// Each sliding node's gradient projected, and s (I − P) added to its diagonal block.
    fn project_slider_gradients(&mut self, sys: &SolidSystem, x: &[Vector3<f64>]) {
        for (k, sl) in sys.sliders.iter().enumerate() {
            let Some((f, _)) = self.slider_node(sys, x, sl.vertex as usize) else {
                continue;
            };
            let p = self.sliders.slide_proj[k];
            let g = p * Vector3::new(
                self.work.grad[3 * f],
                self.work.grad[3 * f + 1],
                self.work.grad[3 * f + 2],
            );
            let normal = self.sliders.slide_scale[k] * (Matrix3::identity() - p);
            for c in 0..3 {
                self.work.grad[3 * f + c] = g[c];
            }
            let block = self.lin.block_mut(f, self.lin.diag_slot[f] as usize);
            for (v, n) in block.iter_mut().zip(normal.as_slice()) {
                *v += n;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::energy::RodStretch;
    use crate::slide::{Rail, SlideOn, Slider};
    use crate::{Integrator, Method, Settings, SolidSystem, State};
    use nalgebra::Vector3;

    fn settings() -> Settings {
        Settings {
            method: Method::Newton,
            tolerance: 1e-12,
            max_iterations: 50,
        }
    }

    /// A rail through the origin tilted θ below +x in the xy plane (gravity −y), long enough.
    fn tilted(theta: f64) -> (Rail, Vector3<f64>) {
        let t = Vector3::new(theta.cos(), -theta.sin(), 0.0);
        (
            Rail {
                points: vec![-10.0 * t, 10.0 * t],
            },
            t,
        )
    }

    /// Two 10 g vertices joined by a stiff 1 cm segment (k/L = 1e6 N/m), both sliding on
    /// `rail` with friction `mu`, under gravity −y.
    fn stiff_pair(rail: Rail, mu: f64) -> SolidSystem {
        let mut sys = SolidSystem::new(vec![0.01, 0.01]);
        sys.gravity = Vector3::new(0.0, -9.81, 0.0);
        sys.elements.stretches.push(RodStretch {
            v: [0, 1],
            rest_length: 0.01,
            k: 1e4,
        });
        sys.rails.push(rail);
        sys.sliders = (0..2)
            .map(|v| Slider {
                vertex: v,
                on: SlideOn::Rail(0),
                friction: mu,
            })
            .collect();
        sys
    }

    #[test]
    fn a_bead_on_a_tilted_wire_accelerates_at_g_sin_theta() {
        // Implicit Euler with a constant force along the rail is exact in the velocity:
        // v_n = n h g sin θ. Two vertices joined by a stiff segment both slide (the rod's
        // stretch couples the two filtered rows).
        let theta = 0.3f64;
        let (rail, t) = tilted(theta);
        let sys = stiff_pair(rail.clone(), 0.0);
        let mut s = State {
            x: vec![Vector3::zeros(), 0.01 * t],
            v: vec![Vector3::zeros(); 2],
        };
        let mut integ = Integrator::new(&sys).unwrap();
        let h = 0.01;
        for _ in 0..100 {
            integ.step(&sys, &mut s, None, h, &settings()).unwrap();
        }
        let a = 9.81 * theta.sin();
        for i in 0..2 {
            let along = s.v[i].dot(&t);
            assert!((along - a).abs() < 1e-9 * a, "v {along} want {a}");
            let off = (s.x[i] - rail.closest(&s.x[i]).unwrap().point).norm();
            assert!(off < 1e-12, "off the rail by {off:e} m");
            // Velocity along the rail only (both ends of every step are on it).
            assert!((s.v[i] - along * t).norm() < 1e-9, "{:?}", s.v[i]);
        }
        assert!(((s.x[1] - s.x[0]).norm() - 0.01).abs() < 1e-6);
    }

    #[test]
    fn a_linearized_step_slides_a_stiff_bead_by_coulomb() {
        // One iteration a step: its friction reads the normal force from the gradient at the
        // first guess, which for a bead moving along a straight wire is exact (m g cos θ;
        // the segment's stretch is along the wire), as is the step (constant forces along
        // it, speed beyond the mollifier's ε_v): v_n = v₀ + n h g (sin θ − μ cos θ). The
        // node is stiff (segment 1e6 N/m against m/h² = 100 N/m): an iterated step's first
        // iteration would run without friction, a linearized one must not.
        let (theta, mu) = (0.3f64, 0.2);
        let (rail, t) = tilted(theta);
        let sys = stiff_pair(rail, mu);
        let mut s = State {
            x: vec![Vector3::zeros(), 0.01 * t],
            v: vec![t; 2],
        };
        let mut integ = Integrator::new(&sys).unwrap();
        let settings = Settings {
            method: Method::Linearized,
            ..settings()
        };
        let h = 0.01;
        for _ in 0..20 {
            integ.step(&sys, &mut s, None, h, &settings).unwrap();
        }
        let want = 1.0 + 20.0 * h * 9.81 * (theta.sin() - mu * theta.cos());
        for v in &s.v {
            assert!((v.dot(&t) - want).abs() < 1e-9, "{} want {want}", v.dot(&t));
        }
    }

    #[test]
    fn a_bead_stops_at_the_end_of_its_rail() {
        let (mut rail, t) = tilted(0.5);
        rail.points[1] = 0.2 * t; // the low end, 0.2 m down the rail
        let mut sys = SolidSystem::new(vec![0.1]);
        sys.gravity = Vector3::new(0.0, -9.81, 0.0);
        sys.rails.push(rail);
        sys.sliders.push(Slider {
            vertex: 0,
            on: SlideOn::Rail(0),
            friction: 0.0,
        });
        let mut s = State {
            x: vec![Vector3::new(0.0, 0.05, 0.0)], // off the rail: put on it first
            v: vec![Vector3::zeros()],
        };
        let mut integ = Integrator::new(&sys).unwrap();
        for _ in 0..200 {
            integ.step(&sys, &mut s, None, 0.01, &settings()).unwrap();
        }
        assert!((s.x[0] - 0.2 * t).norm() < 1e-12, "{:?}", s.x[0]);
        assert!(s.v[0].norm() < 1e-9, "{:?}", s.v[0]);
    }

    #[test]
    fn a_point_target_holds_its_vertex_as_a_moving_pin_does() {
        // A two-segment pendulum whose top vertex is carried round a circle: held by a point
        // target (moved between steps, no pattern change) it must follow as a pinned vertex
        // does, exactly at the point at every step's end, and the free vertices must agree
        // with the pinned system's to the solver's tolerance.
        let strand = || {
            let mut sys = SolidSystem::new(vec![0.01; 3]);
            sys.gravity = Vector3::new(0.0, -9.81, 0.0);
            for i in 0..2u32 {
                sys.elements.stretches.push(RodStretch {
                    v: [i, i + 1],
                    rest_length: 0.1,
                    k: 1e3,
                });
            }
            sys
        };
        let start = State {
            x: (0..3)
                .map(|i| Vector3::new(0.1 * i as f64, 0.0, 0.0))
                .collect(),
            v: vec![Vector3::zeros(); 3],
        };
        let mut held = strand();
        held.sliders.push(Slider {
            vertex: 0,
            on: SlideOn::Point(Vector3::zeros()),
            friction: 0.0,
        });
        let mut pinned = strand();
        pinned.pinned[0] = true;
        let (mut a, mut b) = (start.clone(), start);
        let mut ia = Integrator::new(&held).unwrap();
        let mut ib = Integrator::new(&pinned).unwrap();
        let h = 0.005;
        for k in 1..=100 {
            let t = k as f64 * h;
            let p = 0.05 * Vector3::new((10.0 * t).cos() - 1.0, (10.0 * t).sin(), 0.0);
            held.sliders[0].on = SlideOn::Point(p);
            let mut targets = vec![Vector3::zeros(); 3];
            targets[0] = p;
            ia.step(&held, &mut a, None, h, &settings()).unwrap();
            ib.step(&pinned, &mut b, Some(&targets), h, &settings())
                .unwrap();
            assert_eq!(a.x[0], p, "step {k}: not at its point");
            for i in 1..3 {
                assert!((a.x[i] - b.x[i]).norm() < 1e-9, "step {k} vertex {i}");
            }
        }
        assert!((a.v[0] - b.v[0]).norm() < 1e-9);
    }

    #[test]
    fn a_rigid_group_slides_by_its_centroid_and_keeps_its_shape() {
        // A rigid triangle (a ring) whose centroid slides on a wire 0.3 rad below +x: the
        // centroid accelerates at g sin θ exactly as a bead does (v_n = n h g sin θ, implicit
        // Euler with a constant force along the rail), stays on the wire, and the triangle
        // neither deforms nor turns (gravity has no torque about the centroid).
        let theta = 0.3f64;
        let (rail, t) = tilted(theta);
        let mut sys = SolidSystem::new(vec![0.01, 0.02, 0.01]);
        sys.gravity = Vector3::new(0.0, -9.81, 0.0);
        sys.rigid.push(crate::RigidGroup {
            vertices: vec![0, 1, 2],
        });
        sys.rails.push(rail.clone());
        sys.sliders.push(Slider {
            vertex: 1,
            on: SlideOn::Rail(0),
            friction: 0.0,
        });
        // Centroid (mass-weighted) at the origin, on the rail.
        let start = [
            Vector3::new(-0.02, 0.01, 0.0),
            Vector3::new(0.01, -0.01, 0.005),
            Vector3::new(0.0, 0.01, -0.01),
        ];
        let c0 = (0.01 * start[0] + 0.02 * start[1] + 0.01 * start[2]) / 0.04;
        let mut s = State {
            x: start.iter().map(|p| p - c0).collect(),
            v: vec![Vector3::zeros(); 3],
        };
        let x0 = s.x.clone();
        let mut integ = Integrator::new(&sys).unwrap();
        let h = 0.01;
        for _ in 0..50 {
            integ.step(&sys, &mut s, None, h, &settings()).unwrap();
        }
        let c = (0.01 * s.x[0] + 0.02 * s.x[1] + 0.01 * s.x[2]) / 0.04;
        let a = 9.81 * theta.sin();
        let want = a * h * h * 50.0 * 51.0 / 2.0;
        assert!(
            (c.dot(&t) - want).abs() < 1e-9 * want,
            "{} want {want}",
            c.dot(&t)
        );
        assert!((c - rail.closest(&c).unwrap().point).norm() < 1e-12);
        for (i, (x, x0)) in s.x.iter().zip(&x0).enumerate() {
            // Translated, not turned nor deformed.
            assert!((x - c - x0).norm() < 1e-10, "vertex {i}");
        }
        // A second slider on the same group is refused.
        sys.sliders.push(Slider {
            vertex: 2,
            on: SlideOn::Rail(0),
            friction: 0.0,
        });
        let e = sys.check(&s).unwrap_err().to_string();
        assert!(e.contains("already slides"), "{e}");
    }

    /// The plane z = 0, unbounded.
    #[derive(Debug)]
    struct Floor;

    impl crate::slide::Surface for Floor {
        fn closest(&self, p: &Vector3<f64>) -> Option<crate::slide::OnSurface> {
            Some(crate::slide::OnSurface {
                point: Vector3::new(p.x, p.y, 0.0),
                normal: Vector3::z(),
                border: None,
            })
        }
    }

    #[test]
    fn a_step_stops_at_the_stick_point_of_a_surface_slider_or_a_sliding_ring() {
        // Vertex 0 slides on the floor; the two-vertex ring {1, 2} slides by its centroid on
        // a rail along x (`stick_cap` follows the group's translation node). Both have
        // friction and press on their targets. Over this step so far each slid by u (far
        // beyond the mollifier's ε = ε_v h = 1e-6 m); the step's direction d reverses it.
        // The cap is the first α at which some u + α P d passes within ε/2 of zero.
        use crate::slide::{SlideOn, Slider};
        use nalgebra::Matrix3;
        let mut sys = SolidSystem::new(vec![0.01, 0.01, 0.01]);
        sys.rigid.push(crate::RigidGroup {
            vertices: vec![1, 2],
        });
        sys.surfaces.push(std::sync::Arc::new(Floor));
        sys.rails.push(Rail {
            points: vec![Vector3::new(-1.0, 0.0, 0.0), Vector3::new(1.0, 0.0, 0.0)],
        });
        let slider = |vertex, on, friction| Slider {
            vertex,
            on,
            friction,
        };
        sys.sliders = vec![
            slider(0, SlideOn::Surface(0), 0.3),
            slider(1, SlideOn::Rail(0), 0.3),
        ];
        let x0 = vec![
            Vector3::zeros(),
            Vector3::new(0.0, 0.0, 0.01),
            Vector3::new(0.0, 0.0, -0.01),
        ];
        let (u0, u1) = (Vector3::new(2e-3, 1e-3, 0.0), Vector3::new(3e-3, 0.0, 0.0));
        let x = vec![x0[0] + u0, x0[1] + u1, x0[2] + u1];
        let h = 0.01;
        let mut integ = Integrator::new(&sys).unwrap();
        integ.sliders.slide_normal = vec![1.0, 1.0];
        integ.sliders.slide_proj = vec![
            Matrix3::identity() - Vector3::z() * Vector3::z().transpose(),
            Vector3::x() * Vector3::x().transpose(),
        ];
        let (f0, _) = integ.slider_node(&sys, &x, 0).unwrap();
        let (f1, c) = integ.slider_node(&sys, &x, 1).unwrap();
        assert!((c - u1).norm() < 1e-15, "the ring's centroid slides: {c:?}");
        // The floor's slider back through its stick point at α = 0.4 (its normal part is
        // projected out), the ring's at α = `ring`.
        let n = integ.work.dir.len();
        let dir = |ring: f64, miss: f64| {
            let mut d = vec![0.0; n];
            let d0 = -u0 / 0.4 + Vector3::new(0.0, miss, 5.0);
            let d1 = -u1 / ring + Vector3::new(0.0, 0.2, 0.1);
            d[3 * f0..3 * f0 + 3].copy_from_slice(d0.as_slice());
            d[3 * f1..3 * f1 + 3].copy_from_slice(d1.as_slice());
            d
        };
        let cap = |integ: &Integrator, sys: &SolidSystem, d: &[f64], max: f64| {
            integ.stick_cap(sys, &x, &x0, d, h, max)
        };
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-12;
        // The earlier of the two.
        assert!(close(cap(&integ, &sys, &dir(0.25, 0.0), 1.0), 0.25));
        assert!(close(cap(&integ, &sys, &dir(0.7, 0.0), 1.0), 0.4));
        // Never beyond `max` (an extrapolated step's stretch is the caller's bound).
        assert!(close(cap(&integ, &sys, &dir(0.7, 0.0), 0.3), 0.3));
        // A surface slider's ray that passes its stick point 0.7 mm wide (at α = 0.3) is not
        // stopped there (P d keeps a tangential part that u lacks); the ring reversing after
        // α = 1: no cap.
        assert!(close(cap(&integ, &sys, &dir(1.5, -2.5e-3), 1.0), 1.0));
        // Passing 0.4 µm wide, within ε/2: still stopped, at the ray's closest approach
        // (its extra tangential part moves that by 3e-5 of the step).
        let a = cap(&integ, &sys, &dir(0.7, -1e-6), 1.0);
        assert!((a - 0.4).abs() < 1e-4, "{a}");
        // 0.7 µm wide, beyond ε/2 (but within ε): not stopped; the ring's cap decides.
        assert!(close(cap(&integ, &sys, &dir(0.7, -2e-6), 1.0), 0.7));
        // A slider not pressed on its target (no normal force) has no friction to stop at;
        // nor one without friction.
        integ.sliders.slide_normal = vec![0.0, 1.0];
        assert!(close(cap(&integ, &sys, &dir(0.7, 0.0), 1.0), 0.7));
        sys.sliders[1].friction = 0.0;
        assert!(close(cap(&integ, &sys, &dir(0.7, 0.0), 1.0), 1.0));
    }

    #[test]
    fn bad_sliders_are_refused_by_name() {
        let mut sys = SolidSystem::new(vec![1.0]);
        let s = State {
            x: vec![Vector3::zeros()],
            v: vec![Vector3::zeros()],
        };
        sys.sliders.push(Slider {
            vertex: 0,
            on: SlideOn::Rail(0),
            friction: 0.0,
        });
        let e = sys.check(&s).unwrap_err().to_string();
        assert!(e.contains("rail 0, but there are 0 rails"), "{e}");
        sys.rails.push(Rail {
            points: vec![Vector3::zeros(); 2],
        });
        let e = sys.check(&s).unwrap_err().to_string();
        assert!(e.contains("positive, finite length"), "{e}");
        sys.rails[0].points[1] = Vector3::x();
        sys.sliders.push(Slider {
            vertex: 0,
            on: SlideOn::Rail(0),
            friction: 0.0,
        });
        let e = sys.check(&s).unwrap_err().to_string();
        assert!(e.contains("listed twice"), "{e}");
        sys.sliders.pop();
        sys.pinned[0] = true;
        let e = sys.check(&s).unwrap_err().to_string();
        assert!(e.contains("held in place"), "{e}");
    }
}
