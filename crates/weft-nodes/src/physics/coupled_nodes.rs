//! The coupled solver's node types: `coupled.setup` and the stages of the `solver.coupled`
//! library subgraph (their work is in `coupled.rs`), and the nodes that read a state
//! (`coupled.scene`, `coupled.momentum`; the fluid's probes and files are in `fields.rs`).

use super::checkpoint::{encode_state, restore_state};
use super::coupled::*;
use super::types::Scene;
use weft_graph::{Kernel, NodeSpec, ParamSpec, PortType, Registry, RegistryError, Value};

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
            .input_default("tree", "behavior_tree", serde_json::json!(null), "the Behavior tree at this frame (animated Behavior parameters); unconnected: the one compiled")
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
            .param(ParamSpec::choice("method", &["newton", "linearized", "explicit", "projected_newton"], "newton").doc("the solid solve (see solver.solid's method)"))
            .param(ParamSpec::float("tolerance", 1e-6).gt(0.0).unit("m/s").doc("Newton tolerance of the solid solve"))
            .param(ParamSpec::int("max_iterations", 50).ge(1.0).le(10_000.0).doc("Newton iteration limit of the solid solve"))
            .param(ParamSpec::choice("relaxation", &["aitken", "quasi_newton", "none"], "aitken").doc("relaxation of the solid iterate between coupling iterations (aitken: Irons-Tuck delta-squared; quasi_newton: IQN-ILS, a least-squares inverse Jacobian from the step's iterates)"))
            .param(ParamSpec::int("contact_iterations", 200).ge(1.0).le(100_000.0).doc("ADMM iterations allowed per Newton iteration in a step with contacts (behavior.collision)")),
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
                let scene: Scene = s.compiled.scene_at(s.scene.iter(), &s.sim.solid);
                cx.set("scene", Value::new(scene));
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
