//! `weft bench accuracy`: the solid integrators' speed against their accuracy, and where each
//! is stable (see [`crate::sweep`] for the scenes, references and statuses).
//!
//! Three sweeps of the pendulum:
//! - **convergence**: a stiff rod (k = 10⁶ N, fastest period 6.3 ms) over step sizes from
//!   1/25 s to 1/3200 s, every method (`explicit`, `linearized`, `newton`), the observed order
//!   fitted on the steps at or below 1/200 s;
//! - **stability map**: stiffness 10²…10⁷ N × the same steps, each cell stable, inaccurate or
//!   blown up;
//! - **Newton tolerance**: 10⁻¹…10⁻⁸ m/s at three steps: error, iterations and wall time.
//!
//! And the clamped strand (`scenes/strand.json`) over segments, before and after the root
//! clamp: its static tip deflection against the elastica, with `root_vertices: 2` (the
//! clamp: second order) and with the first two vertices held (how it was clamped before:
//! first order), charted as `accuracy_clamp`.
//!
//! Theory fixes what `--quick` asserts: implicit Euler (`newton`, and `linearized`, which
//! differs from it at second order) and symplectic Euler (`explicit`, where it is stable)
//! converge at first order; symplectic Euler is stable only below h = 2/ω (ω = √k here), so
//! it must blow up above 1.2 × that step and hold below 0.5 × it; `newton` never blows up.
//! Newton stopped at 10⁻⁶ m/s matches the converged error to 0.1 %; at 10⁻¹ m/s (one
//! iteration: linearized Euler) within 25 %; iterations never fall as the tolerance
//! tightens.

use crate::sweep::{self, Run, Status};
use serde::Serialize;
use std::path::Path;

/// What the sweep found.
#[derive(Serialize)]
pub struct Summary {
    /// Observed order of convergence per method (stiff rod, small steps).
    pub orders: Vec<(String, f64)>,
    /// Facts checked against theory (each with whether it held).
    pub checks: Vec<(String, bool)>,
}

fn steps(quick: bool) -> Vec<f64> {
    let n: &[f64] = if quick {
        &[25.0, 100.0, 400.0, 1600.0, 3200.0]
    } else {
        &[25.0, 50.0, 100.0, 200.0, 400.0, 800.0, 1600.0, 3200.0]
    };
    n.iter().map(|n| 1.0 / n).collect()
}

