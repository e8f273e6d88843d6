//! The coupled solid–fluid solver as nodes (DESIGN §6): `solver.coupled` is a library
//! subgraph — an iterating, stepped composite — whose stages are the `coupled.*` nodes below.
//!
//! Per frame (one time step h = 1/fps): **predict** advects the fluid (u*; gravity is in the
//! hydrostatic pressure) and, when asked, diffuses it (viscosity);
//! then, per coupling iteration, **forces** samples the solids in the fluid iterate (drag,
//! pressure, lift), **solid** solves the implicit solid step with them (Aitken- or quasi-Newton-relaxed in
//! Newton mode), **rasterize** puts the solids' fractions, drag and velocities on the faces,
//! **pressure** projects u* with the solids prescribed, and **update** forms the next iterate
//! and tests convergence. **finish** ends the step. Values between stages are immutable
//! (shared with `Arc`), so a frame's state can be cached and resumed; the stages' solver
//! workspaces (integrator pattern, pressure preconditioner) live in their kernels and are
//! rebuilt when the compiled scene changes.
//!
//! `coupled.setup` (outside the composite) compiles the scene and makes the fluid's initial
//! grid — none when the scene has no fluid-domain element. The node types are registered in
//! `coupled_nodes.rs`, with `coupled.scene`, `coupled.probe` and `coupled.momentum`, which
//! read results out of a state; a state's checkpoint encoding is in `checkpoint.rs`.

use super::types::Scene;
use nalgebra::Vector3;
use std::collections::VecDeque;
use std::sync::Arc;
use weft_fluid::{FluidProperties, MacGrid, PressureSolve};
use weft_graph::{Compute, EvalCx, Kernel, NodeError, NodeSpec, Registry, RegistryError, Value};
use weft_scene::Transform;
use weft_sim::{
    BehaviorTree, Compiled, ContactFrameStats, Contacts, CoupledSettings, CoupledStepper, Coupling,
    Exchange, Relaxation, RelaxationMethod, SimState, compile_within, fluid_change, relax,
    velocity_change,
};
use weft_solid::{Method, Settings, SolidSystem, State};

/// The coupled solver's state at a frame, and the iterate within a step.
#[derive(Clone)]
pub struct CoupledState {
    /// The compiled scene (solid system, drag elements, fluid spec).
    pub compiled: Arc<Compiled>,
    /// Solid positions and velocities, and the transforms of this frame.
    pub sim: SimState,
    /// The fluid (None: the scene has no fluid).
    pub fluid: Option<Arc<MacGrid>>,
    /// The input scene at this frame.
    pub scene: Arc<Scene>,
    /// Coupling iteration within the step (0 at a frame's state).
    pub iteration: usize,
    /// Aitken memory within the step.
    pub relaxation: Relaxation,
    /// Last changes of solid and fluid velocity [m/s].
    pub residual: [f64; 2],
    /// The momentum the coupling gave the fluid over the step [kg·m/s]: Σ ρα(u − u*)Δx³,
    /// u* the advected velocity the step started from (what the solids' momentum change
    /// balances; zero for one-way coupling and without fluid).
    pub exchange: [f64; 3],
    /// The rest of the fluid's momentum change over the step [kg·m/s]: Σ ρα u now − Σ ρα u
    /// at the step's start − `exchange`, what advection (not conservative) and the solids'
    /// moving fractions changed.
    pub transport: [f64; 3],
}

/// What a step starts from, fixed across its iterations.
pub struct StepStart {
    compiled: Arc<Compiled>,
    h: f64,
    method: Coupling,
    start: SimState,
    to: Vec<Option<Transform>>,
    scene: Arc<Scene>,
    /// u* (for one-way: the fluid projected without solids).
    u_star: Option<Arc<MacGrid>>,
    /// The frozen vertices' inputs and weights over the step.
    freeze: weft_sim::FreezeFrame,
    /// The fluid's momentum at the step's start, Σ ρ α u Δx³ [kg·m/s] (zero without fluid).
    fluid_momentum: [f64; 3],
}

/// What solids and fluid exchange in one iteration.
pub struct ExchangeValue(Exchange);

/// A solid iterate.
pub struct SolidIterate {
    state: State,
    relaxation: Relaxation,
    iteration: usize,
    /// The fixed point's residual |H(v) − v| before relaxation [m/s].
    change: f64,
}

