//! The steps and the Newton loop: implicit Euler (and BDF2) by Newton on the incremental
//! potential, the static solve, symplectic Euler for comparison. `minimize` chooses the
//! route of this step's directions (factor, one-ring or single-precision preconditioner),
//! `newton` iterates (direction, line search with the rods' second-order correction, the
//! stopping tests of `rate.rs`).

use super::pool::in_pool;
use super::{Integrator, Mode, NONE, Route, Start, partition, rate};
use crate::settings::{Method, Settings, StepError, StepStats};
use crate::system::{SolidSystem, State, SystemError};
use nalgebra::Vector3;
use std::time::Instant;

impl Integrator {
    /// `trial` ← x + α·dir for the free vertices (held ones stay at x), rigid groups' members
    /// moved with their frames and sliders retracted to their curves: every trial point of
    /// the line searches and of the moves along negative curvature.
    pub(super) fn place(
        &self,
        sys: &SolidSystem,
        x: &[Vector3<f64>],
        dir: &[f64],
        alpha: f64,
        trial: &mut [Vector3<f64>],
    ) {
        for ((t, p), &f) in trial.iter_mut().zip(x).zip(&self.lin.free_of) {
            *t = if f == NONE {
                *p
            } else {
                let f = 3 * f as usize;
                p + alpha * Vector3::new(dir[f], dir[f + 1], dir[f + 2])
            };
        }
        self.move_members(dir, alpha, trial);
        self.retract(sys, trial);
    }

    /// Advances `state` by `h`. Pinned vertices move to `pinned_to` (all vertices' targets;
    /// only pinned entries are read) or stay where they are. On error `state` is unchanged.
    pub fn step(
        &mut self,
        sys: &SolidSystem,
        state: &mut State,
        pinned_to: Option<&[Vector3<f64>]>,
        h: f64,
        settings: &Settings,
    ) -> Result<StepStats, StepError> {
        self.step_from(sys, state, None, pinned_to, h, settings)
    }

    /// Advances `state` by `h` with the second-order backward differentiation formula
    /// (BDF2), `prev` being the state one step of the same `h` before `state`:
    /// xₙ₊₁ − x̄ = (2h/3) vₙ₊₁ and vₙ₊₁ − v̄ = (2h/3) M⁻¹ f(xₙ₊₁), with x̄ = (4xₙ − xₙ₋₁)/3 and
    /// v̄ = (4vₙ − vₙ₋₁)/3. That is implicit Euler's minimization with step h̃ = 2h/3 from the
    /// state (x̄, v̄) (inertia ½‖x − x̄ − h̃v̄ − h̃²g‖²_M/h̃², damping and drag measured from x̄),
    /// so it is one: the same Newton, line search and statistics. Implicit Euler damps a swing
    /// at first order in h (a 0.3 rad pendulum at h = 1/48 s: 3.1e-2 rad off after 1 s,
    /// `crates/weft-nodes/tests/time_integration.rs`); BDF2's error is second order (1.1e-3 rad there) and it stays L-stable (stiff modes
    /// are still damped). Pinned vertices go to `pinned_to` as in [`Self::step`]. On error
    /// `state` is unchanged.
    pub fn step_bdf2(
        &mut self,
        sys: &SolidSystem,
        state: &mut State,
        prev: &State,
        pinned_to: Option<&[Vector3<f64>]>,
        h: f64,
        settings: &Settings,
    ) -> Result<StepStats, StepError> {
        if matches!(settings.method, Method::Explicit | Method::Static) {
            // Not implicit steps: nothing to blend.
            return self.step(sys, state, pinned_to, h, settings);
        }
        sys.check(prev)?;
        let blend = |a: &[Vector3<f64>], b: &[Vector3<f64>]| -> Vec<Vector3<f64>> {
            a.iter().zip(b).map(|(a, b)| (4.0 * a - b) / 3.0).collect()
        };
        let mut bar = State {
            x: blend(&state.x, &prev.x),
            v: blend(&state.v, &prev.v),
        };
        // Held vertices without targets stay where they are (not at x̄).
        let held: Vec<Vector3<f64>>;
        let pinned_to = match pinned_to {
            Some(p) => Some(p),
            None => {
                held = state.x.clone();
                Some(&held[..])
            }
        };
        let stats = self.step(sys, &mut bar, pinned_to, 2.0 * h / 3.0, settings)?;
        *state = bar;
        Ok(stats)
    }

