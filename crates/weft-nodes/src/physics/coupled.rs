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
//! grid — none when the scene has no fluid-domain element; `coupled.scene` and
//! `coupled.probe` read results out of a state.

use super::types::Scene;
use nalgebra::Vector3;
use std::collections::VecDeque;
use std::sync::Arc;
use weft_fluid::{FluidProperties, MacGrid, PressureSolve};
use weft_graph::{
    Compute, EvalCx, Kernel, NodeError, NodeSpec, ParamSpec, PortType, Registry, RegistryError,
    Value,
};
use weft_scene::Transform;
use weft_sim::{
    BehaviorTree, Compiled, CoupledSettings, CoupledStepper, Coupling, Exchange, Relaxation,
    RelaxationMethod, SimState, compile_within, fluid_change, relax, velocity_change,
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

fn get<'a, T: 'static>(v: &'a Value, port: &str) -> Result<&'a T, NodeError> {
    v.get::<T>().ok_or_else(|| NodeError::Input {
        port: port.into(),
        message: "unexpected value type".into(),
    })
}

fn failed(e: impl std::fmt::Display) -> NodeError {
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

fn settings(compiled: &Compiled) -> CoupledSettings {
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
struct Workspace {
    compiled: Option<Arc<Compiled>>,
    stepper: CoupledStepper,
    system: Option<SolidSystem>,
    targets: Vec<Vector3<f64>>,
    log: VecDeque<serde_json::Value>,
    /// The graph's stop handle the solvers were given.
    interrupt: Option<weft_graph::Interrupt>,
}

impl Workspace {
    fn for_scene(&mut self, c: &Arc<Compiled>) -> &mut Self {
        if self.compiled.as_ref().is_none_or(|o| !Arc::ptr_eq(o, c)) {
            let interrupt = self.interrupt.take();
            *self = Workspace {
                compiled: Some(c.clone()),
                system: Some(c.system.clone()),
                targets: c.state.x.clone(),
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

fn stage(
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

fn setup(ws: &mut Workspace, cx: &mut EvalCx<'_>) -> Result<(), NodeError> {
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
        },
        compiled,
        fluid,
        scene: Arc::new(scene),
        iteration: 0,
        relaxation: Relaxation::default(),
        residual: [0.0; 2],
        exchange: [0.0; 3],
    };
    cx.set("state", Value::new(state));
    Ok(())
}

fn predict(ws: &mut Workspace, cx: &mut EvalCx<'_>) -> Result<(), NodeError> {
    let sv = cx.input("state")?;
    let s = get::<CoupledState>(&sv, "state")?;
    let scene = cx.input("scene")?;
    let scene = Arc::new(get::<Scene>(&scene, "scene")?.clone());
    let frame = cx.frame();
    s.compiled.check_scene(&scene, frame).map_err(failed)?;
    let method = match cx.params().str("method")? {
        "one_way" => Coupling::OneWay,
        "staggered" => Coupling::Staggered,
        _ => Coupling::Newton,
    };
    let h = 1.0 / cx.context().fps;
    let ws = ws.for_scene(&s.compiled);
    let mut st = settings(&s.compiled);
    st.method = method;
    st.viscosity = cx.params().bool("viscosity")?;
    st.pressure = PressureSolve {
        tolerance: cx.params().f64("pressure_tolerance")?,
        max_iterations: cx.params().i64("pressure_max_iterations")?.max(1) as usize,
    };
    let u_star = match (&s.fluid, &s.compiled.fluid) {
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
    cx.set(
        "step",
        Value::new(StepStart {
            compiled: s.compiled.clone(),
            h,
            method,
            start: s.sim.clone(),
            to: scene.iter().map(|e| e.transform).collect(),
            scene,
            u_star,
        }),
    );
    Ok(())
}

fn forces(ws: &mut Workspace, cx: &mut EvalCx<'_>) -> Result<(), NodeError> {
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
                .gather(
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

fn solid(ws: &mut Workspace, cx: &mut EvalCx<'_>) -> Result<(), NodeError> {
    let stv = cx.input("step")?;
    let step = get::<StepStart>(&stv, "step")?;
    let itv = cx.input("iterate")?;
    let it = get::<CoupledState>(&itv, "iterate")?;
    let exv = cx.input("exchange")?;
    let ex = &get::<ExchangeValue>(&exv, "exchange")?.0;
    let p = cx.params();
    let mut st = settings(&step.compiled);
    st.max_bytes = Some(weft_graph::memory::available());
    st.solid = Settings {
        method: match p.str("method")? {
            "explicit" => Method::Explicit,
            "linearized" => Method::Linearized,
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
    let frame = cx.frame();
    let ws = ws.for_scene(&step.compiled);
    let (Some(sys), targets) = (ws.system.as_mut(), &mut ws.targets) else {
        unreachable!("for_scene sets the system")
    };
    step.compiled
        .set_targets(&step.start.transforms, &step.to, 1.0, sys, targets);
    let mut next = State {
        x: Vec::new(),
        v: Vec::new(),
    };
    let t = std::time::Instant::now();
    let stats = ws
        .stepper
        .solve_solid(
            sys,
            ex,
            &step.start.solid,
            (it.iteration > 0).then_some(&it.sim.solid.x[..]),
            Some(targets),
            step.h,
            &st,
            it.iteration,
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
        "residual": stats.residuals.last(), "omega": relaxation.omega,
        "seconds": t.elapsed().as_secs_f64(),
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

fn rasterize(ws: &mut Workspace, cx: &mut EvalCx<'_>) -> Result<(), NodeError> {
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

fn pressure(ws: &mut Workspace, cx: &mut EvalCx<'_>) -> Result<(), NodeError> {
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
                .project(&mut g, step.h, &st, faces.1)
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

fn update(_: &mut Workspace, cx: &mut EvalCx<'_>) -> Result<(), NodeError> {
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
    let next = CoupledState {
        compiled: step.compiled.clone(),
        sim: SimState {
            solid: solid.state.clone(),
            transforms: step.to.clone(),
        },
        fluid,
        scene: step.scene.clone(),
        iteration: it.iteration + 1,
        relaxation: solid.relaxation.clone(),
        residual: [dv, du],
        exchange,
    };
    cx.set("iterate", Value::new(next));
    cx.set("converged", converged);
    cx.set("residual", dv.max(du));
    Ok(())
}

fn finish(_: &mut Workspace, cx: &mut EvalCx<'_>) -> Result<(), NodeError> {
    let itv = cx.input("iterate")?;
    let mut s = get::<CoupledState>(&itv, "iterate")?.clone();
    s.iteration = 0;
    s.relaxation = Relaxation::default();
    cx.set("state", Value::new(s));
    Ok(())
}

/// A frame's coupled state for a disk checkpoint: solids, fluid fields, last residuals
/// (the compiled scene and the domain come back from the start frame's state).
fn encode_state(v: &Value) -> Option<Vec<u8>> {
    let s = v.get::<CoupledState>()?;
    let mut w = weft_graph::codec::Writer::new();
    super::checkpoint::write_sim(&mut w, &s.sim);
    match &s.fluid {
        Some(g) => {
            w.u64(1);
            super::checkpoint::write_grid(&mut w, g);
        }
        None => {
            w.u64(0);
        }
    }
    w.u64(s.iteration as u64)
        .f64s(&s.residual)
        .f64s(&s.exchange);
    Some(w.finish())
}

/// Rebuilds a coupled state from [`encode_state`]'s bytes, the start frame's state and the
/// solver's inputs at the restored frame (its scene).
fn restore_state(b: &[u8], template: &Value, inputs: &[(String, Value)]) -> Result<Value, String> {
    let t = template
        .get::<CoupledState>()
        .ok_or("the start state is not a coupled state")?;
    let mut r = weft_graph::codec::Reader::new(b);
    let sim = super::checkpoint::read_sim(&mut r, &t.sim)?;
    let fluid = match (r.u64()?, &t.fluid) {
        (0, None) => None,
        (1, Some(g)) => Some(Arc::new(super::checkpoint::read_grid(&mut r, g)?)),
        _ => return Err("the fluid does not match the scene's".into()),
    };
    let iteration = r.u64()? as usize;
    let residual = match r.f64s()?[..] {
        [a, b] => [a, b],
        _ => return Err("expected two residuals".into()),
    };
    let exchange = match r.f64s()?[..] {
        [a, b, c] => [a, b, c],
        _ => return Err("expected a momentum".into()),
    };
    r.end()?;
    let scene = inputs
        .iter()
        .find(|(k, _)| k == "scene")
        .and_then(|(_, v)| v.get::<Scene>())
        .map_or_else(|| t.scene.clone(), |s| Arc::new(s.clone()));
    Ok(Value::new(CoupledState {
        compiled: t.compiled.clone(),
        sim,
        fluid,
        scene,
        iteration,
        relaxation: Relaxation::default(),
        residual,
        exchange,
    }))
}

/// The library definition of `solver.coupled`.
pub const SOLVER_COUPLED: &str = include_str!("solver_coupled.json");

pub(crate) fn register(r: &mut Registry) -> Result<(), RegistryError> {
    r.register_port_type(
        PortType::of::<CoupledState>(
            "coupled",
            "the coupled solver's state: solids, fluid grid, compiled scene",
        )
        .with_json(
            |_| Err("a coupled state is made by coupled.setup".into()),
            |v| {
                v.get::<CoupledState>().map(|s| {
                    serde_json::json!({
                        "vertices": s.sim.solid.x.len(),
                        "fluid_cells": s.fluid.as_ref().map(|g| g.domain.cells),
                        "iteration": s.iteration, "residual": s.residual,
                    })
                })
            },
        )
        .with_restore(encode_state, restore_state)
        .with_size(|v| {
            v.get::<CoupledState>().map_or(0, |s| {
                48 * s.sim.solid.x.len()
                    + s.fluid.as_ref().map_or(0, |g| 104 * g.domain.cell_count())
            })
        }),
    )?;
    r.register_port_type(PortType::of::<StepStart>(
        "coupled_step",
        "a coupled step's start: the previous state, this frame's targets, the predicted fluid",
    ))?;
    r.register_port_type(PortType::of::<ExchangeValue>(
        "coupled_exchange",
        "what solids and fluid exchange in one coupling iteration (samples, drag, forces)",
    ))?;
    r.register_port_type(PortType::of::<SolidIterate>(
        "coupled_solid",
        "a solid iterate of the coupling",
    ))?;
    r.register_port_type(PortType::of::<FluidValue>(
        "coupled_fluid",
        "a fluid iterate of the coupling (face fractions, drag, velocities, pressure)",
    ))?;
    let method = |d: &str| {
        ParamSpec::choice("method", &["newton", "staggered", "one_way"], d)
            .doc("newton: iterate the stages to tolerance; staggered: one pass; one_way: the fluid drives the solids and feels nothing back")
    };
    stage(
        r,
        NodeSpec::new("coupled.setup", "compiles the scene for the coupled solver and makes the fluid's initial grid (none when the scene has no fluid-domain element; --stats shows it)")
            .input("scene", "scene", "the scene at the start frame")
            .input("tree", "behavior_tree", "what is simulated")
            .output("state", "coupled", "the state at the start frame"),
        setup,
    )?;
    stage(
        r,
        NodeSpec::new("coupled.predict", "coupled stage, once per step: advects the fluid (u*; gravity is in the hydrostatic pressure), diffuses it when viscosity is on; one_way also projects it without solids")
            .input("state", "coupled", "the state at the previous frame")
            .input("scene", "scene", "the scene at this frame (attachment targets)")
            .output("step", "coupled_step", "the step's start")
            .param(method("newton"))
            .param(ParamSpec::bool("viscosity", false).doc("viscous diffusion of the fluid after advection (implicit, nu = viscosity/density from the Fluid SEC); off: inviscid, as water and air are at hair and cloth scales"))
            .param(ParamSpec::float("pressure_tolerance", 1e-8).gt(0.0).unit("1/s").doc("one_way: divergence tolerance of its projection"))
            .param(ParamSpec::int("pressure_max_iterations", 2000).ge(1.0).doc("one_way: CG iteration limit of its projection")),
        predict,
    )?;
    stage(
        r,
        NodeSpec::new("coupled.forces", "coupled stage: samples every drag element in the fluid iterate; per sample the drag (seed eqs. 1-3), pressure (buoyancy, -V grad p) and lift (eq. 4), lumped to vertices")
            .input("step", "coupled_step", "the step's start")
            .input("iterate", "coupled", "the coupling iterate")
            .output("exchange", "coupled_exchange", "samples, per-vertex drag and forces"),
        forces,
    )?;
    stage(
        r,
        NodeSpec::new("coupled.solid", "coupled stage: the implicit solid step with the fluid prescribed (drag implicit, pressure and lift explicit), Aitken- or quasi-Newton-relaxed between Newton iterations")
            .input("step", "coupled_step", "the step's start")
            .input("iterate", "coupled", "the coupling iterate")
            .input("exchange", "coupled_exchange", "drag and forces")
            .output("solid", "coupled_solid", "the new solid iterate")
            .param(ParamSpec::choice("method", &["newton", "linearized", "explicit"], "newton").doc("the solid solve"))
            .param(ParamSpec::float("tolerance", 1e-6).gt(0.0).unit("m/s").doc("Newton tolerance of the solid solve"))
            .param(ParamSpec::int("max_iterations", 50).ge(1.0).le(10_000.0).doc("Newton iteration limit of the solid solve"))
            .param(ParamSpec::choice("relaxation", &["aitken", "quasi_newton", "none"], "aitken").doc("relaxation of the solid iterate between coupling iterations (aitken: Irons-Tuck delta-squared; quasi_newton: IQN-ILS, a least-squares inverse Jacobian from the step's iterates)")),
        solid,
    )?;
    stage(
        r,
        NodeSpec::new("coupled.rasterize", "coupled stage: the solids' samples onto the faces as solid fraction, drag and solid velocity (conserving volume, drag and momentum), and lift's reaction")
            .input("step", "coupled_step", "the step's start")
            .input("exchange", "coupled_exchange", "the samples")
            .input("solid", "coupled_solid", "the solid iterate (sample velocities)")
            .output("faces", "coupled_fluid", "u* with the solids rasterized")
            .param(ParamSpec::float("max_solid_fraction", 0.9).gt(0.0).lt(1.0).doc("cap on a face's solid fraction, so every face keeps some fluid")),
        rasterize,
    )?;
    stage(
        r,
        NodeSpec::new("coupled.pressure", "coupled stage: the porous pressure solve (MIC(0)-preconditioned CG) with the solids prescribed, and the velocity update")
            .input("step", "coupled_step", "the step's start")
            .input("faces", "coupled_fluid", "u* with the solids rasterized")
            .output("fluid", "coupled_fluid", "the projected fluid")
            .param(ParamSpec::float("tolerance", 1e-8).gt(0.0).unit("1/s").doc("largest divergence of the mixture flux after the solve"))
            .param(ParamSpec::int("max_iterations", 2000).ge(1.0).doc("CG iteration limit")),
        pressure,
    )?;
    stage(
        r,
        NodeSpec::new("coupled.update", "coupled stage: the next iterate and the convergence test (newton: velocities changed by less than the tolerance after at least two iterations)")
            .input("step", "coupled_step", "the step's start")
            .input("iterate", "coupled", "the coupling iterate")
            .input("solid", "coupled_solid", "the new solid iterate")
            .input("fluid", "coupled_fluid", "the new fluid iterate")
            .output("iterate", "coupled", "the next iterate")
            .output("converged", "bool", "true when the coupling has converged (or the method makes one pass)")
            .output("residual", "float", "largest change of a solid or fluid velocity [m/s]")
            .param(ParamSpec::float("tolerance", 1e-6).gt(0.0).unit("m/s").doc("coupling tolerance")),
        update,
    )?;
    stage(
        r,
        NodeSpec::new(
            "coupled.finish",
            "coupled stage, once per step: the converged iterate becomes the frame's state",
        )
        .input("iterate", "coupled", "the converged iterate")
        .output("state", "coupled", "the state at this frame"),
        finish,
    )?;
    r.register(
        NodeSpec::new("coupled.scene", "the scene of a coupled state: simulated elements at their positions (with a velocity channel)")
            .input("state", "coupled", "the coupled state")
            .output("scene", "scene", "the elements at this frame"),
        |_| {
            Ok(Kernel::from_fn(|cx| {
                let v = cx.input("state")?;
                let s = get::<CoupledState>(&v, "state")?;
                let scene: Scene = s.compiled.scene_at(&s.scene, &s.sim.solid);
                cx.set("scene", Value::new(scene));
                Ok(())
            }))
        },
    )?;
    r.register(
        NodeSpec::new(
            "coupled.probe",
            "reads the fluid of a coupled state: the velocity and pressure at a point, and the largest speed",
        )
        .input("state", "coupled", "the coupled state")
        .output(
            "velocity",
            "vec3",
            "fluid velocity at the point [m/s] (zero without fluid)",
        )
        .output("pressure", "float", "pressure of the cell holding the point [Pa], relative to hydrostatic (the grid solves for p − ρ g·x; zero without fluid)")
        .output("max_speed", "float", "largest face speed [m/s]")
        .param(
            ParamSpec::vec3("point", [0.0; 3])
                .unit("m")
                .doc("where to sample"),
        ),
        |_| {
            Ok(Kernel::from_fn(|cx| {
                let v = cx.input("state")?;
                let s = get::<CoupledState>(&v, "state")?;
                let p = cx.params().vec3("point")?;
                let (vel, pressure, max) = match &s.fluid {
                    Some(g) => (
                        g.velocity_at(p),
                        g.pressure_at(p),
                        g.vel.iter().flatten().fold(0.0f64, |m, u| m.max(u.abs())),
                    ),
                    None => ([0.0; 3], 0.0, 0.0),
                };
                cx.set("velocity", vel);
                cx.set("pressure", pressure);
                cx.set("max_speed", max);
                Ok(())
            }))
        },
    )?;
    r.register(
        NodeSpec::new(
            "coupled.momentum",
            "momentum diagnostics of a coupled state: the solids', the fluid's, and what the last step's coupling gave the fluid (which the solids' change balances: drag and pressure are internal)",
        )
        .input("state", "coupled", "the coupled state")
        .output("solid", "vec3", "Σ m v over the simulated vertices [kg·m/s]")
        .output("fluid", "vec3", "Σ ρ α u Δx³ over the grid's distinct faces [kg·m/s] (zero without fluid)")
        .output("exchange", "vec3", "Σ ρ α (u − u*) Δx³ over the last step [kg·m/s], u* the advected fluid it started from (zero for one-way coupling)"),
        |_| {
            Ok(Kernel::from_fn(|cx| {
                let v = cx.input("state")?;
                let s = get::<CoupledState>(&v, "state")?;
                let sys = &s.compiled.system;
                let mut solid = [0.0; 3];
                for (m, v) in sys.mass.iter().zip(&s.sim.solid.v) {
                    for k in 0..3 {
                        solid[k] += m * v[k];
                    }
                }
                let rho = settings(&s.compiled).fluid.density;
                let fluid = s.fluid.as_ref().map_or([0.0; 3], |g| g.momentum(rho));
                cx.set("solid", solid);
                cx.set("fluid", fluid);
                cx.set("exchange", s.exchange);
                Ok(())
            }))
        },
    )?;
    r.register_subgraph("solver.coupled", SOLVER_COUPLED)
}
