//! Advancing a compiled scene frame by frame.
//!
//! Each frame is split into substeps. Attachment targets follow their element's transform,
//! interpolated between the previous frame's and this frame's (translation linearly, rotation
//! by slerp) at each substep's end time; frozen vertices' inputs are interpolated linearly
//! between the two frames' (`freeze.rs`). A substep that fails (no convergence, a NaN) is
//! retried as two half steps, recursively up to `max_retries` levels, and every retry is
//! counted in the frame's statistics; if it still fails the error names the frame and substep.

use crate::build::Compiled;
use crate::collide::{ContactFrameStats, Contacts};
use crate::error::SimError;
use nalgebra::Vector3;
use std::sync::Arc;
use std::time::Instant;
use weft_scene::{SceneElement, Transform};
use weft_solid::{Integrator, Method, Next, Settings, SolidSystem, State, StepError};

/// The time integration of the implicit steps.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Scheme {
    /// Implicit (backward) Euler: first order, damps swinging motion at O(h).
    #[default]
    ImplicitEuler,
    /// BDF2 ([`Integrator::step_bdf2`]): second order and L-stable. Needs the state one step
    /// before, which [`SimState::history`] carries across frames (and checkpoints); the first
    /// step, a step after a failed one was split, and a step whose length changed start again
    /// with implicit Euler. Needs Newton iterated to the tolerance (`Method::Newton` or
    /// `ProjectedNewton`); not with contacts yet (their detection and their velocity-level
    /// solve are written around implicit Euler's step).
    Bdf2,
}

/// How frames are stepped.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepperSettings {
    /// Substeps per frame (≥ 1).
    pub substeps: usize,
    /// Solver method and tolerance.
    pub solver: Settings,
    /// Levels of step halving allowed when a substep fails.
    pub max_retries: usize,
    /// The most the integrator's matrix and factor may take [bytes]; `None`: no limit.
    pub max_bytes: Option<u64>,
    /// ADMM iterations allowed per Newton iteration in a step with contacts.
    pub contact_iterations: usize,
    /// Time integration.
    pub scheme: Scheme,
}

impl Default for StepperSettings {
    fn default() -> Self {
        StepperSettings {
            substeps: 4,
            solver: Settings::default(),
            max_retries: 4,
            max_bytes: None,
            contact_iterations: 200,
            scheme: Scheme::ImplicitEuler,
        }
    }
}

/// The simulation state at a frame: positions, velocities, and the attachment transforms the
/// frame ended with (the start of the next frame's interpolation).
#[derive(Clone, Debug, PartialEq)]
pub struct SimState {
    /// Solid state.
    pub solid: State,
    /// Transform of each scene element at this frame.
    pub transforms: Vec<Option<Transform>>,
    /// For [`Scheme::Bdf2`]: the state one step before `solid`, and that step's length;
    /// `None` when the next step starts with implicit Euler.
    pub history: Option<(State, f64)>,
    /// Each frozen vertex's input position at this frame (where the next frame's freeze
    /// targets start: [`Compiled::freeze_inputs`]); empty without freeze attachments.
    pub inputs: Vec<Vector3<f64>>,
}

/// What a frame cost.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrameStats {
    /// Solver steps taken (substeps plus the extra ones from retries).
    pub steps: usize,
    /// Substeps that were split because a step failed.
    pub retries: usize,
    /// Why each of those failed, in order: the failure's kind ([`StepError::kind`]) and its
    /// message (the attempt that was split, not its halves' own failures, which come after).
    pub retry_causes: Vec<(&'static str, String)>,
    /// Newton iterations, summed over steps: a contact step's rounds solved again after its
    /// exact check included (not the substeps that failed and were retried as halves).
    pub newton_iterations: usize,
    /// Most Newton iterations in one step (its rounds together).
    pub max_newton_iterations: usize,
    /// Largest final residual of a step [m/s] (where a step's Newton loop ended by its
    /// rate, the estimate of the corrections still to come).
    pub max_residual: f64,
    /// What the linear systems of the Newton iterations cost.
    pub linear: LinearFrameStats,
    /// What the Newton loops did besides full Newton steps.
    pub newton: NewtonFrameStats,
    /// Wall time of the frame.
    pub seconds: f64,
    /// Contacts with colliders: `None` when the scene builds no contact machinery.
    pub contacts: Option<ContactFrameStats>,
}