/// A fluid iterate (None without fluid, or in stages that do nothing for this method).
pub struct FluidValue(Option<Arc<MacGrid>>, usize);

pub(super) fn get<'a, T: 'static>(v: &'a Value, port: &str) -> Result<&'a T, NodeError> {
    v.get::<T>().ok_or_else(|| NodeError::Input {
        port: port.into(),
        message: "unexpected value type".into(),
    })
}

pub(super) fn failed(e: impl std::fmt::Display) -> NodeError {
    NodeError::Failed(e.to_string())
}

/// A stage's error at `frame`: a stop (Ctrl-C, a time limit) stays a stop, with its reason.
fn stage_error(
    frame: i64,
    e: weft_sim::CoupledError,
    stop: &Option<weft_graph::Interrupt>,
) -> NodeError {
    if e.is_interrupted() {
        let why = stop.as_ref().map_or("stopped".into(), |i| i.reason());
        NodeError::Interrupted(format!("{why}: frame {frame}: {e}"))
    } else {
        NodeError::Failed(format!("frame {frame}: {e}"))
    }
}

pub(super) fn settings(compiled: &Compiled) -> CoupledSettings {
    let g = compiled.system.gravity;
    CoupledSettings {
        fluid: compiled
            .fluid
            .as_ref()
            .map_or(FluidProperties::WATER, |f| f.properties),
        gravity: [g.x, g.y, g.z],
        ..Default::default()
    }
}

/// A stage's workspace, rebuilt when the compiled scene changes.
#[derive(Default)]
pub(super) struct Workspace {
    compiled: Option<Arc<Compiled>>,
    stepper: CoupledStepper,
    system: Option<SolidSystem>,
    targets: Vec<Vector3<f64>>,
    /// Contact machinery (stage C; None: no contact pairs, or not built yet).
    contacts: Option<Contacts>,
    log: VecDeque<serde_json::Value>,
    /// The graph's stop handle the solvers were given.
    interrupt: Option<weft_graph::Interrupt>,
    /// Where stage C's solid solve is, shown as the run's activity while it runs.
    progress: Arc<weft_solid::Progress>,
}

impl Workspace {
    fn for_scene(&mut self, c: &Arc<Compiled>) -> &mut Self {
        if self.compiled.as_ref().is_none_or(|o| !Arc::ptr_eq(o, c)) {
            let interrupt = self.interrupt.take();
            // The log is the node's report across frames (an animated parameter compiles the
            // scene again at every frame it changes).
            let log = std::mem::take(&mut self.log);
            *self = Workspace {
                compiled: Some(c.clone()),
                system: Some(c.system.clone()),
                targets: c.state.x.clone(),
                log,
                ..Default::default()
            };
            self.stepper
                .set_stop(interrupt.as_ref().map(|i| i.checker()));
            self.interrupt = interrupt;
        }
        self
    }
    /// Hands the graph's stop handle to the solvers (once per handle).
    fn watch(&mut self, i: weft_graph::Interrupt) {
        if self.interrupt.as_ref().is_none_or(|o| !o.same(&i)) {
            self.stepper.set_stop(Some(i.checker()));
            self.interrupt = Some(i);
        }
    }
    fn record(&mut self, j: serde_json::Value) {
        if self.log.len() == 1024 {
            self.log.pop_front();
        }
        self.log.push_back(j);
    }
}

/// A compute kernel with a workspace.
struct Stage {
    ws: Workspace,
    run: fn(&mut Workspace, &mut EvalCx<'_>) -> Result<(), NodeError>,
}

impl Compute for Stage {
    fn compute(&mut self, cx: &mut EvalCx<'_>) -> Result<(), NodeError> {
        self.ws.watch(cx.interrupt());
        (self.run)(&mut self.ws, cx)
    }
    fn stats_json(&self) -> Option<serde_json::Value> {
        if self.ws.log.is_empty() {
            return None;
        }
        Some(serde_json::json!({ "iterations": self.ws.log }))
    }
}

pub(super) fn stage(
    r: &mut Registry,
    spec: NodeSpec,
    run: fn(&mut Workspace, &mut EvalCx<'_>) -> Result<(), NodeError>,
) -> Result<(), RegistryError> {
    r.register(spec, move |_| {
        Ok(Kernel::Compute(Box::new(Stage {
            ws: Workspace::default(),
            run,
        })))
    })
}

pub(super) fn setup(ws: &mut Workspace, cx: &mut EvalCx<'_>) -> Result<(), NodeError> {
    let scene = cx.input("scene")?;
    let scene = get::<Scene>(&scene, "scene")?.clone();
    let tree = cx.input_as::<BehaviorTree>("tree")?;
    let compiled =
        Arc::new(compile_within(&scene, &tree, Some(cx.memory_budget())).map_err(failed)?);
    for w in &compiled.warnings {
        cx.warn(w.clone());
    }
    // About seven coupling iterations a frame, each a (warm-started) solid solve and a
    // pressure solve: see weft_sim::estimate.
    let cells = compiled.fluid.as_ref().map_or(0, |f| f.domain.cell_count());
    let per_frame = 7.0
        * (0.5 * weft_sim::estimate::solid_step_seconds(&compiled, Method::Newton)
            + weft_sim::estimate::pressure_solve_seconds(cells));
    if per_frame > weft_sim::estimate::WARN_SECONDS_PER_FRAME {
        cx.warn(format!(
            "a rough cost model puts each coupled frame at about {} ({} simulated vertices, {cells} fluid cells); Ctrl-C stops the run and keeps the frames done, --time-limit bounds it",
            weft_sim::estimate::human_seconds(per_frame),
            compiled.state.x.len(),
        ));
    }
    let fluid = compiled.fluid.as_ref().map(|f| Arc::new(f.initial_grid()));
    let grid = compiled.fluid.as_ref().map(|f| {
        let d = &f.domain;
        serde_json::json!({
            "element": f.element, "cells": d.cells, "cell_size": d.dx, "origin": d.origin,
            "megabytes": d.cell_count() as f64 * weft_fluid::grid::BYTES_PER_CELL as f64 / 1e6,
            "density": f.properties.density, "viscosity": f.properties.viscosity, "flow": f.flow,
        })
    });
    ws.log.clear();
    ws.record(serde_json::json!({
        "grid": grid, "terms": compiled.terms, "warnings": compiled.warnings,
    }));
    let state = CoupledState {
        sim: SimState {
            solid: compiled.state.clone(),
            transforms: scene.iter().map(|e| e.transform).collect(),
            history: None,
            inputs: compiled.freeze_inputs(&scene),
        },
        compiled,
        fluid,
        scene: Arc::new(scene),
        iteration: 0,
        relaxation: Relaxation::default(),
        residual: [0.0; 2],
        exchange: [0.0; 3],
        transport: [0.0; 3],
    };
    cx.set("state", Value::new(state));
    Ok(())
}

pub(super) fn predict(ws: &mut Workspace, cx: &mut EvalCx<'_>) -> Result<(), NodeError> {
    let sv = cx.input("state")?;
    let s = get::<CoupledState>(&sv, "state")?;
    let scene = cx.input("scene")?;
    let scene = Arc::new(get::<Scene>(&scene, "scene")?.clone());
    let frame = cx.frame();
    s.compiled.check_scene(&scene, frame).map_err(failed)?;
    // Animated parameters: the SECs (stiffness, drag, friction, the fluid's) are read at
    // every frame, and the Behavior tree when it is wired (else the one compiled).
    let tree = cx
        .input_opt("tree")?
        .and_then(|v| v.get::<weft_sim::BehaviorTree>().cloned());
    let compiled = match s
        .compiled
        .with_params(&scene, tree.as_ref(), frame, Some(cx.memory_budget()))
        .map_err(failed)?
    {
        Some(c) => Arc::new(c),
        None => s.compiled.clone(),
    };
    let method = match cx.params().str("method")? {
        "one_way" => Coupling::OneWay,
        "staggered" => Coupling::Staggered,
        _ => Coupling::Newton,
    };
    let h = 1.0 / cx.context().fps;
    let freeze = compiled
        .freeze_frame(&scene, &s.sim.inputs, frame, h)
        .map_err(failed)?;
    let ws = ws.for_scene(&compiled);
    let mut st = settings(&compiled);
    st.method = method;
    st.viscosity = cx.params().bool("viscosity")?;
    st.pressure = PressureSolve {
        tolerance: cx.params().f64("pressure_tolerance")?,
        max_iterations: cx.params().i64("pressure_max_iterations")?.max(1) as usize,
    };
    let u_star = match (&s.fluid, &compiled.fluid) {
        (Some(g), Some(spec)) => {
            let mut out = MacGrid::new(g.domain.clone());
            let t = std::time::Instant::now();
            let mut obstacles = Vec::new();
            spec.obstacles(&scene, &s.sim.transforms, h, &mut obstacles);
            ws.stepper.set_obstacles(&obstacles);
            let done = ws
                .stepper
                .predict(g, h, &st, &mut out)
                .map_err(|e| stage_error(frame, e, &ws.interrupt))?;
            ws.record(serde_json::json!({
                "frame": frame, "seconds": t.elapsed().as_secs_f64(),
                "one_way_cg_iterations": done.projection_iterations,
                "viscosity_cg_iterations": done.viscosity_iterations,
                "obstacle_faces": obstacles.len(),
            }));
            Some(Arc::new(out))
        }
        _ => None,
    };
    let fluid_momentum = s
        .fluid
        .as_ref()
        .map_or([0.0; 3], |g| g.momentum(settings(&compiled).fluid.density));
    cx.set(
        "step",
        Value::new(StepStart {
            compiled: compiled.clone(),
            h,
            method,
            start: s.sim.clone(),
            to: scene.iter().map(|e| e.transform).collect(),
            scene,
            u_star,
            freeze,
            fluid_momentum,
        }),
    );
    Ok(())
}

pub(super) fn forces(ws: &mut Workspace, cx: &mut EvalCx<'_>) -> Result<(), NodeError> {
    let stv = cx.input("step")?;
    let step = get::<StepStart>(&stv, "step")?;
    let itv = cx.input("iterate")?;
    let it = get::<CoupledState>(&itv, "iterate")?;
    let ws = ws.for_scene(&step.compiled);
    let mut ex = Exchange::default();
    let mut st = settings(&step.compiled);
    st.max_bytes = Some(cx.memory_budget());
    let frame = cx.frame();
    // The fluid the solids see: one-way, the fluid projected without them; otherwise the
    // iterate's (at the first iteration, the last step's: divergence-free, with its pressure).
    let seen = match step.method {
        Coupling::OneWay => step.u_star.as_deref(),
        _ => it.fluid.as_deref(),
    };
    match seen {
        Some(g) => {
            let x = &it.sim.solid;
            ws.stepper
                .forces(
                    &step.compiled.drag_elements,
                    &step.start.solid.x,
                    &x.x,
                    &x.v,
                    g,
                    &st,
                    &mut ex,
                )
                .map_err(|e| stage_error(frame, e, &ws.interrupt))?;
            if ex.outside > 0 && it.iteration == 0 {
                cx.warn(format!(
                    "frame {}: {} of {} solid samples are outside the fluid domain (clipped: they feel the nearest fluid and give nothing back); enlarge the domain",
                    cx.frame(),
                    ex.outside,
                    ex.samples.len()
                ));
            }
        }
        None => {
            let n = it.sim.solid.x.len();
            ex.drag = vec![Default::default(); n];
            ex.forces = vec![Vector3::zeros(); n];
        }
    }
    cx.set("exchange", Value::new(ExchangeValue(ex)));
    Ok(())
}

pub(super) fn solid(ws: &mut Workspace, cx: &mut EvalCx<'_>) -> Result<(), NodeError> {
    let _showing = super::solver::Showing::new(cx.interrupt(), &ws.progress);
    ws.stepper.set_progress(Some(ws.progress.clone()));
    let stv = cx.input("step")?;
    let step = get::<StepStart>(&stv, "step")?;
    let itv = cx.input("iterate")?;
    let it = get::<CoupledState>(&itv, "iterate")?;
    let exv = cx.input("exchange")?;
    let ex = &get::<ExchangeValue>(&exv, "exchange")?.0;
    let p = cx.params();
    let mut st = settings(&step.compiled);
    // Measured now (see `solver.rs`): the integrator adds what it holds.
    st.max_bytes = Some(weft_graph::memory::measure());
    st.solid = Settings {
        method: match p.str("method")? {
            "explicit" => Method::Explicit,
            "linearized" => Method::Linearized,
            "projected_newton" => Method::ProjectedNewton,
            _ => Method::Newton,
        },
        tolerance: p.f64("tolerance")?,
        max_iterations: p.i64("max_iterations")?.max(1) as usize,
    };
    let relaxation_method = match p.str("relaxation")? {
        "quasi_newton" => RelaxationMethod::QuasiNewton,
        "none" => RelaxationMethod::None,
        _ => RelaxationMethod::Aitken,
    };
    let max_admm = p.usize("contact_iterations")?.max(1);
    let frame = cx.frame();
    let ws = ws.for_scene(&step.compiled);
    if ws.contacts.is_none() {
        ws.contacts = Contacts::new(step.compiled.clone(), &step.scene, max_admm, st.max_bytes);
    }
    let (Some(sys), targets) = (ws.system.as_mut(), &mut ws.targets) else {
        unreachable!("for_scene sets the system")
    };
    step.compiled
        .set_targets(&step.start.transforms, &step.to, 1.0, sys, targets);
    step.compiled.set_freeze(&step.freeze, 1.0, sys);
    // The step's contacts are found afresh in every coupling iteration from the step's start
    // (and checked against that iteration's path): an iteration depends only on its inputs.
    let mut contact_stats = ContactFrameStats::default();
    if let Some(c) = &mut ws.contacts {
        c.max_admm = max_admm;
        c.frame(&step.scene, &step.start.transforms, &step.to)
            .map_err(|e| failed(format!("frame {frame}: {e}")))?;
    }
    let mut next = State {
        x: Vec::new(),
        v: Vec::new(),
    };
    let t = std::time::Instant::now();
    let stats = ws
        .stepper
        .solid(
            sys,
            ex,
            &step.start.solid,
            (it.iteration > 0).then_some(&it.sim.solid.x[..]),
            Some(targets),
            step.h,
            &st,
            it.iteration,
            ws.contacts.as_mut().map(|c| (c, &mut contact_stats)),
            &mut next,
        )
        .map_err(|e| stage_error(frame, e, &ws.interrupt))?;
    // The residual before relaxation: the relaxed change is small when the factor is.
    let change = velocity_change(&next.v, &it.sim.solid.v);
    let mut relaxation = it.relaxation.clone();
    relaxation.method = relaxation_method;
    if step.method == Coupling::Newton && it.iteration > 0 {
        relax(
            &step.start.solid,
            &it.sim.solid,
            &mut next,
            step.h,
            &mut relaxation,
        );
        if !next.x.iter().all(|p| p.iter().all(|c| c.is_finite())) {
            return Err(failed(format!(
                "frame {frame}: the relaxed solid iterate of coupling iteration {} is not finite (the iterations diverged)",
                it.iteration
            )));
        }
    }
    ws.record(serde_json::json!({
        "frame": frame, "iteration": it.iteration, "newton_iterations": stats.iterations,
        "residual": stats.residuals.last().map(|_| stats.final_residual()), "omega": relaxation.omega,
        "seconds": t.elapsed().as_secs_f64(),
        "contacts": ws.contacts.is_some().then(|| super::types::contact_stats_json(&contact_stats)),
    }));
    cx.set(
        "solid",
        Value::new(SolidIterate {
            state: next,
            relaxation,
            iteration: it.iteration,
            change,
        }),
    );
    Ok(())
}

pub(super) fn rasterize(ws: &mut Workspace, cx: &mut EvalCx<'_>) -> Result<(), NodeError> {
    let stv = cx.input("step")?;
    let step = get::<StepStart>(&stv, "step")?;
    let exv = cx.input("exchange")?;
    let ex = &get::<ExchangeValue>(&exv, "exchange")?.0;
    let sv = cx.input("solid")?;
    let solid = get::<SolidIterate>(&sv, "solid")?;
    let mut st = settings(&step.compiled);
    st.max_solid_fraction = cx.params().f64("max_solid_fraction")?;
    let ws = ws.for_scene(&step.compiled);
    let faces = match (&step.u_star, step.method) {
        (Some(u), Coupling::Newton | Coupling::Staggered) => {
            let mut out = MacGrid::new(u.domain.clone());
            let rs = ws
                .stepper
                .rasterize(ex, &solid.state.v, u, step.h, &st, &mut out);
            ws.record(serde_json::json!({
                "frame": cx.frame(), "samples": rs.samples, "outside": rs.outside, "capped_faces": rs.capped,
            }));
            Some(Arc::new(out))
        }
        _ => None,
    };
    cx.set("faces", Value::new(FluidValue(faces, solid.iteration)));
    Ok(())
}

pub(super) fn pressure(ws: &mut Workspace, cx: &mut EvalCx<'_>) -> Result<(), NodeError> {
    let stv = cx.input("step")?;
    let step = get::<StepStart>(&stv, "step")?;
    let fv = cx.input("faces")?;
    let faces = get::<FluidValue>(&fv, "faces")?;
    let mut st = settings(&step.compiled);
    st.pressure = PressureSolve {
        tolerance: cx.params().f64("tolerance")?,
        max_iterations: cx.params().i64("max_iterations")?.max(1) as usize,
    };
    let frame = cx.frame();
    let ws = ws.for_scene(&step.compiled);
    let fluid = match &faces.0 {
        Some(g) => {
            let mut g = MacGrid::clone(g);
            let ps = ws
                .stepper
                .pressure(&mut g, step.h, &st, faces.1)
                .map_err(|e| stage_error(frame, e, &ws.interrupt))?;
            ws.record(serde_json::json!({
                "frame": frame, "iteration": faces.1, "cg_iterations": ps.iterations, "divergence": ps.divergence,
                "setup_seconds": ps.setup_seconds, "solve_seconds": ps.solve_seconds,
            }));
            Some(Arc::new(g))
        }
        // One-way: the predictor already projected the fluid without solids.
        None if step.method == Coupling::OneWay => step.u_star.clone(),
        None => None,
    };
    cx.set("fluid", Value::new(FluidValue(fluid, faces.1)));
    Ok(())
}

pub(super) fn update(_: &mut Workspace, cx: &mut EvalCx<'_>) -> Result<(), NodeError> {
    let stv = cx.input("step")?;
    let step = get::<StepStart>(&stv, "step")?;
    let itv = cx.input("iterate")?;
    let it = get::<CoupledState>(&itv, "iterate")?;
    let sv = cx.input("solid")?;
    let solid = get::<SolidIterate>(&sv, "solid")?;
    let fv = cx.input("fluid")?;
    let fluid = get::<FluidValue>(&fv, "fluid")?.0.clone();
    let dv = solid.change;
    let du = match (&fluid, &it.fluid) {
        (Some(a), Some(b)) => fluid_change(a, b),
        _ => 0.0,
    };
    // Without a fluid nothing couples: one pass is the answer.
    let converged = fluid.is_none()
        || step
            .method
            .converged(it.iteration, dv.max(du), cx.params().f64("tolerance")?);
    if !(dv.is_finite() && du.is_finite()) {
        return Err(failed(format!(
            "frame {}: coupling iteration {} produced a non-finite velocity",
            cx.frame(),
            it.iteration
        )));
    }
    let rho = settings(&step.compiled).fluid.density;
    let exchange = match (&fluid, &step.u_star, step.method) {
        (_, _, Coupling::OneWay) => [0.0; 3],
        (Some(u), Some(u_star), _) => u.momentum_gain(u_star, rho),
        _ => [0.0; 3],
    };
    // The rest of the fluid's momentum change: advection (semi-Lagrangian, not
    // conservative) and the solids' fractions moving over the faces. Only the converged
    // iterate becomes the frame's state, so only it needs the sum over the faces.
    let transport = match &fluid {
        Some(u) if converged => {
            let now = u.momentum(rho);
            std::array::from_fn(|k| now[k] - step.fluid_momentum[k] - exchange[k])
        }
        _ => [0.0; 3],
    };
    let next = CoupledState {
        compiled: step.compiled.clone(),
        sim: SimState {
            solid: solid.state.clone(),
            transforms: step.to.clone(),
            history: None,
            inputs: step.freeze.end.clone(),
        },
        fluid,
        scene: step.scene.clone(),
        iteration: it.iteration + 1,
        relaxation: solid.relaxation.clone(),
        residual: [dv, du],
        exchange,
        transport,
    };
    cx.set("iterate", Value::new(next));
    cx.set("converged", converged);
    cx.set("residual", dv.max(du));
    Ok(())
}

pub(super) fn finish(_: &mut Workspace, cx: &mut EvalCx<'_>) -> Result<(), NodeError> {
    let itv = cx.input("iterate")?;
    let mut s = get::<CoupledState>(&itv, "iterate")?.clone();
    s.iteration = 0;
    s.relaxation = Relaxation::default();
    cx.set("state", Value::new(s));
    Ok(())
}
