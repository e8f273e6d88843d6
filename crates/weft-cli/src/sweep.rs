//! Sweeps of speed against accuracy (`weft bench accuracy`): verification scenes run over
//! step sizes, stiffnesses and methods, each run's error against its reference and its wall
//! time recorded, every run written as CSV and JSON.
//!
//! Scenes so far (solids, `weft-solid` directly):
//! - **pendulum**: a 1 kg bob on a 1 m rod of stretch stiffness k, released at 0.3 rad and
//!   run for 1 s. Reference: the same elastic pendulum integrated by classical RK4 at a step
//!   far below its fastest period (converged: halving that step changes the answer by less
//!   than 1e-9 m). Error: the bob's distance from the reference position at t = 1 s.
//!
//! A run is **blown up** when its state became non-finite or left 10 rod lengths, is
//! **inaccurate** when its error exceeds [`INACCURATE`], and **stable** otherwise.

use serde::Serialize;
use std::time::Instant;
use weft_solid::energy::RodStretch;
use weft_solid::{Integrator, Method, Settings, SolidSystem, State};

/// Error above which a run is called inaccurate: 1 cm, 1 % of the pendulum's length.
pub const INACCURATE: f64 = 1e-2;

/// What became of a run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    /// Finite, and within [`INACCURATE`] of the reference.
    Stable,
    /// Finite, but further than [`INACCURATE`] from the reference.
    Inaccurate,
    /// Non-finite, or ran away.
    BlownUp,
}

impl Status {
    /// The name used in CSV and JSON.
    pub fn name(self) -> &'static str {
        match self {
            Status::Stable => "stable",
            Status::Inaccurate => "inaccurate",
            Status::BlownUp => "blown_up",
        }
    }
}

/// One run of a sweep.
#[derive(Clone, Debug, Serialize)]
pub struct Run {
    /// The verification scene.
    pub scene: &'static str,
    /// `explicit`, `linearized` or `newton`.
    pub method: &'static str,
    /// Time step [s].
    pub h: f64,
    /// Stretch stiffness k [N] (the pendulum rod's).
    pub stiffness: f64,
    /// Distance from the reference at the end [m] (NaN when blown up).
    pub error: f64,
    /// Wall time of the run [s].
    pub seconds: f64,
    /// Time steps taken.
    pub steps: usize,
    /// Stable, inaccurate or blown up.
    pub status: Status,
}

/// The methods swept, with their names.
pub const METHODS: [(Method, &str); 3] = [
    (Method::Explicit, "explicit"),
    (Method::Linearized, "linearized"),
    (Method::Newton, "newton"),
];

const G: f64 = 9.81;
const LENGTH: f64 = 1.0;
const THETA0: f64 = 0.3;
const DURATION: f64 = 1.0;

fn bob_start() -> [f64; 3] {
    [LENGTH * THETA0.sin(), -LENGTH * THETA0.cos(), 0.0]
}