/// What a frame's linear systems cost: assembling, factorizing and solving them, summed over
/// steps ([`FrameStats::linear`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LinearFrameStats {
    /// Seconds assembling.
    pub assembly_seconds: f64,
    /// Seconds factorizing.
    pub factor_seconds: f64,
    /// Numeric factorizations, summed over steps (failed inertia tries and a contact
    /// step's refactorizations included).
    pub factorizations: usize,
    /// Seconds in triangular solves (and the one-ring preconditioner's conjugate gradients).
    pub solve_seconds: f64,
    /// Conjugate-gradient iterations of the one-ring preconditioner, summed over steps.
    pub cg_iterations: usize,
    /// Factorizations retried with added inertia (the exact Hessian was not positive
    /// definite), summed over steps.
    pub inertia_shifts: usize,
}

/// What a frame's Newton loops did besides full Newton steps: the fallbacks, corrections,
/// extrapolations and local solves that `weft-solid`'s integrator takes
/// ([`FrameStats::newton`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct NewtonFrameStats {
    /// Newton iterations that fell back to projected Hessians, summed over steps.
    pub projected_iterations: usize,
    /// Full Newton steps accepted after a second-order correction of rod lengths.
    pub corrections: usize,
    /// Iterations the second-order corrections took (accepted or not), summed over steps.
    pub correction_iterations: usize,
    /// Contact-step iterations taken at the sum of a geometric tail (see `weft-solid`'s
    /// `integrator/tail.rs`), summed over steps.
    pub extrapolations: usize,
    /// Halvings of those extrapolations' trial lengths (towards the full step), summed.
    pub extrapolation_halvings: usize,
    /// Newton loops ended by their rate's estimate of the corrections still to come (see
    /// `weft-solid`'s `integrator/rate.rs`), summed over steps and over the solves of a
    /// contact step thrown away for a re-solve.
    pub rate_stops: usize,
    /// Moves along a direction of negative curvature after shifted Newton steps (see
    /// `weft-solid`'s `integrator/curvature.rs`), summed over steps and over the solves of
    /// a contact step thrown away for a re-solve.
    pub curvature_moves: usize,
    /// Patches around lagging vertices solved locally after Newton steps (see
    /// `weft-solid`'s `integrator/elimination.rs`), summed like `curvature_moves`.
    pub eliminations: usize,
}

/// Steps one compiled scene. Owns the integrator (pattern and factorization workspace) and a
/// working copy of the system whose spring targets move; it holds no simulation state, so
/// stepping from any checkpoint gives the same result.
pub struct SolidStepper {
    compiled: Arc<Compiled>,
    system: SolidSystem,
    integrator: Integrator,
    settings: StepperSettings,
    targets: Vec<Vector3<f64>>,
    /// The frame being stepped's frozen vertices (their inputs and weights).
    freeze: crate::FreezeFrame,
    /// Contact machinery (None: the scene has no contact pairs, or no frame was stepped).
    contacts: Option<Contacts>,
}

impl SolidStepper {
    /// A stepper for `compiled`.
    pub fn new(compiled: Arc<Compiled>, settings: StepperSettings) -> Result<Self, SimError> {
        if settings.scheme == Scheme::Bdf2
            && !matches!(
                settings.solver.method,
                Method::Newton | Method::ProjectedNewton
            )
        {
            // One Newton iteration of BDF2 from its predictor is not BDF2 (measured on the
            // hanging square: its error grows with the substeps), and explicit and static
            // steps have no implicit formula to change.
            return Err(SimError::Unsupported(format!(
                "integrator bdf2 needs method newton or projected_newton (Newton iterated to \
                 the tolerance), not {:?}: use integrator euler with this method",
                settings.solver.method
            )));
        }
        let integrator = integrator_for(&compiled, &settings)?;
        let targets = compiled.state.x.clone();
        Ok(SolidStepper {
            system: compiled.system.clone(),
            compiled,
            integrator,
            settings,
            targets,
            freeze: Default::default(),
            contacts: None,
        })
    }

    /// Steps `compiled` from now on (the same scene with other parameter values, see
    /// [`Compiled::with_params`], or the scene recompiled after an upstream change). The
    /// integrator's pattern and symbolic factorization are kept when the system's structure
    /// (vertices, held vertices, rigid groups, the elements' stencils) is the same; contacts
    /// are rebuilt on the next frame.
    pub fn set_compiled(&mut self, compiled: Arc<Compiled>) -> Result<(), SimError> {
        if !same_structure(&self.compiled.system, &compiled.system) {
            let fresh = integrator_for(&compiled, &self.settings)?;
            let old = std::mem::replace(&mut self.integrator, fresh);
            self.integrator.keep_hooks(old);
            self.targets = compiled.state.x.clone();
        }
        self.system = compiled.system.clone();
        self.compiled = compiled;
        self.contacts = None;
        Ok(())
    }

    /// Sets (or clears) the check the integrator asks once per Newton iteration; when it
    /// answers true, [`Self::advance`] fails with [`SimError::Interrupted`].
    pub fn set_stop(&mut self, stop: Option<weft_solid::StopCheck>) {
        self.integrator.set_stop(stop);
    }

