//! Coupled verification scenes for the sweeps, each against a converged reference (the same
//! scene stepped with Newton coupling at h = 1/1600 s to 10⁻⁸ m/s): the error of a run is the
//! largest distance of the solid's mean vertical velocity from the reference's at the
//! sample times, relative to the reference's largest.
//! - **light strand**: a strand (radius 2 mm, 12 cm, density ρ_s) rising in a closed 0.2 m
//!   box of water (2 cm cells) with drag scale ξ_D: the coupling stability map, over the
//!   drag-to-mass ratio K/m = k/ρ_s (k the drag per unit solid volume).
//! - **settling sheet**: a porous sheet (1500 kg/m³, 0.2 mm, D = 0.1 mm) spanning a box of
//!   water periodic across, falling towards the Darcy terminal velocity Δρg/k (VERIFY.md).

use crate::sweep::{Run, Status};
use std::time::Instant;
use weft_fluid::FluidProperties;
use weft_sim::verify::{self, G};
use weft_sim::{CoupledSettings, CoupledStepper, Coupling, RelaxationMethod};

/// The coupling methods swept, with their names.
pub const COUPLINGS: [(Coupling, &str); 3] = [
    (Coupling::OneWay, "one_way"),
    (Coupling::Staggered, "staggered"),
    (Coupling::Newton, "newton"),
];

/// The strand's radius: 2 mm, so it fills about 3 % of the 2 cm cells it crosses (a thick
/// strand, filling half of them, caps solid fractions and makes every partitioned scheme
/// fragile).
const STRAND_RADIUS: f64 = 2e-3;
/// The interval at which velocities are compared with the reference [s] (every swept step
/// divides it).
const SAMPLE: f64 = 0.04;
/// Relative error above which a coupled run is inaccurate.
pub const COUPLED_INACCURATE: f64 = 0.05;

/// A coupled verification scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Scene {
    /// The light strand of density [kg/m³] and drag scale ξ_D.
    Strand { density: f64, xi_d: f64 },
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
                (verify::SHEET_DENSITY - FluidProperties::WATER.density) * verify::G
                    / verify::sheet_terminal()
                    / verify::SHEET_DENSITY,
                "drag-to-mass ratio K/m [1/s]",
            ),
        }
    }

    fn build(self) -> verify::CoupledScene {
        match self {
            Scene::Strand { density, xi_d } => verify::light_strand(STRAND_RADIUS, density, xi_d),
            Scene::Sheet => verify::settling_sheet(2e-4),
        }
    }
}

/// Drag per unit solid volume k [N s/m⁴] of the strand for ξ_D ([`verify::strand_drag`]).
pub fn strand_drag(xi_d: f64) -> f64 {
    verify::strand_drag(STRAND_RADIUS, xi_d)
}

/// The solid's mean vertical velocity every [`SAMPLE`] s over the scene's duration, with
/// step `h` and coupling `method`; the coupling iterations per step; None once a step fails
/// or the solid runs away (faster than 10 m/s).
fn history(scene: Scene, method: Coupling, tolerance: f64, h: f64) -> (Option<Vec<f64>>, f64) {
    let steps = (scene.duration() / h).round().max(1.0) as usize;
    let every = (SAMPLE / h).round().max(1.0) as usize;
    let (mut sys, mut state, elements, mut grid) = scene.build();
    let settings = CoupledSettings {
        method,
        tolerance,
        max_iterations: 100,
        relaxation: RelaxationMethod::Aitken,
        gravity: [0.0, -G, 0.0],
        ..Default::default()
    };
    let Ok(mut stepper) = CoupledStepper::new(&sys, &grid) else {
        return (None, f64::NAN);
    };
    let (mut out, mut iterations) = (Vec::new(), 0);
    for n in 1..=steps {
        match stepper.step(
            &mut sys, &elements, &mut state, &mut grid, None, h, &settings,
        ) {
            Ok(s) => iterations += s.iterations,
            Err(_) => return (None, f64::NAN),
        }
        let v = state.v.iter().map(|v| v.y).sum::<f64>() / state.v.len() as f64;
        if v.is_nan() || v.abs() >= 10.0 {
            return (None, f64::NAN);
        }
        if n % every == 0 {
            out.push(v);
        }
    }
    (Some(out), iterations as f64 / steps as f64)
}

/// The converged reference of `scene`: Newton coupling (Aitken) at h = 1/1600 s to
/// 10⁻⁸ m/s. None when even that fails.
pub fn reference(scene: Scene) -> Option<Vec<f64>> {
    history(scene, Coupling::Newton, 1e-8, 1.0 / 1600.0).0
}

/// `scene` at step `h` with coupling `method` against its `reference`, inaccurate above
/// [`COUPLED_INACCURATE`].
pub fn coupled_run(
    scene: Scene,
    method: (Coupling, &'static str),
    h: f64,
    reference: Option<&[f64]>,
) -> Run {
    let t = Instant::now();
    let (history, iterations) = history(scene, method.0, 1e-6, h);
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
    Run {
        scene: scene.name(),
        method: method.1,
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
    }
}
