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
use weft_solid::Method;

/// Error above which a run is called inaccurate: 1 cm, 1 % of the pendulum's length.
pub const INACCURATE: f64 = 1e-2;

/// What became of a run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    /// Finite, and within the scene's threshold of the reference.
    Stable,
    /// Finite, but further than the threshold from the reference.
    Inaccurate,
    /// A time-stepped run that became non-finite, ran away, or whose step failed.
    BlownUp,
    /// A solve that gave up without blowing up (a static solve that did not converge), or
    /// whose error could not be measured.
    Failed,
    /// Finished, but there was no reference to judge it by.
    Unjudged,
}

impl Status {
    /// The status of a run that `blown` up, or ended `error` from its reference (NaN: not
    /// measured), inaccurate above `threshold`.
    pub fn of(blown: bool, error: f64, threshold: f64) -> Status {
        if blown {
            Status::BlownUp
        } else if error.is_nan() {
            Status::Failed
        } else if error > threshold {
            Status::Inaccurate
        } else {
            Status::Stable
        }
    }

    /// The name used in CSV and JSON.
    pub fn name(self) -> &'static str {
        match self {
            Status::Stable => "stable",
            Status::Inaccurate => "inaccurate",
            Status::BlownUp => "blown_up",
            Status::Failed => "failed",
            Status::Unjudged => "unjudged",
        }
    }

    /// The letter used in text maps.
    pub fn letter(self) -> char {
        match self {
            Status::Stable => 'S',
            Status::Inaccurate => 'I',
            Status::BlownUp => 'X',
            Status::Failed => 'F',
            Status::Unjudged => '?',
        }
    }
}