    /// A static step ([`Method::Static`]): held vertices to their targets, the rest from the
    /// guess (else where they are), the static equilibrium found by Newton; velocities zero.
    pub(super) fn static_step(
        &mut self,
        sys: &SolidSystem,
        state: &mut State,
        start: Start<'_>,
        settings: &Settings,
    ) -> Result<StepStats, StepError> {
        let Start { x0, target, guess } = start;
        let mut x = state.x.clone();
        for i in (0..self.lin.n).filter(|&i| self.held(i)) {
            x[i] = target(i);
        }
        if let Some(g) = guess {
            for i in (0..self.lin.n).filter(|&i| !self.held(i)) {
                x[i] = g[i];
            }
        }
        self.retract(sys, &mut x);
        let stats = in_pool(self.threaded(), || {
            self.minimize(sys, &mut x, x0, Mode::Static, settings)
        })?;
        state.x = x;
        state.v.iter_mut().for_each(|v| *v = Vector3::zeros());
        Ok(stats)
    }

    /// An implicit Euler step by Newton ([`Method::Newton`], [`Method::ProjectedNewton`],
    /// [`Method::Linearized`]) from the guess, else from x⁰ + h v⁰.
    pub(super) fn implicit_step(
        &mut self,
        sys: &SolidSystem,
        state: &mut State,
        start: Start<'_>,
        h: f64,
        settings: &Settings,
    ) -> Result<StepStats, StepError> {
        let Start { x0, target, guess } = start;
        let mut x = state.x.clone();
        self.predict(sys, state, &mut x, target, guess, h);
        let stats = in_pool(self.threaded(), || {
            self.minimize(sys, &mut x, x0, Mode::Dynamic { h }, settings)
        })?;
        for i in 0..self.lin.n {
            state.v[i] = (x[i] - x0[i]) / h;
        }
        state.x = x;
        Ok(stats)
    }

    /// A symplectic Euler step ([`Method::Explicit`]); rigid groups refused.
    pub(super) fn explicit_step(
        &mut self,
        sys: &SolidSystem,
        state: &mut State,
        start: Start<'_>,
        h: f64,
    ) -> Result<StepStats, StepError> {
        if !sys.rigid.is_empty() {
            return Err(StepError::System(SystemError::BadRigid {
                group: 0,
                reason: "explicit steps cannot keep a group rigid: use method newton, linearized or static".into(),
            }));
        }
        self.explicit(sys, state, start.x0, start.target, h)
    }

    /// Moves `state` to static equilibrium under gravity, the constant forces and the elastic
    /// energies (pinned vertices stay put; velocities are set to zero). Newton with a
    /// proximal term μ/2‖x − xₖ‖², μ = 1e-9 of the largest stiffness scaled by the gradient's
    /// relative decrease: it converges to the true minimizer while keeping the Hessian SPD for
    /// bodies with rigid or otherwise free modes.
    /// The residual is ‖Δx‖∞ in metres.
    pub fn solve_static(
        &mut self,
        sys: &SolidSystem,
        state: &mut State,
        settings: &Settings,
    ) -> Result<StepStats, StepError> {
        sys.check(state)?;
        let x0 = state.x.clone();
        let mut x = x0.clone();
        self.retract(sys, &mut x);
        let stats = in_pool(self.threaded(), || {
            self.minimize(sys, &mut x, &x0, Mode::Static, settings)
        })?;
        state.x = x;
        state.v.iter_mut().for_each(|v| *v = Vector3::zeros());
        Ok(stats)
    }

