//! `solver.solid`: the stateful cloth and hair solver.
//!
//! At the start frame it compiles (scene, Behavior tree) into a solid system; each later frame
//! is one step of the [`SolidStepper`] from the previous frame's state, reading the scene at
//! the new frame (so attachments follow animated transforms), and its SECs and Behavior tree
//! there: values an animated parameter changed compile the system's coefficients again. The
//! state checkpointed per frame is the simulation state and the frame's input elements (shared
//! with the nodes upstream, not copied); the compiled system rides along (shared), so resuming
//! from any checkpoint continues exactly. The output scene is built from them when it is asked
//! for, not kept with every frame's state: a frame's kept state is then its positions and
//! velocities (a copied scene, geometry and channels, would be most of it, and its fresh
//! pages would cost every frame page faults).

use super::types::Scene;
use std::collections::VecDeque;
use std::sync::Arc;
use weft_graph::{
    EvalCx, Kernel, NodeError, NodeSpec, ParamSpec, Params, Registry, RegistryError, Step,
    TimeClass, Value,
};
use weft_scene::SceneElement;
use weft_sim::{
    BehaviorTree, Compiled, FrameStats, SimState, SolidStepper, StepperSettings, compile_within,
};
use weft_solid::{Method, Settings};

#[derive(Clone)]
struct SolverState {
    compiled: Arc<Compiled>,
    sim: SimState,
    /// The frame's input elements (the values on `elements` that are elements).
    inputs: Vec<Value>,
}

impl SolverState {
    /// The frame's input elements.
    fn elements(&self) -> impl Iterator<Item = &SceneElement> {
        self.inputs.iter().filter_map(|v| v.get::<SceneElement>())
    }

    /// The input elements, simulated ones moved to the state (with a `velocity` channel).
    fn scene(&self) -> Scene {
        self.compiled.scene_at(self.elements(), &self.sim.solid)
    }
}

#[derive(Default)]
struct SolidSolver {
    stepper: Option<SolidStepper>,
    frames: VecDeque<(i64, FrameStats)>,
    compiled: Option<Arc<Compiled>>,
    /// The graph's stop handle the stepper was given.
    interrupt: Option<weft_graph::Interrupt>,
    /// Steps and Newton iterations over every frame stepped (`frames` keeps the last 1024).
    totals: [u64; 2],
    /// Where the stepper's steps are, shown as the run's activity during a frame.
    progress: Arc<weft_solid::Progress>,
}

/// Shows `progress` as the run's activity ([`weft_graph::Interrupt::set_activity`]) while
/// alive: a frame that takes minutes is seen working (its substep, Newton iteration,
/// contacts and ADMM iterations), not only when it ends.
pub(crate) struct Showing(weft_graph::Interrupt);

impl Showing {
    pub(crate) fn new(run: weft_graph::Interrupt, progress: &Arc<weft_solid::Progress>) -> Self {
        let p = progress.clone();
        run.set_activity(Some(Arc::new(move || p.line())));
        Showing(run)
    }
}

impl Drop for Showing {
    fn drop(&mut self) {
        self.0.set_activity(None);
    }
}

fn settings(p: &Params, max_bytes: u64) -> Result<StepperSettings, weft_graph::ParamError> {
    let method = match p.str("method")? {
        "explicit" => Method::Explicit,
        "linearized" => Method::Linearized,
        "static" => Method::Static,
        "projected_newton" => Method::ProjectedNewton,
        _ => Method::Newton,
    };
    Ok(StepperSettings {
        substeps: p.usize("substeps")?.max(1),
        max_retries: p.usize("max_retries")?,
        max_bytes: Some(max_bytes),
        contact_iterations: p.usize("contact_iterations")?.max(1),
        scheme: match p.str("integrator")? {
            "bdf2" => weft_sim::Scheme::Bdf2,
            _ => weft_sim::Scheme::ImplicitEuler,
        },
        solver: Settings {
            method,
            tolerance: p.f64("tolerance")?,
            max_iterations: p.usize("max_iterations")?.max(1),
        },
    })
}

