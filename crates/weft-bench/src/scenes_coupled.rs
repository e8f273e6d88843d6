//! Coupled verification scenes for the sweeps, each against a converged reference (the same
//! scene stepped with Newton coupling at h = 1/1600 s to 10⁻⁸ m/s): the error of a run is the
//! largest distance of the solid's mean vertical velocity from the reference's at the
//! sample times, relative to the reference's largest.
//! - **light strand**: a strand (radius 2 mm, 12 cm, density ρ_s) rising in a closed 0.2 m
//!   box of water (2 cm cells) with drag scale ξ_D: the coupling stability map, over the
//!   drag-to-mass ratio K/m = k/ρ_s (k the drag per unit solid volume).
//! - **settling sheet**: a porous sheet (1500 kg/m³, 0.2 mm, D = 0.1 mm) spanning a box of
//!   water periodic across, falling towards the Darcy terminal velocity Δρg/k (VERIFY.md).
//!
//! Every scene is a graph file in `scenes/` (what a user would write), loaded, set for the
//! run with the same parameter overrides `weft run --set` makes, and stepped frame by frame
//! through `solver.coupled`: the loop users run is the loop measured.

pub use crate::graphs::{load, set};
use crate::sweep::{Run, Status};
use std::time::Instant;
use weft_fluid::FluidProperties;
use weft_graph::{Context, Graph};
use weft_sim::verify::{self, G};

/// The coupling methods swept, by their `solve.predict.method` names.
pub const COUPLINGS: [&str; 3] = ["one_way", "staggered", "newton"];

/// The strand's radius: 2 mm, so it fills about 3 % of the 2 cm cells it crosses (a thick
/// strand, filling half of them, caps solid fractions and makes every partitioned scheme
/// fragile).
const STRAND_RADIUS: f64 = 2e-3;
/// The interval at which velocities are compared with the reference [s] (every swept step
/// divides it).
const SAMPLE: f64 = 0.04;
/// Relative error above which a coupled run is inaccurate.
pub const COUPLED_INACCURATE: f64 = 0.05;

/// The scene templates: graph files users could have written, stepped by `solver.coupled`.
pub const STRAND_BOX: &str = include_str!("../scenes/strand_box.json");
/// See [`STRAND_BOX`].
pub const SETTLING_SHEET: &str = include_str!("../scenes/settling_sheet.json");
/// See [`STRAND_BOX`].
pub const POROUS_CHANNEL: &str = include_str!("../scenes/porous_channel.json");

/// The strand template set to a strand of `radius` and `density` with drag scale `xi_d`;
/// the stretch stiffness E·πr² stays 10 N.
pub fn strand_graph(radius: f64, density: f64, xi_d: f64) -> Result<Graph, String> {
    let mut g = load(STRAND_BOX, "strand_box.json")?;
    let area = std::f64::consts::PI * radius * radius;
    set(&mut g, "rod.radius", radius.into())?;
    set(&mut g, "rod.youngs_modulus", (10.0 / area).into())?;
    set(&mut g, "density.line_density", (density * area).into())?;
    set(&mut g, "drag.diameter", (2.0 * radius).into())?;
    set(&mut g, "drag.xi_d", xi_d.into())?;
    Ok(g)
}

/// The settling sheet template with a sheet of `thickness` (its area density follows).
pub fn sheet_graph(thickness: f64) -> Result<Graph, String> {
    let mut g = load(SETTLING_SHEET, "settling_sheet.json")?;
    set(&mut g, "shell.thickness", thickness.into())?;
    set(
        &mut g,
        "density.area_density",
        (verify::SHEET_DENSITY * thickness).into(),
    )?;
    Ok(g)
}

/// The solid's mean velocity at frame `frame` of a graph stepped at `fps`.
pub fn mean_velocity(g: &mut Graph, frame: i64, fps: f64) -> Result<[f64; 3], String> {
    let v = g
        .pull("velocity", Context::at(frame, fps))
        .map_err(|e| e.to_string())?;
    v.get::<[f64; 3]>()
        .copied()
        .ok_or_else(|| "output 'velocity' is not a vec3".into())
}

/// Per frame solved so far by the coupled solver `node`: its coupling iterations, and the
/// time the graph itself took per iteration beyond its stages' own (the engine's overhead).
pub fn iteration_stats(g: &Graph, node: &str) -> (Vec<usize>, f64, f64) {
    let (mut its, mut total, mut stages) = (Vec::new(), 0.0, 0.0);
    for r in g.stats() {
        if r.node != node {
            continue;
        }
        let frames = r
            .details
            .as_ref()
            .and_then(|d| d.get("frames"))
            .and_then(|f| f.as_array());
        for f in frames.into_iter().flatten() {
            let iters = f["iterations"].as_array().map_or(&[][..], |a| a.as_slice());
            its.push(iters.len());
            for it in iters {
                total += it["seconds"].as_f64().unwrap_or(0.0);
                stages += it["stages"]
                    .as_object()
                    .map_or(0.0, |m| m.values().filter_map(|x| x.as_f64()).sum());
            }
        }
    }
    (its, total, stages)
}