    /// Says how much more the process may allocate now [bytes] (before a frame): the limit
    /// its integrator builds later factors within, and its contacts' room
    /// ([`Integrator::set_available`]).
    pub fn set_available(&mut self, available: u64) {
        if self.settings.max_bytes.is_none() {
            return;
        }
        self.settings.max_bytes = Some(available);
        self.integrator.set_available(available);
        if let Some(c) = &mut self.contacts {
            c.set_available(available);
        }
    }

    /// Sets (or clears) where the steps store their progress for a progress line.
    pub fn set_progress(&mut self, progress: Option<Arc<weft_solid::Progress>>) {
        self.integrator.set_progress(progress);
    }

    /// The compiled scene.
    pub fn compiled(&self) -> &Compiled {
        &self.compiled
    }

    /// The state at the start frame.
    pub fn initial_state(&self, scene: &[SceneElement]) -> SimState {
        SimState {
            solid: self.compiled.state.clone(),
            transforms: scene.iter().map(|e| e.transform).collect(),
            history: None,
            inputs: self.compiled.freeze_inputs(scene),
        }
    }

    fn set_targets(&mut self, from: &[Option<Transform>], to: &[Option<Transform>], s: f64) {
        self.compiled
            .set_targets(from, to, s, &mut self.system, &mut self.targets);
        self.compiled.set_freeze(&self.freeze, s, &mut self.system);
    }

    #[allow(clippy::too_many_arguments)]
    fn interval(
        &mut self,
        st: &mut State,
        history: &mut Option<(State, f64)>,
        from: &[Option<Transform>],
        to: &[Option<Transform>],
        s0: f64,
        s1: f64,
        h: f64,
        depth: usize,
        stats: &mut FrameStats,
    ) -> Result<(), StepError> {
        self.set_targets(from, to, s1);
        if let Some(p) = self.integrator.progress() {
            let n = self.settings.substeps.max(1);
            p.substep(((s0 * n as f64) as usize + 1).min(n), n, depth);
        }
        let bdf2 = self.settings.scheme == Scheme::Bdf2 && depth == 0;
        let before = bdf2.then(|| st.clone());
        let result = if let Some(c) = &mut self.contacts {
            c.step(
                &mut self.integrator,
                &self.system,
                st,
                Some(&self.targets),
                None,
                (s0, s1, h),
                &self.settings.solver,
                depth >= self.settings.max_retries,
                stats.contacts.get_or_insert_with(Default::default),
            )
        } else if let Some((prev, _)) = history.as_ref().filter(|(_, hp)| bdf2 && *hp == h) {
            self.integrator.step_bdf2(
                &self.system,
                st,
                prev,
                Some(&self.targets),
                h,
                &self.settings.solver,
            )
        } else {
            self.integrator.step(
                &self.system,
                st,
                Some(&self.targets),
                h,
                &self.settings.solver,
            )
        };
        match result {
            Ok(s) => {
                stats.steps += 1;
                stats.newton_iterations += s.iterations;
                stats.max_newton_iterations = stats.max_newton_iterations.max(s.iterations);
                // `f64::max` skips the NaN of a step without residuals (explicit).
                stats.max_residual = stats.max_residual.max(s.final_residual());
                let linear = &mut stats.linear;
                linear.assembly_seconds += s.assembly_seconds;
                linear.factor_seconds += s.factor_seconds;
                linear.factorizations += s.factorizations;
                linear.solve_seconds += s.solve_seconds;
                linear.cg_iterations += s.cg_iterations;
                linear.inertia_shifts += s.shifted;
                let newton = &mut stats.newton;
                newton.projected_iterations += s.projected;
                newton.corrections += s.corrections;
                newton.correction_iterations += s.correction_sweeps;
                newton.extrapolations += s.extrapolations;
                newton.extrapolation_halvings += s.extrapolation_halvings;
                newton.rate_stops += s.rate_stops;
                newton.curvature_moves += s.curvature_moves;
                newton.eliminations += s.eliminations;
                *history = before.map(|b| (b, h));
                Ok(())
            }
            // The step's own answer: only what a smaller step may cure is retried smaller
            // (a stop, an inconsistent system or a refusal to allocate is not).
            Err(e) if e.next() == Next::RetrySmaller && depth < self.settings.max_retries => {
                stats.retries += 1;
                stats.retry_causes.push((e.kind(), e.to_string()));
                let mid = 0.5 * (s0 + s1);
                // Split steps are implicit Euler; the step after them starts BDF2 again.
                *history = None;
                self.interval(st, history, from, to, s0, mid, 0.5 * h, depth + 1, stats)?;
                self.interval(st, history, from, to, mid, s1, 0.5 * h, depth + 1, stats)?;
                *history = None;
                Ok(())
            }
            Err(e) => Err(e),
        }
    }