/// Retried substeps counted by cause, in the order each cause first came: "2 × Newton did not
/// converge, 1 × contact solve diverged".
fn retry_summary(causes: &[(&'static str, String)]) -> String {
    let mut counts: Vec<(&str, usize)> = Vec::new();
    for (kind, _) in causes {
        match counts.iter_mut().find(|(k, _)| k == kind) {
            Some((_, n)) => *n += 1,
            None => counts.push((kind, 1)),
        }
    }
    counts
        .iter()
        .map(|(k, n)| format!("{n} × {k}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The values on `elements` that are elements (shared with upstream).
fn element_inputs(cx: &mut EvalCx<'_>) -> Result<Vec<Value>, NodeError> {
    let mut inputs = cx.inputs("elements")?;
    inputs.retain(|v| v.get::<SceneElement>().is_some());
    Ok(inputs)
}

/// Copies of the elements among `inputs` (the compiler and the stepper read a scene).
fn copies(inputs: &[Value]) -> Scene {
    inputs
        .iter()
        .filter_map(|v| v.get::<SceneElement>().cloned())
        .collect()
}

impl SolidSolver {
    fn stepper(
        &mut self,
        compiled: &Arc<Compiled>,
        p: &Params,
        stop: weft_graph::Interrupt,
    ) -> Result<&mut SolidStepper, NodeError> {
        let fresh = self
            .stepper
            .as_ref()
            .is_none_or(|s| !std::ptr::eq(s.compiled(), &**compiled));
        // Another compile (an animated parameter, an upstream change): the stepper keeps its
        // integrator when the structure is the same.
        if let (true, Some(s)) = (fresh, self.stepper.as_mut()) {
            s.set_compiled(compiled.clone())
                .map_err(|e| NodeError::Failed(e.to_string()))?;
        } else if fresh {
            let mut stepper = SolidStepper::new(
                compiled.clone(),
                settings(p, weft_graph::memory::measure())?,
            )
            .map_err(|e| NodeError::Failed(e.to_string()))?;
            stepper.set_progress(Some(self.progress.clone()));
            self.stepper = Some(stepper);
            self.interrupt = None;
        }
        let stepper = self.stepper.as_mut().expect("just built");
        if self.interrupt.as_ref().is_none_or(|i| !i.same(&stop)) {
            stepper.set_stop(Some(stop.checker()));
            self.interrupt = Some(stop);
        }
        Ok(stepper)
    }
}

impl Step for SolidSolver {
    fn init(&mut self, cx: &mut EvalCx<'_>) -> Result<Value, NodeError> {
        let inputs = element_inputs(cx)?;
        let scene = copies(&inputs);
        let tree = cx.input_as::<BehaviorTree>("tree")?;
        let compiled = Arc::new(
            compile_within(&scene, &tree, Some(cx.memory_budget()))
                .map_err(|e| NodeError::Failed(e.to_string()))?,
        );
        for w in &compiled.warnings {
            cx.warn(w.clone());
        }
        self.compiled = Some(compiled.clone());
        self.frames.clear();
        self.totals = [0; 2];
        let params = cx.params().clone();
        let st = settings(&params, 0)?;
        let per_frame = weft_sim::estimate::solid_step_seconds(&compiled, st.solver.method)
            * st.substeps as f64;
        if per_frame > weft_sim::estimate::WARN_SECONDS_PER_FRAME {
            cx.warn(format!(
                "a rough cost model puts each frame at about {} ({} simulated vertices, {} substeps of {:?}); Ctrl-C stops the run and keeps the frames done, --time-limit bounds it",
                weft_sim::estimate::human_seconds(per_frame),
                compiled.state.x.len(),
                st.substeps,
                st.solver.method,
            ));
        }
        let stepper = self.stepper(&compiled, &params, cx.interrupt())?;
        let sim = stepper.initial_state(&scene);
        Ok(Value::new(SolverState {
            compiled,
            sim,
            inputs,
        }))
    }

    fn step(&mut self, state: &Value, cx: &mut EvalCx<'_>) -> Result<Value, NodeError> {
        let prev = state
            .get::<SolverState>()
            .ok_or_else(|| NodeError::Failed("the state is not a solver.solid state".into()))?;
        let inputs = element_inputs(cx)?;
        let scene = copies(&inputs);
        let tree = cx.input_as::<BehaviorTree>("tree")?;
        let (frame, dt) = (cx.frame(), 1.0 / cx.context().fps);
        // Animated parameters: SEC and Behavior values are read at every frame; a change
        // compiles the system's coefficients again (structure and rest shapes stay).
        let compiled = match prev
            .compiled
            .with_params(&scene, Some(&tree), frame, Some(cx.memory_budget()))
            .map_err(|e| NodeError::Failed(e.to_string()))?
        {
            Some(c) => Arc::new(c),
            None => prev.compiled.clone(),
        };
        let params = cx.params().clone();
        let _showing = Showing::new(cx.interrupt(), &self.progress);
        let stepper = self.stepper(&compiled, &params, cx.interrupt())?;
        // Measured now, not the quarter-second cache: the integrator adds what it holds to
        // it, and a reading from before it was built would count that twice.
        stepper.set_available(weft_graph::memory::measure());
        let (sim, stats) = stepper
            .advance(&prev.sim, &scene, frame, dt)
            .map_err(|e| match e {
                weft_sim::SimError::Interrupted { .. } => {
                    NodeError::Interrupted(format!("{}: {e}", cx.interrupt().reason()))
                }
                e => NodeError::Failed(e.to_string()),
            })?;
        if stats.retries > 0 {
            cx.warn(format!(
                "{} substep(s) failed and were retried with smaller steps ({})",
                stats.retries,
                retry_summary(&stats.retry_causes)
            ));
        }
        if self.frames.len() == 1024 {
            self.frames.pop_front();
        }
        self.totals[0] += stats.steps as u64;
        self.totals[1] += stats.newton_iterations as u64;
        self.frames.push_back((frame, stats));
        Ok(Value::new(SolverState {
            compiled,
            sim,
            inputs,
        }))
    }

    fn outputs(&mut self, state: &Value, cx: &mut EvalCx<'_>) -> Result<(), NodeError> {
        let s = state
            .get::<SolverState>()
            .ok_or_else(|| NodeError::Failed("the state is not a solver.solid state".into()))?;
        cx.set("scene", Value::new(s.scene()));
        Ok(())
    }

    fn state_bytes(&self, state: &Value, _: &weft_graph::Registry) -> usize {
        // Positions and velocities, BDF2's history of them when it keeps one, and the frame's
        // input elements. Those are shared with upstream, and across frames where upstream
        // does not change, but counted in each, as a copy would be: a collider moved every
        // frame is a new element every frame, and the memory budget must see it.
        state.get::<SolverState>().map_or(0, |s| {
            48 * s.sim.solid.x.len() * (1 + usize::from(s.sim.history.is_some()))
                + s.elements().map(SceneElement::heap_bytes).sum::<usize>()
        })
    }

    fn save_state(&self, state: &Value, _: &weft_graph::Registry) -> Option<Vec<u8>> {
        let s = state.get::<SolverState>()?;
        let mut w = weft_graph::codec::Writer::new();
        super::checkpoint::write_solid(&mut w, &s.sim);
        Some(w.finish())
    }

    /// The saved positions, velocities and transforms on the start frame's compiled scene;
    /// the frame's input elements are kept with it, as a step keeps them.
    fn load_state(
        &mut self,
        bytes: &[u8],
        initial: &Value,
        cx: &mut EvalCx<'_>,
    ) -> Result<Value, NodeError> {
        let init = initial.get::<SolverState>().ok_or_else(|| {
            NodeError::Failed("the start state is not a solver.solid state".into())
        })?;
        let mut r = weft_graph::codec::Reader::new(bytes);
        let sim = super::checkpoint::read_solid(&mut r, &init.sim)
            .and_then(|s| r.end().map(|()| s))
            .map_err(|m| NodeError::Failed(format!("checkpoint: {m}")))?;
        let inputs = element_inputs(cx)?;
        let params = cx.params().clone();
        self.stepper(&init.compiled, &params, cx.interrupt())?;
        Ok(Value::new(SolverState {
            compiled: init.compiled.clone(),
            sim,
            inputs,
        }))
    }

    fn stats_json(&self) -> Option<serde_json::Value> {
        let frames: Vec<_> = self
            .frames
            .iter()
            .map(|(f, s)| {
                let mut j = serde_json::json!({
                    "frame": f, "steps": s.steps, "retries": s.retries, "newton_iterations": s.newton_iterations,
                    "max_newton_iterations": s.max_newton_iterations, "max_residual": s.max_residual,
                    "assembly_seconds": s.linear.assembly_seconds, "factor_seconds": s.linear.factor_seconds,
                    "factorizations": s.linear.factorizations,
                    "solve_seconds": s.linear.solve_seconds, "cg_iterations": s.linear.cg_iterations, "seconds": s.seconds,
                    "inertia_shifts": s.linear.inertia_shifts, "projected_iterations": s.newton.projected_iterations,
                    "corrections": s.newton.corrections, "correction_iterations": s.newton.correction_iterations,
                    "extrapolations": s.newton.extrapolations,
                    "extrapolation_halvings": s.newton.extrapolation_halvings,
                    "rate_stops": s.newton.rate_stops, "curvature_moves": s.newton.curvature_moves,
                    "eliminations": s.newton.eliminations,
                    "retry_causes": s.retry_causes.iter().map(|(_, m)| m).collect::<Vec<_>>(),
                });
                if let Some(c) = &s.contacts {
                    j["contacts"] = super::types::contact_stats_json(c);
                }
                j
            })
            .collect();
        let c = self.compiled.as_ref();
        Some(serde_json::json!({
            "terms": c.map(|c| serde_json::json!(c.terms)),
            "warnings": c.map(|c| c.warnings.clone()),
            "solid_frames": frames,
            "total_steps": self.totals[0],
            "total_newton_iterations": self.totals[1],
        }))
    }
}

pub(crate) fn register(r: &mut Registry) -> Result<(), RegistryError> {
    r.register(
        NodeSpec::new("solver.solid", "steps cloth and hair: implicit Euler by Newton (exact Hessians where positive definite, else projected; or explicit / linearized), with substeps and retries")
            .time(TimeClass::Stateful)
            .input_multi("elements", "element", "the scene's elements (cloth, hair, attachments, colliders)")
            .input("tree", "behavior_tree", "what is simulated")
            .output("scene", "scene", "the elements at this frame")
            .param(ParamSpec::int("substeps", 4).ge(1.0).le(100_000.0).doc("steps per frame"))
            .param(ParamSpec::choice("method", &["newton", "linearized", "explicit", "static", "projected_newton"], "newton").doc("newton: implicit Euler to tolerance (exact Hessians where positive definite, else projected); projected_newton: the same answer with every element Hessian projected to PSD (slower where cloth buckles; for comparison); linearized: one Newton step; explicit: symplectic Euler; static: no inertia, each step finds the equilibrium under that step's loads and attachment targets (substeps load the structure gradually)"))
            .param(ParamSpec::choice("integrator", &["euler", "bdf2"], "euler").doc("time integration of the implicit methods: euler: implicit Euler (first order: damps swinging motion, more the longer the step); bdf2: the second-order backward differentiation formula, still L-stable (stiff modes damped), each step solved like Euler's with 2/3 of the step from a blend of the last two states; starts with one Euler step, restarts after a split step; needs method newton or projected_newton; not with contacts yet"))
            .param(ParamSpec::float("tolerance", 1e-6).gt(0.0).unit("m/s").doc("Newton stops when a further iteration would change velocities by less, measured by that iteration or (method newton, and every contact step) estimated from the last two full steps' contraction (method static: positions, in m, measured)"))
            .param(ParamSpec::int("max_iterations", 50).ge(1.0).le(10_000.0).doc("Newton iteration limit per step"))
            .param(ParamSpec::int("max_retries", 4).ge(0.0).le(16.0).doc("levels of step halving when a step fails"))
            .param(ParamSpec::int("contact_iterations", 200).ge(1.0).le(100_000.0).doc("ADMM iterations allowed per Newton iteration in a step with contacts (behavior.collision)")),
        |_| Ok(Kernel::Step(Box::new(SolidSolver::default()))),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use weft_scene::{ElementKind, Geometry};
    use weft_sim::{DiscreteShellMaterial, Gravity, compile};

    /// The warning's summary counts retried substeps by kind, first come first.
    #[test]
    fn retried_substeps_are_summarised_by_cause() {
        let causes = [
            (
                "Newton did not converge",
                "Newton did not converge in 100 …".to_string(),
            ),
            (
                "contact solve diverged",
                "the contact solve diverged at …".to_string(),
            ),
            (
                "Newton did not converge",
                "Newton did not converge in 100 …".to_string(),
            ),
        ];
        assert_eq!(
            retry_summary(&causes),
            "2 × Newton did not converge, 1 × contact solve diverged"
        );
    }

    /// A kept frame's size, which the memory budget thins the kept frames by: its positions
    /// and velocities, and each input element's data (counted even where it is shared, as a
    /// collider moved every frame is a new element every frame).
    #[test]
    fn a_kept_state_counts_its_positions_velocities_and_input_elements() {
        let mesh = weft_scene::procedural::grid(
            [1.0, 1.0],
            [3, 3],
            weft_scene::procedural::Plane::Xy,
            [0.0; 3],
        );
        let cloth = SceneElement::new("cloth", ElementKind::Cloth, Geometry::Mesh(mesh));
        let collider = SceneElement::new(
            "ball",
            ElementKind::Collider,
            Geometry::Points(vec![[0.0; 3]; 100]),
        );
        let tree = BehaviorTree {
            behaviors: vec![
                Arc::new(DiscreteShellMaterial),
                Arc::new(Gravity {
                    acceleration: [0.0, -9.81, 0.0],
                }),
            ],
        };
        let scene = vec![cloth, collider];
        let compiled = Arc::new(compile(&scene, &tree).unwrap());
        let sim = SimState {
            solid: compiled.state.clone(),
            transforms: vec![None; 2],
            history: None,
            inputs: Vec::new(),
        };
        let inputs: Vec<Value> = scene.iter().cloned().map(Value::new).collect();
        let state = Value::new(SolverState {
            compiled,
            sim,
            inputs,
        });
        let solver = SolidSolver::default();
        let registry = crate::registry();
        // 3 × 3 vertices (8 triangles): 48 bytes each for position and velocity, and the
        // elements' own estimate (24 a vertex, 12 a triangle, 256 for the rest).
        let elements: usize = scene.iter().map(SceneElement::heap_bytes).sum();
        assert_eq!(elements, (24 * 9 + 12 * 8 + 256) + (24 * 100 + 256));
        assert_eq!(solver.state_bytes(&state, &registry), 48 * 9 + elements);
    }
}