/// A coupled verification scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Scene {
    /// The light strand.
    Strand {
        /// Its density [kg/m³].
        density: f64,
        /// Its drag scale ξ_D.
        xi_d: f64,
    },
    /// The settling sheet.
    Sheet,
}

impl Scene {
    fn name(self) -> &'static str {
        match self {
            Scene::Strand { .. } => "light_strand",
            Scene::Sheet => "settling_sheet",
        }
    }

    /// How long it runs [s].
    pub fn duration(self) -> f64 {
        match self {
            Scene::Strand { .. } => 0.2,
            Scene::Sheet => 0.32,
        }
    }

    /// The swept parameter and its name.
    fn param(self) -> (f64, &'static str) {
        match self {
            Scene::Strand { density, xi_d } => {
                (strand_drag(xi_d) / density, "drag-to-mass ratio K/m [1/s]")
            }
            Scene::Sheet => (
                (verify::SHEET_DENSITY - FluidProperties::WATER.density) * G
                    / verify::sheet_terminal()
                    / verify::SHEET_DENSITY,
                "drag-to-mass ratio K/m [1/s]",
            ),
        }
    }

    fn build(self) -> Result<Graph, String> {
        match self {
            Scene::Strand { density, xi_d } => strand_graph(STRAND_RADIUS, density, xi_d),
            Scene::Sheet => sheet_graph(2e-4),
        }
    }
}

/// Drag per unit solid volume k [N s/m⁴] of the strand for ξ_D ([`verify::strand_drag`]).
pub fn strand_drag(xi_d: f64) -> f64 {
    verify::strand_drag(STRAND_RADIUS, xi_d)
}

/// What one run of a scene measured.
struct History {
    /// The solid's mean vertical velocity every [`SAMPLE`] s; None once a frame fails or the
    /// solid runs away (faster than 10 m/s).
    velocities: Option<Vec<f64>>,
    /// Coupling iterations per step.
    iterations: f64,
    /// The graph's own time per coupling iteration beyond its stages' [s].
    overhead: f64,
    /// Wall time per coupling iteration [s].
    per_iteration: f64,
}

/// Steps `scene`'s graph at `h` with coupling `method` to `tolerance`.
fn history(scene: Scene, method: &str, tolerance: f64, h: f64) -> History {
    let failed = History {
        velocities: None,
        iterations: f64::NAN,
        overhead: f64::NAN,
        per_iteration: f64::NAN,
    };
    let steps = (scene.duration() / h).round().max(1.0) as i64;
    let every = (SAMPLE / h).round().max(1.0) as i64;
    let fps = steps as f64 / scene.duration();
    let Ok(mut g) = scene.build().and_then(|mut g| {
        set(&mut g, "solve.predict.method", method.into())?;
        set(&mut g, "solve.update.tolerance", tolerance.into())?;
        Ok(g)
    }) else {
        return failed;
    };
    let mut out = Vec::new();
    for n in 1..=steps {
        let v = match mean_velocity(&mut g, n, fps) {
            Ok(v) => v[1],
            Err(_) => return failed,
        };
        if v.is_nan() || v.abs() >= 10.0 {
            return failed;
        }
        if n % every == 0 {
            out.push(v);
        }
    }
    let (its, total, stages) = iteration_stats(&g, "solve");
    let count: usize = its.iter().sum();
    History {
        velocities: Some(out),
        iterations: count as f64 / steps as f64,
        overhead: (total - stages) / count.max(1) as f64,
        per_iteration: total / count.max(1) as f64,
    }
}

/// The converged reference of `scene`: Newton coupling (Aitken) at h = 1/1600 s to
/// 10⁻⁸ m/s. None when even that fails.
pub fn reference(scene: Scene) -> Option<Vec<f64>> {
    history(scene, "newton", 1e-8, 1.0 / 1600.0).velocities
}

/// `scene` at step `h` with coupling `method` against its `reference`, inaccurate above
/// [`COUPLED_INACCURATE`]; with the graph's own time per coupling iteration beyond its
/// stages' and the wall time per iteration [s].
pub fn coupled_run(
    scene: Scene,
    method: &'static str,
    h: f64,
    reference: Option<&[f64]>,
) -> (Run, f64, f64) {
    let t = Instant::now();
    let History {
        velocities: history,
        iterations,
        overhead,
        per_iteration,
    } = history(scene, method, 1e-6, h);
    let seconds = t.elapsed().as_secs_f64();
    let steps = (scene.duration() / h).round().max(1.0) as usize;
    let error = match (&history, reference) {
        (Some(v), Some(r)) if v.len() == r.len() => {
            let scale = r.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            v.iter()
                .zip(r)
                .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()))
                / scale
        }
        _ => f64::NAN,
    };
    let (param, param_name) = scene.param();
    let run = Run {
        scene: scene.name(),
        method,
        h: scene.duration() / steps as f64,
        dx: 0.02,
        param,
        param_name,
        error,
        error_unit: "relative",
        iterations,
        seconds,
        steps,
        // Without a reference only a blow-up can be judged.
        status: if reference.is_none() && history.is_some() {
            Status::Unjudged
        } else {
            Status::of(history.is_none(), error, COUPLED_INACCURATE)
        },
    };
    (run, overhead, per_iteration)
}