/// Runs both sweeps, writes `accuracy.csv` and `accuracy.json` into `out`, prints the orders
/// and the stability map, and returns the summary.
pub fn suite(quick: bool, out: &Path) -> Result<Summary, String> {
    let hs = steps(quick);
    let stiff = 1e6;
    let stiffnesses: &[f64] = if quick {
        &[1e3, 1e5, 1e7]
    } else {
        &[1e2, 1e3, 1e4, 1e5, 1e6, 1e7]
    };
    let mut runs: Vec<Run> = Vec::new();
    let mut ks: Vec<f64> = stiffnesses.to_vec();
    if !ks.contains(&stiff) {
        ks.push(stiff);
    }
    for &k in &ks {
        let reference = sweep::pendulum_reference(k);
        for &m in &sweep::METHODS {
            for &h in &hs {
                runs.push(sweep::pendulum_run(m, h, k, reference));
            }
        }
    }
    // The run of stiffness k, method m and step h (of the step sweep).
    let find = |k: f64, m: &str, h: f64| {
        runs.iter()
            .find(|r| r.param == k && r.method == m && (r.h - h).abs() < 1e-12)
    };
    let mut orders = Vec::new();
    println!("pendulum, k = {stiff:e} N: error at 1 s against RK4 [m]");
    println!("| h [s] | {} |", sweep::METHODS.map(|m| m.1).join(" | "));
    println!("|---:|{}", "---:|".repeat(3));
    for &h in &hs {
        let cells: Vec<String> = sweep::METHODS
            .iter()
            .map(|m| {
                find(stiff, m.1, h).map_or("-".into(), |r| {
                    format!("{:.3e} ({:.1} ms)", r.error, r.seconds * 1e3)
                })
            })
            .collect();
        println!("| 1/{:.0} | {} |", 1.0 / h, cells.join(" | "));
    }
    for m in &sweep::METHODS {
        let pts: Vec<(f64, f64)> = runs
            .iter()
            .filter(|r| {
                r.param == stiff
                    && r.method == m.1
                    && r.h <= 1.0 / 200.0 + 1e-12
                    && r.status != Status::BlownUp
            })
            .map(|r| (r.h, r.error))
            .collect();
        let order = if pts.len() >= 2 {
            sweep::fitted_order(&pts)
        } else {
            f64::NAN
        };
        orders.push((m.1.to_string(), order));
    }
    sweep::print_orders(&orders);
    println!(
        "\nstability map (S stable, I inaccurate > 1 cm, X blown up, F failed): rows k [N], columns h"
    );
    sweep::print_map(&runs, &sweep::METHODS.map(|m| m.1), stiffnesses, &hs);
    // What theory fixes.
    let mut checks = Vec::new();
    for (m, o) in &orders {
        checks.push((
            format!("{m}: first order (observed {o:.3}, band 0.8–1.2)"),
            (0.8..=1.2).contains(o),
        ));
    }
    let explicit = |pred: &dyn Fn(&Run) -> bool| {
        runs.iter()
            .filter(|r| r.method == "explicit" && pred(r))
            .collect::<Vec<_>>()
    };
    let above = explicit(&|r| r.h > 1.2 * 2.0 / r.param.sqrt());
    checks.push((
        format!("explicit blows up above 1.2 × 2/ω ({} runs)", above.len()),
        !above.is_empty() && above.iter().all(|r| r.status == Status::BlownUp),
    ));
    let below = explicit(&|r| r.h < 0.5 * 2.0 / r.param.sqrt());
    checks.push((
        format!("explicit holds below 0.5 × 2/ω ({} runs)", below.len()),
        !below.is_empty() && below.iter().all(|r| r.status != Status::BlownUp),
    ));
    checks.push((
        "newton never blows up".into(),
        runs.iter()
            .filter(|r| r.method == "newton")
            .all(|r| r.status != Status::BlownUp),
    ));
    // The Newton tolerance: error and cost against how far each step is converged.
    let tol_steps: &[f64] = if quick {
        &[100.0]
    } else {
        &[25.0, 100.0, 400.0]
    };
    let tolerances: &[f64] = if quick {
        &[1e-1, 1e-3, 1e-6]
    } else {
        &[1e-1, 3e-2, 1e-2, 3e-3, 1e-3, 1e-4, 1e-6, 1e-8]
    };
    let reference = sweep::pendulum_reference(stiff);
    let newton = sweep::METHODS[2];
    let mut tol_runs = Vec::new();
    for &n in tol_steps {
        for &tol in tolerances {
            tol_runs.push(sweep::pendulum_run_to(
                newton,
                1.0 / n,
                stiff,
                reference,
                tol,
            ));
        }
    }
    println!("\nNewton tolerance (k = {stiff:e} N): error [m] (iterations per step, wall time)");
    println!(
        "| tolerance [m/s] | {} |",
        tol_steps
            .iter()
            .map(|n| format!("h = 1/{n}"))
            .collect::<Vec<_>>()
            .join(" | ")
    );
    println!("|---:|{}", "---:|".repeat(tol_steps.len()));
    for &tol in tolerances {
        let cells: Vec<String> = tol_steps
            .iter()
            .map(|&n| {
                tol_runs
                    .iter()
                    .find(|r| r.param == tol && (r.h - 1.0 / n).abs() < 1e-12)
                    .map_or("-".into(), |r| {
                        format!(
                            "{:.3e} ({:.2} it, {:.1} ms)",
                            r.error,
                            r.iterations,
                            r.seconds * 1e3
                        )
                    })
            })
            .collect();
        println!("| {tol:.0e} | {} |", cells.join(" | "));
    }
    // Theory: the loosest tolerance that still resolves a step's velocity change leaves the
    // converged answer; at 1e-6 m/s (10⁻⁶ of the bob's speed) the run must match the
    // 1e-10 one to 0.1 %, and iterations per step cannot fall as the tolerance tightens.
    for &n in tol_steps {
        let h = 1.0 / n;
        let exact = runs
            .iter()
            .find(|r| r.param == stiff && r.method == "newton" && (r.h - h).abs() < 1e-12)
            .map(|r| r.error);
        let at = |tol: f64| {
            tol_runs
                .iter()
                .find(|r| r.param == tol && (r.h - h).abs() < 1e-12)
        };
        // A missing run fails its check rather than skipping it.
        let close = |tol: f64, within: f64| match (exact, at(tol)) {
            (Some(exact), Some(r)) => (
                format!(
                    "newton at tolerance {tol:.0e} m/s, h = 1/{n}: error {:.4e} within {} % of the converged {exact:.4e}",
                    r.error,
                    within * 100.0
                ),
                (r.error / exact - 1.0).abs() < within,
            ),
            _ => (
                format!("newton at tolerance {tol:.0e} m/s, h = 1/{n}: run missing"),
                false,
            ),
        };
        checks.push(close(1e-6, 1e-3));
        // One Newton step is linearized implicit Euler: first order like the converged step,
        // so a tolerance above the step's velocity change costs little accuracy (and must not
        // leave the bob where it was).
        checks.push(close(1e-1, 0.25));
        let its: Vec<f64> = tolerances
            .iter()
            .filter_map(|&t| at(t).map(|r| r.iterations))
            .collect();
        checks.push((
            format!(
                "newton iterations per step grow as the tolerance tightens (h = 1/{n}: {its:.2?})"
            ),
            its.len() == tolerances.len() && its.windows(2).all(|w| w[1] >= w[0]),
        ));
    }
    let clamp_runs = clamp_sweep(quick, &mut orders, &mut checks);
    sweep::print_checks(&checks);
    let summary = Summary { orders, checks };
    let mut all = runs.clone();
    all.extend(tol_runs.iter().cloned());
    all.extend(clamp_runs.iter().cloned());
    sweep::write_runs(
        out,
        "accuracy",
        &all,
        serde_json::json!({
            "orders": summary.orders,
            "checks": summary.checks,
            "inaccurate_above_m": sweep::INACCURATE,
        }),
    )?;
    crate::charts::error_vs_time_by(
        &tol_runs,
        |r| format!("h = 1/{:.0}", 1.0 / r.h),
        "Pendulum (k = 1e6 N), newton: error against wall time over the tolerance",
        &out.join("accuracy_tolerance"),
    )?;
    let stiff_runs: Vec<Run> = runs.iter().filter(|r| r.param == stiff).cloned().collect();
    crate::charts::error_vs_time(
        &stiff_runs,
        "Pendulum (k = 1e6 N): error at 1 s against wall time",
        &out.join("accuracy_error_time"),
    )?;
    crate::charts::error_vs(
        crate::charts::Across::Step,
        &stiff_runs,
        &summary.orders,
        "Pendulum (k = 1e6 N): error at 1 s against step size",
        &out.join("accuracy_error_step"),
    )?;
    let clamp_orders: Vec<(String, f64)> = summary
        .orders
        .iter()
        .filter(|(m, _)| m == "clamped" || m == "two_pins")
        .cloned()
        .collect();
    crate::charts::error_vs(
        crate::charts::Across::Size,
        &clamp_runs,
        &clamp_orders,
        "Clamped strand (0.1 m, 1 GPa, r = 0.5 mm): tip deflection error against segment length",
        &out.join("accuracy_clamp"),
    )?;
    let map_runs: Vec<Run> = runs
        .iter()
        .filter(|r| stiffnesses.contains(&r.param))
        .cloned()
        .collect();
    crate::charts::stability_map(
        &map_runs,
        |r| r.param,
        "rod stiffness k [N]",
        "Pendulum stability: green stable, orange error > 1 cm, red blown up",
        &out.join("accuracy_stability"),
    )?;
    println!(
        "\nwrote {} runs and charts (PNG, SVG) to {}",
        all.len(),
        out.display()
    );
    Ok(summary)
}