    /// Whether this system has work for more than one thread (an assembly tree with a split,
    /// or a split factorization): its steps then run on a pool worker ([`in_pool`]).
    pub(super) fn threaded(&self) -> bool {
        self.dirs.factor.split.is_some()
            || self.dirs.one_ring.as_ref().is_some_and(|o| o.is_split())
            || self.dirs.single.is_some()
            || matches!(self.lin.parts, partition::Part::Split { .. })
    }

    /// Newton (exact Hessians first for [`Method::Newton`] in dynamic steps, projected ones
    /// otherwise) with backtracking line search on the mode's objective. Callers run it on a
    /// worker of the thread pool ([`in_pool`]). A dynamic step's Newton directions go through
    /// the one-ring preconditioner where the system has one (a static solve's matrix may be
    /// singular, and a linearized step's one direction is the answer: both factor H).
    pub(super) fn minimize(
        &mut self,
        sys: &SolidSystem,
        x: &mut Vec<Vector3<f64>>,
        x0: &[Vector3<f64>],
        mode: Mode,
        settings: &Settings,
    ) -> Result<StepStats, StepError> {
        let pcg = matches!(mode, Mode::Dynamic { .. }) && settings.method == Method::Newton;
        if pcg && !self.dirs.one_ring_tried {
            self.dirs.one_ring_tried = true;
            // Not paying, or too large for the memory limit: H's factor serves as before. The
            // limit holds for all the factors together: each preconditioner gets half of what
            // H's factor and the one built before it left. Half: they are optional, and the
            // rest of the run (its output nodes, a rebuild for contacts) needs room too (under
            // a tight `ulimit -v` a twin that takes all of it leaves an output's preview
            // refused; weft-cli's `tests/memory.rs` runs such ceilings).
            let max = self.hooks.max_bytes;
            let left = |used: u64| max.map(|m| m.saturating_sub(used) / 2);
            self.dirs.one_ring = self
                .build_one_ring(sys, left(self.dirs.factor.bytes()))
                .ok()
                .flatten();
            let used =
                self.dirs.factor.bytes() + self.dirs.one_ring.as_ref().map_or(0, |o| o.bytes());
            self.dirs.single = self.build_single(sys, left(used)).ok().flatten();
        }
        if let Mode::Dynamic { h } = mode {
            for pre in [self.dirs.one_ring.as_mut(), self.dirs.single.as_mut()]
                .into_iter()
                .flatten()
            {
                pre.set_inertia(&self.lin.free_of, &sys.mass, h);
            }
        }
        // The one-ring's factor first (the cheaper one); the single-precision one where
        // there is no one-ring, or from where it declines.
        self.dirs.route = match (pcg, self.dirs.one_ring.is_some()) {
            (false, _) => Route::Factor,
            (true, true) => Route::OneRing,
            (true, false) => Route::Single,
        };
        let out = self.newton(sys, x, x0, mode, settings);
        self.dirs.route = Route::Factor;
        // Carried stresses belong to this step's iteration only.
        self.carried.clear();
        out
    }