/// The elastic pendulum's bob at t = [`DURATION`] by RK4 with `n` steps: a 1 kg bob pulled
/// towards the pivot by k (l/L − 1) (the rod's stretch force) and down by gravity.
fn rk4_bob(k: f64, n: usize) -> [f64; 3] {
    let accel = |x: [f64; 3]| {
        let l = (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt();
        let f = -k * (l / LENGTH - 1.0) / l;
        [f * x[0], f * x[1] - G, f * x[2]]
    };
    let add =
        |a: [f64; 3], b: [f64; 3], s: f64| [a[0] + s * b[0], a[1] + s * b[1], a[2] + s * b[2]];
    let (mut x, mut v) = (bob_start(), [0.0; 3]);
    let dt = DURATION / n as f64;
    for _ in 0..n {
        let (k1x, k1v) = (v, accel(x));
        let (k2x, k2v) = (add(v, k1v, dt / 2.0), accel(add(x, k1x, dt / 2.0)));
        let (k3x, k3v) = (add(v, k2v, dt / 2.0), accel(add(x, k2x, dt / 2.0)));
        let (k4x, k4v) = (add(v, k3v, dt), accel(add(x, k3x, dt)));
        for i in 0..3 {
            x[i] += dt / 6.0 * (k1x[i] + 2.0 * k2x[i] + 2.0 * k3x[i] + k4x[i]);
            v[i] += dt / 6.0 * (k1v[i] + 2.0 * k2v[i] + 2.0 * k3v[i] + k4v[i]);
        }
    }
    x
}

/// The reference bob position for stiffness `k`: RK4 at 200 steps per fastest period
/// (ω = √k for the 1 kg bob on a 1 m rod), and at least 20 000 steps.
pub fn pendulum_reference(k: f64) -> [f64; 3] {
    let omega = k.sqrt().max((G / LENGTH).sqrt());
    let n = ((DURATION * omega / std::f64::consts::TAU * 200.0).ceil() as usize).max(20_000);
    rk4_bob(k, n)
}

/// Runs the pendulum with `method` at step `h` (rounded so that whole steps reach 1 s) and
/// stiffness `k`, against `reference` (the bob at 1 s).
pub fn pendulum_run(method: (Method, &'static str), h: f64, k: f64, reference: [f64; 3]) -> Run {
    let steps = (DURATION / h).round().max(1.0) as usize;
    let h = DURATION / steps as f64;
    let mut sys = SolidSystem::new(vec![1.0, 1.0]);
    sys.pinned[0] = true;
    sys.gravity = nalgebra::Vector3::new(0.0, -G, 0.0);
    sys.elements.stretches.push(RodStretch {
        v: [0, 1],
        rest_length: LENGTH,
        k,
    });
    let mut state = State {
        x: vec![nalgebra::Vector3::zeros(), bob_start().into()],
        v: vec![nalgebra::Vector3::zeros(); 2],
    };
    let settings = Settings {
        method: method.0,
        tolerance: 1e-10,
        max_iterations: 100,
    };
    let t = Instant::now();
    let mut blown = false;
    match Integrator::new(&sys) {
        Ok(mut integ) => {
            for _ in 0..steps {
                let ok = integ.step(&sys, &mut state, None, h, &settings).is_ok();
                if !ok || !state.x[1].iter().all(|c| c.is_finite()) || state.x[1].norm() > 10.0 {
                    blown = true;
                    break;
                }
            }
        }
        Err(_) => blown = true,
    }
    let seconds = t.elapsed().as_secs_f64();
    let error = if blown {
        f64::NAN
    } else {
        (state.x[1] - nalgebra::Vector3::from(reference)).norm()
    };
    Run {
        scene: "pendulum",
        method: method.1,
        h,
        stiffness: k,
        error,
        seconds,
        steps,
        status: if blown {
            Status::BlownUp
        } else if error > INACCURATE {
            Status::Inaccurate
        } else {
            Status::Stable
        },
    }
}

/// The least-squares slope of log(error) against log(h): the observed order of convergence.
pub fn fitted_order(points: &[(f64, f64)]) -> f64 {
    let n = points.len() as f64;
    let (lx, ly): (Vec<f64>, Vec<f64>) = points.iter().map(|(h, e)| (h.ln(), e.ln())).unzip();
    let (mx, my) = (lx.iter().sum::<f64>() / n, ly.iter().sum::<f64>() / n);
    let sxy: f64 = lx.iter().zip(&ly).map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: f64 = lx.iter().map(|x| (x - mx).powi(2)).sum();
    sxy / sxx
}

/// For each run, whether it is on the Pareto front of (wall time, error) among the finite
/// runs: no other run is both faster and more accurate.
pub fn pareto_front(runs: &[Run]) -> Vec<bool> {
    runs.iter()
        .map(|r| {
            r.error.is_finite()
                && !runs.iter().any(|o| {
                    o.error.is_finite()
                        && o.seconds <= r.seconds
                        && o.error <= r.error
                        && (o.seconds < r.seconds || o.error < r.error)
                })
        })
        .collect()
}

/// The runs as CSV (a header, then a row per run, with the Pareto flag).
pub fn csv(runs: &[Run]) -> String {
    let front = pareto_front(runs);
    let mut s = String::from("scene,method,h,stiffness,error,seconds,steps,status,pareto\n");
    for (r, p) in runs.iter().zip(front) {
        s += &format!(
            "{},{},{:e},{:e},{:e},{:e},{},{},{}\n",
            r.scene,
            r.method,
            r.h,
            r.stiffness,
            r.error,
            r.seconds,
            r.steps,
            r.status.name(),
            p
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The RK4 reference is converged: doubling its steps moves it by less than 1e-9 m.
    #[test]
    fn the_reference_is_converged() {
        for k in [1e3, 1e6] {
            let a = pendulum_reference(k);
            let omega = k.sqrt();
            let n = ((omega / std::f64::consts::TAU * 200.0).ceil() as usize).max(20_000);
            let b = rk4_bob(k, 2 * n);
            let d = (0..3).map(|i| (a[i] - b[i]).powi(2)).sum::<f64>().sqrt();
            assert!(d < 1e-9, "k = {k}: {d}");
        }
    }

    /// A fitted order on exact power laws is the power; the Pareto front drops dominated runs.
    #[test]
    fn orders_and_pareto_fronts() {
        let pts: Vec<(f64, f64)> = [0.1, 0.05, 0.025]
            .iter()
            .map(|h| (*h, 3.0 * h * h))
            .collect();
        assert!((fitted_order(&pts) - 2.0).abs() < 1e-12);
        let run = |seconds, error| Run {
            scene: "t",
            method: "m",
            h: 0.1,
            stiffness: 1.0,
            error,
            seconds,
            steps: 1,
            status: Status::Stable,
        };
        let runs = [
            run(1.0, 0.1),
            run(2.0, 0.2),
            run(3.0, 0.01),
            run(0.5, f64::NAN),
        ];
        assert_eq!(pareto_front(&runs), [true, false, true, false]);
    }
}