/// One run of a sweep.
#[derive(Clone, Debug, Serialize)]
pub struct Run {
    /// The verification scene.
    pub scene: &'static str,
    /// The method: `explicit`, `linearized` or `newton` for solids; `one_way`, `staggered` or
    /// `newton` for coupling; the scene's own name for resolution sweeps.
    pub method: &'static str,
    /// Time step [s] (NaN for static solves).
    pub h: f64,
    /// Cell or segment size [m] (NaN where the scene has no grid).
    pub dx: f64,
    /// The scene's swept parameter, named by `param_name` (the pendulum's stiffness, the
    /// strand's drag-to-mass ratio, the Newton tolerance; NaN when none).
    pub param: f64,
    /// What `param` is, with its unit.
    pub param_name: &'static str,
    /// Distance from the reference (NaN when blown up), in `error_unit`.
    pub error: f64,
    /// `m`, `m/s`, or `relative` (a fraction of the reference).
    pub error_unit: &'static str,
    /// Solver iterations per step (Newton for solids, coupling iterations for coupled
    /// scenes; NaN where none are counted).
    pub iterations: f64,
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
/// stiffness `k`, against `reference` (the bob at 1 s), Newton converged to 10⁻¹⁰ m/s.
pub fn pendulum_run(method: (Method, &'static str), h: f64, k: f64, reference: [f64; 3]) -> Run {
    pendulum(method, h, k, reference, 1e-10, false)
}

/// The parameter name of a Newton-tolerance sweep (its runs compare across tolerances).
pub const TOLERANCE: &str = "Newton tolerance [m/s]";

/// [`pendulum_run`] with Newton stopping at `tolerance` [m/s] (the largest velocity change
/// of an iteration): a run of the scene `pendulum_tolerance`, whose parameter is the
/// tolerance.
pub fn pendulum_run_to(
    method: (Method, &'static str),
    h: f64,
    k: f64,
    reference: [f64; 3],
    tolerance: f64,
) -> Run {
    pendulum(method, h, k, reference, tolerance, true)
}

/// The pendulum scene: a graph file (`scenes/pendulum.json`) stepped by `solver.solid`,
/// the node users run.
pub const PENDULUM: &str = include_str!("../scenes/pendulum.json");

fn pendulum(
    method: (Method, &'static str),
    h: f64,
    k: f64,
    reference: [f64; 3],
    tolerance: f64,
    swept: bool,
) -> Run {
    let steps = (DURATION / h).round().max(1.0) as usize;
    let h = DURATION / steps as f64;
    let fps = steps as f64 / DURATION;
    let t = Instant::now();
    let mut blown = false;
    let mut bob = [f64::NAN; 3];
    let mut graph = crate::graphs::load(PENDULUM, "pendulum.json").and_then(|mut g| {
        // The rod's cross-section is 1 m², so Young's modulus is the stiffness k.
        crate::graphs::set(&mut g, "rod.youngs_modulus", k.into())?;
        crate::graphs::set(&mut g, "solve.method", method.1.into())?;
        crate::graphs::set(&mut g, "solve.tolerance", tolerance.into())?;
        Ok(g)
    });
    match &mut graph {
        Ok(g) => {
            for f in 1..=steps as i64 {
                let x = g
                    .pull("bob", weft_graph::Context::at(f, fps))
                    .ok()
                    .and_then(|v| v.get::<[f64; 3]>().copied());
                match x {
                    Some(x) if x.iter().all(|c| c.is_finite()) && norm(x) <= 10.0 => bob = x,
                    _ => {
                        blown = true;
                        break;
                    }
                }
            }
        }
        Err(_) => blown = true,
    }
    let seconds = t.elapsed().as_secs_f64();
    let iterations = graph
        .as_ref()
        .map_or(f64::NAN, |g| newton_per_step(g, "solve"));
    let error = if blown {
        f64::NAN
    } else {
        norm([0, 1, 2].map(|c| bob[c] - reference[c]))
    };
    Run {
        scene: if swept {
            "pendulum_tolerance"
        } else {
            "pendulum"
        },
        method: method.1,
        h,
        dx: f64::NAN,
        param: if swept { tolerance } else { k },
        param_name: if swept {
            TOLERANCE
        } else {
            "rod stiffness k [N]"
        },
        error,
        error_unit: "m",
        iterations: if method.0 == Method::Explicit {
            f64::NAN
        } else {
            iterations
        },
        seconds,
        steps,
        status: Status::of(blown, error, INACCURATE),
    }
}

fn norm(x: [f64; 3]) -> f64 {
    (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt()
}

/// Newton iterations per step of a `solver.solid` node over every frame it stepped.
fn newton_per_step(g: &weft_graph::Graph, node: &str) -> f64 {
    g.stats()
        .iter()
        .find(|r| r.node == node)
        .and_then(|r| {
            let d = r.details.as_ref()?;
            Some(d["total_newton_iterations"].as_f64()? / d["total_steps"].as_f64()?)
        })
        .unwrap_or(f64::NAN)
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

/// Whether two runs belong on one Pareto front: the same scene, and the same parameter
/// where that parameter changes the problem (stiffness, drag); a tolerance sweep compares
/// across tolerances, which is its point.
pub fn comparable(a: &Run, b: &Run) -> bool {
    a.scene == b.scene && (a.param.to_bits() == b.param.to_bits() || a.param_name == TOLERANCE)
}

/// For each run, whether it is on the Pareto front of (wall time, error) among the finite
/// runs `same` says it compares with: no such run is both faster and more accurate.
pub fn pareto_front_by(runs: &[Run], same: fn(&Run, &Run) -> bool) -> Vec<bool> {
    runs.iter()
        .map(|r| {
            r.error.is_finite()
                && !runs.iter().any(|o| {
                    o.error.is_finite()
                        && same(o, r)
                        && o.seconds <= r.seconds
                        && o.error <= r.error
                        && (o.seconds < r.seconds || o.error < r.error)
                })
        })
        .collect()
}

/// [`pareto_front_by`] among [`comparable`] runs.
pub fn pareto_front(runs: &[Run]) -> Vec<bool> {
    pareto_front_by(runs, comparable)
}

/// The runs as CSV (a header, then a row per run, with the Pareto flag).
pub fn csv(runs: &[Run]) -> String {
    let front = pareto_front(runs);
    let mut s = String::from(
        "scene,method,h,dx,param,param_name,error,error_unit,iterations,seconds,steps,status,pareto\n",
    );
    for (r, p) in runs.iter().zip(front) {
        s += &format!(
            "{},{},{:e},{:e},{:e},\"{}\",{:e},{},{:e},{:e},{},{},{}\n",
            r.scene,
            r.method,
            r.h,
            r.dx,
            r.param,
            r.param_name,
            r.error,
            r.error_unit,
            r.iterations,
            r.seconds,
            r.steps,
            r.status.name(),
            p
        );
    }
    s
}

/// Facts checked against theory, each with whether it held.
pub type Checks = Vec<(String, bool)>;

/// The fitted order in step h of each of `methods` among `runs`.
pub fn orders_in_step(runs: &[Run], methods: &[&str]) -> Vec<(String, f64)> {
    methods
        .iter()
        .map(|m| (m.to_string(), order_of(runs, |r| r.h, |r| r.method == *m)))
        .collect()
}

/// The order named `name` in `orders` (NaN when absent).
pub fn order_named(orders: &[(String, f64)], name: &str) -> f64 {
    orders
        .iter()
        .find(|(m, _)| m == name)
        .map_or(f64::NAN, |o| o.1)
}

/// Prints the observed orders on one line.
pub fn print_orders(orders: &[(String, f64)]) {
    let list: Vec<String> = orders.iter().map(|(m, o)| format!("{m} {o:.3}")).collect();
    println!("\nobserved orders: {}", list.join(", "));
}

/// Prints the checks (ok / FAIL per line).
pub fn print_checks(checks: &Checks) {
    println!();
    for (c, ok) in checks {
        println!("{} {c}", if *ok { "ok  " } else { "FAIL" });
    }
}

/// Writes `runs` as `name`.csv and `name`.json (with `summary` and the status thresholds)
/// into `out`, atomically.
pub fn write_runs(
    out: &std::path::Path,
    name: &str,
    runs: &[Run],
    summary: serde_json::Value,
) -> Result<(), String> {
    std::fs::create_dir_all(out).map_err(|e| format!("cannot create {}: {e}", out.display()))?;
    let json = serde_json::json!({"runs": runs, "summary": summary});
    let json = serde_json::to_string_pretty(&json).map_err(|e| format!("JSON: {e}"))?;
    for (file, text) in [
        (format!("{name}.csv"), csv(runs)),
        (format!("{name}.json"), json),
    ] {
        let p = out.join(file);
        weft_graph::atomic_write(&p, text.as_bytes())
            .map_err(|e| format!("cannot write {}: {e}", p.display()))?;
    }
    Ok(())
}

/// The fitted order of the finite runs among `runs` that `keep` selects, by `x` (step or
/// cell size); NaN with fewer than two.
pub fn order_of(runs: &[Run], x: fn(&Run) -> f64, keep: impl Fn(&Run) -> bool) -> f64 {
    let pts: Vec<(f64, f64)> = runs
        .iter()
        .filter(|r| keep(r) && r.error.is_finite() && r.error > 0.0)
        .map(|r| (x(r), r.error))
        .collect();
    if pts.len() >= 2 {
        fitted_order(&pts)
    } else {
        f64::NAN
    }
}

/// Prints a stability map as text: a row per parameter value (ascending), a column per step
/// (descending), by [`Status::letter`]: S stable, I inaccurate, X blown up, F failed,
/// ? unjudged.
pub fn print_map(runs: &[Run], methods: &[&str], params: &[f64], hs: &[f64]) {
    for m in methods {
        println!("{m}:");
        for &p in params {
            let row: String = hs
                .iter()
                .map(|&h| {
                    runs.iter()
                        .find(|r| r.method == *m && r.param == p && (r.h - h).abs() < 1e-12)
                        .map_or(' ', |r| r.status.letter())
                })
                .collect();
            println!("  {p:9.2e}  {row}");
        }
    }
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
            dx: f64::NAN,
            param: 1.0,
            param_name: "p",
            error,
            error_unit: "m",
            iterations: 1.0,
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
        // Runs of another stiffness are not compared (each k is its own problem); runs of a
        // tolerance sweep are compared across tolerances.
        let mut other = run(5.0, 0.001);
        other.param = 2.0;
        let mixed = [run(1.0, 0.1), other.clone()];
        assert_eq!(pareto_front(&mixed), [true, true]);
        let mut tols = [run(1.0, 0.1), other];
        for r in tols.iter_mut() {
            r.param_name = TOLERANCE;
        }
        tols[1].seconds = 0.5;
        assert_eq!(pareto_front(&tols), [false, true]);
    }
}