    /// [`Self::minimize`]'s iteration.
    pub(super) fn newton(
        &mut self,
        sys: &SolidSystem,
        x: &mut Vec<Vector3<f64>>,
        x0: &[Vector3<f64>],
        mode: Mode,
        settings: &Settings,
    ) -> Result<StepStats, StepError> {
        let mut stats = StepStats::default();
        let linearized = settings.method == Method::Linearized;
        let max_it = if linearized {
            1
        } else {
            settings.max_iterations.max(1)
        };
        let scale = match mode {
            Mode::Dynamic { h } => 1.0 / h,
            Mode::Static => 1.0,
        };
        let mut lp = Loop {
            g0: 0.0,
            e_at_x: None,
            last_shift: 0.0,
            stuck: false,
        };
        let mut rate = rate::RateStop::default();
        let mut friction_rate = rate::RateStop::default();
        // Membranes carry their stress (the mixed form) where the first tries are exact.
        let carry = matches!(mode, Mode::Dynamic { .. }) && settings.method == Method::Newton;
        self.start_carried(sys, x0, carry);
        self.start_slide_forces(sys, !linearized);
        for it in 0..max_it {
            if self.should_stop() {
                return Err(StepError::Interrupted { iteration: it });
            }
            let (first, res, reassembled) =
                self.iteration_direction(sys, x, x0, mode, settings, it, &mut lp, &mut stats)?;
            stats.iterations = it + 1;
            stats.residuals.push(res);
            self.report_newton(it + 1, res);
            // Converged: the step still takes this last (small) Newton correction, whole.
            // Stopping before it would leave a step that starts below the tolerance (a
            // body at rest whose first velocity change g·h is below it) where it started.
            // (Not an iteration that left a slider's friction out: `SlideForces`.)
            let done =
                !linearized && res < settings.tolerance && !self.sliders.slide_forces.frictionless;
            let corrections = stats.corrections;
            let alpha = self.line_search(sys, x, x0, mode, linearized || done, &mut lp, &mut stats);
            std::mem::swap(x, &mut self.work.x_trial);
            if !sys.sliders.is_empty() {
                let dir = std::mem::take(&mut self.work.dir);
                self.predict_slide_forces(&dir, alpha);
                self.work.dir = dir;
            }
            if linearized || done {
                stats.converged = true;
                break;
            }
            let accepted = Accepted {
                alpha,
                first,
                reassembled,
                carry,
                scale,
            };
            self.after_accepted(sys, x, x0, mode, settings, accepted, &mut lp, &mut stats);
            // Or the corrections still to come, estimated from the contraction of the full
            // steps (`rate.rs`), are below the tolerance: with the first Hessians only
            // (exact where cheap, membranes' tension carried — the mixed form's Newton —,
            // midedge bending's Gauss–Newton term; unshifted), whose
            // convergence is superlinear. A shifted direction is not Newton's, and projected
            // Hessians converge linearly at a rate that can worsen as the fast modes die
            // out (on cloth_hang where it buckles they cost more iterations a step and end
            // centimetres off the converged run). Sliders'
            // friction, lagged a normal force behind, is a fixed-point iteration of its own:
            // its normal forces' changes must contract too (`friction_rate`).
            let full = alpha == 1.0 && stats.corrections == corrections && first == Some(false);
            let budget = self.friction_budget(sys, &mut friction_rate, full, settings);
            if matches!(mode, Mode::Dynamic { .. })
                && rate.ends_within(budget, &mut stats, res, full)
            {
                break;
            }
        }
        if !stats.converged {
            return Err(stats.not_converged(settings.tolerance));
        }
        if !x.iter().all(|p| p.iter().all(|c| c.is_finite())) {
            return Err(StepError::NonFinite {
                iteration: stats.iterations,
            });
        }
        Ok(stats)
    }

