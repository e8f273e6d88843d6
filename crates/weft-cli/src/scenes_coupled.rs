//! Coupled verification scenes for the sweeps: a light strand rising in strong drag (the
//! coupling stability map) and a settling porous sheet.

use crate::sweep::{Run, Status};
use nalgebra::Vector3;
use std::time::Instant;
use weft_fluid::{Boundaries, Domain, DragParams, FluidProperties, MacGrid};
use weft_sim::{
    CoupledSettings, CoupledStepper, Coupling, DragElement, DragShape, RelaxationMethod,
};
use weft_solid::energy::RodStretch;
use weft_solid::{SolidSystem, State};

/// The coupling methods swept, with their names.
pub const COUPLINGS: [(Coupling, &str); 3] = [
    (Coupling::OneWay, "one_way"),
    (Coupling::Staggered, "staggered"),
    (Coupling::Newton, "newton"),
];

const G: f64 = 9.81;
/// The strand's radius: 2 mm, so it fills about 3 % of the 2 cm cells it crosses (a thick
/// strand, filling half of them, caps solid fractions and makes every partitioned scheme
/// fragile).
const STRAND_RADIUS: f64 = 2e-3;

/// Drag per unit solid volume k [N s/m⁴] of the strand's linear branch for ξ_D:
/// (μ/D²)·ξ_D ξ⊥/10⁴ with ξ⊥ = 1.
pub fn strand_drag(xi_d: f64) -> f64 {
    let d = 2.0 * STRAND_RADIUS;
    FluidProperties::WATER.viscosity / (d * d) * xi_d / 1e4
}

/// How long the strand rises [s], and the interval at which its speed is compared with the
/// reference [s] (every swept step divides it).
pub const STRAND_DURATION: f64 = 0.2;
const STRAND_SAMPLE: f64 = 0.04;

/// The strand's mean vertical velocity every [`STRAND_SAMPLE`] s over [`STRAND_DURATION`],
/// with step `h` and coupling `method`; the coupling iterations per step; None once a step
/// fails or the strand runs away (faster than 10 m/s).
fn strand_history(
    method: Coupling,
    relaxation: RelaxationMethod,
    tolerance: f64,
    h: f64,
    density: f64,
    xi_d: f64,
) -> (Option<Vec<f64>>, f64) {
    let steps = (STRAND_DURATION / h).round().max(1.0) as usize;
    let every = (STRAND_SAMPLE / h).round().max(1.0) as usize;
    let (mut sys, mut state, elements, mut grid) = light_strand(density, xi_d);
    let settings = CoupledSettings {
        method,
        tolerance,
        max_iterations: 100,
        relaxation,
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

/// The converged reference for the strand of `density` and drag scale `xi_d`: Newton
/// coupling (Aitken) at h = 1/1600 s to 10⁻⁸ m/s. None when even that fails.
pub fn strand_reference(density: f64, xi_d: f64) -> Option<Vec<f64>> {
    strand_history(
        Coupling::Newton,
        RelaxationMethod::Aitken,
        1e-8,
        1.0 / 1600.0,
        density,
        xi_d,
    )
    .0
}

/// A light strand (radius 2 mm, 12 cm long, density `density`) rising in a closed box of
/// water, with drag scale `xi_d`, at step `h` with coupling `method`. Error: the largest
/// distance of its mean vertical velocity from the `reference`'s at the sample times,
/// relative to the reference's largest; inaccurate above 5 %. The swept parameter is the
/// drag-to-mass ratio K/m = k/ρ_s [1/s] (k the drag per unit solid volume).
pub fn light_strand_run(
    method: (Coupling, &'static str),
    h: f64,
    density: f64,
    xi_d: f64,
    reference: Option<&[f64]>,
) -> Run {
    let t = Instant::now();
    let (history, iterations) =
        strand_history(method.0, RelaxationMethod::Aitken, 1e-6, h, density, xi_d);
    let seconds = t.elapsed().as_secs_f64();
    let steps = (STRAND_DURATION / h).round().max(1.0) as usize;
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
    Run {
        scene: "light_strand",
        method: method.1,
        h: STRAND_DURATION / steps as f64,
        dx: 0.02,
        param: strand_drag(xi_d) / density,
        param_name: "drag-to-mass ratio K/m [1/s]",
        error,
        error_unit: "relative",
        iterations,
        seconds,
        steps,
        // Without a reference only a blow-up can be judged.
        status: if reference.is_none() && history.is_some() {
            Status::Stable
        } else {
            Status::of(history.is_none(), error, STRAND_INACCURATE)
        },
    }
}

/// Relative error above which a strand run is inaccurate.
pub const STRAND_INACCURATE: f64 = 0.05;

type Coupled = (SolidSystem, State, Vec<DragElement>, MacGrid);

/// The strand (8 segments along x at mid-height) and its 0.2 m box of 2 cm cells.
fn light_strand(density: f64, xi_d: f64) -> Coupled {
    let d = Domain::new([0.0; 3], [0.2; 3], 0.02, Boundaries::closed(), None).expect("a valid box");
    let grid = MacGrid::new(d);
    let (n, len, start) = (8, 0.12, [0.04, 0.1, 0.1]);
    let area = std::f64::consts::PI * STRAND_RADIUS * STRAND_RADIUS;
    let l = len / n as f64;
    let mut mass = vec![density * area * l; n + 1];
    mass[0] *= 0.5;
    mass[n] *= 0.5;
    let mut sys = SolidSystem::new(mass);
    sys.gravity = Vector3::new(0.0, -G, 0.0);
    let params = DragParams {
        xi_d,
        diameter: 2.0 * STRAND_RADIUS,
        ..Default::default()
    };
    let mut elements = Vec::new();
    for i in 0..n as u32 {
        sys.elements.stretches.push(RodStretch {
            v: [i, i + 1],
            rest_length: l,
            k: 10.0,
        });
        elements.push(DragElement {
            shape: DragShape::Segment([i, i + 1], area),
            params,
        });
    }
    let x = (0..=n)
        .map(|i| Vector3::new(start[0] + i as f64 * l, start[1], start[2]))
        .collect();
    let state = State {
        x,
        v: vec![Vector3::zeros(); n + 1],
    };
    (sys, state, elements, grid)
}