/// The clamped strand's static tip deflection against the elastica over segments, with the
/// root clamp (`clamped`: `root_vertices: 2`) and as clamps were made before it
/// (`two_pins`: the first two vertices held, which clamps the tangent half a segment out).
/// Theory: the clamp is second order and within 0.5 % at 40 segments; two pins are first
/// order (their beam is l/2 short: the error is −2l/L).
fn clamp_sweep(
    quick: bool,
    orders: &mut Vec<(String, f64)>,
    checks: &mut Vec<(String, bool)>,
) -> Vec<Run> {
    use crate::scenes_strand::Root;
    let segments: &[usize] = if quick {
        &[10, 20, 40]
    } else {
        &[10, 20, 40, 80, 160]
    };
    let mut runs = Vec::new();
    for root in [Root::TwoPins, Root::Clamped] {
        for &n in segments {
            runs.push(crate::scenes_resolution::strand_cantilever(n, root));
        }
    }
    println!("\nclamped strand cantilever: relative error of the tip deflection");
    println!("| segments | two pins (before) | clamped root |");
    println!("|---:|---:|---:|");
    let at = |m: &str, n: usize| {
        runs.iter().find(|r: &&Run| {
            r.method == m && (r.dx * n as f64 - crate::scenes_strand::LENGTH).abs() < 1e-12
        })
    };
    for &n in segments {
        let cell = |m: &str| at(m, n).map_or("-".into(), |r| format!("{:.2e}", r.error));
        println!("| {n} | {} | {} |", cell("two_pins"), cell("clamped"));
    }
    for m in ["two_pins", "clamped"] {
        let pts: Vec<(f64, f64)> = runs
            .iter()
            .filter(|r| r.method == m && r.error.is_finite())
            .map(|r| (r.dx, r.error))
            .collect();
        let order = if pts.len() >= 2 {
            sweep::fitted_order(&pts)
        } else {
            f64::NAN
        };
        orders.push((m.to_string(), order));
        let (lo, hi) = if m == "clamped" {
            (1.8, 2.3)
        } else {
            (0.8, 1.2)
        };
        checks.push((
            format!("{m} strand cantilever: order {order:.3} in {lo}–{hi}"),
            (lo..=hi).contains(&order),
        ));
    }
    let e40 = at("clamped", 40).map_or(f64::NAN, |r| r.error);
    checks.push((
        format!(
            "clamped strand cantilever within 0.5 % at 40 segments ({:.3} %)",
            e40 * 100.0
        ),
        e40 < 5e-3,
    ));
    runs
}