    /// One Newton iteration's direction in `dir` and its size (the residual): with the
    /// exact Hessian where it is positive definite (quadratic convergence), else the
    /// projected one (always a descent direction; linear convergence where the cloth
    /// buckles, since projection drops the membrane's negative compressive stiffness that
    /// bending balances). Returns whether the first (exact) try made it (`Some(shifted)`),
    /// the residual, and whether a shifted direction was replaced by the projected one.
    #[allow(clippy::too_many_arguments)]
    fn iteration_direction(
        &mut self,
        sys: &SolidSystem,
        x: &[Vector3<f64>],
        x0: &[Vector3<f64>],
        mode: Mode,
        settings: &Settings,
        it: usize,
        lp: &mut Loop,
        stats: &mut StepStats,
    ) -> Result<(Option<bool>, f64, bool), StepError> {
        let scale = match mode {
            Mode::Dynamic { h } => 1.0 / h,
            Mode::Static => 1.0,
        };
        let first = match mode {
            Mode::Dynamic { h } if settings.method == Method::Newton => {
                self.first_direction(sys, x, x0, h, &mut lp.last_shift, stats)
            }
            _ => None,
        };
        if first.is_none() {
            let t = Instant::now();
            self.assemble(sys, x, x0, mode);
            stats.assembly_seconds += t.elapsed().as_secs_f64();
            if matches!(mode, Mode::Dynamic { .. }) && settings.method == Method::Newton {
                stats.projected += 1;
            }
        }
        if !self.work.grad.iter().all(|g| g.is_finite()) {
            return Err(StepError::NonFinite { iteration: it });
        }
        let gnorm = self.work.grad.iter().fold(0.0f64, |m, g| m.max(g.abs()));
        if it == 0 {
            lp.g0 = gnorm.max(f64::MIN_POSITIVE);
        }
        // Static: a proximal shift μ that shrinks with the gradient (Levenberg–Marquardt),
        // so free modes stay regular while convergence stays superlinear.
        let shift = match mode {
            Mode::Static => {
                1e-9 * self.lin.values.iter().fold(0.0f64, |m, v| m.max(v.abs()))
                    * (gnorm / lp.g0).clamp(1e-4, 1.0)
            }
            Mode::Dynamic { .. } => 0.0,
        };
        if first.is_none() {
            self.newton_direction(stats, shift)?;
        }
        let mut res = self.direction_size(scale);
        // A direction computed with added inertia is shorter than Newton's: below the
        // tolerance it proves nothing, so the projected Hessians' direction decides.
        let reassembled = first == Some(true) && res < settings.tolerance;
        if reassembled {
            let t = Instant::now();
            self.assemble(sys, x, x0, mode);
            stats.assembly_seconds += t.elapsed().as_secs_f64();
            stats.projected += 1;
            self.newton_direction(stats, shift)?;
            res = self.direction_size(scale);
        }
        if !res.is_finite() {
            return Err(StepError::NonFinite { iteration: it });
        }
        Ok((first, res, reassembled))
    }