    /// State at `frame` from the state at the previous frame; `scene` is the scene at `frame`
    /// (its attachment transforms are this frame's targets).
    pub fn advance(
        &mut self,
        prev: &SimState,
        scene: &[SceneElement],
        frame: i64,
        frame_dt: f64,
    ) -> Result<(SimState, FrameStats), SimError> {
        let t0 = Instant::now();
        self.compiled.check_scene(scene, frame)?;
        let to: Vec<Option<Transform>> = scene.iter().map(|e| e.transform).collect();
        self.freeze = self
            .compiled
            .freeze_frame(scene, &prev.inputs, frame, frame_dt)?;
        let n = self.settings.substeps.max(1);
        let h = frame_dt / n as f64;
        let mut st = prev.solid.clone();
        let mut history = prev.history.clone();
        let mut stats = FrameStats::default();
        if self.contacts.is_none() {
            let max_admm = self.settings.contact_iterations;
            self.contacts = Contacts::new(
                self.compiled.clone(),
                scene,
                max_admm,
                self.settings.max_bytes,
            );
        }
        if !self.compiled.system.rigid.is_empty() && self.settings.scheme == Scheme::Bdf2 {
            return Err(SimError::Unsupported(
                "integrator bdf2 does not keep rigid attachments rigid yet (its blended start \
                 state is not a rigid placement): use integrator euler for this scene"
                    .into(),
            ));
        }
        if self.contacts.is_some() && self.settings.scheme == Scheme::Bdf2 {
            return Err(SimError::Unsupported(
                "integrator bdf2 does not step contacts yet (their detection and solve are \
                 written around implicit Euler's step): use integrator euler for this scene"
                    .into(),
            ));
        }
        if let Some(c) = &mut self.contacts {
            c.frame(scene, &prev.transforms, &to)?;
            stats.contacts = Some(ContactFrameStats::default());
        }
        for k in 0..n {
            let (s0, s1) = (k as f64 / n as f64, (k + 1) as f64 / n as f64);
            let retries_before = stats.retries;
            self.interval(
                &mut st,
                &mut history,
                &prev.transforms,
                &to,
                s0,
                s1,
                h,
                0,
                &mut stats,
            )
            .map_err(|e| match e.next() {
                Next::Stop => SimError::Interrupted {
                    frame,
                    substep: k + 1,
                    substeps: n,
                    detail: e.to_string(),
                },
                Next::RetrySmaller | Next::Fail => SimError::StepFailed {
                    frame,
                    substep: k + 1,
                    substeps: n,
                    retries: stats.retries - retries_before,
                    message: e.to_string(),
                },
            })?;
        }
        stats.seconds = t0.elapsed().as_secs_f64();
        Ok((
            SimState {
                solid: st,
                transforms: to,
                history,
                inputs: std::mem::take(&mut self.freeze.end),
            },
            stats,
        ))
    }

    /// The scene with simulated elements moved to `state` (and a `velocity` channel set).
    pub fn scene_at<'a>(
        &self,
        scene: impl IntoIterator<Item = &'a SceneElement>,
        state: &SimState,
    ) -> Vec<SceneElement> {
        self.compiled.scene_at(scene, &state.solid)
    }
}

/// The integrator for `compiled`'s system (its pattern and factorization workspace).
fn integrator_for(compiled: &Compiled, settings: &StepperSettings) -> Result<Integrator, SimError> {
    Integrator::new_within(&compiled.system, settings.max_bytes).map_err(|e| match e {
        StepError::TooLarge { .. } => SimError::TooLarge(e.to_string()),
        e => SimError::StepFailed {
            frame: 0,
            substep: 0,
            substeps: settings.substeps,
            retries: 0,
            message: format!("setting up the solver: {e}"),
        },
    })
}

/// Whether an integrator built for `a` serves `b`: the same vertices, held vertices, rigid
/// groups and element stencils, in the same order.
fn same_structure(a: &SolidSystem, b: &SolidSystem) -> bool {
    let stencils = |s: &SolidSystem| {
        let mut v = Vec::new();
        s.elements.for_each(|e| {
            v.push(u32::MAX);
            v.extend_from_slice(e.vertices());
        });
        v
    };
    a.mass.len() == b.mass.len()
        && a.pinned == b.pinned
        && a.rigid.len() == b.rigid.len()
        && a.rigid
            .iter()
            .zip(&b.rigid)
            .all(|(x, y)| x.vertices == y.vertices)
        && a.elements.len() == b.elements.len()
        && stencils(a) == stencils(b)
}