    /// The step length α along `dir`, with the trial point x + α·dir left in `x_trial`:
    /// backtracking on the objective (Armijo, c = 1e-4) with the rods' second-order
    /// correction, from a full step or from a frictional slider's stick point. `whole`
    /// (linearized, or converged): the full step, untested.
    #[allow(clippy::too_many_arguments)]
    fn line_search(
        &mut self,
        sys: &SolidSystem,
        x: &[Vector3<f64>],
        x0: &[Vector3<f64>],
        mode: Mode,
        whole: bool,
        lp: &mut Loop,
        stats: &mut StepStats,
    ) -> f64 {
        // Sliders' friction depends on this iteration's normal forces: a new objective.
        if Self::slide_friction(sys) {
            lp.e_at_x = None;
        }
        let (e0, slope, xmax) = if whole {
            (0.0, 0.0, 0.0)
        } else {
            (
                lp.e_at_x
                    .unwrap_or_else(|| self.objective(sys, x, x0, mode)),
                self.work
                    .grad
                    .iter()
                    .zip(&self.work.dir)
                    .map(|(g, d)| g * d)
                    .sum(),
                x.iter().fold(0.0f64, |m, p| m.max(p.amax())),
            )
        };
        // Stopped at a frictional slider's stick point, where friction's potential has
        // its kink (`stick_cap`), once a step: several sliders reversing at different
        // fractions are then left to the line search rather than taking a cut each.
        let mut alpha = match mode {
            Mode::Dynamic { h } if !whole && !lp.stuck && Self::slide_friction(sys) => {
                self.stick_cap(sys, x, x0, &self.work.dir, h, 1.0)
            }
            _ => 1.0,
        };
        lp.stuck |= alpha < 1.0;
        lp.e_at_x = None;
        loop {
            let mut trial = std::mem::take(&mut self.work.x_trial);
            self.place(sys, x, &self.work.dir, alpha, &mut trial);
            self.work.x_trial = trial;
            if whole {
                break;
            }
            let e1 = self.objective(sys, &self.work.x_trial, x0, mode);
            lp.e_at_x = Some(e1);
            // When the predicted decrease is below a bound on the objective's floating-point
            // resolution (≈ ε · |forces| · |positions|: terms like ½kL(l/L − 1)² are small
            // numbers made from large ones) the comparison may be noise: take the Newton
            // step, which descends locally. The bound is loose (on a buckling sheet the
            // objective resolves changes far smaller), and that helps: tighter ones cut
            // the nearly singular steps that cross flat buckling modes and cost iterations.
            let unresolvable = -slope * alpha <= 64.0 * f64::EPSILON * self.force_scale * xmax;
            if e1 <= e0 + 1e-4 * alpha * slope || unresolvable || alpha < 1e-10 {
                break;
            }
            // A full step that stretches rods more than the Newton model predicted (the
            // model is linear in each segment's length, the length is not: a strand
            // swinging by d lengthens its segments by ~d²/2L) is rejected here, and
            // halving it converges slowly (the Maratos effect). A second-order
            // correction restores the lengths the model predicted, then the step is
            // tested again.
            if alpha == 1.0 && !self.correction.is_empty() {
                stats.correction_sweeps += self.correction.apply(
                    &self.lin.free_of,
                    &sys.mass,
                    x,
                    &self.work.dir,
                    &self.work.x_trial,
                    &mut self.work.x_soc,
                );
                let mut soc = std::mem::take(&mut self.work.x_soc);
                self.retract(sys, &mut soc);
                self.work.x_soc = soc;
                let e2 = self.objective(sys, &self.work.x_soc, x0, mode);
                if e2 <= e0 + 1e-4 * slope {
                    std::mem::swap(&mut self.work.x_trial, &mut self.work.x_soc);
                    stats.corrections += 1;
                    lp.e_at_x = Some(e2);
                    break;
                }
            }
            alpha *= 0.5;
            stats.halvings += 1;
        }
        alpha
    }

    /// After an accepted step (x moved, its start in `x_trial`): the membranes' carried
    /// stress follows, then a move along the negative curvature a shifted direction hid,
    /// then the lagging vertices' local solves.
    #[allow(clippy::too_many_arguments)]
    fn after_accepted(
        &mut self,
        sys: &SolidSystem,
        x: &mut Vec<Vector3<f64>>,
        x0: &[Vector3<f64>],
        mode: Mode,
        settings: &Settings,
        step: Accepted,
        lp: &mut Loop,
        stats: &mut StepStats,
    ) {
        let Accepted {
            alpha,
            first,
            reassembled,
            carry,
            scale,
        } = step;
        if !self.carried.is_empty() {
            let from = std::mem::take(&mut self.work.x_trial);
            self.carry_stress(sys, &from, x, alpha);
            self.work.x_trial = from;
        }
        // After a shifted direction, a move along the negative curvature its inertia
        // hid (`curvature.rs`). (The rate's test counts unshifted steps only.)
        if let (Mode::Dynamic { h }, Some(true), false) = (mode, first, reassembled)
            && self.curvature_moves(sys)
        {
            let t = Instant::now();
            let lambda = self.negative_curvature(sys, h, lp.last_shift);
            stats.solve_seconds += t.elapsed().as_secs_f64();
            if lambda < 0.0 {
                let base = alpha * self.step_size(&self.work.dir);
                let moved = self.curvature_search(sys, x, x0, mode, base, &mut lp.e_at_x);
                stats.curvature_moves += usize::from(moved);
            }
        }
        // Then the few vertices whose steps lag the rest solved locally, each patch
        // around one of them by its own Newton iterations (`elimination.rs`). Where
        // they end the step's last iterations, the rate's test reads the
        // contraction of Newton and this together, the iteration that is repeated.
        if let (Mode::Dynamic { h }, true) = (mode, carry && self.eliminates(sys)) {
            let mut before = std::mem::take(&mut self.work.x_trial);
            before.copy_from_slice(x);
            let moved = self.eliminate(sys, x, x0, h, alpha, scale, settings.tolerance);
            if moved > 0 {
                stats.eliminations += moved;
                lp.e_at_x = None;
                // The moved membranes' carried stress follows by their linearized strain,
                // as after a move along negative curvature.
                self.carry_stress(sys, &before, x, 0.0);
            }
            self.work.x_trial = before;
        }
    }

    pub(super) fn explicit(
        &mut self,
        sys: &SolidSystem,
        state: &mut State,
        x0: &[Vector3<f64>],
        target: &dyn Fn(usize) -> Vector3<f64>,
        h: f64,
    ) -> Result<StepStats, StepError> {
        if self.should_stop() {
            return Err(StepError::Interrupted { iteration: 0 });
        }
        // Forces at x⁰: f = −∇E + m g − c m v.
        let mut force = vec![Vector3::zeros(); self.lin.n];
        let local = &mut self.work.local;
        sys.elements.for_each(|el| {
            el.eval(x0, false, local);
            for (a, &v) in el.vertices().iter().enumerate() {
                force[v as usize] -= Vector3::new(
                    local.grad[3 * a],
                    local.grad[3 * a + 1],
                    local.grad[3 * a + 2],
                );
            }
        });
        let mut v = state.v.clone();
        let mut x = x0.to_vec();
        for i in 0..self.lin.n {
            if self.lin.free_of[i] == NONE {
                x[i] = target(i);
                v[i] = (x[i] - x0[i]) / h;
            } else {
                let m = sys.mass[i];
                let drag = sys
                    .drag(i)
                    .map_or_else(Vector3::zeros, |d| -(d.matrix * (state.v[i] - d.flow)));
                v[i] += h
                    * ((force[i] + sys.force(i) + drag) / m + sys.gravity
                        - sys.damping(i) * state.v[i]);
                x[i] = x0[i] + h * v[i];
            }
        }
        if !sys.sliders.is_empty() {
            // On its rail at the end of the step, with the velocity that took it there.
            self.retract(sys, &mut x);
            for sl in &sys.sliders {
                let i = sl.vertex as usize;
                v[i] = (x[i] - x0[i]) / h;
            }
        }
        if !x.iter().chain(&v).all(|p| p.iter().all(|c| c.is_finite())) {
            return Err(StepError::NonFinite { iteration: 0 });
        }
        state.x = x;
        state.v = v;
        Ok(StepStats {
            converged: true,
            ..Default::default()
        })
    }
}

/// The Newton loop's state across one step's iterations.
struct Loop {
    /// The first iteration's gradient norm (the static shift's scale).
    g0: f64,
    /// The objective at the current iterate, when the last line search computed it (the
    /// accepted trial's): the next line search starts from it instead of evaluating every
    /// element's energy again. Same function, same bits.
    e_at_x: Option<f64>,
    /// The inertia that last made the exact Hessian positive definite in this step.
    last_shift: f64,
    /// Whether a step of this loop stopped at a slider's stick point (`stick_cap`).
    stuck: bool,
}

/// What an accepted step was: its length, how its direction was found
/// ([`Integrator::iteration_direction`]), whether membranes carry stress, the residual's scale.
#[derive(Clone, Copy)]
struct Accepted {
    alpha: f64,
    first: Option<bool>,
    reassembled: bool,
    carry: bool,
    scale: f64,
}
